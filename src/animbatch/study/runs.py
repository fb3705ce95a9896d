"""The runs of a study: which integrator settings to try, and running each one twice over: once untimed to keep
its frames (for the errors), then ``repeats`` times timed.

Timing is the minimum wall time of the timed repeats, with BLAS and OpenMP pools pinned to one thread (threadpoolctl)
so that one method's sparse solves do not borrow cores another method cannot use. A run that raises (refused by the
stability check, diverged, solver failure, energy rising in a scene without energy input) or exceeds the timeout is
kept as a failure with its reason: the same checks as every ``animbatch render``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from animbatch.errors import SimulationError
from animbatch.sim.integrate import integrator_for
from animbatch.sim.integrators import FIXED_STEP_SCHEMES, SCIPY_METHODS, IntegrationResult, Integrator
from animbatch.sim.integrators.guard import check_energy_growth
from animbatch.sim.model import Dynamics, Model
from animbatch.stages import choose_dynamics


@dataclass(frozen=True)
class StepValues:
    """Step settings in the shape of a scene's solver section
    (:class:`~animbatch.sim.integrators.interface.StepSettings`): ``dt`` [s] for fixed steps, ``rtol`` and a scalar
    ``atol`` for adaptive ones."""

    method: str
    dt: float | None
    rtol: float
    atol: float
    max_step: float | None = None


@dataclass(frozen=True)
class RunSetting:
    """One integrator setting: an adaptive ``method`` at ``rtol`` (atol = rtol × the per-component scale), or a
    fixed-step one at ``dt`` [s]."""

    method: str
    rtol: float | None = None
    dt: float | None = None

    @property
    def adaptive(self) -> bool:
        return self.rtol is not None

    @property
    def label(self) -> str:
        return f"rtol {self.rtol:.0e}" if self.adaptive else f"dt {self.dt:.3g} s"

    def steps(self, atol: float) -> StepValues:
        """This setting as a scene's solver section would give it (what cost estimates and emitters read)."""
        return StepValues(self.method, self.dt, self.rtol or 1e-3, atol)

    def integrator(self, model: Model, tolerance_scale: np.ndarray) -> Integrator:
        """The integrator of this setting for ``model`` (with its contacts, if any)."""
        if self.adaptive:
            assert self.rtol is not None
            return integrator_for(model, self.method, rtol=self.rtol, atol=self.rtol * tolerance_scale)
        assert self.dt is not None
        return integrator_for(model, self.method, dt=self.dt)


@dataclass
class RunOutcome:
    """What one setting did: ``status`` ok, failed or timeout (with ``reason``), its frames (F, n) when ok (or
    its emitters' particles), the work (minimum ``wall_time`` [s] over the timed repeats, RHS evaluations, steps,
    Jacobians, factorisations)."""

    setting: RunSetting
    status: str
    reason: str = ""
    states: np.ndarray | None = None
    wall_time: float | None = None
    rhs_evaluations: int | None = None
    steps: int | None = None
    jacobian_evaluations: int | None = None
    lu_decompositions: int | None = None
    wall_times: list[float] = field(default_factory=list)
    impacts: list[tuple[float, int]] = field(default_factory=list)  # (time [s], body) of each bounce, in order
    particles: list[Any] | None = None  # a scene of emitters: each emitter's ParticleFrames instead of states


class RunTimeout(Exception):
    """A run went over its wall-time budget."""


def applicable_methods(model: Model, chosen: list[str] | None) -> tuple[list[str], dict[str, str]]:
    """The methods to study (``chosen``, or all) and those left out with the reason (methods that cannot run this
    kind of scene at all, as opposed to settings that fail)."""
    methods = list(chosen) if chosen else [*SCIPY_METHODS, *FIXED_STEP_SCHEMES]
    skipped: dict[str, str] = {}
    if model.contact_world is not None:
        for method in ("euler", "midpoint"):
            if method in methods:
                skipped[method] = "not used with collisions (no contact treatment for it)"
    return [m for m in methods if m not in skipped], skipped


def plan_settings(methods: list[str], rtols: list[float], frame_interval: float, dt_levels: int) -> list[RunSetting]:
    """Every setting of a study: each adaptive method at each ``rtol``, each fixed-step method at
    ``frame_interval / 2^k`` for k = 0 … dt_levels-1."""
    settings = []
    for method in methods:
        if method in SCIPY_METHODS:
            settings += [RunSetting(method, rtol=r) for r in sorted(rtols, reverse=True)]
        else:
            settings += [RunSetting(method, dt=frame_interval / 2**k) for k in range(dt_levels)]
    return settings


def _integrate(model: Model, setting: RunSetting, integrator: Integrator, timeout: float) -> IntegrationResult:
    """One run of ``setting``, on the equations of motion a render with it would choose (compiled where they repay
    loading: :func:`animbatch.stages.choose_dynamics`), so that its time is what the setting costs a render."""
    deadline = time.perf_counter() + timeout

    def on_frame(frame: int, t: float) -> None:
        if time.perf_counter() > deadline:
            raise RunTimeout

    system, _cost = choose_dynamics(model, setting.steps(atol=1e-6))
    return integrator.integrate(_with_deadline(system, deadline), model.y0, model.frame_times, on_frame=on_frame)


def _with_deadline(system: Dynamics, deadline: float) -> Dynamics:
    """``system`` whose force evaluations raise :class:`RunTimeout` after ``deadline`` (``time.perf_counter``): a
    run that crawls inside one frame (thousands of contact events, or steps shrinking to nothing) must time out
    too, not only between frames."""
    for name in ("rhs", "motion_rate"):
        evaluate = getattr(system, name)

        def checked(*args: Any, _evaluate: Any = evaluate, **kwargs: Any) -> Any:
            if time.perf_counter() > deadline:
                raise RunTimeout
            return _evaluate(*args, **kwargs)

        setattr(system, name, checked)
    return system


def execute(model: Model, setting: RunSetting, tolerance_scale: np.ndarray, *, repeats: int, timeout: float,
            ) -> RunOutcome:
    """Run one setting: untimed for its frames, then ``repeats`` timed runs (only one when a run takes longer than
    a few seconds: its time is then far above the timer's noise; none with ``repeats`` 0, when only the frames
    matter, as for a reference)."""
    from threadpoolctl import threadpool_limits  # only when studies run in parallel

    with threadpool_limits(limits=1):
        try:
            first = _integrate(model, setting, setting.integrator(model, tolerance_scale), timeout)
            check_energy_growth(model, first.states, setting.method, first.stats.dt)  # as every run is checked
        except RunTimeout:
            return RunOutcome(setting, "timeout", f"took longer than {timeout:g} s")
        except SimulationError as error:
            return RunOutcome(setting, "failed", str(error))
        outcome = RunOutcome(setting, "ok", states=first.states, rhs_evaluations=first.stats.rhs_evaluations,
                             steps=first.stats.steps, jacobian_evaluations=first.stats.jacobian_evaluations,
                             lu_decompositions=first.stats.lu_decompositions, impacts=first.stats.impacts)
        timed = repeats if first.stats.wall_time < 2.0 else min(repeats, 1)
        for _ in range(timed):
            try:
                outcome.wall_times.append(_integrate(model, setting, setting.integrator(model, tolerance_scale),
                                                     timeout).stats.wall_time)
            except RunTimeout:  # the untimed run made it, a timed one did not: keep what was measured
                outcome.wall_times.append(timeout)
    outcome.wall_time = min(outcome.wall_times, default=first.stats.wall_time)
    if not np.isfinite(first.states).all():
        outcome.status, outcome.reason = "failed", "non-finite state in the frames"
    return outcome
