"""The work-precision study: closed forms, the reference and its accuracy, errors, figures of merit, failures and
outputs."""

from __future__ import annotations

import csv
import json
import shutil
import types
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from animbatch.cli import cli
from animbatch.compile.model import compile_scene
from animbatch.errors import SceneError
from animbatch.sim.closed_forms import exact_motion
from animbatch.sim.invariants import angular_momentum, total_energy
from animbatch.study import run_study, write_outputs
from animbatch.study.merit import Point, observed_order, time_to
from animbatch.study.report import csv_text, table
from support.paths import REPO
from support.scenes import body, run, scene

G = 9.81

LINEAR_DRAG_WITH_WIND = """
    duration: 3
    fps: 20
    solver: {method: DOP853, rtol: 1.0e-12, atol: 1.0e-13}
    bodies: [{name: leaf, mass: 0.05, position: [0, 10, 0], velocity: [1, 4, -2]}]
    fields:
      - {type: gravity}
      - {type: wind, model: linear, velocity: [3, 0, 1], coefficient: 0.02}
"""
KEPLER_FALLING = """
    duration: 8
    fps: 10
    solver: {method: DOP853, rtol: 1.0e-12, atol: 1.0e-13}
    bodies:
      - {name: star, mass: 3.0, position: [-0.25, 0, 0], velocity: [0, -0.4, 0.1]}
      - {name: planet, mass: 1.0, position: [0.75, 0, 0], velocity: [0, 1.2, 0.1]}
    fields: [{type: gravitation, G: 1.0}, {type: gravity, g: [0, 0, -1]}]
"""
OSCILLATOR_HANGING = """
    duration: 4
    fps: 25
    solver: {method: DOP853, rtol: 1.0e-12, atol: 1.0e-13}
    anchors: [{name: top, position: [0, 3, 0]}]
    bodies: [{name: bob, mass: 0.5, position: [0, 1.6, 0], velocity: [0, 0.3, 0]}]
    springs: [{between: [top, bob], stiffness: 20, damping: 0.4, rest_length: 1.0}]
    fields: [{type: gravity}]
"""


# ------------------------------------------------------------------------------------------------ closed forms


def test_linear_drag_closed_form_reaches_the_terminal_velocity_and_matches_a_tight_run():
    """u = v - w relaxes to m g / c with time constant m / c; the tight DOP853 run agrees to 1e-9 m."""
    model, trajectory = run(LINEAR_DRAG_WITH_WIND)
    exact = exact_motion(model)
    assert exact.forms == {"leaf": "linear drag"}
    tau, wind = 0.05 / 0.02, np.array([3.0, 0.0, 1.0])
    late = exact.velocities[-1, 0]
    terminal = wind + np.array([0, -G, 0]) * tau
    assert np.allclose(late - terminal, (np.array([1, 4, -2]) - terminal) * np.exp(-model.frame_times[-1] / tau))
    x, v = body(trajectory, "leaf")
    assert np.abs(exact.positions[:, 0] - x).max() < 1e-9
    assert np.abs(exact.velocities[:, 0] - v).max() < 1e-9


def test_oscillator_closed_form_of_a_hanging_damped_mass():
    """A mass on a vertical spring with gravity and damping: the closed form agrees with a tight run and settles
    toward rest length + m g / k below the anchor."""
    model, trajectory = run(OSCILLATOR_HANGING)
    exact = exact_motion(model)
    assert exact.forms == {"bob": "oscillator"}
    x, v = body(trajectory, "bob")
    assert np.abs(exact.positions[:, 0] - x).max() < 1e-9 and np.abs(exact.velocities[:, 0] - v).max() < 1e-9
    assert np.allclose(exact.positions[:, 0, [0, 2]], 0.0)
    equilibrium = 3 - 1.0 - 0.5 * G / 20
    amplitude = np.abs(exact.positions[:, 0, 1] - equilibrium)
    assert amplitude[-10:].max() < amplitude[:10].max() * np.exp(-0.4 / (2 * 0.5) * 3.0)


def test_kepler_closed_form_conserves_energy_and_angular_momentum_and_matches_a_tight_run():
    """The f and g solution of a bound pair (whose centre of mass also falls): relative energy and angular momentum
    are exactly those of the start, and a tight run agrees to 1e-8."""
    model, trajectory = run(KEPLER_FALLING)
    exact = exact_motion(model)
    assert exact.forms == {"star": "kepler", "planet": "kepler"}
    assert np.abs(exact.positions - trajectory.positions).max() < 1e-8
    separation = exact.positions[:, 1] - exact.positions[:, 0]
    rate = exact.velocities[:, 1] - exact.velocities[:, 0]
    energy = 0.5 * np.sum(rate**2, axis=1) - 4.0 / np.linalg.norm(separation, axis=1)
    spin = np.cross(separation, rate)
    assert np.ptp(energy) < 1e-12 and np.abs(spin - spin[0]).max() < 1e-12


