"""When frames are sampled: the one rule for a run's frame times, read by the scene format (to count frames), the
model builder (to sample the motion) and every driver (through the run plan)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np


def frame_count(duration: float, fps: float) -> int:
    """Number of frames of a ``duration`` [s] run at ``fps``: ``ceil(duration · fps)``, at least 1, so that the video
    lasts ``duration`` (the 1e-9 keeps 2 s at 30 fps at 60 frames despite rounding)."""
    return max(1, math.ceil(duration * fps - 1e-9))


def frame_times(duration: float, fps: float) -> np.ndarray:
    """The frame times ``k / fps`` [s] for ``k = 0 … frame_count(duration, fps) - 1``, shape (F,), read-only."""
    times = np.arange(frame_count(duration, fps)) / fps
    times.flags.writeable = False
    return times


@dataclass(frozen=True)
class Timeline:
    """A run's frames: ``times`` (F,) [s] at ``fps`` frames per second (``times[k] = k / fps``)."""

    times: np.ndarray
    fps: int

    @classmethod
    def of(cls, duration: float, fps: int) -> Timeline:
        return cls(frame_times(duration, fps), fps)

    @property
    def count(self) -> int:
        return len(self.times)

    @property
    def interval(self) -> float | None:
        """Seconds between frames (None with a single frame)."""
        return float(self.times[1] - self.times[0]) if len(self.times) > 1 else None

    def frames(self, text: str | None) -> FrameRange:
        """The range ``--frames`` names (:func:`parse_frames`; None: every frame)."""
        return parse_frames(text, self.count)


@dataclass(frozen=True)
class FrameRange:
    """Frames ``start`` … ``stop - 1`` (0-based, like ``range``)."""
    start: int
    stop: int

    def __iter__(self) -> Iterator[int]:
        return iter(range(self.start, self.stop))

    def __len__(self) -> int:
        return max(0, self.stop - self.start)

    def __str__(self) -> str:
        return f"{self.start}-{self.stop - 1}"

    def chunks(self, size: int) -> list[FrameRange]:
        """Consecutive ranges of at most ``size`` frames covering this one."""
        return [FrameRange(start, min(start + size, self.stop)) for start in range(self.start, self.stop, size)]


def parse_frames(text: str | None, frame_count: int) -> FrameRange:
    """``"120-239"`` (inclusive), ``"120-"`` (to the end), ``"7"`` (one frame), or None (all frames)."""
    if text is None:
        return FrameRange(0, frame_count)
    match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d*)\s*)?", text)
    if match is None:
        raise ValueError(f"--frames {text!r}: expected FIRST-LAST (e.g. 120-239), FIRST- or one frame number")
    first = int(match.group(1))
    last = first if match.group(2) is None and "-" not in text else (
        int(match.group(2)) if match.group(2) else frame_count - 1)
    if last < first:
        raise ValueError(f"--frames {text!r}: the last frame comes before the first")
    if first >= frame_count:
        raise ValueError(f"--frames {text!r}: the scene has {frame_count} frames (0-{frame_count - 1})")
    return FrameRange(first, min(last, frame_count - 1) + 1)
