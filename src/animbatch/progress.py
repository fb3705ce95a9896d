"""Progress output: a bar per stage on a terminal or in a Jupyter notebook (tqdm's widget there), nothing while
running otherwise (logs get one summary line)."""

from __future__ import annotations

import contextlib
import importlib.util
import shutil
import sys
from collections.abc import Callable, Iterator
from typing import Any, TextIO

FrameCallback = Callable[[int, float], None]


def _ignore(index: int, t: float) -> None:
    pass


class Progress:
    """Reports per-frame progress of long stages. ``enabled=None`` means: only when ``stream`` is a terminal or
    the code runs in a Jupyter kernel."""

    def __init__(self, *, enabled: bool | None = None, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.notebook = in_notebook()
        self.enabled = (self.stream.isatty() or self.notebook) if enabled is None else enabled

    @contextlib.contextmanager
    def task(self, label: str, total: int) -> Iterator[FrameCallback]:
        """Yield a callback ``on_frame(index, t)`` that advances a bar of ``total`` frames."""
        if not self.enabled:
            yield _ignore
            return
        if self.notebook and _widgets_available():
            from tqdm.notebook import tqdm as widget_bar  # a bar in the cell's output, removed when done

            with widget_bar(total=total, desc=label, unit="frame", leave=False) as bar:
                yield _advance(bar)
            return
        from tqdm import tqdm  # optional: only when progress bars are shown

        # Some terminals (and bare ptys) report a size of 0×0, which makes tqdm draw nothing; fall back to 100×24.
        width, height = shutil.get_terminal_size((100, 24))
        with tqdm(total=total, desc=f"{label:>8}", unit="frame", file=self.stream, leave=False, ncols=width,
                  nrows=height) as bar:
            yield _advance(bar)


def _advance(bar: Any) -> FrameCallback:
    """The per-frame callback of a tqdm bar: one step, with the frame's time shown beside it."""

    def on_frame(index: int, t: float) -> None:
        bar.set_postfix_str(f"t={t:.3f} s", refresh=False)
        bar.update(1)

    return on_frame


def in_notebook() -> bool:
    """Whether this code runs in a Jupyter kernel (IPython with a kernel attached), where stderr is no terminal but
    a bar is still seen."""
    ipython = sys.modules.get("IPython")  # never imported here: a kernel has imported it already
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    return getattr(shell, "kernel", None) is not None


def _widgets_available() -> bool:
    """tqdm's notebook bar is an ipywidgets widget; without the package it falls back to text bars."""
    return importlib.util.find_spec("ipywidgets") is not None