def test_a_body_without_a_closed_form_is_named_with_the_key_location():
    """Quadratic drag has no closed form: the error points at study.closed_form in the file and names the body."""
    loaded = scene("""
        duration: 1
        bodies: [{name: a}, {name: b}]
        fields: [{type: gravity}, {type: drag, model: quadratic, coefficient: 0.1, bodies: [b]}]
        study:
          closed_form: true
    """)
    with pytest.raises(SceneError) as caught:
        run_study(loaded)
    message = str(caught.value)
    assert message.startswith("test.yaml:6:16: study.closed_form: body 'b' has no closed form: it feels quadratic")


# ------------------------------------------------------------------------------------------------ figures of merit


def test_time_to_an_error_interpolates_between_bracketing_points_and_never_extrapolates():
    points = [Point(1e-2, 1.0, 10, None, 1e-3, False), Point(1e-4, 10.0, 100, None, 1e-5, False)]
    assert time_to(points, 1e-3).seconds == pytest.approx(10**0.5)  # halfway in log-log
    assert time_to(points, 1e-6).seconds is None  # beyond the most accurate point: not reached
    bound = time_to(points, 1e-1)
    assert bound.bound and bound.seconds == 1.0  # even the fastest is below: only a bound
    limited = [points[0], Point(1e-15, 20.0, 200, None, 1e-7, True)]
    assert time_to(limited, 1e-6, floor=1e-12).seconds is not None  # a limited point counts as "below the floor"


def test_observed_order_from_fixed_steps_and_from_work():
    """Error ∝ dt^p or ∝ steps^-p gives p; loose tolerances that take the same few steps for very different errors
    (a floor on the step count) do not skew it; points without a factor 1.5 in work between them give no order."""
    fixed = [Point(0.02 * dt, 1 / dt, 0, dt, None, False) for dt in (0.1, 0.05, 0.025)]
    assert observed_order(fixed) == pytest.approx(1.0)
    adaptive = [Point(n**-5.0, n, 15 * n, None, 1e-3, False, steps=n) for n in (20, 40, 80, 160)]
    assert observed_order(adaptive) == pytest.approx(5.0)
    # DOP853 on the damped oscillators: the two loosest tolerances both take 20 steps
    measured = [(20, 1.06e-3), (20, 2.26e-4), (22, 2.18e-6), (26, 2.46e-7), (33, 2.74e-8), (43, 3.17e-9),
                (56, 3.7e-10), (73, 5.44e-11)]
    floored = [Point(error, 1.0, 15 * steps, None, 1e-3, False, steps=steps) for steps, error in measured]
    assert 8 <= observed_order(floored) <= 10  # a least-squares fit over the same points gives 11.6
    assert observed_order(adaptive[:1]) is None
    assert observed_order(floored[:2]) is None


def test_no_order_where_the_step_does_not_set_the_error():
    """Measured runs whose error is not a power of the step give no order: BDF on a projectile (its order-one start
    sets an error ∝ rtol while the steps only go from 11 to 23: a slope of 21), and LSODA on it (five tolerances
    at 3 steps and errors over 4 decades, then 5 to 9 steps: the line explains too little, R² = 0.74)."""
    bdf = [(11, 2.87e-3), (13, 2.86e-4), (15, 2.83e-5), (17, 2.83e-6), (18, 2.83e-7), (20, 2.84e-8), (22, 2.85e-9),
           (23, 2.85e-10)]
    assert observed_order([Point(error, 1.0, 2 * n, None, 1e-3, False, steps=n) for n, error in bdf]) is None
    scattered = [(3, 6.95e-4), (3, 6.95e-5), (3, 6.95e-6), (3, 6.95e-7), (3, 6.95e-8), (5, 6.95e-9), (6, 6.95e-10),
                 (9, 6.95e-11)]
    assert observed_order([Point(error, 1.0, 4 * n, None, 1e-3, False, steps=n) for n, error in scattered]) is None


# ------------------------------------------------------------------------------------------------ whole studies

