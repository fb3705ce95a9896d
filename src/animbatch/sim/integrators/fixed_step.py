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

Explicit Runge–Kutta methods are given as Butcher tableaux, so adding one is adding data.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.errors import SimulationError
from animbatch.sim.integrators.base import EquationsOfMotion, FrameCallback, IntegrationResult, Integrator, SolverStats
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.guard import divergence_error, first_non_finite

DEFAULT_DT = 1e-3  # s


def substeps(interval: float, dt: float) -> int:
    """Number of equal steps of at most ``dt`` that cover ``interval``. A relative tolerance of 1e-6 absorbs a dt
    written to a few digits: ``dt: 0.008333333`` means 1/120 s, four steps per frame at 30 fps, not five."""
    return max(1, math.ceil(interval / dt * (1 - 1e-6)))


class Scheme(ABC):
    """One fixed-step method, advancing a state in place. Schemes may cache work between steps (Verlet does)."""

    #: Classical order of accuracy.
    order: int
    #: Right-hand-side (force) evaluations per step, after the first.
    evaluations_per_step: int

    def __init__(self, system: EquationsOfMotion) -> None:
        self.system = system
        self.evaluations = 0

    def start(self, t: float, y: np.ndarray) -> None:
        """Prepare for stepping from state ``y`` at time ``t`` (called once, and again after a restore)."""

    @abstractmethod
    def step(self, t: float, y: np.ndarray, h: float) -> None:
        """Advance ``y`` in place from ``t`` to ``t + h``."""

    def snapshot(self) -> Any:
        """Whatever the scheme caches between steps, so that a replay from a saved state is exact."""
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
    """Any explicit Runge–Kutta method, from its tableau."""

    tableau: ButcherTableau

    def __init__(self, system: EquationsOfMotion) -> None:
        super().__init__(system)
        self.order = self.tableau.order
        self.evaluations_per_step = len(self.tableau.b)
        self._k = np.empty((len(self.tableau.b), system.size))

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
        self.system.project(y)


class ExplicitEuler(ExplicitRungeKutta):
    tableau = EULER


