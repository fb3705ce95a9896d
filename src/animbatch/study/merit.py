"""Figures of merit of one method's points (error against work): the time it needs to reach an error, and its
observed order of convergence.

* ``time_to(target)``: along the method's points sorted by wall time, the first pair whose errors bracket the
  target, interpolated in log–log. Never extrapolated: when even the fastest point is below the target the answer is
  a bound ("at most the fastest time"), and when no point reaches it, None. A point limited by the reference counts
  with the error it is known to be below (the reference's floor times its margin).
* ``observed_order``: for a fixed-step method, the slope of log error against log dt; for an adaptive one, minus
  the slope of log error against log steps (mean step ∝ 1/steps, error ∝ h^p ∝ steps^-p). The slope is the median
  of the slopes between pairs of points whose step counts differ by at least half (Theil–Sen): the loosest
  tolerances often take nearly the same few steps for very different errors, which would skew a least-squares fit.
  Only points in the asymptotic range are used (error below 10 % of the scale and not limited by the reference).
  None (no order to see) unless those points span a factor of :data:`ORDER_SPAN` in work and lie on the fitted line
  (R² of at least :data:`ORDER_FIT`): where the error is not set by the step (round-off, a startup step, contact
  detection, a chaotic scene) a slope through scattered points reads as orders like 21 or -39. For BDF and LSODA,
  which change order as they go, it is an effective order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Errors above this fraction of the length scale are not in the asymptotic range of any method.
ASYMPTOTIC = 0.1
#: An order is read only from points whose work (steps, or 1/dt) spans at least this factor …
ORDER_SPAN = 3.0
#: … and whose log error the fitted line explains to at least this R².
ORDER_FIT = 0.8


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
    steps: int | None = None


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
        work = np.log(np.array([p.dt for p in usable], float))
        sign = 1.0
    else:
        work = np.log([p.steps or p.rhs_evaluations for p in usable])
        sign = -1.0
    if np.ptp(work) < np.log(ORDER_SPAN):  # the work hardly changed (a problem the method solves exactly)
        return None
    first, second = np.triu_indices(len(usable), k=1)
    apart = np.abs(work[first] - work[second]) >= np.log(1.5)
    slope = float(np.median((error[first] - error[second])[apart] / (work[first] - work[second])[apart]))
    residual = error - np.median(error - slope * work) - slope * work
    explained = 1.0 - np.sum(residual**2) / max(np.sum((error - error.mean()) ** 2), 1e-300)
    return sign * slope if explained >= ORDER_FIT else None
