"""Grade a student's scene (or trajectory) against a reference: the checks of an assignment, each scored.

The checks come from the reference scene's ``assignment`` block (the teacher's copy, so that a student who edits
the tolerances in their own file changes nothing), or from ``checks_from`` when the reference is a trajectory file.
Each check compares the submission with the reference run, or with the value or closed form it declares; values
between frames come from the cubic through positions and velocities, so two runs at different frame rates compare
fairly. A submission that does not validate, or whose simulation fails, gets the partial credit the assignment
declares and the error's own message, never a traceback.

Reports: a table for people, JSON in the shape autograders read (Gradescope's ``results.json``: ``score``,
``max_score`` and per test ``name``, ``score``, ``max_score``, ``status``, ``output``) and JUnit XML.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from animbatch import stages
from animbatch.compile.stopwatches import stopwatch_readings
from animbatch.curves import compile_expression
from animbatch.errors import AnimbatchError, OverBudget, SceneError, SimulationError, TrajectoryError
from animbatch.scene import LoadedScene
from animbatch.scene.schema import SAMPLED_QUANTITIES, AssignmentSpec, CheckSpec, StopwatchSpec
from animbatch.sim.events import hermite_sample
from animbatch.teaching.differences import allowed, scene_differences
from animbatch.trajectory import Trajectory

UNITS = {"position": "m", "velocity": "m/s", "speed": "m/s", "stopwatch": "s"}


class GradeError(AnimbatchError):
    """The grading itself cannot run: the reference is missing, invalid, or declares no checks."""

    exit_code = 2


@dataclass(frozen=True)
class CheckResult:
    """How one check went: ``score`` of ``max_score`` points, and what to tell the student."""

    name: str
    score: float
    max_score: float
    passed: bool
    output: str


@dataclass
class Grade:
    """The grade of one submission."""

    submission: str
    reference: str
    title: str
    results: list[CheckResult] = field(default_factory=list)
    message: str = ""  # why nothing could be checked (the submission is invalid or its run failed), if so
    # what the submission changed from the reference (with assignment.edit, only what it may not), and whether that
    # fails it
    differences: list[str] = field(default_factory=list)
    differences_fail: bool = False

    @property
    def differences_text(self) -> str:
        """The differences from the reference, one per line under a heading ('' without any)."""
        if not self.differences:
            return ""
        heading = ("changed from the reference, which the assignment does not allow:" if self.differences_fail
                   else "changed from the reference (listed only):")
        return "\n".join([heading, *(f"  {line}" for line in self.differences)])

    @property
    def score(self) -> float:
        return sum(result.score for result in self.results)

    @property
    def max_score(self) -> float:
        return sum(result.max_score for result in self.results)

    @property
    def passed(self) -> bool:
        return bool(self.results) and all(result.passed for result in self.results)

    def table(self) -> str:
        """The grade for people: one line per check, then the total."""
        width = max([len(r.name) for r in self.results] + [5])
        lines = [f"{self.title or 'assignment'}: {self.submission} against {self.reference}"]
        if self.differences:
            lines.append(self.differences_text)
        if self.message:
            lines.append(self.message)
        lines += [f"  {'PASS' if r.passed else 'FAIL'}  {r.name:<{width}}  {r.score:g}/{r.max_score:g}  {r.output}"
                  for r in self.results]
        lines.append(f"score {self.score:g} / {self.max_score:g}")
        return "\n".join(lines)

    def as_json(self) -> dict[str, Any]:
        """Gradescope's results.json shape (also read by other autograders)."""
        output = "\n".join(text for text in (self.differences_text, self.message) if text) or self.title
        return {"score": self.score, "max_score": self.max_score, "output": output,
                "tests": [{"name": r.name, "score": r.score, "max_score": r.max_score,
                           "status": "passed" if r.passed else "failed", "output": r.output}
                          for r in self.results]}

    def junit(self) -> str:
        """JUnit XML: one test case per check, a failure element for each that failed."""
        suite = ElementTree.Element("testsuite", name=self.title or "animbatch grade", tests=str(len(self.results)),
                                    failures=str(sum(not r.passed for r in self.results)), errors="0")
        properties = ElementTree.SubElement(suite, "properties")
        for name, value in (("score", self.score), ("max_score", self.max_score)):
            ElementTree.SubElement(properties, "property", name=name, value=f"{value:g}")
        for result in self.results:
            case = ElementTree.SubElement(suite, "testcase", classname=self.title or "assignment", name=result.name)
            if not result.passed:
                failure = ElementTree.SubElement(case, "failure", message=result.output)
                failure.text = (self.message + "\n" if self.message else "") + result.output
            else:
                ElementTree.SubElement(case, "system-out").text = result.output
        return ElementTree.tostring(suite, encoding="unicode", xml_declaration=True)

    def write(self, json_path: str | Path | None = None, junit_path: str | Path | None = None) -> str:
        """Write the JSON and JUnit reports to their files; a path ``-`` is not a file: that report is returned
        instead (for standard output), else ''."""
        from animbatch.files import write_text_atomic

        to_output = ""
        for path, text in ((json_path, lambda: json.dumps(self.as_json(), indent=2)), (junit_path, self.junit)):
            if path is None:
                continue
            if str(path) == "-":
                to_output += text() + "\n"
            else:
                write_text_atomic(Path(path), text() + "\n")
        return to_output


