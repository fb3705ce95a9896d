"""Prescribed motion: anchors that stay put or follow keyframes.

An anchor is a point the simulation does not move; springs and cloth pins attach to it. With keyframes it follows a
path: ``linear`` interpolation (constant velocity between keys) or ``cubic`` (a C² cubic spline through the keys,
starting and ending at rest). Before the first key and after the last the anchor holds its position. Velocities are
the exact derivatives of the interpolant, so dampers see the anchor's true speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline


@dataclass(frozen=True, eq=False)
class KeyframePath:
    """A path through ``positions`` (K, 3) [m] at increasing ``times`` (K,) [s]."""

    times: np.ndarray
    positions: np.ndarray
    interpolation: str = "linear"

    def __post_init__(self) -> None:
        if self.interpolation == "cubic" and len(self.times) > 1:
            object.__setattr__(self, "_spline", CubicSpline(self.times, self.positions, bc_type="clamped"))

    def _clamped(self, t: float) -> float:
        return float(np.clip(t, self.times[0], self.times[-1]))

    def position(self, t: float) -> np.ndarray:
        """Position (3,) [m] at time ``t`` [s]."""
        if len(self.times) == 1:
            return self.positions[0]
        if self.interpolation == "cubic":
            return self._spline(self._clamped(t))  # type: ignore[attr-defined]
        return np.array([np.interp(t, self.times, self.positions[:, k]) for k in range(3)])

    def acceleration(self, t: float) -> np.ndarray:
        """Acceleration (3,) [m/s²] at time ``t`` [s]: the spline's second derivative between cubic keys, zero on
        linear segments (their kinks are impulses no step can take) and outside the keys."""
        if self.interpolation != "cubic" or len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return np.zeros(3)
        return self._spline(t, 2)  # type: ignore[attr-defined]

    def velocity(self, t: float) -> np.ndarray:
        """Velocity (3,) [m/s] at time ``t`` [s] (zero outside the keys)."""
        if len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return np.zeros(3)
        if self.interpolation == "cubic":
            return self._spline(t, 1)  # type: ignore[attr-defined]
        segment = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2))
        span = self.times[segment + 1] - self.times[segment]
        return (self.positions[segment + 1] - self.positions[segment]) / span


@dataclass(frozen=True, eq=False)
class AnchorMotion:
    """Where the A anchors are at any time: ``rest`` (A, 3) [m] for the fixed ones, and keyframe paths for the
    moving ones (``paths``: anchor index -> path)."""

    rest: np.ndarray
    paths: dict[int, KeyframePath]

    @property
    def count(self) -> int:
        return len(self.rest)

    @property
    def moving(self) -> bool:
        return bool(self.paths)

    def only(self, used: np.ndarray) -> AnchorMotion:
        """The same anchors, with keyframes kept only for the ``used`` (indices): what one force term needs, so
        that a moving anchor nothing is attached to costs no evaluation."""
        wanted = {int(i) for i in np.asarray(used).ravel()}
        return AnchorMotion(self.rest, {i: path for i, path in self.paths.items() if i in wanted})

    def positions(self, t: float) -> np.ndarray:
        """Anchor positions (A, 3) [m] at time ``t`` [s] (the fixed array itself when nothing moves)."""
        if not self.paths:
            return self.rest
        result = self.rest.copy()
        for index, path in self.paths.items():
            result[index] = path.position(t)
        return result

    def velocities(self, t: float) -> np.ndarray:
        """Anchor velocities (A, 3) [m/s] at time ``t`` [s]."""
        result = np.zeros_like(self.rest)
        for index, path in self.paths.items():
            result[index] = path.velocity(t)
        return result
