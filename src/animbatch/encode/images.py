"""PNG frame sequences: ``frames/frame_00000.png`` …, each file written atomically.

PNG compression level 1 is used: several times faster than the default 6, for files about 1.5× larger.
"""

from __future__ import annotations

import collections
import contextlib
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Protocol

import numpy as np

from animbatch.files import atomic_path

FRAME_PATTERN = "frame_{index:05d}.png"


class PngSequenceWriter:
    """Writes frame ``k`` to ``folder/frame_0000k.png``."""
    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.frames_written = 0

    def path_of(self, index: int) -> Path:
        return self.folder / FRAME_PATTERN.format(index=index)

    def write(self, index: int, image: np.ndarray) -> Path:
        from PIL import Image

        target = self.path_of(index)
        with atomic_path(target) as temporary:
            Image.fromarray(image).save(temporary, format="PNG", compress_level=1)
        self.frames_written += 1
        return target

    def remove_beyond(self, count: int) -> None:
        """Delete frames numbered ``count`` and above, left over from an earlier, longer run."""
        for path in self.folder.glob("frame_*.png"):
            stem = path.stem.removeprefix("frame_")
            if stem.isdigit() and int(stem) >= count:
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()


class FrameWriter(Protocol):
    """Where drawn frames go: a PNG sequence, or a :class:`~animbatch.encode.stream.FrameStream` (videos too)."""

    def write(self, index: int, image: np.ndarray) -> object: ...


class BackgroundFrameWriter:
    """Writes frames with a :class:`FrameWriter` on one background thread while the caller draws the next.

    PNG compression is a quarter of a frame's time at 720p, and Pillow releases the GIL while it compresses (as does
    writing to ffmpeg's pipe), so the two overlap. At most ``depth`` frames wait to be written (bounded memory).
    ``on_written(index, seconds)`` is called on the caller's thread, in frame order, once a frame is written.
    Leaving the ``with`` block, even on an error or Ctrl-C, first finishes the frames already handed over, so every
    frame drawn is either whole on disk or absent, and an error from a write is raised.
    """
    def __init__(self, writer: FrameWriter, on_written: Callable[[int, float], None], depth: int = 2) -> None:
        self.writer, self.on_written, self.depth = writer, on_written, depth
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="frame-writer")
        self._pending: collections.deque[tuple[int, Future[float]]] = collections.deque()

    def _write(self, index: int, image: np.ndarray) -> float:
        started = time.perf_counter()
        self.writer.write(index, image)
        return time.perf_counter() - started

    def submit(self, index: int, image: np.ndarray) -> None:
        """Queue frame ``index`` (the array must not change afterwards), first waiting while ``depth`` are queued."""
        while len(self._pending) >= self.depth:
            self._finish_oldest()
        self._pending.append((index, self._pool.submit(self._write, index, image)))

    def _finish_oldest(self) -> None:
        index, future = self._pending.popleft()
        self.on_written(index, future.result())

    def __enter__(self) -> BackgroundFrameWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        try:
            while self._pending:
                if kind is None:
                    self._finish_oldest()
                else:  # already failing: finish the files, report nothing more
                    self._pending.popleft()[1].exception()
        finally:
            self._pool.shutdown(wait=True)
