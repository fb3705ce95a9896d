"""The equations of motion of a Model: ``dy/dt = f(t, y)`` for the flat state, and its partitioned form.

For particles, ``dx/dt = v`` and ``dv/dt = F(t, x, v) / m``, where F sums the model's force terms (only those the scene
declares). Fixed-step symplectic integrators use the partitioned form (:meth:`ParticleDynamics.acceleration`);
adaptive ones use :meth:`ParticleDynamics.rhs`.
"""

from __future__ import annotations

import numpy as np

from animbatch.model.model import Model


class ParticleDynamics:
    """Right-hand side for a Model. Holds one force buffer, reused by every evaluation."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.terms = model.force_terms
        self.count = model.particle_count
        self.size = model.layout.size
        self._inverse_mass = (1.0 / model.particles.mass)[:, None]
        self._force = np.zeros((self.count, 3))

    def split(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Views ``(x, v)`` of a state vector, each of shape (N, 3)."""
        n3 = 3 * self.count
        return y[:n3].reshape(self.count, 3), y[n3:].reshape(self.count, 3)

    def forces(self, t: float, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total force [N] on each particle, shape (N, 3). The returned buffer is overwritten by the next call."""
        force = self._force
        force.fill(0.0)
        for term in self.terms:
            term.accumulate(t, x, v, force)
        return force

    def acceleration(self, t: float, x: np.ndarray, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``a = F(t, x, v) / m`` [m/s²], shape (N, 3), written to ``out`` when given."""
        return np.multiply(self.forces(t, x, v), self._inverse_mass, out=out)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt`` as a new array (solve_ivp keeps references to the arrays it receives)."""
        x, v = self.split(y)
        dydt = np.empty_like(y)
        n3 = 3 * self.count
        dydt[:n3] = y[n3:]
        self.acceleration(t, x, v, out=dydt[n3:].reshape(self.count, 3))
        return dydt