#: The least wall-time budget [s] of a submission's simulation, whatever the reference's: below it, loading the
#: compiled kernels and the machine's own noise would decide.
MIN_BUDGET = 2.0


@dataclass(frozen=True)
class Run:
    """A scene (None for a trajectory file) and its trajectory."""

    scene: LoadedScene | None
    trajectory: Trajectory

    @property
    def seconds(self) -> float:
        """The wall time its simulation took [s] (bodies and emitted particles), as the trajectory records it."""
        return float(self.trajectory.solver_stats.get("wall_time", 0.0)
                     + self.trajectory.particle_stats.get("wall_time", 0.0))


def _load(path: Path) -> LoadedScene | Trajectory:
    """A scene file, validated, or a trajectory file (.npz); scene and trajectory errors propagate."""
    return Trajectory.load(path) if path.suffix == ".npz" else stages.load_scene(path)


def _simulated(loaded: LoadedScene | Trajectory, budget: float | None = None) -> Run:
    """The run of a loaded scene (simulation errors propagate) or of a trajectory. ``budget`` [s]: the simulation's
    wall-time budget, in place of the scene's own ``solver.max_cost`` (OverBudget past it)."""
    if isinstance(loaded, Trajectory):
        return Run(None, loaded)
    scene = loaded
    if budget is not None:
        solver = scene.spec.solver.model_copy(update={"max_cost": budget})
        scene = dataclasses.replace(scene, spec=scene.spec.model_copy(update={"solver": solver}))
    return Run(scene, stages.simulate(scene, reactions=False))  # no check reads the joints' reactions


def grade(submission: str | Path, reference: str | Path, *, checks_from: str | Path | None = None) -> Grade:
    """Grade ``submission`` (a scene or trajectory file) against ``reference`` (the teacher's scene, or a trajectory
    file together with ``checks_from``, a scene whose ``assignment`` declares the checks)."""
    submission, reference = Path(submission), Path(reference)
    try:
        expected = _simulated(_load(reference))
    except (SceneError, SimulationError, TrajectoryError) as error:
        raise GradeError(f"the reference {reference} cannot be used: {error}") from None
    teacher = _teachers_scene(expected, checks_from, reference)
    assignment = teacher.spec.assignment
    assert assignment is not None  # (checked by _teachers_scene)
    report = Grade(str(submission), str(reference), assignment.title)
    try:
        loaded = _load(submission)
    except (SceneError, TrajectoryError) as error:
        return _partial(report, assignment, assignment.partial_credit.invalid, "the submission does not validate",
                        f"\n{error}")
    if isinstance(loaded, LoadedScene):
        reference_data = teacher.spec.model_dump(mode="json")
        found = scene_differences(reference_data, loaded.spec.model_dump(mode="json"))
        if assignment.edit is not None:
            found = [d for d in found if not allowed(d, assignment.edit, reference_data)]
        report.differences = [d.describe() for d in found]
        report.differences_fail = assignment.edit is not None and assignment.differences == "fail"
        if found and report.differences_fail:
            return _partial(report, assignment, 0.0, "the submission changes what the assignment does not let it "
                            f"change ({len(found)} difference{'s' if len(found) > 1 else ''} from the reference, "
                            "listed above)", "")
    budget = max(assignment.budget * expected.seconds, MIN_BUDGET)
    started = time.perf_counter()
    try:
        run = _simulated(loaded, budget)
    except OverBudget as error:
        spent = (f"about {error.estimate:.3g} s estimated" if error.estimate is not None
                 else f"stopped after {time.perf_counter() - started:.3g} s")
        allowed_time = f"{assignment.budget:g} × the reference's {expected.seconds:.3g} s, at least {MIN_BUDGET:g} s"
        return _partial(report, assignment, 0.0, f"over budget: {spent} against {budget:.3g} s ({allowed_time})",
                        f" {error} (In grading, the budget is the assignment's: the submission's solver.max_cost is "
                        "ignored.)")
    except SimulationError as error:
        return _partial(report, assignment, assignment.partial_credit.failed, "the submission's simulation failed",
                        f" {error}")
    for check in assignment.checks:
        passed, output = _judge(check, run, expected, teacher.spec.stopwatches)
        report.results.append(CheckResult(check.name, check.points if passed else 0.0, check.points, passed,
                                          output if passed or not check.hint else f"{output}. Hint: {check.hint}"))
    return report


