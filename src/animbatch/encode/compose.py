"""Videos side by side: one video whose frames are the frames of several, left to right (a kinematic and a dynamic
run of the same scene, two methods, two parameter values), written atomically like every video."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from animbatch.encode.video import VideoWriter
from animbatch.errors import RenderError


def _frames(path: Path) -> tuple[dict, object]:
    import imageio_ffmpeg  # finds the ffmpeg binary: only when encoding

    if not path.is_file():
        raise RenderError(f"{path}: no such video")
    reader = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgb24")
    meta = reader.__next__()
    return meta, reader


def side_by_side(videos: list[Path], output: Path, *, gap: int = 4, background: int = 255) -> Path:
    """Write ``output`` (mp4) with the frames of ``videos`` next to each other, ``gap`` [px] apart, in the first
    video's frame rate; they must share it. Shorter videos hold their last frame; shorter frames are padded with
    ``background`` below."""
    if len(videos) < 2:
        raise RenderError("side by side needs at least two videos")
    readers = [_frames(Path(path)) for path in videos]
    fps = [float(meta["fps"]) for meta, _ in readers]
    if any(abs(rate - fps[0]) > 1e-6 for rate in fps):
        shown = ", ".join(f"{path} {rate:g} fps" for path, rate in zip(videos, fps))
        raise RenderError(f"the videos have different frame rates ({shown}): render them at the same fps")
    sizes = [tuple(meta["size"]) for meta, _ in readers]  # (width, height) each
    height = max(h for _, h in sizes)
    width = sum(w for w, _ in sizes) + gap * (len(sizes) - 1)
    width += width % 2  # yuv420p needs even sides
    height += height % 2
    canvas = np.full((height, width, 3), background, np.uint8)
    last: list[np.ndarray | None] = [None] * len(readers)
    with VideoWriter(output, (width, height), fps[0]) as writer:
        for frames in itertools.zip_longest(*(reader for _, reader in readers)):
            left = 0
            for index, (frame, (w, h)) in enumerate(zip(frames, sizes)):
                if frame is not None:
                    last[index] = np.frombuffer(frame, np.uint8).reshape(h, w, 3)
                if last[index] is not None:
                    canvas[:h, left:left + w] = last[index]
                left += w + gap
            writer.write(canvas)
        return writer.commit()
