"""Fixed-step methods: explicit Euler, midpoint (RK2), semi-implicit (symplectic) Euler, velocity Verlet, and
linearised backward Euler (in :mod:`animbatch.sim.integrators.implicit`).

Step size: ``solver.dt`` is an upper bound. Each frame interval ``1/fps`` is split into ``n = ceil(interval / dt)``
equal steps, so frames fall exactly on steps and no interpolation is needed; the step used is recorded in the run's
statistics.

Methods (h: step, a(t, x, v) = F/m):

* ``euler`` — explicit Euler, ``y' = y + h f(t, y)``; order 1; gains energy on oscillators.
* ``midpoint`` — explicit midpoint (RK2), ``y' = y + h f(t + h/2, y + h/2 f(t, y))``; order 2.
* ``symplectic_euler`` — semi-implicit Euler: ``v' = v + h a(t, x, v)``, then ``x' = x + h v'``; order 1,
  symplectic (energy stays bounded on conservative systems). This is the "dynamics" update of the lecture notes.
* ``verlet`` — velocity Verlet: ``x' = x + h v + h²/2 a``, ``v' = v + h/2 (a + a')``; order 2, symplectic, one
  force evaluation per step. For velocity-dependent forces (drag, dampers) the new acceleration is evaluated with the
  predicted velocity ``v + h a``, which keeps the method second order (plain Verlet drops to first order there);
  for position-only forces this is exactly the classic method. This is the lecture notes' update
  ``p' = p + (v + v')/2 Δt`` with ``v' = v + a Δt``.

The partitioned methods work on configuration c and motion m (for rigid bodies: x, q and P, L): a *kick* changes m by
``h dm/dt`` and a *drift* moves c with m held fixed, turning orientations by the exact rotation ``exp(h ω)``
(:meth:`~animbatch.sim.model.dynamics.Dynamics.drift`). Semi-implicit Euler is kick, drift; Verlet is half kick, drift,
half kick. After every step of every method, quaternions are re-normalised.

Explicit Runge–Kutta methods are given as Butcher tableaux, so adding one is adding data. Every method is listed once,
with its order, stability matrix and particle kernel, in :data:`animbatch.sim.integrators.methods.METHODS`; the
loop that steps them between frames is :class:`~animbatch.sim.integrators.fixed_step_loop.FixedStepIntegrator`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.sim.integrators.interface import EquationsOfMotion, VelocityConstraint


class Scheme(ABC):
    """One fixed-step method, advancing a state in place. Schemes may cache work between steps (Verlet does)."""

    #: Classical order of accuracy.
    order: int
    #: Right-hand-side (force) evaluations per step, after the first.
    evaluations_per_step: int
    #: True when the scheme applies velocity constraints (contacts) between its kick and its drift. Explicit Euler
    #: and midpoint move positions with the velocities from before the step, so they cannot.
    takes_constraints: bool = False

    def __init__(self, system: EquationsOfMotion) -> None:
        self.system = system
        self.evaluations = 0
        self.factorisations = 0  # of an implicit step's matrix (with a force Jacobian each)
        self.constraint: VelocityConstraint | None = None  # set by the integrator for scenes with contacts

    def start(self, t: float, y: np.ndarray) -> None:
        """Prepare for stepping from state ``y`` at time ``t`` (called once, and again after a restore)."""

    @abstractmethod
    def step(self, t: float, y: np.ndarray, h: float) -> None:
        """Advance ``y`` in place from ``t`` to ``t + h``."""

    def snapshot(self) -> Any:
        """Whatever the scheme caches between steps, so that a replay from a saved state is exact."""
        return None

    def compiled_form(self) -> tuple[str, Any] | None:
        """How a compiled stepper takes this scheme's steps (``system.advance``): ``("runge_kutta", (a, b, c))``
        from the tableau, ``("symplectic_euler", None)``, ``("verlet", rate)`` with the rate buffer the scheme keeps
        between steps; None where it has no compiled form (implicit steps, or contacts between kick and drift)."""
        return None

    def restore(self, saved: Any) -> None:
        pass


@dataclass(frozen=True)
class ButcherTableau:
    """An explicit Runge–Kutta method: ``k_i = f(t + c_i h, y + h Σ_j a_ij k_j)``, ``y' = y + h Σ_i b_i k_i``."""

    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    order: int


EULER = ButcherTableau(a=((),), b=(1.0,), c=(0.0,), order=1)
MIDPOINT = ButcherTableau(a=((), (0.5,)), b=(0.0, 1.0), c=(0.0, 0.5), order=2)


