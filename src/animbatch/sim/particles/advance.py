"""Moving the live particles of a pool over one step, with the scene's integrator.

The particles' equations are ``dx/dt = v``, ``dv/dt = a(x, v) = Σ fields``, independent from particle to particle.
Fixed-step methods are written out here on the pool's arrays (one gather of the moving slots, a few vectorised
operations, one scatter), since births and deaths change the set of moving particles at every step:

* ``euler``: ``x' = x + h v``, ``v' = v + h a``;
* ``midpoint``: the same from the half-step state;
* ``symplectic_euler``: ``v' = v + h a``, then ``x' = x + h v'``;
* ``verlet``: ``x' = x + h v + h²/2 a``, ``v' = v + h/2 (a + a')``, with ``a'`` at the predicted velocity
  ``v + h a`` (as for bodies) and kept per slot for the next step, so a step costs one evaluation;
* ``backward_euler``: velocity-dependent forces (drag, the fluid's damping) at the end of the step, linearised:
  ``(I - h ∂a/∂v) Δv = h a``, a 3×3 system per particle solved in closed form (Sherman–Morrison on
  ``(1 + h α) I + h β û ûᵀ``); then ``x' = x + h v'``. It stays stable under any drag however strong.

Adaptive methods integrate the moving particles with ``scipy.integrate.solve_ivp`` over each frame interval (and the
particles born during it from their own birth instants, in one more call: :func:`adaptive_segment`), the state
interleaved per particle ``[x, v]`` so that the Jacobian (given to Radau and BDF; LSODA estimates it within its
band) is block diagonal, 6×6 per particle.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from animbatch.errors import SimulationError
from animbatch.sim.forces.on_particles import ParticleLaw, Slots
from animbatch.sim.integrators.methods import METHODS

#: The fixed-step methods (each has a particle kernel).
FIXED_METHODS = tuple(name for name, method in METHODS.items() if method.particle_step is not None)


class Accelerations:
    """``a(x, v)`` [m/s²] of a set of slots under the emitter's fields; counts its evaluations."""

    def __init__(self, fields: tuple[ParticleLaw, ...]) -> None:
        self.fields = fields
        self.evaluations = 0

    def __call__(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray, radius: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        out = np.zeros_like(x)
        slots = Slots(x, v, mass, radius)
        for field in self.fields:
            field.add_acceleration(slots, out)
        return out

    def drag_rates(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """``-∂a/∂v = α I + β û ûᵀ`` as (α, β) (K, 2); ``û`` is the direction of the quadratic law's relative
        velocity (one quadratic field at most keeps this exact; several add their β along different û, and the
        sum uses the first one's direction)."""
        slots = Slots(x, v, mass, radius)
        rates = np.zeros((len(mass), 2))
        for field in self.fields:
            field_rates = field.rates(slots)
            if field_rates is not None:
                rates += field_rates
        return rates

    def quadratic_direction(self, v: np.ndarray) -> np.ndarray:
        relative = next((found for f in self.fields if (found := f.quadratic_relative(v)) is not None), v)
        speed = np.linalg.norm(relative, axis=1, keepdims=True)
        return np.divide(relative, speed, out=np.zeros_like(relative), where=speed > 0)


def fixed_step(method: str, acceleration: Accelerations, x: np.ndarray, v: np.ndarray, cached: np.ndarray,
               mass: np.ndarray, radius: np.ndarray, h: float | np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step ``h`` [s] of ``method`` for slots at ``x``, ``v`` (K, 3) (its kernel in
    :mod:`animbatch.sim.integrators.particle_kernels`); ``cached``: each slot's acceleration at the start of the step
    (Verlet). ``h`` may also be one step per slot, shape (K, 1). Returns the new positions, velocities and
    accelerations to cache."""
    kernel = METHODS[method].particle_step if method in METHODS else None
    if kernel is None:
        raise ValueError(f"unknown fixed-step method {method!r}; choose from {', '.join(FIXED_METHODS)}")
    return kernel(acceleration, x, v, cached, mass, radius, h)


def adaptive_segment(method: str, rtol: float, atol: float, max_step: float | None, acceleration: Accelerations,
                     x: np.ndarray, v: np.ndarray, mass: np.ndarray, radius: np.ndarray, t0: float, t1: float,
                     durations: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Integrate slots (K, 3) from ``t0`` to ``t1`` [s] with a solve_ivp method; returns x, v and the steps taken.

    ``durations`` (K,) [s]: each slot for its own time instead (newborns, from their birth instants to the step's
    end), all in one call over ``τ`` from 0 to 1: the fields do not depend on time, so slot ``j``'s equations in
    ``τ = (t − t_birth) / d_j`` are ``dx/dτ = d_j v``, ``dv/dτ = d_j a(x, v)``, exactly."""
    from scipy.integrate import solve_ivp  # kept off the start-up path of validate and --help

    count = len(mass)
    if durations is not None:
        t0, t1 = 0.0, 1.0
        if max_step is not None:  # in τ: the longest flight's steps are as long as they may be
            max_step = max_step / max(float(np.max(durations, initial=0.0)), 1e-300)
    if count == 0 or t1 <= t0:
        return x, v, 0
    scale = durations[:, None, None] if durations is not None else None

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        state = y.reshape(count, 2, 3)
        rate = np.empty_like(state)
        rate[:, 0] = state[:, 1]
        rate[:, 1] = acceleration(state[:, 0], state[:, 1], mass, radius)
        if scale is not None:
            rate *= scale
        return rate.ravel()

    options: dict = {"rtol": rtol, "atol": atol}
    if max_step is not None:
        options["max_step"] = max_step
    if method in ("Radau", "BDF"):
        options["jac"] = _block_jacobian(acceleration, mass, radius, count, durations)
    elif method == "LSODA":
        options.update(lband=5, uband=5)
    y0 = np.stack([x, v], axis=1).ravel()
    solution = solve_ivp(rhs, (t0, t1), y0, method=method, t_eval=None, dense_output=False, **options)
    if solution.status < 0:

        raise SimulationError(f"{method} failed on the particles between t = {t0:g} and {t1:g} s: "
                              f"{solution.message}. Use a fixed-step method (e.g. verlet) for particles.", time=t0)
    end = solution.y[:, -1].reshape(count, 2, 3)
    return end[:, 0].copy(), end[:, 1].copy(), len(solution.t) - 1


def _block_jacobian(acceleration: Accelerations, mass: np.ndarray, radius: np.ndarray, count: int,
                    durations: np.ndarray | None = None) -> Callable[[float, np.ndarray], sp.bsr_matrix]:
    """``∂(dy/dt)/∂y`` of interleaved particle states: 6×6 blocks ``[[0, I], [0, ∂a/∂v]]`` on the diagonal (the
    position dependence of buoyancy near the surface is left out; Newton's iteration tolerates it), each times its
    slot's duration where the time is scaled (``durations``, see :func:`adaptive_segment`)."""
    indices = np.arange(count, dtype=np.int32)
    indptr = np.arange(count + 1, dtype=np.int32)

    def jacobian(t: float, y: np.ndarray) -> sp.bsr_matrix:
        state = y.reshape(count, 2, 3)
        rates = acceleration.drag_rates(state[:, 0], state[:, 1], mass, radius)
        unit = acceleration.quadratic_direction(state[:, 1])
        blocks = np.zeros((count, 6, 6))
        blocks[:, 0:3, 3:6] = np.eye(3)
        blocks[:, 3:6, 3:6] = -(rates[:, 0, None, None] * np.eye(3)
                                + rates[:, 1, None, None] * unit[:, :, None] * unit[:, None, :])
        if durations is not None:
            blocks *= durations[:, None, None]
        return sp.bsr_matrix((blocks, indices, indptr), shape=(6 * count, 6 * count)).tocsc()

    return jacobian
