"""One step of each fixed-step method for independent particles (emitted particles in their pools).

Each kernel takes the slots' accelerations ``acceleration(x, v, mass, radius)`` [m/s²], positions ``x`` [m] and
velocities ``v`` [m/s] (K, 3), the acceleration cached from the previous step (Verlet), masses [kg] and radii [m]
(K,), and the step ``h`` [s] (a number, or one per slot, (K, 1)); it returns the new positions, velocities and the
acceleration to cache. They are the particle forms of the schemes in :mod:`animbatch.sim.integrators.fixed_step`,
listed with them in :data:`animbatch.sim.integrators.methods.METHODS`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

Step = tuple[np.ndarray, np.ndarray, np.ndarray]
#: (acceleration, x, v, cached a, mass, radius, h) -> (x', v', a to cache)
ParticleKernel = Callable[[Any, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, Any], Step]


def euler(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
          radius: np.ndarray, h: Any) -> Step:
    """``x' = x + h v``, ``v' = v + h a``."""
    a = acceleration(x, v, mass, radius)
    return x + h * v, v + h * a, a


def midpoint(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
             radius: np.ndarray, h: Any) -> Step:
    """The same as Euler from the half-step state."""
    a = acceleration(x, v, mass, radius)
    v_half = v + 0.5 * h * a
    a_half = acceleration(x + 0.5 * h * v, v_half, mass, radius)
    return x + h * v_half, v + h * a_half, a_half


def symplectic_euler(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
                     radius: np.ndarray, h: Any) -> Step:
    """``v' = v + h a``, then ``x' = x + h v'``."""
    a = acceleration(x, v, mass, radius)
    v_new = v + h * a
    return x + h * v_new, v_new, a


def verlet(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
           radius: np.ndarray, h: Any) -> Step:
    """``x' = x + h v + h²/2 a``, ``v' = v + h/2 (a + a')`` with ``a'`` at the predicted velocity ``v + h a``."""
    a = cached
    x_new = x + h * v + (0.5 * h * h) * a
    a_new = acceleration(x_new, v + h * a, mass, radius)
    return x_new, v + (0.5 * h) * (a + a_new), a_new


def backward_euler(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
                   radius: np.ndarray, h: Any) -> Step:
    """Velocity-dependent forces at the end of the step, linearised: ``(I + h D) dv = h a`` with
    ``D = α I + β û ûᵀ`` (``acceleration.drag_rates``), solved in closed form; then ``x' = x + h v'``."""
    a = acceleration(x, v, mass, radius)
    rates = acceleration.drag_rates(x, v, mass, radius)
    step = np.ravel(h) if np.ndim(h) else h
    c = 1.0 + step * rates[:, 0]
    b = step * rates[:, 1]
    unit = acceleration.quadratic_direction(v)
    rhs = h * a
    along = np.einsum("ij,ij->i", unit, rhs)
    dv = (rhs - (b / (c + b) * along)[:, None] * unit) / c[:, None]  # ((c I + b û ûᵀ)⁻¹ rhs)
    v_new = v + dv
    return x + h * v_new, v_new, a