PROJECTILE = """
    duration: 1.0
    fps: 10
    bodies: [{name: ball, position: [0, 1, 0], velocity: [3, 5, 0]}]
    fields: [{type: gravity}]
    study: {closed_form: true, rtols: [1.0e-3, 1.0e-6, 1.0e-9], dt_levels: 4, repeats: 1}
"""


@pytest.fixture(scope="module")
def projectile_study():
    return run_study(scene(PROJECTILE), methods=["RK45", "euler", "symplectic_euler", "verlet"])


def test_projectile_study_against_its_closed_form(projectile_study):
    """Euler and symplectic Euler converge at order 1, with error h g T / 2 … scaled; Verlet is exact (round-off,
    marked as limited by the reference); RK45 meets its tolerance; energy drift is reported (gravity only)."""
    result = projectile_study
    assert result.reference.startswith("closed form (ball: projectile)")
    merits = {m.method: m for m in result.merits}
    assert merits["euler"].order == pytest.approx(1.0, abs=0.05)
    assert merits["symplectic_euler"].order == pytest.approx(1.0, abs=0.05)
    verlet = [row for row in result.rows if row.method == "verlet"]
    assert all(row.limited_by_reference and row.position_error < 1e-12 for row in verlet)
    rk45 = [row for row in result.rows if row.method == "RK45"]
    assert [row.rtol for row in rk45] == [1e-3, 1e-6, 1e-9]
    assert all(row.error_over_tolerance < 10 for row in rk45)
    euler = [row for row in result.rows if row.method == "euler"]
    assert [row.dt for row in euler] == pytest.approx([0.1 / 2**k for k in range(4)])
    assert all(row.energy_drift is not None for row in euler)
    assert result.conserved == {"energy": True, "momentum": False, "angular_momentum": False}
    for row in euler:  # explicit Euler lags the parabola by g h t / 2 at time t
        t = np.arange(10) / 10
        expected = np.sqrt(np.mean((G * row.dt * t / 2) ** 2)) / result.length_scale
        assert row.position_error == pytest.approx(expected, rel=1e-6)


def test_study_without_closed_form_checks_its_reference_and_marks_points_it_cannot_resolve():
    """Quadratic drag: the reference is DOP853 at 1e-12 checked against 1e-11; its accuracy is far below every
    run's error except the tightest, which are marked as limited by it."""
    loaded = scene("""
        duration: 1.0
        fps: 10
        bodies: [{name: ball, velocity: [8, 8, 0]}]
        fields: [{type: gravity}, {type: drag, model: quadratic, coefficient: 0.05}]
        study: {rtols: [1.0e-3, 1.0e-6, 1.0e-10], repeats: 1}
    """)
    result = run_study(loaded, methods=["RK23"])
    assert result.reference.startswith("DOP853 at rtol 1e-12, checked against DOP853 at rtol 1e-11")
    assert 0 < result.reference_floor < 1e-9
    rows = result.rows
    assert rows[0].position_error > 1e3 * result.reference_floor and not rows[0].limited_by_reference
    assert all(row.limited_by_reference == (row.position_error <= 2 * result.reference_floor) for row in rows)


@pytest.mark.slow
def test_failed_runs_are_kept_with_their_reason():
    """A step the stability check refuses and a run over its time limit are rows with status and reason, and count
    as failures of their method."""
    loaded = scene("""
        duration: 0.3
        fps: 10
        anchors: [{name: wall, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 0.01, position: [1.1, 0, 0]}]
        springs: [{between: [wall, bob], stiffness: 1.0e3, damping: 0.0, rest_length: 1.0}]
        study: {dt_levels: 2, rtols: [1.0e-6], repeats: 1}
    """)
    result = run_study(loaded, methods=["symplectic_euler"])
    assert result.reference.endswith("checked against Radau at rtol 1e-09")  # a stiff scene: ω = 316 rad/s
    refused = [row for row in result.rows if row.method == "symplectic_euler"]
    # dt = 0.1 s: two steps grow the vibration a millionfold, just under the refusal limit, and the energy guard
    # stops it; dt = 0.05 s is refused before it starts
    assert [row.status for row in refused] == ["failed", "failed"]
    assert "the total energy rose by" in refused[0].reason and "cannot hold this scene's springs" in refused[1].reason
    assert {m.method: m.failures for m in result.merits}["symplectic_euler"] == 2
    timed_out = run_study(scene(PROJECTILE, "study.timeout=1.0e-9"), methods=["RK45"])
    assert [row.status for row in timed_out.rows] == ["timeout"] * 3
    assert timed_out.rows[0].reason == "took longer than 1e-09 s"


