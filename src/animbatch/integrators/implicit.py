"""Backward Euler, linearised once per step (Baraff & Witkin 1998, "Large Steps in Cloth Simulation").

Backward Euler takes the forces at the *end* of the step: ``Δv = h M⁻¹ f(x + Δx, v + Δv)``, ``Δx = h (v + Δv)``.
Expanding f to first order about the start of the step gives one linear system for the velocity change::

    (M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f₀ + h ∂f/∂x v₀)

then ``v₁ = v₀ + Δv`` and ``x₁ = x₀ + h v₁``. For a spring of stiffness k on a mass m the step damps instead of
amplifying, whatever ``h √(k/m)``: stiff cloth runs at one step per frame where explicit methods need hundreds.
The price is numerical damping (energy is lost at a rate that grows with ``h ω``), and one sparse solve per step.

* The derivatives come from the force terms (:meth:`ForceTerm.jacobian`): springs and dampers, controllers, drag
  and dihedral springs give them; terms that give none (aerodynamics, buoyancy, gravitation, applied forces) enter
  with their value at the start of the step only.
* Pinned vertices are not unknowns at all (they are anchors), which is the exact constraint; vertices attached to a
  rigid body move with it.
* Rigid bodies take a semi-implicit Euler step (kick, then drift) beside the particles: their inertia is not in the
  linear system.
* The system matrix is sparse and, for springs without dampers, symmetric positive definite; with dampers the
  ``∂(damping)/∂x`` term makes it slightly unsymmetric, so it is solved directly (SuperLU), which is robust and, for
  cloth-sized systems, fast.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from animbatch.integrators.fixed_step import PartitionedScheme


class BackwardEuler(PartitionedScheme):
    """Linearised backward Euler on the particles; semi-implicit Euler on rigid bodies."""

    order = 1
    evaluations_per_step = 1

    def __init__(self, system) -> None:  # noqa: ANN001 - a Dynamics
        super().__init__(system)
        model = system.model
        self._particle_dofs = 3 * system.particles
        self._mass = sp.diags(np.repeat(np.asarray(model.bodies.mass[: system.particles], float), 3), format="csr")
        self.explicit_terms: list[str] = []

    def kick(self, t: float, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        """Change the motion by one step: the linear solve for the particles, an explicit kick for rigid bodies."""
        system = self.system
        rate = system.motion_rate(t, config, motion, out=self._rate)
        self.evaluations += 1
        size = self._particle_dofs
        if size:
            derivatives, self.explicit_terms = system.force_jacobian(t, config, motion)
            stiffness, damping = derivatives.matrix("x"), derivatives.matrix("v")
            velocity = motion[:size]
            force = self._mass @ rate[:size]
            matrix = (self._mass - h * damping - (h * h) * stiffness).tocsc()
            change = spsolve(matrix, h * (force + h * (stiffness @ velocity)))
            motion[:size] += change
        motion[size:] += h * rate[size:]

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        config, motion = self.system.split(y)
        self.kick(t, config, motion, h)
        self.system.drift(config, motion, h)
        self.system.project(y)
