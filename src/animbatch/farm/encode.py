"""Encoding a scene's rendered frames (``frames/frame_00000.png`` …) into MP4, and WebM or GIF on request.

Every frame must be complete first (see :func:`~animbatch.farm.frames.frame_is_complete`); otherwise the error lists
the missing ones and the command that renders them. All videos are encoded in one pass over the frames, each under a
temporary name renamed when ffmpeg has finished.
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
from animbatch.farm.frames import frame_is_complete, frames_folder, output_stem
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


def encode(scene: LoadedScene, frame_count: int, *, out_dir: str | Path = "renders",
           kinds: tuple[str, ...] = ("mp4",)) -> EncodeResult:
    """Encode frames 0 … ``frame_count - 1`` of ``scene`` into ``out_dir/<scene>/<stem>.<kind>`` for each kind (the
    stem is the scene's name, with ``-<camera>`` for a named camera)."""
    from PIL import Image

    started = time.perf_counter()
    unknown = [kind for kind in kinds if kind not in VIDEO_KINDS]
    if unknown:
        raise ValueError(f"unknown video format {', '.join(unknown)}; choose from {', '.join(VIDEO_KINDS)}")
    frames = PngSequenceWriter(frames_folder(scene, out_dir))
    size = tuple(scene.spec.render.resolution)
    missing = [index for index in range(frame_count) if not frame_is_complete(frames.path_of(index), size)]
    if missing:
        where = scene.path or scene.name
        raise RenderError(f"{len(missing)} of {frame_count} frames are missing or incomplete in {frames.folder} "
                          f"({_ranges(missing)}); render them first: animbatch render {where} --frames "
                          f"{missing[0]}-{missing[-1]}")
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