def test_a_run_that_crawls_inside_one_frame_times_out_there(monkeypatch):
    """The time limit is checked at every force evaluation, not only between frames: a run whose first frame takes
    thousands of steps stops within a few evaluations of its deadline (a clock that ticks 1 s per reading)."""
    from animbatch.study import runs

    clock = iter(range(10**9))
    monkeypatch.setattr(runs, "time", types.SimpleNamespace(perf_counter=lambda: float(next(clock))))
    loaded = scene("""
        duration: 1
        fps: 2
        anchors: [{name: wall, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 0.01, position: [1.1, 0, 0]}]
        springs: [{between: [wall, bob], stiffness: 1.0e3, damping: 0.0, rest_length: 1.0}]
    """)
    model = compile_scene(loaded.spec)
    evaluations = []
    model_rhs = runs.Dynamics.rhs
    monkeypatch.setattr(runs.Dynamics, "rhs", lambda self, t, y: evaluations.append(t) or model_rhs(self, t, y))
    outcome = runs.execute(model, runs.RunSetting("RK45", rtol=1e-10), np.ones(model.layout.size), repeats=0,
                           timeout=20)
    assert outcome.status == "timeout" and outcome.reason == "took longer than 20 s"
    assert len(evaluations) < 25  # ω = 316 rad/s for 0.5 s at rtol 1e-10 needs thousands


def test_a_study_without_a_reference_says_which_runs_failed_and_what_to_do(monkeypatch, tmp_cwd):
    """When no tight reference run finishes in time (a clock that ticks 1 s per reading), 'animbatch study' exits 3
    with one message, no traceback: the runs tried (DOP853 at 1e-12, then straight to 1e-10 after the timeout, then
    Radau since the spring is stiff) with their reasons, and the remedies."""
    from animbatch.study import runs

    clock = iter(range(10**9))
    monkeypatch.setattr(runs, "time", types.SimpleNamespace(perf_counter=lambda: float(next(clock))))
    (tmp_cwd / "bob.yaml").write_text("""
        duration: 1
        fps: 2
        anchors: [{name: wall, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 0.01, position: [1.1, 0, 0]}]
        springs: [{between: [wall, bob], stiffness: 1.0e3, damping: 0.0, rest_length: 1.0}]
    """)
    result = CliRunner().invoke(cli, ["study", "bob.yaml", "--methods", "RK45"])
    assert result.exit_code == 3 and "Traceback" not in result.output
    assert ("error: no reference for the study: every tight run failed (DOP853 at rtol 1e-12: took longer than "
            "600 s; DOP853 at rtol 1e-10: took longer than 600 s; Radau at rtol 1e-11: took longer than 600 s). "
            in result.output)
    assert "--set duration=" in result.output and "--timeout T" in result.output and "--closed-form" in result.output


def test_outputs_table_csv_json_and_plot(projectile_study, tmp_path):
    paths = write_outputs(projectile_study, tmp_path)
    rows = list(csv.DictReader(paths["csv"].open()))
    assert len(rows) == len(projectile_study.rows) == 3 + 3 * 4
    assert {row["method"] for row in rows} == {"RK45", "euler", "symplectic_euler", "verlet"}
    data = json.loads(paths["json"].read_text())
    assert [m["method"] for m in data["figures_of_merit"]] == ["RK45", "euler", "symplectic_euler", "verlet"]
    image = np.asarray(Image.open(paths["png"]).convert("L"))
    assert image.shape == (605, 880) and image.std() > 10  # a drawn figure, not a blank one
    text = paths["txt"].read_text()
    assert "time to 0.001 [s]" in text and "limited by reference" in text
    assert not list(tmp_path.glob(".*partial*"))


def test_a_written_study_reads_back_with_the_same_runs_and_figures_of_merit(projectile_study, tmp_path):
    """``docs/accuracy.md`` can be rebuilt from the scenes' saved study.json (``--only`` restudies one scene): the
    result read back has every run and the same times to each target and orders as the study that wrote it."""
    from animbatch.study.study import StudyResult

    paths = write_outputs(projectile_study, tmp_path)
    back = StudyResult.from_dict(json.loads(paths["json"].read_text()))
    assert back.rows == projectile_study.rows and back.seconds == projectile_study.seconds > 0
    assert back.reference_floor == projectile_study.reference_floor
    assert [(m.method, m.time_to, m.order, m.failures) for m in back.merits] == [
        (m.method, m.time_to, m.order, m.failures) for m in projectile_study.merits]
    # the reference's accuracy is read back and used: with every run limited by a reference good to 1e-2 only, no
    # method can be said to reach 1e-3, though every run's own error is round-off
    from dataclasses import replace

    from animbatch.study.study import merits

    rows = [replace(row, limited_by_reference=True) for row in projectile_study.rows]
    coarse = replace(projectile_study, rows=rows, reference_floor=1e-2, merits=merits(rows, 1e-2))
    paths = write_outputs(coarse, tmp_path / "coarse")
    back = StudyResult.from_dict(json.loads(paths["json"].read_text()))
    assert back.reference_floor == 1e-2
    assert all(m.time_to[1e-3].seconds is None for m in back.merits)


