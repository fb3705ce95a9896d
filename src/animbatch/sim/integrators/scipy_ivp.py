"""Adaptive methods from ``scipy.integrate``: RK23, RK45, DOP853, Radau, BDF, LSODA.

The solver object is stepped directly (as ``solve_ivp`` does internally) rather than through ``solve_ivp``, so that
each accepted step can be checked for a finite state, progress can be reported per frame, and a failure can name the
time and body. Frames are evaluated from the solver's dense output at exactly the requested times, independent of
where its steps fall.

Radau and BDF get the model's analytic sparse Jacobian (:meth:`Dynamics.jacobian`) when the model has only particles:
without it scipy estimates a dense one by finite differences, one right-hand side per state component, which for a
cloth costs thousands of evaluations per Jacobian and a dense LU. Their Newton matrices are then factored through the
half-size velocity system (:mod:`animbatch.sim.integrators.linear_algebra`), not as 6N × 6N general sparse matrices.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from scipy.integrate import OdeSolver

from animbatch.errors import SimulationError
from animbatch.sim.integrators.advice import failure_advice
from animbatch.sim.integrators.base import (
    CountingRhs,
    EquationsOfMotion,
    EventIntegration,
    FrameCallback,
    IntegrationResult,
    Integrator,
    SolverStats,
)
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.guard import divergence_error, fastest_body, first_non_finite
from animbatch.sim.integrators.linear_algebra import use_second_order_factors
from animbatch.sim.integrators.methods import SCIPY_METHODS
from animbatch.sim.model.dynamics import Dynamics

#: A solver whose steps stay shorter than this fraction of the frame interval for more than STALL_STEPS steps in a
#: row has stalled (LSODA crawled through 5.6 million steps of 1e-16 s for 5 minutes at the centre of a gravitational
#: plunge without failing); no physical transient needs that.
STALL_FRACTION = 1e-9
STALL_STEPS = 10_000

#: Implicit methods given the analytic sparse Jacobian (models of particles; LSODA only takes dense ones).
JACOBIAN_METHODS = ("Radau", "BDF")


class NewtonStepCap:
    """Holds scipy's BDF back from the step sizes where its Newton iteration just failed (as CVODE does after a
    convergence failure).

    scipy's BDF halves the step when Newton's iteration fails with a fresh Jacobian, and then lets its error
    estimate grow the step up to tenfold again, straight back into the failure: on a stiff cloth at rtol 1e-2 most
    of the run went into failed iterations and refactorisations. Here a step during which the Jacobian had to be
    re-evaluated (scipy does so only when Newton fails) caps the next steps at the one that finally converged,
    and the cap then grows by :data:`GROWTH` per step without a failure. Measured on the 32×32 cloth for 1 s: rtol
    1e-2 went from 26.6 s to 9.2 s, rtol 1e-3 from 7.6 s to 7.3 s.
    """

    GROWTH = 1.2

    def __init__(self, solver: OdeSolver, max_step: float) -> None:
        self.solver = solver
        self.limit = max_step
        self.cap = np.inf
        self.jacobians = solver.njev

    def after_step(self) -> None:
        solver = self.solver
        if solver.njev > self.jacobians and solver.t_old is not None:
            self.cap = abs(solver.t - solver.t_old)
        else:
            self.cap *= self.GROWTH
        self.jacobians = solver.njev
        solver.max_step = min(self.limit, self.cap)


class ScipyIntegrator(Integrator):
    """An adaptive scipy method with tolerances ``rtol``, ``atol`` (a number, or one per state component) and an
    optional ``max_step`` [s]."""

    def __init__(self, method: str, *, rtol: float = 1e-6, atol: float | np.ndarray = 1e-9,
                 max_step: float | None = None, events: EventIntegration | None = None) -> None:
        """``events``: integrates with events between frames (collisions), or None for plain stepping."""
        if method not in SCIPY_METHODS:
            raise ValueError(f"unknown adaptive method {method!r}; choose from {', '.join(SCIPY_METHODS)}")
        self.method = method
        self.rtol = rtol
        self.atol = atol
        self.max_step = max_step
        self.events = events

    def describe(self) -> str:
        limit = f", max_step {self.max_step:g} s" if self.max_step else ""
        atol = f"{self.atol:g}" if np.ndim(self.atol) == 0 else "per component"
        return f"{self.method} (adaptive, rtol {self.rtol:g}, atol {atol}{limit})"

    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        started = time.perf_counter()
        if self.events is not None:
            options = {"rtol": self.rtol, "atol": self.atol, "max_step": self.max_step if self.max_step else np.inf}
            return self.events(self.method, SCIPY_METHODS[self.method], options, system, y0, times, on_frame)
        layout = getattr(getattr(system, "model", None), "layout", None)
        stats = SolverStats(self.method)
        states = np.empty((len(times), len(y0)))
        states[0] = y0
        if on_frame is not None:
            on_frame(0, float(times[0]))
        fun = CountingRhs(system.rhs)
        with np.errstate(all="ignore"):  # overflow is detected and reported by the checks below, not as warnings
            self._run(system, fun, y0, times, states, stats, layout, on_frame)
        stats.rhs_evaluations = fun.count
        stats.wall_time = time.perf_counter() - started
        return IntegrationResult(states, stats)

    def _run(self, system: EquationsOfMotion, fun: CountingRhs, y0: np.ndarray, times: np.ndarray,
             states: np.ndarray, stats: SolverStats, layout: Any, on_frame: FrameCallback | None) -> None:
        if len(times) > 1:
            options = {}
            if self.method in JACOBIAN_METHODS and isinstance(system, Dynamics) and system.has_jacobian:
                options["jac"] = system.jacobian  # analytic and sparse: no finite differences, sparse LU
            solver = SCIPY_METHODS[self.method](fun, float(times[0]), np.array(y0, dtype=float), float(times[-1]),
                                                rtol=self.rtol, atol=self.atol,
                                                max_step=self.max_step if self.max_step else np.inf, **options)
            if isinstance(system, Dynamics) and "jac" in options:
                mass = np.repeat(np.asarray(system.model.bodies.mass[: system.particles], np.float64), 3)
                use_second_order_factors(solver, mass)
            cap = NewtonStepCap(solver, self.max_step or np.inf) if self.method == "BDF" else None
            frame = 1
            tiny, stall_step = 0, STALL_FRACTION * float(times[1] - times[0])
            while frame < len(times):
                before = solver.y.copy()  # the last finite state, for advice should this step diverge
                message = solver.step()
                if solver.status == "failed":
                    raise self._failure(solver, fun, system, message)
                if cap is not None:
                    cap.after_step()
                stats.count_step(solver.t - solver.t_old)
                tiny = tiny + 1 if solver.t - solver.t_old < stall_step else 0
                if tiny > STALL_STEPS:
                    raise self._failure(solver, fun, system, f"its last {STALL_STEPS} steps were all shorter than "
                                        f"{stall_step:.2g} s, so it has stalled ({stats.steps} steps so far).")
                spent = budget_spent(solver.t)
                if spent is not None:
                    raise self._failure(solver, fun, system, f"{spent} ({stats.steps} steps so far, the last "
                                        f"{solver.t - solver.t_old:.3g} s long).")
                bad = first_non_finite(solver.y)
                if bad is not None:
                    raise divergence_error(layout, solver.y, bad, solver.t, method=self.method, step=stats.steps,
                                           model=getattr(system, "model", None), last_finite=before)
                if times[frame] <= solver.t:
                    interpolant = solver.dense_output()
                    while frame < len(times) and times[frame] <= solver.t:
                        states[frame] = solver.y if times[frame] == solver.t else interpolant(times[frame])
                        system.project(states[frame])  # unit quaternions in every output
                        if on_frame is not None:
                            on_frame(frame, float(times[frame]))
                        frame += 1
            stats.jacobian_evaluations = int(solver.njev)
            stats.lu_decompositions = int(solver.nlu)
            stats.scipy_nfev = int(solver.nfev)

    def _failure(self, solver: OdeSolver, fun: CountingRhs, system: EquationsOfMotion,
                 message: str | None) -> SimulationError:
        """Why the solver gave up: non-finite forces if any were seen, else advice that fits what happened (a close
        gravitational encounter, a stiff spring, the fastest-changing body; :mod:`animbatch.sim.integrators.advice`)."""
        model = getattr(system, "model", None)
        layout = getattr(model, "layout", None)
        if fun.first_non_finite is not None and layout is not None:
            seen_at, index = fun.first_non_finite
            body, quantity = layout.describe_index(index)
            return SimulationError(
                f"{self.method} failed at t = {solver.t:.6g} s: the rate of change of body {body!r} {quantity} "
                f"became non-finite (first at t = {seen_at:.6g} s), so no step could be accepted. Check that body's "
                "springs and fields for extreme values.", time=solver.t, body=body)
        body = fastest_body(layout, fun(solver.t, solver.y), solver.y, self.atol, self.rtol)
        advice = failure_advice(model, self.method, solver.y, solver.t, body)
        return SimulationError(f"{self.method} failed at t = {solver.t:.6g} s: {message} {advice}.", time=solver.t,
                               body=body)
