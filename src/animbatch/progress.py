"""Progress output: a bar per stage on a terminal, nothing while running otherwise (logs get one summary line)."""

from __future__ import annotations

import contextlib
import shutil
import sys
from collections.abc import Callable, Iterator
from typing import TextIO

FrameCallback = Callable[[int, float], None]


def _ignore(index: int, t: float) -> None:
    pass


class Progress:
    """Reports per-frame progress of long stages. ``enabled=None`` means: only when ``stream`` is a terminal."""

    def __init__(self, *, enabled: bool | None = None, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled

    @contextlib.contextmanager
    def task(self, label: str, total: int) -> Iterator[FrameCallback]:
        """Yield a callback ``on_frame(index, t)`` that advances a bar of ``total`` frames."""
        if not self.enabled:
            yield _ignore
            return
        from tqdm import tqdm  # optional: only when progress bars are shown

        # Some terminals (and bare ptys) report a size of 0×0, which makes tqdm draw nothing; fall back to 100×24.
        width, height = shutil.get_terminal_size((100, 24))
        with tqdm(total=total, desc=f"{label:>8}", unit="frame", file=self.stream, leave=False, ncols=width,
                  nrows=height) as bar:

            def on_frame(index: int, t: float) -> None:
                bar.set_postfix_str(f"t={t:.3f} s", refresh=False)
                bar.update(1)

            yield on_frame