class ExplicitRungeKutta(Scheme):
    """Any explicit Runge–Kutta method, from its tableau (one subclass per tableau: :meth:`of`)."""

    tableau: ButcherTableau

    @classmethod
    def of(cls, name: str, tableau: ButcherTableau) -> type[ExplicitRungeKutta]:
        """The scheme class of ``tableau``: what the method table lists for an explicit Runge–Kutta method."""
        return type(f"ExplicitRungeKutta[{name}]", (cls,), {"tableau": tableau})

    def __init__(self, system: EquationsOfMotion) -> None:
        super().__init__(system)
        self.order = self.tableau.order
        self.evaluations_per_step = len(self.tableau.b)
        self._k = np.empty((len(self.tableau.b), system.size))
        stages = len(self.tableau.b)
        a = np.zeros((stages, stages))
        for i, row in enumerate(self.tableau.a):
            a[i, : len(row)] = row
        self._arrays = (a, np.array(self.tableau.b, float), np.array(self.tableau.c, float))

    def compiled_form(self) -> tuple[str, Any] | None:
        return "runge_kutta", self._arrays

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        tableau, k = self.tableau, self._k
        for i, (row, c) in enumerate(zip(tableau.a, tableau.c)):
            stage = y
            for j, a_ij in enumerate(row):
                if a_ij:
                    stage = stage + (h * a_ij) * k[j]
            k[i] = self.system.rhs(t + c * h, stage)
        self.evaluations += len(tableau.b)
        for b_i, k_i in zip(tableau.b, k):
            if b_i:
                y += (h * b_i) * k_i
        self.system.project(y, t=t + h)


class PartitionedScheme(Scheme):
    """A scheme that kicks the motion and drifts the configuration, in preallocated buffers shaped like the motion.

    At 1e4+ particles every numpy temporary is a fresh memory mapping; doing the arithmetic in these buffers with
    ``out=`` makes a step several times faster.
    """

    def __init__(self, system: EquationsOfMotion) -> None:
        super().__init__(system)
        self._size = len(system.split(np.zeros(system.size))[1])
        self._rate = self.buffer()
        self._work = self.buffer()

    def buffer(self) -> np.ndarray:
        return np.empty(self._size)


class SymplecticEuler(PartitionedScheme):
    """Kick ``m' = m + h dm/dt(t, c, m)``, then drift c with m'. For particles: ``v' = v + h a``; ``x' = x + h v'``."""

    order = 1
    evaluations_per_step = 1
    takes_constraints = True

    def kick(self, t: float, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        rate = self.system.motion_rate(t, config, motion, out=self._rate)
        self.evaluations += 1
        motion += np.multiply(rate, h, out=self._work)

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        kick_constrain_drift(self, t, y, h)

    def compiled_form(self) -> tuple[str, Any] | None:
        return ("symplectic_euler", None) if self.constraint is None else None


def kick_constrain_drift(scheme: SymplecticEuler | Any, t: float, y: np.ndarray, h: float) -> None:
    """One step of a one-kick scheme (symplectic or backward Euler): kick, constraints (contacts), drift."""
    system = scheme.system
    config, motion = system.split(y)
    start = config.copy()  # the joints' SHAKE projection moves along their rows here
    scheme.kick(t, config, motion, h)
    drifting = scheme.constraint.resolve(config, motion, h, t=t) if scheme.constraint is not None else None
    system.drift(config, motion if drifting is None else drifting, h)
    # SHAKE turns the joints' correction into momentum, as the drift's own doing; a push out of an overlap (the
    # contacts' pseudo-velocities) moved the positions beyond it and must not become motion: a plain projection
    system.project(y, t=t + h, start=start if drifting is None else None, step=h)


class VelocityVerlet(PartitionedScheme):
    """Half kick, drift, half kick; the second rate is evaluated with the predicted motion ``m + h dm/dt`` and kept
    for the next step, so each step costs one evaluation. For particles this is
    ``x' = x + h v + h²/2 a``, ``v' = v + h/2 (a + a')``."""

    order = 2
    evaluations_per_step = 1
    takes_constraints = True

    def __init__(self, system: EquationsOfMotion) -> None:
        super().__init__(system)
        self._rate_next = self.buffer()
        self._predicted = self.buffer()

    def start(self, t: float, y: np.ndarray) -> None:
        config, motion = self.system.split(y)
        self.system.motion_rate(t, config, motion, out=self._rate)
        self.evaluations += 1

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        config, motion = self.system.split(y)
        rate, work, constraint = self._rate, self._work, self.constraint
        drifting = None
        if constraint is None:
            np.add(motion, np.multiply(rate, h, out=work), out=self._predicted)  # m + h dm/dt
            motion += np.multiply(rate, 0.5 * h, out=work)
        else:  # half kick, contacts, and the prediction from the corrected motion
            motion += np.multiply(rate, 0.5 * h, out=work)
            drifting = constraint.resolve(config, motion, h, t=t)
            np.add(motion, np.multiply(rate, 0.5 * h, out=work), out=self._predicted)
        self.system.drift(config, motion if drifting is None else drifting, h)
        rate_next = self.system.motion_rate(t + h, config, self._predicted, out=self._rate_next)
        self.evaluations += 1
        motion += np.multiply(rate_next, 0.5 * h, out=work)
        if constraint is not None:  # end-of-step velocities back onto the contacts, without bouncing again
            constraint.resolve(config, motion, h, bounce=False, t=t + h)
        self.system.project(y, t=t + h)
        self._rate, self._rate_next = rate_next, rate

    def snapshot(self) -> Any:
        return self._rate.copy()

    def compiled_form(self) -> tuple[str, Any] | None:
        return ("verlet", self._rate) if self.constraint is None else None

    def restore(self, saved: Any) -> None:
        self._rate[...] = saved
