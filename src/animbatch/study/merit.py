"""Figures of merit of one method's points (error against work): the time it needs to reach an error, and its
observed order of convergence.

* ``time_to(target)``: along the method's points sorted by wall time, the first pair whose errors bracket the
  target, interpolated in log–log. Never extrapolated: when even the fastest point is below the target the answer is
  a bound ("at most the fastest time"), and when no point reaches it, None. A point limited by the reference counts
  with the error it is known to be below (the reference's floor times its margin).
* ``observed_order``: for a fixed-step method, the least-squares slope of log error against log dt; for an adaptive
  one, minus the slope of log error against log RHS evaluations (work ∝ steps, error ∝ h^p ∝ steps^-p). Only points
  in the asymptotic range are used (error below 10 % of the scale and not limited by the reference); None with fewer
  than two, or when the work varies by less than a factor of two among them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Errors above this fraction of the length scale are not in the asymptotic range of any method.
ASYMPTOTIC = 0.1


@dataclass(frozen=True)
class Point:
    """One successful run of a method: its error, wall time [s], RHS evaluations, step or tolerance, and whether
    its error is limited by the reference."""

    error: float
    wall_time: float
    rhs_evaluations: int
    dt: float | None
    rtol: float | None
    limited: bool


@dataclass(frozen=True)
class TimeTo:
    """Wall time [s] to reach an error: ``seconds``, with ``bound`` True when it is only an upper bound (every point
    is already below the target); None seconds when no point reaches it."""

    seconds: float | None
    bound: bool = False

    def __str__(self) -> str:
        if self.seconds is None:
            return "not reached"
        return f"≤ {self.seconds:.3g}" if self.bound else f"{self.seconds:.3g}"


def time_to(points: list[Point], target: float, floor: float = 0.0) -> TimeTo:
    """``floor``: the error a point limited by the reference is known to be below (its own error is not trusted)."""
    usable = sorted((Point(max(p.error, floor), p.wall_time, p.rhs_evaluations, p.dt, p.rtol, p.limited)
                     if p.limited else p for p in points if p.error > 0 or p.limited), key=lambda p: p.wall_time)
    if not usable:
        return TimeTo(None)
    if usable[0].error <= target:
        return TimeTo(usable[0].wall_time, bound=True)
    for slower, faster in zip(usable[1:], usable[:-1]):
        if slower.error <= target < faster.error:
            fraction = np.log(faster.error / target) / np.log(faster.error / slower.error)
            return TimeTo(float(np.exp(np.log(faster.wall_time)
                                       + fraction * np.log(slower.wall_time / faster.wall_time))))
    return TimeTo(None)


def observed_order(points: list[Point]) -> float | None:
    usable = [p for p in points if not p.limited and 0 < p.error < ASYMPTOTIC]
    if len(usable) < 2:
        return None
    error = np.log([p.error for p in usable])
    if usable[0].dt is not None:
        work = np.log([p.dt for p in usable])  # type: ignore[misc]
        sign = 1.0
    else:
        work = np.log([p.rhs_evaluations for p in usable])
        sign = -1.0
    if np.ptp(work) < np.log(2):  # the work hardly changed (a problem the method solves exactly): no order to see
        return None
    slope = np.polyfit(work, error, 1)[0]
    return float(sign * slope)