def _teachers_scene(reference: Run, checks_from: str | Path | None, path: Path) -> LoadedScene:
    """The scene that defines the assignment: its checks, what a check measures (stopwatches) and what the
    submission is compared with: the reference scene, or the ``checks_from`` scene for a trajectory reference."""
    if checks_from is not None:
        try:
            source = stages.load_scene(Path(checks_from))
        except SceneError as error:
            raise GradeError(f"the checks file {checks_from} does not validate: {error}") from None
        where = str(checks_from)
    elif reference.scene is not None:
        source, where = reference.scene, str(path)
    else:
        raise GradeError(f"the reference {path} is a trajectory: give the checks with --checks SCENE (a scene whose "
                         "'assignment' block lists them)")
    assignment = source.spec.assignment
    if assignment is None or not assignment.checks:
        raise GradeError(f"{where} declares no checks: add 'assignment: {{title: ..., checks: [...]}}' "
                         "(see docs/teaching.md)")
    return source


def _partial(report: Grade, assignment: AssignmentSpec, fraction: float, reason: str, detail: str) -> Grade:
    """Every check not checked, for ``reason`` (a clause), with the assignment's partial credit; the report's
    message adds the ``detail`` (the error)."""
    report.message = f"{reason}, so nothing could be checked" + (f":{detail}" if detail else "")
    for check in assignment.checks:
        report.results.append(CheckResult(check.name, fraction * check.points, check.points, False,
                                          f"not checked: {reason}"))
    return report


# ------------------------------------------------------------------------------------------ the checks


def _judge(check: CheckSpec, run: Run, reference: Run, stopwatches: list[StopwatchSpec]) -> tuple[bool, str]:
    """(passed, what to say) for one check of ``run`` against ``reference``; ``stopwatches``: the reference's
    definitions, which the stopwatch checks read both runs with."""
    try:
        if check.quantity in SAMPLED_QUANTITIES:
            return _sampled(check, run.trajectory, reference.trajectory)
        if check.quantity.endswith("_drift"):
            return _drift(check, run)
        if check.quantity == "stopwatch":
            return _stopwatch(check, run, reference, stopwatches)
        return {"method": _method, "field": _field}[check.quantity](check, run, reference)
    except _CannotCheck as reason:
        return False, str(reason)


class _CannotCheck(Exception):
    """The submission lacks what the check needs (a body, a stopwatch, a scene)."""


def _times(check: CheckSpec, reference: Trajectory) -> np.ndarray:
    if check.at == "all":
        return np.asarray(reference.times, float)
    if check.at == "end":
        return np.asarray(reference.times[-1:], float)
    return np.asarray(check.at, float)


def _values(check: CheckSpec, trajectory: Trajectory, times: np.ndarray, who: str) -> np.ndarray:
    """The checked quantity of the body at ``times``: (T, 3) for vectors, (T,) for speeds."""
    if check.body not in trajectory.body_names:
        raise _CannotCheck(f"{who} has no body {check.body!r} (it has {', '.join(trajectory.body_names)})")
    end = float(trajectory.times[-1])
    if times.max() > end + 1e-9:
        raise _CannotCheck(f"{who} ends at t = {end:.4g} s, before t = {times.max():.4g} s: check its duration")
    body = trajectory.body_names.index(check.body)
    x, v = hermite_sample(trajectory.times, trajectory.positions[:, body], trajectory.velocities[:, body], times)
    if check.quantity == "position":
        return x
    return v if check.quantity == "velocity" else np.linalg.norm(v, axis=-1)


def _expected(check: CheckSpec, times: np.ndarray, reference: Trajectory) -> tuple[np.ndarray, str]:
    """What the check expects at ``times``, and where that comes from."""
    expected = check.expected
    vector = check.quantity != "speed"
    if expected is None:
        return _values(check, reference, times, "the reference"), "the reference run"
    values = expected if isinstance(expected, list) else [expected]
    if any(isinstance(value, str) for value in values):
        columns = [compile_expression(str(value), "t")(times) for value in values]
        result = np.stack(columns, axis=-1)
        source = "the closed form " + (", ".join(map(str, values)))
    else:
        result = np.broadcast_to(np.asarray(values, float), (len(times), len(values)))
        source = "the value " + ", ".join(f"{value:g}" for value in values)
    width = 3 if vector else 1
    if result.shape[-1] != width:
        raise _CannotCheck(f"the check expects {len(values)} value(s) but {check.quantity} has {width}")
    return (result if vector else result[:, 0]), source


