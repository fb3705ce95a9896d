"""Backward Euler, linearised once per step (Baraff & Witkin 1998, "Large Steps in Cloth Simulation"), with Newton
corrections where the linearised step would gain energy.

Backward Euler takes the forces at the *end* of the step: ``Δv = h M⁻¹ f(x + Δx, v + Δv)``, ``Δx = h (v + Δv)``.
Expanding f to first order about the start of the step gives one linear system for the velocity change::

    (M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f₀ + h ∂f/∂x v₀)

then ``v₁ = v₀ + Δv`` and ``x₁ = x₀ + h v₁``. For a spring of stiffness k on a mass m the step damps instead of
amplifying, whatever ``h √(k/m)``: stiff cloth runs at one step per frame where explicit methods need hundreds.
The price is numerical damping (energy is lost at a rate that grows with ``h ω``), and one sparse solve per step.

* The derivatives come from the force terms (:meth:`ForceTerm.jacobian`) in their *definite* form (see
  :class:`~animbatch.sim.forces.term.ForceJacobian`): springs and dampers, controllers, drag and dihedral springs give
  them; terms that give none (aerodynamics, buoyancy, gravitation, applied forces) enter with their value at the
  start of the step only. With the exact derivatives a compressed spring or a bent hinge makes the matrix
  indefinite, and a falling cloth's energy grew ten-thousandfold in forty steps; with the definite ones (a
  compressed spring adds no sideways stiffness, Choi & Ko 2002) the matrix is symmetric positive definite.
* It is solved directly (:class:`~animbatch.sim.integrators.linear_algebra.StepMatrixSolver`: a compiled
  supernodal Cholesky analysed once per run, 24 ms per factorisation on a 64×64 cloth on two cores, or SuperLU,
  155–270 ms).
  Iterative solvers did not pay: Jacobi-preconditioned conjugate gradients needed 900+ iterations at h = 1/30 s
  (``h² k / m`` being 10⁴–10⁵), and preconditioned by the previous step's factors they converged within 100
  iterations on 2 steps of 92, the springs having turned in between.
* Pinned vertices are not unknowns at all (they are anchors), which is the exact constraint; vertices attached to a
  rigid body move with it.
* Rigid bodies take a semi-implicit Euler step (kick, then drift) beside the particles: their inertia is not in the
  linear system.
* Energy guard: in a scene without energy inputs (no applied forces, wind, moving anchors or targets, untracked
  potentials; see :attr:`ForceTerm.adds_energy`) a step after which the total mechanical energy is higher than
  before is not kept as it is. The linearisation gains energy where springs turn fast within a step (the step moves
  the vertices along the tangent of their turn, which stretches the springs). So the step is first corrected by up
  to :data:`NEWTON_CORRECTIONS` Newton iterations on the backward-Euler equations themselves::

      g(v₁) = M (v₁ − v₀) − h f(x₀ + h v₁, v₁) = 0,    x₁ = x₀ + h v₁

  with the derivatives at the iterate (a fresh factorisation each), stopping as soon as the energy is no higher
  than at the start. Exact backward Euler takes energy out of a conservative system of convex potentials, so the
  iterates approach a step that keeps the guard. If the energy still rose, the step is redone as two half steps,
  down to ``h / 2^MAX_HALVINGS``; so such a scene never gains energy. On the 64×64 stiff cloth of the benchmarks
  (5 s at one step per frame), halving alone took 3.7 factorisations per frame; the corrections take 1.14 and never
  halve. Where the linearised step keeps the energy (a linear spring, a calm cloth) nothing changes: it is the step.
  Only for models of particles: rigid bodies take an explicit kick whose energy wobbles a little every step (it
  stays bounded, but is not monotone), and halving could never satisfy the guard. Nor when a force enters
  explicitly (gravitation, aerodynamics, buoyancy, applied forces: no derivatives), for the same reason: on an
  orbit every other step would be halved ten times over. With a controller on a curve, whose definite derivative
  leaves out the curve's turn, a step is halved at most ``APPROXIMATE_HALVINGS`` times: what is left are rises of
  O(h²) of either sign (a bead on a circular wire at one step per frame stays at or below its starting energy at
  every frame; halving ten times over made its 4 s loop take a minute). Not in scenes with contacts either, whose
  position corrections do not keep energy accounts; cloth's self-collision alone is guarded in the steps where its
  filter changes no velocity (a Newton correction passes through the filter again, as the step did).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.errors import OverBudget, SimulationError
from animbatch.sim.forces.jacobian import ForceJacobian
from animbatch.sim.forces.term import ForceTerm
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.fixed_step import PartitionedScheme, kick_constrain_drift
from animbatch.sim.integrators.linear_algebra import StepMatrixSolver, compiled_solves
from animbatch.sim.model.dynamics import Dynamics

#: Newton iterations tried on a step that raised the energy, before it is halved.
NEWTON_CORRECTIONS = 2
#: How many times a step may be halved to keep a scene without inputs from gaining energy.
MAX_HALVINGS = 10
#: How many times, where a term's definite derivatives leave out part of its change (ForceTerm.steps_lose_energy).
APPROXIMATE_HALVINGS = 3
#: Energy rises smaller than this fraction of the energy's scale are rounding, not gains.
ENERGY_TOLERANCE = 1e-12
#: Times Σ k r² of the springs: the smallest energy rise [J] the guard takes for real (see BackwardEuler).
ROUNDING_FLOOR = 64 * np.finfo(float).eps


class BackwardEuler(PartitionedScheme):
    """Linearised backward Euler on the particles; semi-implicit Euler on rigid bodies."""

    order = 1
    evaluations_per_step = 1
    takes_constraints = True
    system: Dynamics  # the linear solve needs the force Jacobian, the masses and the energy

    def __init__(self, system: Dynamics) -> None:
        super().__init__(system)
        model = system.model
        self._particle_dofs = 3 * system.particles
        self._mass_diagonal = np.repeat(np.asarray(model.bodies.mass[: system.particles], np.float64), 3)  # (3N,) [kg]
        # the step matrix is assembled and factored by compiled kernels where they pay (large cloth)
        self._compiled = compiled_solves(self._particle_dofs)
        self.solver = StepMatrixSolver(self._compiled)
        self.explicit_terms: list[str] = []
        # forces without derivatives (gravitation, aerodynamics, …) enter explicitly: then the step is partly
        # symplectic Euler, whose energy oscillates every step, and halving would chase that down to h / 2^10
        linearised = all(type(term).jacobian is not ForceTerm.jacobian for term in model.force_terms)
        # rods (joints) act explicitly and are then projected, which moves the energy by O(h²) of either sign every
        # step: the guard would halve every step; the projection (orthogonal in the mass metric) keeps it bounded
        rods = getattr(model, "joints", None) is not None
        self.guard_energy = system.rigid == 0 and not system.adds_energy and linearised and not rods
        self.halvings = 0  # steps redone as two half steps by the energy guard
        self.corrections = 0  # Newton iterations after the linearised step, by the energy guard
        self.max_halvings = (MAX_HALVINGS if all(term.steps_lose_energy for term in model.force_terms)
                             else APPROXIMATE_HALVINGS)
        # Springs at rest hold almost no energy, so a relative tolerance alone would take the rounding of their
        # lengths for a rise and halve every step ten times over (a lattice at rest without gravity did): below
        # this floor [J], a rise is rounding. It is ε Σ k r², far below anything a step can do to the motion.
        springs = model.springs
        self.energy_floor = (ROUNDING_FLOOR * float(np.sum(springs.stiffness * springs.rest_length ** 2))
                             if springs is not None else 0.0)

    def kick(self, t: float, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        """Change the motion by one step: the linear solve for the particles, an explicit kick for rigid bodies."""
        system = self.system
        rate = system.motion_rate(t, config, motion, out=self._rate)
        self.evaluations += 1
        size = self._particle_dofs
        if size:
            factors, derivatives = self._step_matrix(t, config, motion, h)
            velocity = motion[:size]
            force = self._mass_diagonal * rate[:size]
            motion[:size] += factors.solve(h * (force + h * derivatives.product("x", velocity)))
        motion[size:] += h * rate[size:]

    def _step_matrix(self, t: float, config: np.ndarray, motion: np.ndarray, h: float
                     ) -> tuple[Any, ForceJacobian]:
        """Factors of the step's matrix ``M − h D − h² K``, with D and K at ``(t, config, motion)``, and the
        derivatives."""
        derivatives, self.explicit_terms = self.system.force_jacobian(t, config, motion, definite=True,
                                                                      compiled=self._compiled)
        # positive definite; symmetric too, unless a magnetic field adds its antisymmetric ∂f/∂v
        matrix = derivatives.step_matrix(self._mass_diagonal, h)
        self.factorisations += 1
        try:
            return self.solver.factor(matrix), derivatives
        except RuntimeError:  # SuperLU: "Factor is exactly singular"
            raise self._singular(t, h) from None

    def _correct(self, t: float, start: np.ndarray, y: np.ndarray, h: float) -> None:
        """One Newton iteration on the backward-Euler equations of a particle model, from the step's result in
        ``y`` (started from ``start`` at ``t``): ``g(v₁) = M (v₁ − v₀) − h f(x₀ + h v₁, v₁) = 0``, with the
        derivatives at the iterate, then the drift again from ``x₀``."""
        system = self.system
        size = self._particle_dofs
        config, motion = system.split(y)
        start_config, start_motion = system.split(start)
        rate = system.motion_rate(t + h, config, motion, out=self._rate)
        self.evaluations += 1
        factors, _ = self._step_matrix(t + h, config, motion, h)
        residual = self._mass_diagonal * (motion[:size] - start_motion[:size] - h * rate[:size])
        motion[:size] -= factors.solve(residual)
        config[...] = start_config
        drifting = self.constraint.resolve(config, motion, h, t=t) if self.constraint is not None else None
        system.drift(config, motion if drifting is None else drifting, h)
        system.project(y, t=t + h)

    def _singular(self, t: float, h: float) -> SimulationError:
        """Why the step's matrix M − h D − h² K could not be factored: springs so stiff or so damped, next to their
        masses, that the masses vanish in its rounding (the matrix is then as singular as D or K alone)."""
        springs = self.system.model.springs
        if springs is None or not springs.count:
            return SimulationError(f"backward_euler could not solve its step at t = {t:.6g} s: the step's matrix is "
                                   "singular. Check the scene's masses and the forces on them", time=t)
        mass = np.asarray(self.system.model.bodies.mass, np.float64)
        lightest = np.where(springs.second_is_anchor, mass[springs.first],
                            np.minimum(mass[springs.first],
                                       mass[np.where(springs.second_is_anchor, 0, springs.second)]))
        ratio = np.maximum(h * springs.damping, h * h * springs.stiffness) / lightest
        k = int(np.argmax(ratio))
        return SimulationError(
            f"backward_euler could not solve its step at t = {t:.6g} s: spring {springs.names[k]!r} (stiffness "
            f"{springs.stiffness[k]:.3g} N/m, damping {springs.damping[k]:.3g} N·s/m) is {ratio[k]:.3g} times its "
            f"lighter end's mass ({lightest[k]:.3g} kg) over a step of {h:.3g} s, so the masses vanish in the "
            "rounding of the step's matrix M − h D − h² K and it is singular. Give that spring a physical stiffness "
            "and damping (or the bodies physical masses)", time=t, body=springs.names[k])

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        # impacts change the energy by design; self-collision alone only in the steps where it acts (below)
        if self.guard_energy and (self.constraint is None or getattr(self.constraint, "guards_energy", False)):
            self._guarded_step(t, y, h, 0)
        else:
            self._plain_step(t, y, h)

    def _plain_step(self, t: float, y: np.ndarray, h: float) -> None:
        kick_constrain_drift(self, t, y, h)

    def _guarded_step(self, t: float, y: np.ndarray, h: float, depth: int) -> None:
        """A step that may not raise the energy: corrected by Newton iterations while it does, then, if it still
        does, two half steps instead (recursively)."""
        before = y.copy()
        energy, scale = self.system.energy(t, *self.system.split(y))
        self._plain_step(t, y, h)
        for correction in range(NEWTON_CORRECTIONS + 1):
            if getattr(self.constraint, "acted", False):  # self-collision's impulses: a collision, not a gain
                return
            after, after_scale = self.system.energy(t + h, *self.system.split(y))
            if after <= energy + max(ENERGY_TOLERANCE * max(scale, after_scale), self.energy_floor):
                return
            if correction < NEWTON_CORRECTIONS:
                self._correct(t, before, y, h)
                self.corrections += 1
        if depth < self.max_halvings:
            y[...] = before
            self.halvings += 1
            spent = budget_spent(t)
            if spent is not None:  # halvings can multiply one step into thousands
                raise OverBudget(f"backward_euler at dt = {h:.3g} s, halving its steps {self.halvings} times so far "
                                 f"to keep the energy from rising: {spent}", time=t)
            self._guarded_step(t, y, 0.5 * h, depth + 1)
            self._guarded_step(t + 0.5 * h, y, 0.5 * h, depth + 1)
