"""``run_study``: every applicable integrator over a sweep of tolerances or steps, each run's error against the
reference and its work, and each method's figures of merit.

    from animbatch import api
    from animbatch.study import run_study, write_outputs
    result = run_study(api.load_scene("scenes/projectile.yaml"))
    write_outputs(result, "renders/projectile")
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

from animbatch.compile.particles import ParticleSystems
from animbatch.compile.plan import plan_run
from animbatch.errors import SceneError, SceneIssue
from animbatch.scene import LoadedScene
from animbatch.sim.closed_forms import NoClosedForm
from animbatch.sim.model import Model
from animbatch.study.emitter_study import births_by_end, execute_particles, particle_motion, particle_reference
from animbatch.study.measure import Motion, conserved, contact_time_error, drifts, final_error, position_error
from animbatch.study.merit import Point, TimeTo, observed_order, time_to
from animbatch.study.reference import REFERENCE_MARGIN, Reference, find_reference
from animbatch.study.runs import RunOutcome, applicable_methods, execute, plan_settings

#: The errors (relative RMS position error) whose cost the study reports: "visually exact" and "accurate".
TARGETS = (1e-3, 1e-6)


@dataclass
class StudyRow:
    """One run of the study: its setting, status, errors and work (see :mod:`animbatch.study.measure`)."""

    method: str
    setting: str
    rtol: float | None
    dt: float | None
    status: str
    reason: str = ""
    position_error: float | None = None
    final_error: float | None = None
    energy_drift: float | None = None
    momentum_drift: float | None = None
    angular_momentum_drift: float | None = None
    limited_by_reference: bool = False
    contact_time_error: float | None = None  # [s]
    impacts: int | None = None
    wall_time: float | None = None
    rhs_evaluations: int | None = None
    steps: int | None = None
    jacobian_evaluations: int | None = None
    lu_decompositions: int | None = None

    @property
    def error_over_tolerance(self) -> float | None:
        """Achieved error over requested relative tolerance (adaptive runs)."""
        if self.rtol is None or self.position_error is None:
            return None
        return self.position_error / self.rtol


@dataclass
class MethodMerit:
    """A method's figures of merit: time to each of :data:`TARGETS`, observed order, and its failed runs."""

    method: str
    time_to: dict[float, TimeTo]
    order: float | None
    failures: int