def _sampled(check: CheckSpec, run: Trajectory, reference: Trajectory) -> tuple[bool, str]:
    times = _times(check, reference)
    actual = _values(check, run, times, "the submission")
    wanted, source = _expected(check, times, reference)
    difference = np.abs(actual - wanted)
    difference = difference.max(axis=-1) if difference.ndim > 1 else difference
    worst = int(np.argmax(difference))
    unit = UNITS[check.quantity]
    shown = (f"{np.round(actual[worst], 6).tolist()} {unit}, expected {np.round(wanted[worst], 6).tolist()} {unit}"
             if check.quantity != "speed" else f"{actual[worst]:.6g} {unit}, expected {wanted[worst]:.6g} {unit}")
    where = f"t = {times[worst]:.4g} s" if len(times) > 1 else f"t = {times[0]:.4g} s"
    passed = bool(difference[worst] <= check.tolerance)
    return passed, (f"{check.quantity} of {check.body!r} at {len(times)} time(s) against {source}: "
                    f"{'largest difference' if len(times) > 1 else 'difference'} {difference[worst]:.3g} {unit} "
                    f"at {where} ({shown}; tolerance {check.tolerance:g} {unit})")


def _stopwatch(check: CheckSpec, run: Run, reference: Run, definitions: list[StopwatchSpec]) -> tuple[bool, str]:
    """The stopwatch's interval on the submission's run against the expected one, both read with the reference's
    definition (a submission that redefines its stopwatch changes nothing but is told so)."""
    watch = next((w for w in definitions if w.name == check.stopwatch), None)
    if watch is None:
        raise _CannotCheck(f"the reference has no stopwatch {check.stopwatch!r}")

    def elapsed(side: Run, who: str) -> float:
        try:
            (reading,) = stopwatch_readings([watch], side.trajectory)
        except (KeyError, ValueError) as error:
            raise _CannotCheck(f"the stopwatch {check.stopwatch!r} cannot be read on {who}'s run: {error}") from None
        if reading.elapsed is None:
            raise _CannotCheck(f"{who}'s stopwatch {check.stopwatch!r} never stopped: {reading.describe()}")
        return reading.elapsed

    own = next((w for w in run.scene.spec.stopwatches if w.name == check.stopwatch), None) if run.scene else None
    note = ("" if run.scene is None or own == watch else
            f"; read with the reference's definition (the submission's {'differs' if own else 'is missing'})")
    actual = elapsed(run, "the submission")
    if check.expected is not None and not isinstance(check.expected, list):
        wanted = (float(compile_expression(check.expected, "t")(np.zeros(1))[0]) if isinstance(check.expected, str)
                  else float(check.expected))
        source = f"{check.expected}"
    else:
        wanted, source = elapsed(reference, "the reference"), "the reference run"
    difference = abs(actual - wanted)
    return difference <= check.tolerance, (f"stopwatch {check.stopwatch!r}: {actual:.6g} s against {source} "
                                           f"({wanted:.6g} s): difference {difference:.3g} s (tolerance "
                                           f"{check.tolerance:g} s){note}")


def _drift(check: CheckSpec, run: Run) -> tuple[bool, str]:
    quantity = check.quantity.removesuffix("_drift")
    law = run.trajectory.ledger.get("conservation", {}).get(quantity, {})
    drift = law.get("drift")
    shown = quantity.replace("_", " ")
    if drift is None:
        raise _CannotCheck(f"the submission does not conserve {shown} ({law.get('reason', 'no ledger')}), so its "
                           "drift is not measured")
    method = run.trajectory.ledger.get("method", "?")
    return drift <= check.tolerance, (f"{shown} drift {drift:.3g} of its scale with {method} (tolerance "
                                      f"{check.tolerance:g})")


def _method(check: CheckSpec, run: Run, reference: Run) -> tuple[bool, str]:
    if run.scene is None:
        raise _CannotCheck("the submission is a trajectory file; the method check needs its scene")
    method = run.scene.spec.solver.method
    allowed = check.methods or []
    return method in allowed, (f"solver.method is {method}" + ("" if method in allowed else
                               f"; this assignment asks for {' or '.join(allowed)}"))


def _field(check: CheckSpec, run: Run, reference: Run) -> tuple[bool, str]:
    if run.scene is None:
        raise _CannotCheck("the submission is a trajectory file; the field check needs its scene")
    acting = [f for f in run.scene.spec.fields if f.type == check.field
              and (check.body is None or f.bodies is None or check.body in f.bodies)]
    on = f" acting on {check.body!r}" if check.body else ""
    if acting:
        return True, f"a {check.field} field{on} is declared"
    return False, f"the scene declares no {check.field} field{on}"


def summary_line(report: Grade) -> str:
    """'7 / 10 points: 2 of 4 checks failed'."""
    failed = sum(not r.passed for r in report.results)
    return (f"{report.score:g} / {report.max_score:g} points: "
            + (f"{failed} of {len(report.results)} checks failed" if failed else "every check passed"))
