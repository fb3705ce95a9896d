"""When the contact impulse sweeps have stalled: one rule for the numpy sweeps
(:func:`animbatch.sim.contact.impulses.solve_impulses`) and the compiled ones
(:mod:`animbatch.sim.kernels.contact_impulses` compiles :func:`stalled` as it is). Plain Python on numbers, so that
the numpy side needs no numba.

The sweeps stop when the smallest violation of the last STALL_WINDOW sweeps is not below STALL_RATIO times the
smallest before them. Where many contacts share bodies (a pile), the violation falls for a few dozen sweeps and then
wanders: over the solves of scenes/mixed_pile.yaml its median is 3e-3 m/s after 40 sweeps and still 3e-3 after 300.
Stopping at the stall takes 87 sweeps on average instead of 290, and leaves the same largest violation (0.043 m/s);
at 0.9 (a stall: less than 10 % better) the largest was 0.059 m/s, and the 12-box pile of the benchmarks kept 5
times the kinetic energy at its end.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

STALL_WINDOW = 20
STALL_RATIO = 0.97


def stalled(iteration: int, worst: float, watch: list[float] | np.ndarray) -> bool:
    """Whether the sweeps have stalled at sweep ``iteration`` ≥ 1 with violation ``worst`` [m/s]; ``watch`` (2,) is
    [smallest before this window, smallest in it], starting at [inf, inf] and kept up to date here (a list, or an
    array in the compiled sweeps)."""
    watch[1] = min(watch[1], worst)
    if iteration % STALL_WINDOW:
        return False
    if iteration >= 2 * STALL_WINDOW and watch[1] > STALL_RATIO * watch[0]:
        return True
    watch[0], watch[1] = min(watch[0], watch[1]), math.inf
    return False
