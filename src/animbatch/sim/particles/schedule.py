"""When an emitter's particles are born: a rate that may follow keyframes, plus bursts, counted exactly.

The rate ``r(t)`` [1/s] is piecewise linear (constant, or linear between keyframes and held outside them), and on
only between ``start`` and ``stop``. Its integral ``C(t) = ∫₀ᵗ r`` is piecewise quadratic, and the k-th particle of
the rate (k = 0, 1, …) is born at the time ``τ_k`` where ``C(τ_k) = k + 1``. So by any time t exactly ``⌊C(t)⌋``
have been born, however the simulation steps: fractions of a particle carry over from step to step instead of being
rounded away (a rate of 10/s stepped at 1/60 s would otherwise give 0 or 60 per second). Each particle is born at
its own instant within a step, not all at the step's start, so a moving emitter or a fast stream leaves no bands.

Births are numbered in time order (rate before burst at equal times); that number, the particle's *serial*, picks
its random numbers (:mod:`animbatch.sim.particles.streams`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

#: Counts within this of a whole number are that number (C(t) is computed in floating point).
COUNT_TOLERANCE = 1e-9
#: Up to this many rate births are timed one by one in Python floats (numpy's per-call cost outweighs a few).
FEW = 8


@dataclass(frozen=True)
class Births:
    """Particles born in an interval: their serials (K,) and birth times [s] (K,), in time order."""

    serials: np.ndarray
    times: np.ndarray

    @property
    def count(self) -> int:
        return len(self.serials)


class EmissionSchedule:
    """The births of one emitter.

    ``knot_times`` (K,) [s] and ``knot_rates`` (K,) [1/s]: the rate, linear between knots and zero outside the
    first and last (the start and stop of emission). ``burst_times`` (B,) [s], ``burst_counts`` (B,).
    """

    def __init__(self, knot_times: np.ndarray, knot_rates: np.ndarray, burst_times: np.ndarray,
                 burst_counts: np.ndarray) -> None:
        self.knot_times = np.asarray(knot_times, float)
        self.knot_rates = np.asarray(knot_rates, float)
        order = np.argsort(burst_times, kind="stable")
        self.burst_times = np.asarray(burst_times, float)[order]
        self.burst_counts = np.asarray(burst_counts, np.int64)[order]
        self._burst_before = np.concatenate([[0], np.cumsum(self.burst_counts)])
        widths = np.diff(self.knot_times)
        pieces = 0.5 * (self.knot_rates[1:] + self.knot_rates[:-1]) * widths  # trapezoids
        self._cumulative = np.concatenate([[0.0], np.cumsum(pieces)])  # C at each knot
        # the same numbers as Python floats: a step asks for its births one time at a time, and numpy's per-call
        # cost on a single number (some 40 µs for C(t)) was most of a small emitter's step
        self._knots, self._rates = self.knot_times.tolist(), self.knot_rates.tolist()
        self._sums, self._bursts = self._cumulative.tolist(), self.burst_times.tolist()

    # ---------------------------------------------------------------- the rate

    def rate(self, t: np.ndarray | float) -> np.ndarray:
        """r(t) [1/s]."""
        t = np.asarray(t, float)
        inside = (t >= self.knot_times[0]) & (t < self.knot_times[-1])
        return np.where(inside, np.interp(t, self.knot_times, self.knot_rates), 0.0)

    def accumulated(self, t: np.ndarray | float) -> np.ndarray:
        """C(t) = ∫₀ᵗ r: the (fractional) number of rate particles born by ``t``."""
        t = np.clip(np.asarray(t, float), self.knot_times[0], self.knot_times[-1])
        piece = np.clip(np.searchsorted(self.knot_times, t, side="right") - 1, 0, len(self.knot_times) - 2)
        a, b = self.knot_times[piece], self.knot_times[piece + 1]
        ra, rb = self.knot_rates[piece], self.knot_rates[piece + 1]
        s = t - a
        slope = np.divide(rb - ra, b - a, out=np.zeros_like(s), where=b > a)
        return self._cumulative[piece] + ra * s + 0.5 * slope * s * s

    def _accumulated_at(self, t: float) -> float:
        """:meth:`accumulated` at one time, in Python floats: the same operations in the same order, so the same
        number."""
        knots = self._knots
        t = min(max(t, knots[0]), knots[-1])
        piece = min(max(bisect.bisect_right(knots, t) - 1, 0), len(knots) - 2)
        a, b = knots[piece], knots[piece + 1]
        ra, rb = self._rates[piece], self._rates[piece + 1]
        s = t - a
        slope = (rb - ra) / (b - a) if b > a else 0.0
        return self._sums[piece] + ra * s + 0.5 * slope * s * s

    def _rate_born_by(self, t: float) -> int:
        """How many rate particles are born at or before ``t`` [s]: ⌊C(t)⌋."""
        return math.floor(self._accumulated_at(t) + COUNT_TOLERANCE)

    def born_by(self, t: float) -> int:
        """How many particles are born at or before ``t`` (rate and bursts)."""
        t = float(t)
        return self._rate_born_by(t) + int(self._burst_before[bisect.bisect_right(self._bursts, t)])

    def born_by_each(self, t: np.ndarray) -> np.ndarray:
        """:meth:`born_by` at each of the times ``t`` (N,) [s], in one pass: (N,) int64."""
        from_rate = np.floor(self.accumulated(t) + COUNT_TOLERANCE).astype(np.int64)
        return from_rate + self._burst_before[np.searchsorted(self.burst_times, t, side="right")]

    def rate_birth_times(self, first: int, stop: int) -> np.ndarray:
        """τ_k for rate particles k = first … stop - 1: where C(τ_k) = k + 1 (inverting the quadratic pieces)."""
        if stop - first <= FEW:
            return np.array([self._rate_birth_time(k) for k in range(first, stop)], float)
        target = np.arange(first, stop, dtype=float) + 1.0
        piece = np.clip(np.searchsorted(self._cumulative, target - COUNT_TOLERANCE, side="left") - 1, 0,
                        len(self.knot_times) - 2)
        a = self.knot_times[piece]
        ra, rb = self.knot_rates[piece], self.knot_rates[piece + 1]
        width = self.knot_times[piece + 1] - a
        slope = np.divide(rb - ra, width, out=np.zeros_like(a), where=width > 0)
        remaining = np.maximum(target - self._cumulative[piece], 0.0)
        # ½ slope s² + ra s = remaining, in the form without cancellation:
        # s = 2 remaining / (ra + √(ra² + 2 slope remaining))
        root = np.sqrt(np.maximum(ra * ra + 2.0 * slope * remaining, 0.0))
        s = np.divide(2.0 * remaining, ra + root, out=np.zeros_like(a), where=(ra + root) > 0)
        return np.minimum(a + np.minimum(s, width), self.knot_times[-1])

    def _rate_birth_time(self, k: int) -> float:
        """:meth:`rate_birth_times` of the one particle ``k``, in Python floats (the same operations, the same
        number)."""
        knots, rates, sums = self._knots, self._rates, self._sums
        target = float(k) + 1.0
        piece = min(max(bisect.bisect_left(sums, target - COUNT_TOLERANCE) - 1, 0), len(knots) - 2)
        a = knots[piece]
        ra, rb = rates[piece], rates[piece + 1]
        width = knots[piece + 1] - a
        slope = (rb - ra) / width if width > 0 else 0.0
        remaining = max(target - sums[piece], 0.0)
        root = math.sqrt(max(ra * ra + 2.0 * slope * remaining, 0.0))
        s = 2.0 * remaining / (ra + root) if (ra + root) > 0 else 0.0
        return min(a + min(s, width), knots[-1])

    # ---------------------------------------------------------------- births

    def births(self, t0: float, t1: float) -> Births:
        """The particles born in ``(t0, t1]``, numbered from ``born_by(t0)``."""
        t0, t1 = float(t0), float(t1)
        rate_first, rate_stop = self._rate_born_by(t0), self._rate_born_by(t1)
        lo, hi = bisect.bisect_right(self._bursts, t0), bisect.bisect_right(self._bursts, t1)
        first = rate_first + int(self._burst_before[lo])  # born_by(t0)
        if lo == hi:  # rate particles only (most steps): already in time order
            return Births(first + np.arange(rate_stop - rate_first, dtype=np.int64),
                          self.rate_birth_times(rate_first, rate_stop))
        times = [self.rate_birth_times(rate_first, rate_stop)]
        kinds = [np.zeros(rate_stop - rate_first, np.int8)]
        for index in range(lo, hi):
            count = int(self.burst_counts[index])
            times.append(np.full(count, self.burst_times[index]))
            kinds.append(np.ones(count, np.int8))
        all_times = np.concatenate(times)
        order = np.lexsort((np.concatenate(kinds), all_times))  # by time, rate before bursts
        return Births(first + np.arange(len(all_times), dtype=np.int64), all_times[order])

    def most_alive(self, longest_life: float, end: float, samples: int = 4096) -> int:
        """An upper bound of how many particles are alive at once before ``end`` [s], when none lives longer than
        ``longest_life`` [s]: the most born within any window of that length, sampled finely, plus one sample's
        worth."""
        grid = np.linspace(0.0, end, samples)
        grid = np.unique(np.concatenate([grid, self.burst_times[self.burst_times <= end], self.knot_times[
            self.knot_times <= end]]))
        born = self.born_by_each(grid)
        before = np.where(grid - longest_life >= 0, self.born_by_each(grid - longest_life), 0)
        step = end / (samples - 1) if samples > 1 else end
        margin = int(np.ceil(float(np.max(self.knot_rates, initial=0.0)) * step)) + 1
        return int(np.max(born - before, initial=0)) + margin