@dataclass
class StudyResult:
    scene: str
    reference: str
    reference_impacts: int | None
    reference_floor: float
    length_scale: float
    speed_scale: float
    conserved: dict[str, bool]
    rows: list[StudyRow]
    merits: list[MethodMerit]
    skipped: dict[str, str] = field(default_factory=dict)
    seconds: float | None = None  # wall time of the whole study (reference and every run)

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON (non-finite numbers as None)."""
        return _finite({
            "scene": self.scene, "reference": self.reference, "reference_floor": self.reference_floor,
            "reference_impacts": self.reference_impacts,
            "length_scale_m": self.length_scale, "speed_scale_m_per_s": self.speed_scale,
            "conserved": self.conserved, "skipped": self.skipped, "study_seconds": self.seconds,
            "runs": [{**row.__dict__, "error_over_tolerance": row.error_over_tolerance} for row in self.rows],
            "figures_of_merit": [{"method": m.method, "order": m.order, "failures": m.failures,
                                  **{f"time_to_{t:g}_s": m.time_to[t].seconds for t in TARGETS},
                                  **{f"time_to_{t:g}_is_bound": m.time_to[t].bound for t in TARGETS}}
                                 for m in self.merits],
        })

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StudyResult:
        """The result :meth:`as_dict` wrote (``study.json``), its figures of merit computed again from its runs."""
        names = {f.name for f in fields(StudyRow)}
        rows = [StudyRow(**{k: v for k, v in run.items() if k in names}) for run in data["runs"]]
        floor = data["reference_floor"]
        floor = math.inf if floor is None else float(floor)  # as_dict writes an unchecked reference's inf as null
        return cls(data["scene"], data["reference"], data["reference_impacts"], floor, data["length_scale_m"],
                   data["speed_scale_m_per_s"], data["conserved"], rows, merits(rows, floor), data["skipped"],
                   data.get("study_seconds"))


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def _row(model: Model, outcome: RunOutcome, reference: Reference, which: dict[str, bool],
         systems: ParticleSystems | None = None) -> StudyRow:
    setting = outcome.setting
    row = StudyRow(setting.method, setting.label, setting.rtol, setting.dt, outcome.status, outcome.reason,
                   wall_time=outcome.wall_time, rhs_evaluations=outcome.rhs_evaluations, steps=outcome.steps,
                   jacobian_evaluations=outcome.jacobian_evaluations, lu_decompositions=outcome.lu_decompositions)
    if outcome.status != "ok" or (outcome.states is None and outcome.particles is None):
        return row
    if outcome.particles is not None:
        run = particle_motion(outcome.particles, births_by_end(model, systems))
    else:
        run = Motion.of_states(model, outcome.states, outcome.impacts)
    scales = reference.scales
    row.position_error = position_error(model, run, reference.motion, scales)
    row.final_error = final_error(run, reference.motion, scales)
    if outcome.states is not None:
        drift = drifts(model, outcome.states, scales, which)
        row.energy_drift, row.momentum_drift = drift["energy"], drift["momentum"]
        row.angular_momentum_drift = drift["angular_momentum"]
    row.limited_by_reference = reference.limits(row.position_error, row.final_error)
    if model.contact_world is not None:
        row.contact_time_error = contact_time_error(run, reference.motion)
        row.impacts = len(outcome.impacts)
    return row


def merits(rows: list[StudyRow], floor: float) -> list[MethodMerit]:
    """Figures of merit per method; ``floor`` is the error below which the reference cannot resolve errors."""
    result = []
    for method in dict.fromkeys(row.method for row in rows):
        mine = [row for row in rows if row.method == method]
        points = [Point(row.position_error, row.wall_time, row.rhs_evaluations or 0, row.dt, row.rtol,
                        row.limited_by_reference, row.steps)
                  for row in mine if row.status == "ok" and row.position_error is not None
                  and row.wall_time is not None]
        result.append(MethodMerit(method, {target: time_to(points, target, REFERENCE_MARGIN * floor)
                                           for target in TARGETS},
                                  observed_order(points), sum(row.status != "ok" for row in mine)))
    return result


def run_study(scene: LoadedScene, *, model: Model | None = None, methods: list[str] | None = None,
              progress: Callable[[str], None] = lambda message: None) -> StudyResult:
    """Study ``scene`` with its ``study`` settings (``methods`` overrides ``study.methods``). ``progress`` receives
    one line per run."""
    started = time.perf_counter()
    settings = scene.spec.study
    run = plan_run(scene, model=model)  # compiled once (mesh files beside the scene file)
    model = run.model
    # a scene of emitters only is studied on its particles; a scene with bodies on its bodies
    systems = None if model.layout.size else run.particles
    if not model.layout.size and systems is None:
        raise SceneError([SceneIssue(scene.source.source_of(("bodies",)), "bodies",
                                     "the scene has neither bodies nor emitters: nothing to study")])
    if systems is not None and settings.closed_form:
        raise SceneError([SceneIssue(scene.source.source_of(("study", "closed_form")), "study.closed_form",
                                     "emitted particles have no closed forms here: remove study.closed_form (the "
                                     "reference is then a tight DOP853 run, or set study.reference)")])
    reference_timeout = max(10 * settings.timeout, 120.0)
    fixed = (settings.reference.method, settings.reference.dt) if settings.reference is not None else None
    try:
        reference = (particle_reference(model, systems, timeout=reference_timeout, progress=progress, fixed=fixed)
                     if systems is not None else
                     find_reference(model, closed_form=settings.closed_form, timeout=reference_timeout,
                                    progress=progress, fixed=fixed))
    except NoClosedForm as error:
        raise SceneError([SceneIssue(scene.source.source_of(("study", "closed_form")), "study.closed_form",
                                     f"{error}. Remove study.closed_form to measure errors against a tight "
                                     "reference run instead.")]) from None
    chosen, skipped = applicable_methods(model, methods or settings.methods)
    frame_interval = float(model.frame_times[1] - model.frame_times[0]) if len(model.frame_times) > 1 else 0.1
    plan = plan_settings(chosen, settings.rtols, frame_interval, settings.dt_levels)
    which = conserved(model) if systems is None else {"energy": False, "momentum": False,
                                                      "angular_momentum": False}  # drag, births and deaths
    tolerance_scale = reference.scales.tolerance_scale(model) if systems is None else None
    rows = []
    for number, setting in enumerate(plan, 1):
        if systems is not None:
            outcome = execute_particles(model, systems, setting, reference.scales, repeats=settings.repeats,
                                        timeout=settings.timeout)
        else:
            assert tolerance_scale is not None
            outcome = execute(model, setting, tolerance_scale, repeats=settings.repeats, timeout=settings.timeout)
        row = _row(model, outcome, reference, which, systems)
        rows.append(row)
        shown = (f"error {row.position_error:.2e}, {row.wall_time:.3g} s" if row.status == "ok"
                 else f"{row.status}: {row.reason.splitlines()[0][:100]}")
        progress(f"[{number}/{len(plan)}] {setting.method} {setting.label}: {shown}")
    impacts = len(reference.motion.impacts) if model.contact_world is not None else None
    return StudyResult(scene.name, reference.description, impacts, reference.floor, reference.scales.length,
                       reference.scales.speed, which, rows, merits(rows, reference.floor), skipped,
                       time.perf_counter() - started)