def test_study_command(tmp_cwd):
    (tmp_cwd / "ball.yaml").write_text(PROJECTILE)
    result = CliRunner().invoke(cli, ["study", "ball.yaml", "--methods", "RK45,verlet", "--repeats", "1"])
    assert result.exit_code == 0, result.output
    assert "study of ball: reference closed form" in result.output
    assert sorted(p.name for p in (tmp_cwd / "renders/ball").iterdir()) == ["study.csv", "study.json", "study.png",
                                                                           "study.txt"]


def test_energy_drift_is_only_reported_where_energy_is_conserved():
    loaded = scene(PROJECTILE.replace("fields: [{type: gravity}]",
                                      "fields: [{type: gravity}, {type: drag, model: linear, coefficient: 0.1}]"))
    result = run_study(loaded, methods=["RK45"])
    assert result.conserved["energy"] is False and all(row.energy_drift is None for row in result.rows)
    model = compile_scene(loaded.spec)
    assert total_energy(model, model.y0) != 0 and angular_momentum(model, model.y0).shape == (3,)


def test_a_study_with_collisions_measures_bounce_time_errors():
    """A ball bouncing (e = 0.5) from 1 m: the reference (DOP853 with impacts located on its dense output) bounces
    at t₀ and 2 t₀ in the first second; a tight RK45 run's bounce times agree to 1e-7 s, symplectic Euler's are off
    by at most a step per bounce, and the error shrinks with the step (first order: speculative contacts bounce
    within the step)."""
    loaded = scene("""
        duration: 1.0
        fps: 20
        materials: {m: {restitution: 0.5, static_friction: 0.5, kinetic_friction: 0.3}}
        bodies: [{name: ball, radius: 0.1, position: [0, 1.1, 0], material: m}]
        colliders: [{type: plane, material: m}]
        fields: [{type: gravity}]
        study: {rtols: [1.0e-8], dt_levels: 3, repeats: 1}
    """)
    result = run_study(loaded, methods=["RK45", "symplectic_euler"])
    t0 = np.sqrt(2 / G)
    assert result.reference_impacts == 2 and 2 * t0 < 1.0 < 2.5 * t0
    rk45 = next(row for row in result.rows if row.method == "RK45")
    assert rk45.impacts == 2 and rk45.contact_time_error < 1e-7
    euler = [row for row in result.rows if row.method == "symplectic_euler"]
    assert [row.dt for row in euler] == pytest.approx([0.05, 0.025, 0.0125])
    assert [row.impacts for row in euler] == [2, 2, 2]
    errors = [row.contact_time_error for row in euler]
    assert errors[0] > errors[1] > errors[2] > 0
    assert all(error < 2 * row.dt for error, row in zip(errors, euler))  # at most a step per bounce
    assert errors[0] / errors[2] == pytest.approx(4, rel=0.3)  # first order: dt / 4 gives a quarter
    assert "contact" in table(result) and "contact_time_error" in csv_text(result).splitlines()[0]


@pytest.mark.slow
def test_bundled_scenes_that_declare_closed_forms_have_them_and_a_tight_run_agrees():
    """Every scene in scenes/ with study.closed_form gets its exact motion, and a DOP853 run at 1e-11 matches it to
    1e-7 of the scene's length scale (so the study measures against the right thing)."""

    from animbatch import api
    from animbatch.study.measure import Motion, Scales, position_error

    root = REPO
    declared = []
    for path in sorted((root / "scenes").glob("*.yaml")):
        if not api.load_scene(path).spec.study.closed_form:  # (some scenes need their fixed-step method)
            continue
        loaded = api.load_scene(path, ["solver.method=DOP853", "solver.rtol=1.0e-11", "solver.atol=1.0e-13"])
        declared.append(path.stem)
        model = compile_scene(loaded.spec)
        exact = exact_motion(model)
        trajectory = api.simulate(loaded, model=model)
        scales = Scales.of_motion(model, exact.positions, exact.velocities)
        identity = np.zeros((*exact.positions.shape[:2], 4))
        identity[..., 0] = 1
        error = position_error(model, Motion(trajectory.positions, trajectory.velocities, identity),
                               Motion(exact.positions, exact.velocities, identity), scales)
        assert error < 1e-7, path.name
    assert set(declared) >= {"projectile", "damped_oscillator", "two_body_orbit"}


