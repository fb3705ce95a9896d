"""Frames to every output at once, as they are drawn: each video's ffmpeg pipe, and the PNG sequence when asked.

A single-machine render streams its frames straight into the encoders (ffmpeg runs in its own process, so encoding
overlaps drawing) instead of writing PNGs and reading them back to encode afterwards. What is left after the last
frame is ffmpeg's tail: the frames still in its pipe and look-ahead, and the moov atom ``faststart`` moves to the
front. Videos are written under temporary names and renamed only when every one has finished, so an interrupted
render leaves no video under its final name.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import numpy as np

from animbatch.encode.images import PngSequenceWriter
from animbatch.encode.video import VideoWriter


class FrameStream:
    """Sends frame ``index`` (H, W, 3) uint8 to every video of ``videos`` (in frame order: frames must come in
    order) and to ``png`` when given. Use as a context manager; :meth:`commit` makes the videos final."""

    def __init__(self, videos: list[VideoWriter], png: PngSequenceWriter | None = None) -> None:
        self.videos = videos
        self.png = png
        self.next_index: int | None = None
        self._stack = contextlib.ExitStack()

    def write(self, index: int, image: np.ndarray) -> None:
        if self.next_index is not None and index != self.next_index:
            raise ValueError(f"frame {index} sent after frame {self.next_index - 1}: videos need every frame in order")
        self.next_index = index + 1
        if self.png is not None:
            self.png.write(index, image)
        for video in self.videos:
            video.write(image)

    def commit(self) -> tuple[list[Path], float]:
        """Finish every video (ffmpeg's tail) and move them to their final names; returns them and the seconds it
        took."""
        started = time.perf_counter()
        outputs = [video.commit() for video in self.videos]
        return outputs, time.perf_counter() - started

    def __enter__(self) -> FrameStream:
        for video in self.videos:
            self._stack.enter_context(video)
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.__exit__(*exc)  # aborts any video left uncommitted
