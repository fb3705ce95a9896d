"""Proper-time clocks carried by bodies: special relativity's time dilation, dτ = dt √(1 − v²/c²).

The clocks only read the motion: the dynamics stay Newtonian. A clock's proper time τ is part of the state's
configuration (it is integrated like a position, from the velocity), so every method, adaptive or fixed-step,
advances it with the same accuracy as the motion, and a trajectory keeps it at every frame. ``c`` is the scene's
speed of light, which a classroom scene lowers so that dilation shows at the speeds it animates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.errors import SimulationError


@dataclass(frozen=True, eq=False)
class ProperClocks:
    """Clocks on the points ``index`` (K,) (particles first, then rigid bodies), named ``names`` (K,); ``c`` [m/s]."""

    index: np.ndarray
    names: tuple[str, ...]
    c: float

    @property
    def count(self) -> int:
        return len(self.index)

    def rate(self, velocities: np.ndarray, t: float | None = None) -> np.ndarray:
        """dτ/dt (K,) for the clocks' velocities (K, 3) [m/s]. Raises SimulationError, naming the body, when a clock
        reaches the speed of light (its proper time stops being defined)."""
        beta2 = np.einsum("ij,ij->i", velocities, velocities) / self.c**2
        if np.any(beta2 >= 1) or not np.all(np.isfinite(beta2)):
            k = int(np.argmax(np.where(np.isfinite(beta2), beta2, np.inf)))
            speed = float(np.sqrt(beta2[k]) * self.c) if np.isfinite(beta2[k]) else float("nan")
            when = f" at t ≈ {t:.6g} s" if t is not None else ""
            raise SimulationError(
                f"body {self.names[k]!r} reached {speed:.6g} m/s{when}, at least the speed of light c = {self.c:.6g} "
                "m/s of its proper-time clock. The motion itself is Newtonian, so nothing stops a body at c: raise "
                "clocks.c above the fastest speed in the scene, or slow the body down", time=t, body=self.names[k])
        return np.sqrt(1.0 - beta2)