class Midpoint(ExplicitRungeKutta):
    tableau = MIDPOINT


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

    def kick(self, t: float, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        rate = self.system.motion_rate(t, config, motion, out=self._rate)
        self.evaluations += 1
        motion += np.multiply(rate, h, out=self._work)

    def step(self, t: float, y: np.ndarray, h: float) -> None:
        config, motion = self.system.split(y)
        self.kick(t, config, motion, h)
        self.system.drift(config, motion, h)
        self.system.project(y)


class VelocityVerlet(PartitionedScheme):
    """Half kick, drift, half kick; the second rate is evaluated with the predicted motion ``m + h dm/dt`` and kept
    for the next step, so each step costs one evaluation. For particles this is
    ``x' = x + h v + h²/2 a``, ``v' = v + h/2 (a + a')``."""

    order = 2
    evaluations_per_step = 1

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
        rate, work = self._rate, self._work
        np.add(motion, np.multiply(rate, h, out=work), out=self._predicted)  # m + h dm/dt
        motion += np.multiply(rate, 0.5 * h, out=work)
        self.system.drift(config, motion, h)
        rate_next = self.system.motion_rate(t + h, config, self._predicted, out=self._rate_next)
        self.evaluations += 1
        motion += np.multiply(rate_next, 0.5 * h, out=work)
        self.system.project(y)
        self._rate, self._rate_next = rate_next, rate

    def snapshot(self) -> Any:
        return self._rate.copy()

    def restore(self, saved: Any) -> None:
        self._rate[...] = saved


FIXED_STEP_SCHEMES: dict[str, type[Scheme]] = {
    "euler": ExplicitEuler,
    "midpoint": Midpoint,
    "symplectic_euler": SymplecticEuler,
    "verlet": VelocityVerlet,
}

from animbatch.sim.integrators.implicit import BackwardEuler  # noqa: E402  (built on PartitionedScheme, above)

FIXED_STEP_SCHEMES["backward_euler"] = BackwardEuler


class FixedStepIntegrator(Integrator):
    """A fixed-step scheme with step at most ``dt`` [s], aligned to the frame times."""

    def __init__(self, method: str, *, dt: float = DEFAULT_DT) -> None:
        if method not in FIXED_STEP_SCHEMES:
            raise ValueError(f"unknown fixed-step method {method!r}; choose from {', '.join(FIXED_STEP_SCHEMES)}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 (got {dt})")
        self.method = method
        self.dt = dt

    def describe(self) -> str:
        return f"{self.method} (fixed step, dt <= {self.dt:g} s)"

    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        started = time.perf_counter()
        model = getattr(system, "model", None)
        layout = getattr(model, "layout", None)
        if model is not None and len(times) > 1:  # refuse a step that cannot hold the springs, before any work
            from animbatch.sim.integrators.stability import check_fixed_step

            count = substeps(float(times[1] - times[0]), self.dt)
            check_fixed_step(model, self.method, float(times[1] - times[0]) / count, count * (len(times) - 1))
        scheme = self._scheme(system, model)
        stats = SolverStats(self.method)
        y = np.array(y0, dtype=float)
        states = np.empty((len(times), len(y)))
        states[0] = y
        if on_frame is not None:
            on_frame(0, float(times[0]))
        with np.errstate(all="ignore"):  # overflow is detected once per frame and reported, not warned about
            largest_step = self._run(scheme, y, states, times, stats, layout, on_frame)
        stats.rhs_evaluations = scheme.evaluations
        if hasattr(scheme, "contacts"):  # contact schemes log their impacts
            stats.impacts = scheme.contacts.impacts.as_list()
        stats.dt = largest_step or None
        if len(times) > 1:
            stats.substeps_per_frame = substeps(float(times[1] - times[0]), self.dt)
        stats.wall_time = time.perf_counter() - started
        return IntegrationResult(states, stats)

    def _scheme(self, system: EquationsOfMotion, model: Any) -> Scheme:
        """The scheme for this method; scenes with contacts get its contact-resolving variant."""
        if getattr(model, "contact_world", None) is None:
            return FIXED_STEP_SCHEMES[self.method](system)
        from animbatch.sim.contact.stepping import CONTACT_SCHEMES  # contact code only for scenes with contacts

        if self.method not in CONTACT_SCHEMES:
            raise ValueError(f"{self.method} cannot keep contacts; use one of {', '.join(CONTACT_SCHEMES)}")
        return CONTACT_SCHEMES[self.method](system)  # type: ignore[arg-type]

    def _run(self, scheme: Scheme, y: np.ndarray, states: np.ndarray, times: np.ndarray, stats: SolverStats,
             layout: Any, on_frame: FrameCallback | None) -> float:
        """Step through every frame interval; return the largest step used [s]."""
        scheme.start(float(times[0]), y)
        largest_step = 0.0
        for frame in range(1, len(times)):
            t0, t1 = float(times[frame - 1]), float(times[frame])
            count = substeps(t1 - t0, self.dt)
            h = (t1 - t0) / count
            largest_step = max(largest_step, h)
            saved_state, saved_scheme = y.copy(), scheme.snapshot()
            for i in range(count):
                scheme.step(t0 + i * h, y, h)
                if i % 64 == 63:  # a clock read per 64 steps; a frame may hold 10⁶ of them
                    self._check_budget(t0 + (i + 1) * h, h, count)
            stats.steps += count
            self._check_budget(t1, h, count)
            if first_non_finite(y) is not None:
                # Checked once per frame to keep the loop cheap; replay the frame to find the exact step.
                y[...] = saved_state
                scheme.restore(saved_scheme)
                self._raise_at_first_bad_step(scheme, layout, y, t0, h, count, stats.steps - count)
            states[frame] = y
            if on_frame is not None:
                on_frame(frame, t1)
        return largest_step

    def _check_budget(self, t: float, h: float, count: int) -> None:
        spent = budget_spent(t)
        if spent is not None:
            raise SimulationError(f"{self.method} at dt = {h:.3g} s ({count} steps per frame): {spent}", time=t)

    def _raise_at_first_bad_step(self, scheme: Scheme, layout: Any, y: np.ndarray, t0: float, h: float, count: int,
                                 steps_before: int) -> None:
        for i in range(count):
            scheme.step(t0 + i * h, y, h)
            bad = first_non_finite(y)
            if bad is not None:
                raise divergence_error(layout, y, bad, t0 + (i + 1) * h, method=self.method, dt=h,
                                       step=steps_before + i + 1)
        # Not reproduced (should not happen: the replay is exact). Report the frame interval instead.
        bad = first_non_finite(y)
        raise divergence_error(layout, y, bad if bad is not None else 0, t0 + count * h, method=self.method, dt=h)
