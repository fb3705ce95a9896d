"""The fixed-step integration loop: a scheme stepped ``ceil(interval / dt)`` equal steps per frame interval, so that
frames fall exactly on steps; divergence is caught once per frame and the frame replayed to name the first bad step."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from animbatch.errors import OverBudget
from animbatch.sim.blas import threads_for_state
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.description import describe_method
from animbatch.sim.integrators.fixed_step import Scheme
from animbatch.sim.integrators.guard import divergence_error, first_non_finite, project_start
from animbatch.sim.integrators.interface import (
    ConstraintFactory,
    EquationsOfMotion,
    FrameCallback,
    IntegrationResult,
    Integrator,
    SolverStats,
)
from animbatch.sim.integrators.methods import FIXED_STEP_SCHEMES
from animbatch.sim.integrators.stability import check_fixed_step
from animbatch.sim.integrators.step_plan import resolve_dt, substeps

#: At most this many steps per compiled call, between reads of the wall-time budget.
COMPILED_CHUNK = 256


class FixedStepIntegrator(Integrator):
    """A fixed-step scheme with step at most ``dt`` [s] (None: the method's default, see
    :func:`~animbatch.sim.integrators.step_plan.resolve_dt`), aligned to the frame times."""

    def __init__(self, method: str, *, dt: float | None = None, constraint: ConstraintFactory | None = None) -> None:
        """``constraint``: makes the velocity constraints (contacts) for the system integrated, or None."""
        if method not in FIXED_STEP_SCHEMES:
            raise ValueError(f"unknown fixed-step method {method!r}; choose from {', '.join(FIXED_STEP_SCHEMES)}")
        if dt is not None and not dt > 0:
            raise ValueError(f"dt must be > 0 (got {dt})")
        if constraint is not None and not FIXED_STEP_SCHEMES[method].takes_constraints:
            keeping = [name for name, scheme in FIXED_STEP_SCHEMES.items() if scheme.takes_constraints]
            raise ValueError(f"{method} cannot keep contacts; use one of {', '.join(keeping)}")
        self.method = method
        self.dt = dt
        self.constraint = constraint

    def describe(self) -> str:
        return describe_method(self.method, adaptive=False, dt=self.dt)

    def step_bound(self, times: np.ndarray) -> float:
        """The largest step [s] over frames at ``times`` (F,): ``dt``, or the method's default for their interval."""
        return resolve_dt(self.dt, self.method, float(times[1] - times[0]) if len(times) > 1 else None)

    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        started = time.perf_counter()
        dt = self.step_bound(times)
        model = getattr(system, "model", None)
        layout = getattr(model, "layout", None)
        if model is not None and len(times) > 1:  # refuse a step that cannot hold the springs, before any work
            count = substeps(float(times[1] - times[0]), dt)
            check_fixed_step(model, self.method, float(times[1] - times[0]) / count, count * (len(times) - 1))
        scheme = FIXED_STEP_SCHEMES[self.method](system)
        if self.constraint is not None:
            scheme.constraint = self.constraint(system)
        stats = SolverStats(self.method)
        y = np.array(y0, dtype=float)
        # a start that breaks its joints (see EquationsOfMotion.project) is put on them first
        project_start(system, y, float(times[0]))
        if hasattr(system, "joint_stabilisation"):  # projected after every step, joints need no Baumgarte term
            system.joint_stabilisation = 0.0
        states = np.empty((len(times), len(y)))
        states[0] = y
        if on_frame is not None:
            on_frame(0, float(times[0]))
        # overflow is detected once per frame and reported, not warned about; small systems keep BLAS on one thread
        with np.errstate(all="ignore"), threads_for_state(len(y)):
            largest_step = self._run(scheme, y, states, times, dt, stats, layout, on_frame)
        stats.rhs_evaluations = scheme.evaluations
        stats.jacobian_evaluations = stats.lu_decompositions = scheme.factorisations
        if scheme.constraint is not None:  # contacts log their impacts, and how their solves ended
            stats.impacts = scheme.constraint.impacts.as_list()
            stats.contact_solves = scheme.constraint.solves
            totals = getattr(scheme.constraint, "totals", None)  # self-collision's counters
            stats.self_contact = dict(totals) if totals is not None else None
        stats.dt = largest_step or None
        if len(times) > 1:
            stats.substeps_per_frame = substeps(float(times[1] - times[0]), dt)
        stats.wall_time = time.perf_counter() - started
        return IntegrationResult(states, stats)

    def _run(self, scheme: Scheme, y: np.ndarray, states: np.ndarray, times: np.ndarray, dt: float,
             stats: SolverStats, layout: Any, on_frame: FrameCallback | None) -> float:
        """Step through every frame interval; return the largest step used [s]."""
        scheme.start(float(times[0]), y)
        # a system that takes a scheme's form (compiled equations of motion: every form; a tree of hinges and
        # sliders: Runge–Kutta and Verlet, in its joint coordinates) steps it in one call per frame
        form = scheme.compiled_form()
        advances = getattr(scheme.system, "advances", None)
        advance = getattr(scheme.system, "advance") if advances is not None and advances(form) else None
        largest_step = 0.0
        for frame in range(1, len(times)):
            t0, t1 = float(times[frame - 1]), float(times[frame])
            count = substeps(t1 - t0, dt)
            h = (t1 - t0) / count
            largest_step = max(largest_step, h)
            saved_state, saved_scheme = y.copy(), scheme.snapshot()
            if advance is not None and form is not None:  # a call per frame (or per chunk of steps)
                for first in range(0, count, COMPILED_CHUNK):
                    steps = min(COMPILED_CHUNK, count - first)
                    scheme.evaluations += advance(form, y, t0 + first * h, h, steps)
                    self._check_budget(t0 + (first + steps) * h, h, count)
            else:
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
            raise OverBudget(f"{self.method} at dt = {h:.3g} s ({count} steps per frame): {spent}", time=t)

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
