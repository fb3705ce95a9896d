"""A stopwatch for timing the stages of a run, after the one in the lecture notes (start, stop, elapsed).

It uses ``time.perf_counter`` (monotonic, sub-microsecond) rather than wall-clock time, so that timings never jump when
the system clock is adjusted.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager


class Stopwatch:
    """Accumulates elapsed seconds per named stage.

    >>> watch = Stopwatch()
    >>> with watch.stage("simulate"):
    ...     pass
    >>> sorted(watch.seconds)
    ['simulate']
    """

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._started: float | None = None

    def start(self) -> None:
        self._started = time.perf_counter()

    def stop(self) -> float:
        """Stop and return the seconds since the last start."""
        if self._started is None:
            raise RuntimeError("Stopwatch.stop() called before start()")
        elapsed = time.perf_counter() - self._started
        self._started = None
        return elapsed

    def add(self, stage: str, seconds: float) -> None:
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the body of a ``with`` block and add it to stage ``name`` (also when the block raises)."""
        started = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - started)
