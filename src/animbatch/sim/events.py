"""Events found in a sampled motion: when a point crosses a plane, between frames.

Between two frames the motion is the cubic Hermite curve through the positions and velocities at both ends, so a
crossing time is found to the accuracy of the trajectory itself, not of the frame spacing: exact for motion under
constant acceleration (a parabola is a cubic of that family), O(h⁴) otherwise. A crossing and its return within one
frame (a bounce between two frames, say) are both found when the cubic shows them, which it does when the motion
between the frames is smooth; keep a frame or two between events.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

Direction = Literal["any", "along", "against"]


def hermite_cubic(x0: np.ndarray, x1: np.ndarray, d0: np.ndarray, d1: np.ndarray) -> tuple[np.ndarray, ...]:
    """Coefficients (a, b, c, d) of the cubic ``a τ³ + b τ² + c τ + d`` on τ ∈ [0, 1] with values ``x0``, ``x1`` and
    slopes ``d0``, ``d1`` (velocities times the interval) at its ends: the Hermite curve between two frames."""
    return 2 * (x0 - x1) + d0 + d1, 3 * (x1 - x0) - 2 * d0 - d1, d0, x0


def plane_crossings(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, point: np.ndarray,
                    normal: np.ndarray, direction: Direction = "any", *, impacts: bool = False) -> np.ndarray:
    """Times [s] (K,), increasing, at which a point moving through ``positions`` (F, 3) [m] with ``velocities``
    (F, 3) [m/s] at ``times`` (F,) crosses the plane through ``point`` with ``normal``; ``direction`` along
    keeps the crossings moving along the normal, against those moving against it. Touching the plane without
    crossing it is not a crossing, nor is starting on it.

    With ``impacts``, reaching the plane and bouncing back counts too (a ball's centre one radius above a floor
    when it hits the floor), at the time the motion before the bounce reaches the plane: extrapolated from the
    frame before, with the acceleration of the frames before it (exact under constant acceleration)."""
    unit = np.asarray(normal, float) / np.linalg.norm(normal)
    height = (np.asarray(positions, float) - point) @ unit  # (F,)
    rate = np.asarray(velocities, float) @ unit
    step = np.diff(times)
    s0, s1, d0, d1 = height[:-1], height[1:], rate[:-1] * step, rate[1:] * step  # per interval, τ ∈ [0, 1]
    a, b, c, d = hermite_cubic(s0, s1, d0, d1)  # s(τ) on each interval
    # intervals where the cubic can reach zero: the ends differ in sign, the end is on the plane, or it turns
    # inside the interval (a dip through the plane and back)
    candidates = np.flatnonzero((s0 * s1 < 0) | (s1 == 0) | (d0 * d1 < 0))
    found, crossed = [], set()
    for k in candidates:  # a loop over the few intervals that may hold a crossing
        roots = np.sort(np.roots([a[k], b[k], c[k], d[k]]))
        real = roots[np.abs(roots.imag) < 1e-9].real
        # a double root is the motion touching the plane (an apex on it), which rounding splits into two
        double = np.zeros(len(real), bool)
        close = np.diff(real) < 1e-6  # rounding splits a double root by ~√ε
        double[1:] |= close
        double[:-1] |= close
        for tau in real[~double]:
            if not 0 < tau <= 1:
                continue
            slope = 3 * a[k] * tau**2 + 2 * b[k] * tau + c[k]
            if slope == 0 or (direction == "along" and slope < 0) or (direction == "against" and slope > 0):
                continue
            found.append(times[k] + tau * step[k])
            crossed.add(int(k))
    if impacts:
        found += _impacts(times, height, rate, direction, crossed)
    return np.array(sorted(found), float)


def _impacts(times: np.ndarray, height: np.ndarray, rate: np.ndarray, direction: Direction,
             crossed: set[int]) -> list[float]:
    """Times at which the motion reaches the plane and turns back within one frame interval (see
    :func:`plane_crossings`); intervals in ``crossed`` already hold a crossing."""
    found = []
    # approaching the plane at one frame, leaving it at the next, on the same side: a bounce in between
    bounces = np.flatnonzero((height[:-1] * rate[:-1] < 0) & (height[1:] * rate[1:] > 0)
                             & (height[:-1] * height[1:] > 0))
    for k in bounces:  # a loop over the few bounces
        if k in crossed or (direction == "along" and rate[k] < 0) or (direction == "against" and rate[k] > 0):
            continue
        acceleration = (rate[k] - rate[k - 1]) / (times[k] - times[k - 1]) if k > 0 else 0.0
        # height[k] + rate[k] τ + ½ acceleration τ² = 0, its first root after the frame
        roots = np.roots([0.5 * acceleration, rate[k], height[k]])
        roots = roots[(np.abs(roots.imag) < 1e-12) & (roots.real > 0)].real
        if len(roots):
            found.append(float(times[k] + min(roots.min(), times[k + 1] - times[k])))
    return found


def hermite_sample(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, at: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (T, …, 3) at the times ``at`` (T,) [s] within ``times`` (F,), from the cubic
    Hermite curve through ``positions`` and ``velocities`` (F, …, 3) of the frames around each time (exact under
    constant acceleration; the velocity is the curve's derivative)."""
    times = np.asarray(times, float)
    at = np.asarray(at, float)
    if len(times) == 1:
        return np.repeat(positions[:1], len(at), axis=0), np.repeat(velocities[:1], len(at), axis=0)
    k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    h = times[k + 1] - times[k]
    tau = (at - times[k]) / h
    shape = (-1,) + (1,) * (positions.ndim - 1)
    tau, h = tau.reshape(shape), h.reshape(shape)
    a, b, c, d = hermite_cubic(positions[k], positions[k + 1], velocities[k] * h, velocities[k + 1] * h)
    return ((a * tau + b) * tau + c) * tau + d, ((3 * a * tau + 2 * b) * tau + c) / h
