"""Assignments: templates to start from ('animbatch new'), and grading against a reference ('animbatch grade'):
a solved template passes every check, and a submission with a wrong constant, a wrong integrator or a missing
force fails the check that names it."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from xml.etree import ElementTree

import pytest
import yaml

from animbatch.errors import AnimbatchError
from animbatch.stages import load_scene
from animbatch.teaching.grade import GradeError, grade
from animbatch.teaching.templates import find, start, templates
from support.paths import REPO

L_SECONDS = 9.81 * 4 / (4 * math.pi**2)  # the length of a pendulum with a 2 s period

#: What a student changes in each template to solve it (key path -> value, applied to the YAML data).
SOLUTIONS: dict[str, dict[tuple, object]] = {
    "projectile_drag": {("fields", 1, "coefficient"): 0.5 * 1.2 * 0.47 * math.pi * 0.11**2},
    "spring_damper": {("springs", 0, "damping"): 20.0},
    "pendulum": {("bodies", 0, "position"): [0, 2 - L_SECONDS, 0]},
    "kepler_orbit": {("solver", "method"): "verlet", ("bodies", 1, "velocity"): [0, 1.0, 0]},
    "collision_lab": {("materials", "cart", "restitution"): 1 / 3},
    "friction_slope": {("bodies", 0, "material"): "ice"},
    "buoyancy": {("bodies", 0, "density"): 500.0},
    "hanging_chain": {("springs", k, "stiffness"): 49.05 for k in range(4)},
    "particle_system": {("solver", "method"): "verlet",
                        ("fields",): [{"type": "gravity"},
                                      {"type": "drag", "model": "quadratic", "coefficient": 2e-5,
                                       "bodies": ["fountain"]}]},
}


#: An assignment that lists a submission's other differences from the reference instead of failing it for them,
#: for the tests of what happens after (a failed run, a budget).
LISTED: dict[tuple, object] = {("assignment", "differences"): "list"}


def write(folder: Path, name: str, changes: dict[tuple, object], file: str) -> Path:
    """The template ``name`` with ``changes`` applied, written to ``folder/file``."""
    data = yaml.safe_load(find(name).text)
    for path, value in changes.items():
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    out = folder / file
    out.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False))
    return out


def test_there_are_templates_for_the_notes_topics_each_with_a_line_saying_what_it_teaches():
    found = {t.name: t for t in templates()}
    assert len(found) >= 8 and set(SOLUTIONS) <= set(found)
    for template in found.values():
        assert template.description and template.title and template.task, template.name
        assert "TODO" in template.text, f"{template.name} marks what to change"


@pytest.mark.parametrize("name", sorted(SOLUTIONS))
def test_every_template_validates_as_it_is(name, tmp_path):
    assert load_scene(start(name, tmp_path)).spec.assignment is not None


def test_templates_ship_as_package_data_so_an_installed_wheel_has_them():
    data = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["animbatch"]
    assert "teaching/templates/*.yaml" in data
    folder = REPO / "src" / "animbatch" / "teaching" / "templates"
    assert {p.stem for p in folder.glob("*.yaml")} == {t.name for t in templates()}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SOLUTIONS))
def test_a_solved_template_passes_and_the_template_as_given_does_not(name, tmp_path):
    reference = write(tmp_path, name, SOLUTIONS[name], "solution.yaml")
    solved = grade(write(tmp_path, name, SOLUTIONS[name], "mine.yaml"), reference)
    assert solved.passed and solved.score == solved.max_score > 0, solved.table()
    unsolved = grade(start(name, tmp_path / "as_given.yaml"), reference)
    assert not unsolved.passed and unsolved.score < unsolved.max_score, unsolved.table()


@pytest.mark.slow
def test_a_wrong_spring_constant_fails_the_check_that_depends_on_it(tmp_path):
    reference = write(tmp_path, "hanging_chain", SOLUTIONS["hanging_chain"], "solution.yaml")
    wrong = dict(SOLUTIONS["hanging_chain"])
    wrong[("springs", 2, "stiffness")] = 40.0
    result = grade(write(tmp_path, "hanging_chain", wrong, "mine.yaml"), reference)
    (check,) = result.results
    assert not check.passed and check.name == "lowest bead at rest"
    assert "position of 'b4'" in check.output and "tolerance 0.005 m" in check.output and "Hint: k = " in check.output


@pytest.mark.slow
def test_a_wrong_integrator_fails_the_method_check_naming_what_is_asked(tmp_path):
    reference = write(tmp_path, "kepler_orbit", SOLUTIONS["kepler_orbit"], "solution.yaml")
    euler = {**SOLUTIONS["kepler_orbit"], ("solver", "method"): "euler"}
    result = {r.name: r for r in grade(write(tmp_path, "kepler_orbit", euler, "mine.yaml"), reference).results}
    assert not result["symplectic method"].passed
    assert "solver.method is euler; this assignment asks for verlet or symplectic_euler" in result[
        "symplectic method"].output
    assert not result["energy kept"].passed  # Euler's energy drifts over ten orbits
    assert not result["circular orbit"].passed, "Euler spirals out of the circle over ten orbits"


def test_a_missing_drag_term_fails_the_drag_check_and_the_path_in_air(tmp_path):
    reference = write(tmp_path, "projectile_drag", SOLUTIONS["projectile_drag"], "solution.yaml")
    no_drag = {("fields",): [{"type": "gravity"}]}
    result = {r.name: r for r in grade(write(tmp_path, "projectile_drag", no_drag, "mine.yaml"), reference).results}
    assert result["vacuum path"].passed  # the closed form: gravity only
    assert not result["drag declared"].passed
    assert result["drag declared"].output == "the scene declares no drag field acting on 'air'"
    assert not result["path in air"].passed and "against the reference run" in result["path in air"].output


def test_a_submission_that_does_not_validate_gets_the_declared_partial_credit_and_the_error(tmp_path):
    changes = {("assignment", "partial_credit"): {"invalid": 0.25}}
    reference = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"], **changes}, "solution.yaml")
    broken = tmp_path / "mine.yaml"
    broken.write_text(find("spring_damper").text.replace("stiffness: 100", "stifness: 100"))
    result = grade(broken, reference)
    assert not result.passed and result.score == pytest.approx(0.25 * 3)
    assert "does not validate" in result.message and "did you mean 'stiffness'?" in result.message
    # each check says why in a whole clause (the error itself is in the message above the table)
    assert {r.output for r in result.results} == {"not checked: the submission does not validate"}


def test_a_submission_whose_run_fails_gets_the_failed_credit(tmp_path):
    reference = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"], **LISTED}, "solution.yaml")
    diverging = write(tmp_path, "spring_damper", {("solver",): {"method": "euler", "dt": 0.5}}, "mine.yaml")
    result = grade(diverging, reference)
    assert result.score == 0 and "simulation failed" in result.message
    assert {r.output for r in result.results} == {"not checked: the submission's simulation failed"}


def test_a_submission_estimated_over_budget_is_refused_before_it_runs_and_scores_nothing(tmp_path):
    """duration 3000 s (1500 times the reference's 2 s), and its own solver.max_cost raised: the
    assignment's budget holds, the pre-flight refuses it, every check scores 0 and says why."""
    reference = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"], **LISTED}, "solution.yaml")
    greedy = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"], ("duration",): 3000,
                                               ("solver", "max_cost"): 1e9}, "mine.yaml")
    result = grade(greedy, reference)
    assert result.score == 0 and not result.passed
    (output,) = {r.output for r in result.results}
    assert output.startswith("not checked: over budget: about ") and "s estimated against 2 s (4 × the" in output
    assert "refused before it starts" in result.message


