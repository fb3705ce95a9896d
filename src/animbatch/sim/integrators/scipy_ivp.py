"""Adaptive methods from ``scipy.integrate``: RK23, RK45, DOP853, Radau, BDF, LSODA.

The solver object is stepped directly (as ``solve_ivp`` does internally) rather than through ``solve_ivp``, so that
each accepted step can be checked for a finite state, progress can be reported per frame, and a failure can name the
time and body. Frames are evaluated from the solver's dense output at exactly the requested times, independent of
where its steps fall.

Radau and BDF get the model's analytic sparse Jacobian (:meth:`Dynamics.jacobian`) when the model has only particles:
without it scipy estimates a dense one by finite differences, one right-hand side per state component, which for a
cloth costs thousands of evaluations per Jacobian and a dense LU. Their Newton matrices are then factored through the
half-size velocity system (:mod:`animbatch.sim.integrators.linear_algebra`), not as 6N × 6N general sparse matrices.

Given events (:class:`~animbatch.sim.integrators.interface.StepEvents`; contacts,
:mod:`animbatch.sim.contact.impact_events`), the same loop asks after each step for the first event inside it, writes
the frames before it from the step's dense output, lets the events act on the state at that instant, and restarts the
solver from there.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import OdeSolver

from animbatch.errors import OverBudget, SimulationError
from animbatch.sim.blas import threads_for_state
from animbatch.sim.integrators.advice import failure_advice
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.description import describe_method
from animbatch.sim.integrators.guard import divergence_error, fastest_body, first_non_finite, project_start
from animbatch.sim.integrators.interface import (
    CountingRhs,
    EquationsOfMotion,
    EventsFactory,
    FrameCallback,
    IntegrationResult,
    Integrator,
    SolverStats,
    StepEvents,
)
from animbatch.sim.integrators.linear_algebra import use_second_order_factors
from animbatch.sim.integrators.methods import METHODS, SCIPY_METHODS
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
                 max_step: float | None = None, events: EventsFactory | None = None) -> None:
        """``events``: makes the events (collisions) the solver stops at between frames, or None for none."""
        if method not in SCIPY_METHODS:
            raise ValueError(f"unknown adaptive method {method!r}; choose from {', '.join(SCIPY_METHODS)}")
        self.method = method
        self.rtol = rtol
        self.atol = atol
        self.max_step = max_step
        self.events = events

    def describe(self) -> str:
        return describe_method(self.method, adaptive=True, rtol=self.rtol, atol=self.atol, max_step=self.max_step)

    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        started = time.perf_counter()
        events = self.events(system) if self.events is not None else None
        stats = SolverStats(self.method)
        states = np.empty((len(times), len(y0)))
        fun = CountingRhs(events.rhs if events is not None else system.rhs)
        start = np.array(y0, dtype=float)
        # a start that breaks its joints (see EquationsOfMotion.project) is put on them first
        project_start(system, start, float(times[0]))
        # overflow is detected and reported by the checks below, not as warnings; small systems keep BLAS on one thread
        with np.errstate(all="ignore"), threads_for_state(len(start)):
            self._run(system, events, fun, start, times, states, stats, on_frame)
        stats.rhs_evaluations = fun.count
        if events is not None:
            stats.impacts = events.impacts.as_list()
        stats.wall_time = time.perf_counter() - started
        return IntegrationResult(states, stats)

    def _solver(self, system: EquationsOfMotion, events: StepEvents | None, fun: CountingRhs, t: float,
                y: np.ndarray, end: float) -> OdeSolver:
        """A solver from ``y`` at ``t`` [s] to ``end``: with the analytic Jacobian where it helps (not with events,
        whose forces it leaves out), and the step the events allow from here."""
        max_step = self.max_step or np.inf
        if events is not None:
            allowed = events.restart(t, y)
            max_step = min(max_step, allowed) if allowed is not None else max_step
        options = {}
        # analytic and sparse: no finite differences, and a Newton matrix factored at half size
        analytic = (system if events is None and self.method in JACOBIAN_METHODS and isinstance(system, Dynamics)
                    and system.has_jacobian else None)
        if analytic is not None:
            options["jac"] = analytic.jacobian
        solver_class = METHODS[self.method].solver_class()
        solver = solver_class(fun, t, y.copy(), end, rtol=self.rtol, atol=self.atol, max_step=max_step, **options)
        if analytic is not None:
            use_second_order_factors(solver, np.repeat(np.asarray(analytic.model.bodies.mass[: analytic.particles],
                                                                  np.float64), 3))
        return solver

    def _run(self, system: EquationsOfMotion, events: StepEvents | None, fun: CountingRhs, y: np.ndarray,
             times: np.ndarray, states: np.ndarray, stats: SolverStats, on_frame: FrameCallback | None) -> None:
        """Step solvers over ``times``, writing frames from their dense output; at each event (if any) write the
        frames before it, let the events act at that instant, and restart from there."""
        layout = getattr(getattr(system, "model", None), "layout", None)
        t = float(times[0])
        if events is not None:
            events.start(t, y, len(times), self.method)
        states[0] = y
        if on_frame is not None:
            on_frame(0, t)
        frame = 1
        stall_step = STALL_FRACTION * float(times[1] - times[0]) if len(times) > 1 else 0.0
        while frame < len(times):
            solver = self._solver(system, events, fun, t, y, float(times[-1]))
            cap = NewtonStepCap(solver, self.max_step or np.inf) if self.method == "BDF" and events is None else None
            tiny, event_time = 0, None
            while frame < len(times):
                before = solver.y.copy()  # the last finite state, for advice should this step diverge
                message = solver.step()
                if solver.status == "failed":
                    raise self._failure(solver, fun, system, events, "failed", message)
                if cap is not None:
                    cap.after_step()
                stats.count_step(solver.t - solver.t_old)
                # steps end at events, which may be close together: a stall is only judged without events
                tiny = tiny + 1 if events is None and solver.t - solver.t_old < stall_step else 0
                if tiny > STALL_STEPS:
                    raise self._failure(solver, fun, system, events, "failed", f"its last {STALL_STEPS} steps were "
                                        f"all shorter than {stall_step:.2g} s, so it has stalled ({stats.steps} "
                                        "steps so far).")
                spent = budget_spent(solver.t)
                if spent is not None:
                    failure = self._failure(solver, fun, system, events, "stopped", f"{spent} ({stats.steps} "
                                            f"steps so far, the last {solver.t - solver.t_old:.3g} s long).")
                    raise OverBudget(str(failure), time=failure.time, body=failure.body)
                bad = first_non_finite(solver.y)
                if bad is not None:
                    raise divergence_error(layout, solver.y, bad, solver.t, method=self.method, step=stats.steps,
                                           model=getattr(system, "model", None), last_finite=before)
                event_time = events.first_event(solver, before) if events is not None else None
                end = solver.t if event_time is None else event_time
                interpolant = solver.dense_output() if times[frame] <= end or event_time is not None else None
                while frame < len(times) and times[frame] <= end:
                    exact = times[frame] == solver.t and event_time is None
                    states[frame] = solver.y if exact or interpolant is None else interpolant(times[frame])
                    system.project(states[frame], joints=False)  # unit quaternions in every output
                    if on_frame is not None:
                        on_frame(frame, float(times[frame]))
                    frame += 1
                if events is not None and event_time is not None and interpolant is not None:
                    t, y = float(event_time), interpolant(event_time)
                    system.project(y, t=t)
                    events.handle(t, y)
                    system.project(y, t=t)  # impulses can break joints' velocities (a ball hit across its string)
                    break  # restart the solver from the event
                if solver.status == "finished":
                    break
            stats.jacobian_evaluations += int(solver.njev)
            stats.lu_decompositions += int(solver.nlu)
            stats.scipy_nfev = (stats.scipy_nfev or 0) + int(solver.nfev)
            if event_time is None:
                break

    def _failure(self, solver: OdeSolver, fun: CountingRhs, system: EquationsOfMotion, events: StepEvents | None,
                 verb: str, message: str | None) -> SimulationError:
        """Why the solver gave up: non-finite forces if any were seen, else advice that fits what happened (a close
        gravitational encounter, a stiff spring, the fastest-changing body; :mod:`animbatch.sim.integrators.advice`),
        and with events what to try for them."""
        model = getattr(system, "model", None)
        layout = getattr(model, "layout", None)
        when = f"at t = {solver.t:.6g} s" + (f" with {events.label}" if events is not None else "")
        if fun.first_non_finite is not None and layout is not None:
            seen_at, index = fun.first_non_finite
            body, quantity = layout.describe_index(index)
            return SimulationError(
                f"{self.method} {verb} {when}: the rate of change of body {body!r} {quantity} became non-finite "
                f"(first at t = {seen_at:.6g} s), so no step could be accepted. Check that body's springs and fields "
                "for extreme values.", time=solver.t, body=body)
        body = fastest_body(layout, fun(solver.t, solver.y), solver.y, self.atol, self.rtol)
        advice = failure_advice(model, self.method, solver.y, solver.t, body)
        return SimulationError(f"{self.method} {verb} {when}: {message} {advice}."
                               + (f" {events.advice}" if events is not None and verb == "failed" else ""),
                               time=solver.t, body=body)
