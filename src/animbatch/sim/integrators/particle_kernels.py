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

from animbatch.sim.integrators.fixed_step import ButcherTableau

Step = tuple[np.ndarray, np.ndarray, np.ndarray]
#: (acceleration, x, v, cached a, mass, radius, h) -> (x', v', a to cache)
ParticleKernel = Callable[[Any, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, Any], Step]


def runge_kutta(tableau: ButcherTableau) -> ParticleKernel:
    """The particle step of an explicit Runge–Kutta method on ``x' = v``, ``v' = a(x, v)``: stage i is at
    ``x + h Σ a_ij v_j``, ``v + h Σ a_ij a_j``; the step adds ``h Σ b_i`` of the stages' (v_i, a_i). Euler is
    ``x + h v``, ``v + h a``; the midpoint method evaluates a again at the half step."""

    def step(acceleration: Any, x: np.ndarray, v: np.ndarray, cached: np.ndarray, mass: np.ndarray,
             radius: np.ndarray, h: Any) -> Step:
        velocities: list[np.ndarray] = []
        accelerations: list[np.ndarray] = []
        for row in tableau.a:
            x_stage, v_stage = x, v
            for j, a_ij in enumerate(row):
                if a_ij:
                    x_stage = x_stage + (h * a_ij) * velocities[j]
                    v_stage = v_stage + (h * a_ij) * accelerations[j]
            velocities.append(v_stage)
            accelerations.append(acceleration(x_stage, v_stage, mass, radius))
        x_new, v_new = x, v
        for b_i, v_i, a_i in zip(tableau.b, velocities, accelerations):
            if b_i:
                x_new = x_new + (h * b_i) * v_i
                v_new = v_new + (h * b_i) * a_i
        return x_new, v_new, accelerations[-1]

    return step


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