def test_a_submission_that_uses_up_its_budget_is_stopped_and_scores_nothing(tmp_path, monkeypatch):
    """A run the pre-flight lets through (here: the pre-flight is switched off) is stopped by the wall clock once it
    has used the assignment's budget: 4 × the reference's time, here at least 0.3 s."""
    from animbatch import stages
    from animbatch.teaching import grade as grading

    monkeypatch.setattr(grading, "MIN_BUDGET", 0.3)
    monkeypatch.setattr(stages, "check_cost", lambda *arguments, **keywords: None)
    reference = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"], **LISTED}, "solution.yaml")
    slow = write(tmp_path, "spring_damper", {**SOLUTIONS["spring_damper"],
                                             ("solver",): {"method": "verlet", "dt": 1e-7}}, "mine.yaml")
    result = grade(slow, reference)
    assert result.score == 0
    (output,) = {r.output for r in result.results}
    assert output.startswith("not checked: over budget: stopped after ") and "used up its wall-time budget" in \
        result.message


#: The stopwatch trick: the template's wrong length (0.8 m) kept, the stopwatch redefined to read 2 s.
TWO_SECONDS = {("stopwatches", 0, "start"): {"time": 0.5}, ("stopwatches", 0, "stop"): {"time": 2.5}}


def test_a_redefined_stopwatch_fails_the_submission_naming_the_definition(tmp_path):
    """Only the bob's position may change: the redefined stopwatch is listed, path by path with both values, and
    every check scores 0."""
    reference = write(tmp_path, "pendulum", SOLUTIONS["pendulum"], "solution.yaml")
    trick = write(tmp_path, "pendulum", TWO_SECONDS, "mine.yaml")
    result = grade(trick, reference)
    assert result.score == 0 and not result.passed
    assert all(line.startswith("stopwatches[period].") for line in result.differences)
    assert {"stopwatches[period].start.time: 0.5 (the reference: null)",
            "stopwatches[period].stop.time: 2.5 (the reference: null)",
            'stopwatches[period].start.body: null (the reference: "bob")'} <= set(result.differences)
    assert "which the assignment does not allow" in result.table()
    count = len(result.differences)
    assert {r.output for r in result.results} == {
        f"not checked: the submission changes what the assignment does not let it change ({count} differences from "
        "the reference, listed above)"}
    assert not result.message.endswith(":")