def test_accuracy_page_sections_link_the_plot_and_list_every_method(projectile_study):
    """docs/accuracy.md is generated: each scene's section links its plot and files and has one row per method."""
    from animbatch.study.document import GUIDE, LEDGER, page, section

    text = section("projectile", "a ball", projectile_study, "accuracy/projectile")
    assert "![work-precision plot of projectile](accuracy/projectile/study.png)" in text
    assert "[CSV](accuracy/projectile/study.csv)" in text
    for method in ("RK45", "euler", "symplectic_euler", "verlet"):
        assert f"| {method} | " in text
    assert "Fastest to 1e-3: **" in text
    ledger = LEDGER + "| a table |\n"
    assert page([text], 1.0, ledger).endswith(GUIDE + "\n" + ledger)


def test_the_accuracy_page_holds_the_guide_and_the_ledger_as_the_generator_writes_them():
    """docs/accuracy.md is regenerated rarely (it takes half an hour): its guide and its ledger section must still be
    the text the generator writes, and the ledger table must have a row per run of the generator."""

    from animbatch.study.document import GUIDE, LEDGER, LEDGER_RUNS

    text = (REPO / "docs" / "accuracy.md").read_text(encoding="utf-8")
    assert GUIDE + "\n" + LEDGER in text
    table = text.split(LEDGER, 1)[1].strip().splitlines()
    assert len(table) == 2 + len(LEDGER_RUNS)
    assert [row.split("|")[1].strip() for row in table[2:]] == [method for method, _ in LEDGER_RUNS]


# ------------------------------------------------------------------------------------------------ emitters

EMITTER_BURST = """
    duration: 1.0
    fps: 10
    seed: 3
    emitters:
      - name: puff
        source: {type: sphere, position: [0, 1, 0], radius: 0.1}
        bursts: [{time: 0, count: 200}]
        speed: {mean: 4, spread: 1}
        direction: {cone: 60}
        lifetime: 5
        radius: 0.01
        mass: 1.0e-3
    fields: [{type: gravity}]
    study: {rtols: [1.0e-3, 1.0e-6], dt_levels: 4, repeats: 1}
"""


def test_a_scene_of_emitters_is_studied_particle_by_particle():
    """200 particles burst at t = 0 under gravity alone: each one is a projectile, so explicit Euler lags each by
    g h t / 2 at time t (the same for all of them), and Verlet and RK45 are exact to round-off. The errors are
    measured particle by particle against a tight DOP853 run; nothing is conserved (births and deaths)."""
    result = run_study(scene(EMITTER_BURST), methods=["RK45", "euler", "verlet"])
    assert result.reference.startswith("DOP853 at rtol 1e-12, checked against DOP853 at rtol 1e-11")
    assert result.reference_floor < 1e-13
    assert result.conserved == {"energy": False, "momentum": False, "angular_momentum": False}
    euler = [row for row in result.rows if row.method == "euler"]
    assert [row.dt for row in euler] == pytest.approx([0.1 / 2**k for k in range(4)])
    t = np.arange(10) / 10  # the frame times
    for row in euler:
        expected = np.sqrt(np.mean((G * row.dt * t / 2) ** 2)) / result.length_scale
        assert row.position_error == pytest.approx(expected, rel=1e-6)
        assert row.energy_drift is None
    exact = [row for row in result.rows if row.method in ("verlet", "RK45")]
    assert len(exact) == 6 and all(row.position_error < 1e-12 for row in exact)
    assert len(table(result).splitlines()) > len(result.rows)  # the table prints (work the kernels do not count)


@pytest.mark.slow
def test_emitted_particles_converge_at_their_methods_order_under_drag():
    """With linear drag (velocity-dependent: Verlet's predicted velocity matters) Euler and backward Euler converge
    at order 1 and Verlet at order 2, measured over every particle of the burst."""
    loaded = scene(EMITTER_BURST.replace("fields: [{type: gravity}]",
                                         "fields: [{type: gravity}, {type: drag, model: linear, coefficient: 2.0e-3}]"))
    merits = {m.method: m for m in run_study(loaded, methods=["euler", "backward_euler", "verlet"]).merits}
    assert merits["euler"].order == pytest.approx(1.0, abs=0.1)
    assert merits["backward_euler"].order == pytest.approx(1.0, abs=0.1)
    assert merits["verlet"].order == pytest.approx(2.0, abs=0.1)


