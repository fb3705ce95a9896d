"""Encoding a scene's rendered frames (``frames/frame_00000.png`` …) into MP4, and WebM or GIF on request.

Every frame must be complete first (see :func:`~animbatch.farm.frame_files.frame_is_complete`); otherwise the error
lists the missing ones and the command that renders them. All videos are encoded in one pass over the frames, each
under a temporary name renamed when ffmpeg has finished.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from animbatch.encode.images import PngSequenceWriter
from animbatch.encode.video import VIDEO_KINDS, VideoWriter
from animbatch.errors import RenderError
from animbatch.farm.frame_files import frame_is_complete, frames_folder, output_stem, sweep_killed_writers
from animbatch.scene import LoadedScene


@dataclass
class EncodeResult:
    outputs: list[Path]
    frame_count: int
    seconds: float


def _ranges(indices: list[int]) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"``."""
    parts, start = [], None
    for k, index in enumerate(indices):
        if start is None:
            start = index
        if k + 1 == len(indices) or indices[k + 1] != index + 1:
            parts.append(f"{start}-{index}" if index != start else f"{index}")
            start = None
    return ", ".join(parts)


def _size_on_disk(frames: PngSequenceWriter, missing: list[int], size: tuple[int, int]) -> tuple[int, int] | None:
    """The size of the first of the ``missing`` frames that is on disk at another size than ``size`` (rendered with
    other options), or None."""
    from PIL import Image, UnidentifiedImageError

    for index in missing:
        path = frames.path_of(index)
        if not path.is_file():
            continue
        try:
            with Image.open(path) as image:
                found = image.size
        except (OSError, UnidentifiedImageError):
            continue
        if found != size:
            return found
    return None


def missing_frames_message(scene: LoadedScene, frames: PngSequenceWriter, missing: list[int], frame_count: int,
                           size: tuple[int, int], render_options: str = "") -> str:
    """What is missing, what differs when the frames on disk have another size, and the commands that fix it."""
    where = scene.path or scene.name
    again = f"animbatch render {where} --frames {missing[0]}-{missing[-1]}" + (f" {render_options}"
                                                                             if render_options else "")
    text = (f"{len(missing)} of {frame_count} frames are missing or incomplete in {frames.folder} "
            f"({_ranges(missing)})")
    other = _size_on_disk(frames, missing, size)
    if other is None:
        return f"{text}; render them first: {again}"
    return (f"{text}: the frames there are {other[0]}×{other[1]}, but this scene, with these options, renders "
            f"{size[0]}×{size[1]} (render.resolution). To encode them as they are, give encode the options they "
            f"were rendered with (--resolution {other[0]}x{other[1]}, or the same --quality or --set); to draw them "
            f"at {size[0]}×{size[1]}: {again}")


def encode(scene: LoadedScene, frame_count: int, *, out_dir: str | Path = "renders",
           kinds: tuple[str, ...] = ("mp4",), render_options: str = "") -> EncodeResult:
    """Encode frames 0 … ``frame_count - 1`` of ``scene`` into ``out_dir/<scene>/<stem>.<kind>`` for each kind (the
    stem is the scene's name, with ``-<camera>`` for a named camera). ``render_options``: the command-line options
    the scene was loaded with, for the render command an error suggests."""
    from PIL import Image

    started = time.perf_counter()
    unknown = [kind for kind in kinds if kind not in VIDEO_KINDS]
    if unknown:
        raise ValueError(f"unknown video format {', '.join(unknown)}; choose from {', '.join(VIDEO_KINDS)}")
    sweep_killed_writers(scene, out_dir)  # a killed encoder's half-written video is never taken for one
    frames = PngSequenceWriter(frames_folder(scene, out_dir))
    size = (int(scene.spec.render.resolution[0]), int(scene.spec.render.resolution[1]))
    missing = [index for index in range(frame_count) if not frame_is_complete(frames.path_of(index), size)]
    if missing:
        raise RenderError(missing_frames_message(scene, frames, missing, frame_count, size, render_options))
    folder = Path(out_dir) / scene.name
    video = scene.spec.render.video
    writers = [VideoWriter(folder / f"{output_stem(scene)}.{kind}", size, scene.spec.fps, preset=video.preset,
                           crf=video.crf, kind=kind) for kind in kinds]
    with contextlib.ExitStack() as stack:
        for writer in writers:
            stack.enter_context(writer)
        for index in range(frame_count):
            with Image.open(frames.path_of(index)) as image:
                pixels = np.asarray(image.convert("RGB"))
            for writer in writers:
                writer.write(pixels)
        outputs = [writer.commit() for writer in writers]
    return EncodeResult(outputs, frame_count, time.perf_counter() - started)