def test_a_redefined_stopwatch_is_read_with_the_reference_definition(tmp_path):
    """With the differences only listed, the period is still read with the reference's stopwatch: the wrong length
    swings with its own period (2π √(0.8 / g) = 1.79 s), not 2 s, and the check says whose definition it used."""
    reference = write(tmp_path, "pendulum", {**SOLUTIONS["pendulum"], **LISTED}, "solution.yaml")
    result = grade(write(tmp_path, "pendulum", TWO_SECONDS, "mine.yaml"), reference)
    period = {r.name: r for r in result.results}["period"]
    assert not period.passed and period.score == 0
    assert "stopwatch 'period': 1.79" in period.output
    assert "read with the reference's definition (the submission's differs)" in period.output
    assert result.differences and all(line.startswith("stopwatches[period].") for line in result.differences)
    assert "listed only" in result.table()  # (the bob's position may change: it is not listed)
    solved = grade(write(tmp_path, "pendulum", {**SOLUTIONS["pendulum"], **TWO_SECONDS}, "solved.yaml"), reference)
    assert {r.name: r for r in solved.results}["period"].passed  # the right length passes whatever it redefines


def test_what_a_submission_may_change_is_checked_path_by_path(tmp_path):
    """springs[*].stiffness lets every spring's stiffness change and nothing else of them; a mass is not allowed;
    a difference inside an item chosen by name, or by its number, is covered."""
    from animbatch.teaching.differences import allowed, scene_differences

    reference = load_scene(write(tmp_path, "hanging_chain", SOLUTIONS["hanging_chain"], "solution.yaml"))
    changed = {**SOLUTIONS["hanging_chain"], ("springs", 1, "stiffness"): 60.0, ("springs", 2, "rest_length"): 0.3,
               ("bodies", 1, "mass"): 0.2}
    mine = load_scene(write(tmp_path, "hanging_chain", changed, "mine.yaml"))
    data = reference.spec.model_dump(mode="json")
    found = scene_differences(data, mine.spec.model_dump(mode="json"))
    assert [d.where for d in found] == ["bodies[b2].mass", "springs[1].stiffness", "springs[2].rest_length"]
    assert [allowed(d, ["springs[*].stiffness"], data) for d in found] == [False, True, False]
    assert [allowed(d, ["bodies[1]"], data) for d in found] == [True, False, False]  # bodies[1] is b2
    assert [allowed(d, ["bodies[b2].mass", "springs"], data) for d in found] == [True, True, True]


def test_an_edit_path_that_cannot_be_read_is_a_scene_error(tmp_path):
    bad = write(tmp_path, "pendulum", {("assignment", "edit"): ["bodies[bob.position"]}, "solution.yaml")
    with pytest.raises(AnimbatchError, match=r"assignment\.edit.*write paths as --set does"):
        load_scene(bad)


def test_a_reference_without_checks_is_refused(tmp_path):
    reference = tmp_path / "plain.yaml"
    reference.write_text("bodies: [{name: a}]\nduration: 0.1\n")
    with pytest.raises(GradeError, match="declares no checks"):
        grade(reference, reference)