@pytest.mark.slow
def test_particles_born_between_frames_fly_exactly_under_an_adaptive_method():
    """A hose: 400 drops a second, each born at its own instant within a frame, under quadratic drag. An adaptive
    run integrates each newborn from its birth to the frame's end to its tolerance (in one call, time scaled per
    drop), so the tight reference is exact and Verlet converges to it at order 2 down to 1/384 s. Before, newborns
    took one Verlet step of up to a frame under adaptive methods: the reference was off by 1e-5 of the scene and
    Verlet stopped converging there."""
    loaded = scene("""
        duration: 1.0
        fps: 24
        seed: 7
        emitters:
          - {name: spray, source: {type: point, position: [0, 0.5, 0]}, rate: 400, lifetime: 5,
             speed: {mean: 5, spread: 0.5}, direction: {axis: [1, 1, 0], cone: 8}, radius: 0.01, mass: 1.0e-4}
        fields: [{type: gravity}, {type: drag, model: quadratic, coefficient: 2.0e-5}]
        study: {dt_levels: 5, repeats: 1}
    """)
    result = run_study(loaded, methods=["verlet"])
    errors = [row.position_error for row in result.rows]
    assert result.reference_floor < 1e-12 and errors[-1] < 1e-6
    assert all(3.5 < coarse / fine < 4.5 for coarse, fine in zip(errors, errors[1:]))


def test_an_emitter_study_cannot_ask_for_closed_forms():
    """Emitted particles have no closed forms here: asking for them is an error at the key, not a silent DOP853."""
    with pytest.raises(SceneError, match=r"study.closed_form: emitted particles have no closed forms"):
        run_study(scene(EMITTER_BURST.replace("study: {", "study: {closed_form: true, ")), methods=["verlet"])


def test_a_study_of_more_particles_than_fit_is_refused_before_it_runs():
    from animbatch.errors import StudyError

    with pytest.raises(StudyError, match=r"600,000 particles at 10 frames .* shorten the scene"):
        run_study(scene(EMITTER_BURST.replace("count: 200", "count: 600000")), methods=["verlet"])


def test_particles_are_matched_by_serial_whatever_slot_holds_them():
    """Two runs may hold a particle in different pool slots: the study compares it with itself, by serial, and
    leaves out frames where it is not alive."""
    from animbatch.study.emitter_study import particle_motion
    from animbatch.trajectory import ParticleFrames

    positions = np.arange(2 * 3 * 3, dtype=float).reshape(2, 3, 3)
    serials = np.array([[0, 1, -1], [2, 0, 1]])
    first = particle_motion([ParticleFrames("a", positions, serials, np.zeros((2, 3)))], [3])
    swapped = particle_motion([ParticleFrames("a", positions[:, ::-1], serials[:, ::-1], np.zeros((2, 3)))], [3])
    np.testing.assert_array_equal(first.positions, swapped.positions)
    assert np.isnan(first.positions[0, 2]).all()  # serial 2 is not born by frame 0
    np.testing.assert_array_equal(first.positions[1, 0], positions[1, 1])


def test_a_study_finds_mesh_files_beside_the_scene_file(tmp_path, tmp_cwd):
    """A scene whose body is a mesh file next to it is studied from any folder (it failed with 'no such file')."""
    import shutil

    from animbatch import api

    folder = tmp_path / "elsewhere"
    (folder / "meshes").mkdir(parents=True)
    shutil.copy(REPO / "scenes" / "meshes" / "gem.obj", folder / "meshes")
    (folder / "gem.yaml").write_text("""
duration: 0.5
fps: 10
bodies: [{name: gem, type: rigid, shape: {type: mesh, file: meshes/gem.obj}, density: 2600, velocity: [1, 2, 0]}]
fields: [{type: gravity}]
study: {dt_levels: 2, repeats: 1}
""")
    result = run_study(api.load_scene(folder / "gem.yaml"), methods=["verlet"])
    assert [row.status for row in result.rows] == ["ok", "ok"]
    assert all(row.position_error < 1e-12 for row in result.rows)