@pytest.mark.slow
def test_the_command_prints_a_table_writes_json_and_junit_and_exits_by_the_result(tmp_path):
    reference = write(tmp_path, "projectile_drag", SOLUTIONS["projectile_drag"], "solution.yaml")
    mine = start("projectile_drag", tmp_path / "mine.yaml")  # drag left at 0: the path in air fails
    from click.testing import CliRunner

    from animbatch.cli import cli

    command = ["grade", str(mine), "--reference", str(reference),
               "--json", str(tmp_path / "results.json"), "--junit", str(tmp_path / "junit.xml")]
    result = CliRunner().invoke(cli, command)  # in this process: the entry point itself is tested in test_run
    assert result.exit_code == 1, result.output
    assert "FAIL  path in air" in result.output and "PASS  vacuum path" in result.output
    assert "2 / 5 points" in result.output
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["score"] == 2 and results["max_score"] == 5
    assert {t["name"]: t["status"] for t in results["tests"]}["path in air"] == "failed"
    suite = ElementTree.parse(tmp_path / "junit.xml").getroot()
    assert suite.get("tests") == "3" and suite.get("failures") == "1"
    assert [case.get("name") for case in suite.iter("testcase") if case.find("failure") is not None] == ["path in air"]
    solved = write(tmp_path, "projectile_drag", SOLUTIONS["projectile_drag"], "solved.yaml")
    command[1] = str(solved)
    assert CliRunner().invoke(cli, command).exit_code == 0


def test_json_to_standard_output_is_the_only_thing_there(tmp_path, monkeypatch):
    """--json - prints the JSON alone on standard output (the table goes to standard error) and writes no file
    named '-'; two reports cannot both go there."""
    from click.testing import CliRunner

    from animbatch.cli import cli

    reference = write(tmp_path, "spring_damper", SOLUTIONS["spring_damper"], "solution.yaml")
    broken = tmp_path / "mine.yaml"
    broken.write_text(find("spring_damper").text.replace("stiffness: 100", "stifness: 100"))
    monkeypatch.chdir(tmp_path)
    import inspect

    # standard error apart from standard output: click ≥ 8.2 always, 8.1 when asked
    runner = CliRunner(**({"mix_stderr": False} if "mix_stderr" in inspect.signature(CliRunner).parameters else {}))
    result = runner.invoke(cli, ["grade", str(broken), "--reference", str(reference), "--json", "-"])
    assert result.exit_code == 1 and not (tmp_path / "-").exists()
    results = json.loads(result.stdout)
    assert results["score"] == 0 and results["tests"][0]["output"] == "not checked: the submission does not validate"
    assert "FAIL" in result.stderr and "did you mean 'stiffness'?" in result.stderr
    both = runner.invoke(cli, ["grade", str(broken), "--reference", str(reference), "--json", "-", "--junit", "-"])
    assert both.exit_code == 2 and "only one of --json and --junit" in both.stderr


def test_new_lists_copies_and_refuses_to_overwrite(tmp_path):
    from click.testing import CliRunner

    from animbatch.cli import cli

    listing = CliRunner().invoke(cli, ["new", "--list"]).output
    assert "kepler_orbit" in listing and "circular orbit" in listing
    target = start("pendulum", tmp_path)
    assert target == tmp_path / "pendulum.yaml" and "TODO" in target.read_text()
    with pytest.raises(AnimbatchError, match="exists"):
        start("pendulum", tmp_path)
    with pytest.raises(AnimbatchError, match="did you mean 'pendulum'"):
        find("pendulm")


def test_a_check_naming_an_unknown_body_or_stopwatch_is_refused_with_the_fix(tmp_path):
    text = find("pendulum").text.replace("body: bob, tolerance: 0.01}", "body: bobb, tolerance: 0.01}").replace(
        "stopwatch: period, expected", "stopwatch: perod, expected")
    path = tmp_path / "teacher.yaml"
    path.write_text(text)
    from animbatch.errors import SceneError

    with pytest.raises(SceneError) as error:
        load_scene(path)
    message = str(error.value)
    assert "assignment.checks[1].body: unknown body 'bobb'; did you mean 'bob'?" in message
    assert "assignment.checks[0].stopwatch: unknown stopwatch 'perod'; did you mean 'period'?" in message


@pytest.mark.slow
def test_conserved_quantities_are_checked_by_their_drift(tmp_path):
    """The solved orbit keeps momentum and angular momentum to round-off, so tight drift checks pass; energy with
    Euler drifts and fails."""
    changes = {**SOLUTIONS["kepler_orbit"], ("assignment", "checks"): [
        {"name": "momentum", "quantity": "momentum_drift", "tolerance": 1e-9},
        {"name": "angular momentum", "quantity": "angular_momentum_drift", "tolerance": 1e-6}]}
    reference = write(tmp_path, "kepler_orbit", changes, "solution.yaml")
    result = {r.name: r for r in grade(reference, reference).results}
    assert result["momentum"].passed and result["angular momentum"].passed
    assert "momentum drift" in result["momentum"].output