def test_a_fixed_step_reference_and_its_accuracy():
    """``study.reference``: a projectile against symplectic Euler at 1 ms, which leads the parabola by g dt t / 2;
    its check at 2 ms leads by twice that, so the measured floor is exactly the reference's own error. Explicit
    Euler at h lags by g h t / 2, so against this reference it is off by g (h + dt) t / 2."""
    dt = 1e-3
    loaded = scene(PROJECTILE.replace("study: {closed_form: true,",
                                      f"study: {{reference: {{method: symplectic_euler, dt: {dt}}},"))
    result = run_study(loaded, methods=["euler"])
    assert result.reference == "symplectic_euler at dt 0.001 s, checked against symplectic_euler at dt 0.002 s"
    t = np.arange(10) / 10
    assert result.reference_floor == pytest.approx(np.sqrt(np.mean((G * dt * t / 2) ** 2)) / result.length_scale,
                                                   rel=1e-6)
    for row in result.rows:
        expected = np.sqrt(np.mean((G * (row.dt + dt) * t / 2) ** 2)) / result.length_scale
        assert row.position_error == pytest.approx(expected, rel=1e-6)


def test_a_study_has_one_reference():
    with pytest.raises(SceneError, match=r"study.reference.*closed_form .*or reference .*not both"):
        scene(PROJECTILE.replace("study: {closed_form: true,",
                                 "study: {closed_form: true, reference: {method: verlet, dt: 1.0e-3},"))


@pytest.mark.slow
def test_a_study_times_the_equations_of_motion_a_render_would_run(monkeypatch):
    """Every run of a study (the reference, its check and each setting) integrates what a render with that setting
    would: here the compiled equations of motion (asked for with ANIMBATCH_KERNELS=numba), which the study timed as
    numpy before. A hinged bar swinging: Verlet converges at its order 2 on them, and RK45 meets its tolerance."""
    from animbatch.sim.kernels import KERNELS_VARIABLE
    from animbatch.sim.model import compiled
    from support.scenes import counting

    monkeypatch.setenv(KERNELS_VARIABLE, "numba")
    built = counting(monkeypatch, compiled, "CompiledDynamics")
    loaded = scene("""
        duration: 1.0
        fps: 10
        bodies:
          - {name: bar, type: rigid, shape: {type: box, size: [0.05, 1.0, 0.05]}, density: 500,
             position: [0.25, -0.433, 0], orientation: {axis: [0, 0, 1], angle: 30}}
        joints: [{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]}]
        fields: [{type: gravity}]
        study: {rtols: [1.0e-6], dt_levels: 4, repeats: 1}
    """)
    result = run_study(loaded, methods=["RK45", "verlet"])
    assert len(built) >= 2 + 2 * len(result.rows)  # reference and check, then each run untimed and timed
    merits = {m.method: m for m in result.merits}
    assert merits["verlet"].order == pytest.approx(2.0, abs=0.15)
    assert next(row for row in result.rows if row.method == "RK45").position_error < 1e-5


@pytest.mark.slow
def test_the_accuracy_page_is_rebuilt_from_saved_studies_alone(projectile_study, tmp_path, monkeypatch):
    """``--page`` studies nothing: every section comes from its saved study.json (each scene's table rewritten), and
    the page holds the guide as the generator has it now, and each scene's plot is drawn anew (by a stand-in here:
    drawing is tested on its own, and a real one costs most of a second a scene)."""
    from animbatch.study import document, report

    saved = write_outputs(projectile_study, tmp_path / "saved")["json"].parent  # drawn once, copied per scene
    for name in document.SCENES:
        shutil.copytree(saved, tmp_path / "docs" / "accuracy" / name)
    (tmp_path / "docs" / "accuracy" / "projectile" / "study.txt").write_text("stale")
    monkeypatch.setattr(document, "run_study", lambda *a, **k: pytest.fail("--page studied a scene"))
    monkeypatch.setattr(document, "ledger_section", lambda root: document.LEDGER + "| a table |\n")
    drawn = []
    monkeypatch.setattr(report, "plot", lambda result, target: drawn.append(Path(target).parent.name))
    assert document.main(["--root", str(tmp_path), "--page"]) == 0
    assert drawn == list(document.SCENES)
    page = (tmp_path / "docs" / "accuracy.md").read_text()
    assert all(f"## {name}" in page for name in document.SCENES) and document.GUIDE in page
    assert (tmp_path / "docs" / "accuracy" / "projectile" / "study.txt").read_text().startswith("study of")


def test_the_accuracy_page_refuses_to_rebuild_and_study_at_once(capsys):
    from animbatch.study import document

    with pytest.raises(SystemExit):
        document.main(["--page", "--only", "projectile"])
    assert "--page studies nothing" in capsys.readouterr().err
