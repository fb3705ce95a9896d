"""The accuracy ledger of every run: conservation laws and their drifts against closed forms, the drift warning and
its advice (followed, it works), the step used, the work of every part, the per-frame quantities, the plot, and
re-judging a cached bake."""

from __future__ import annotations

import csv
import io
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch import api
from animbatch.cli import cli
from animbatch.errors import AccuracyWarning
from animbatch.sim.ledger import QuantitySeries, conservation_laws, summary
from support.scenes import run, scene, states

G = 9.81

# The Kepler binary of scenes/two_body_orbit.yaml (G = 1): masses 3 and 1, 1 m apart, relative speed 1.6 m/s.
KEPLER = """
    duration: {duration}
    fps: 30
    solver: {solver}
    bodies:
      - {{name: star,   mass: 3.0, radius: 0.08, position: [-0.25, 0, 0], velocity: [0, -0.4, 0]}}
      - {{name: planet, mass: 1.0, radius: 0.05, position: [ 0.75, 0, 0], velocity: [0,  1.2, 0]}}
    fields: [{{type: gravitation, G: 1.0}}]
"""
KEPLER_ENERGY = 0.5 * 3 * 0.4**2 + 0.5 * 1 * 1.2**2 - 3 * 1 / 1.0  # -2.04 J: kinetic minus G m1 m2 / r


def kepler(solver: str, duration: float = 19.8, *overrides: str):
    """Simulate the binary, returning the model, the trajectory and the accuracy warnings issued."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model, trajectory = run(KEPLER.format(duration=duration, solver=solver), *overrides)
    return model, trajectory, [str(w.message) for w in caught if issubclass(w.category, AccuracyWarning)]


def kepler_energy_drift(trajectory) -> float:
    """max |E(t) - E₀| / |E₀| from the trajectory, with E = ½ m₁ v₁² + ½ m₂ v₂² - G m₁ m₂ / r (written out here)."""
    v, x = trajectory.velocities, trajectory.positions
    kinetic = 0.5 * 3 * np.sum(v[:, 0] ** 2, axis=1) + 0.5 * 1 * np.sum(v[:, 1] ** 2, axis=1)
    energy = kinetic - 3 / np.linalg.norm(x[:, 0] - x[:, 1], axis=1)
    return float(np.max(np.abs(energy - KEPLER_ENERGY)) / abs(KEPLER_ENERGY))


# ------------------------------------------------------------------------------------------------ drift warning


@pytest.mark.slow
def test_explicit_euler_over_ten_kepler_orbits_warns_with_the_energy_drift_and_the_fix():
    """Euler at 1 ms spirals the orbit out over ten periods: the ledger's energy drift is max|E - E₀|/|E₀| with E₀
    the closed-form binding energy (-2.04 J), far above 1 %, and the warning names both drifting quantities, the
    method and the fixes (a symplectic method, a step)."""
    model, trajectory, warned = kepler("{method: euler, dt: 1.0e-3}")
    ledger = trajectory.ledger
    assert ledger["conservation"]["energy"]["scale"] == pytest.approx(abs(KEPLER_ENERGY))
    assert ledger["conservation"]["energy"]["drift"] == pytest.approx(kepler_energy_drift(trajectory), rel=1e-9)
    assert ledger["conservation"]["energy"]["drift"] > 0.1
    assert len(warned) == 1 and warned == ledger["warnings"]
    message = warned[0]
    for words in ("the energy drifted by", "the angular momentum by", "this scene conserves them", "euler",
                  "not symplectic", "solver.method: verlet", "solver.dt ≤"):
        assert words in message, words
    assert ledger["conservation"]["momentum"]["drift"] < 1e-12  # Euler keeps linear momentum: forces pair up
    assert "1 accuracy warning" in summary(ledger)


@pytest.mark.slow
def test_a_symplectic_method_at_the_same_step_keeps_the_orbit_and_gives_no_warning():
    """Verlet at the same 1 ms keeps the energy within 1e-4 of |E₀| and the angular momentum to round-off."""
    _, trajectory, warned = kepler("{method: verlet, dt: 1.0e-3}")
    drift = trajectory.ledger["conservation"]
    assert not warned and not trajectory.ledger["warnings"]
    assert drift["energy"]["drift"] == pytest.approx(kepler_energy_drift(trajectory), rel=1e-9)
    assert drift["energy"]["drift"] < 1e-4 and drift["angular_momentum"]["drift"] < 1e-12


@pytest.mark.slow
def test_the_drift_threshold_is_the_scenes_to_set():
    """solver.drift_warning = 0.5 lets the same 30 % drift pass without a warning, and the ledger records it."""
    _, trajectory, warned = kepler("{method: euler, dt: 1.0e-3, drift_warning: 0.5}")
    assert not warned and trajectory.ledger["drift_warning"] == 0.5
    assert 0.1 < trajectory.ledger["conservation"]["energy"]["drift"] < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["{method: euler, dt: 1.0e-3}", "{method: symplectic_euler, dt: 2.0e-2}",
                                    "{method: RK23, rtol: 1.0e-2, atol: 1.0e-5}",
                                    "{method: RK45, rtol: 1.0e-3, atol: 1.0e-6}"])
def test_following_the_advice_brings_the_drift_under_the_threshold(solver):
    """Over one orbit each of these drifts by more than 1 %; rerun with the step or tolerance the warning gives
    (atol scaled with rtol), the drift falls below 1 % and the warning goes."""
    _, _, warned = kepler(solver, 2.0)
    assert len(warned) == 1
    step = re.search(r"solver\.dt ≤ ([0-9.e+-]+) s", warned[0])
    tolerance = re.search(r"solver\.rtol to ([0-9.e+-]+)", warned[0])
    if step:
        overrides = [f"solver.dt={step.group(1)}"]
    else:
        rtol = float(tolerance.group(1))
        overrides = [f"solver.rtol={rtol}", f"solver.atol={rtol * 1e-3}"]
    _, trajectory, warned = kepler(solver, 2.0, *overrides)
    assert not warned
    assert trajectory.ledger["conservation"]["energy"]["drift"] < 0.01


# ------------------------------------------------------------------------------------------------ conservation


def laws(text: str) -> dict:
    loaded = scene(text)
    return conservation_laws(api.compile_model(loaded))


def test_which_quantities_a_scene_conserves_and_why_not():
    """Gravity keeps energy but is an external force; a damper dissipates; anchors hold; wind does work; inelastic
    collisions lose energy; a floor pushes; pucks that only hit each other elastically keep everything."""
    ball = "bodies: [{name: ball, position: [0, 1, 0], velocity: [1, 2, 0]}]"
    projectile = laws(f"{ball}\nfields: [{{type: gravity}}]")
    assert projectile["energy"].conserved and "gravity" in projectile["energy"].reason
    assert not projectile["momentum"].conserved and "gravity is an external force" in projectile["momentum"].reason
    damped = laws(f"{ball}\nanchors: [{{name: hook, position: [0, 2, 0]}}]\n"
                  "springs: [{between: [hook, ball], stiffness: 10, damping: 0.5}]")
    assert not damped["energy"].conserved and "spring damping dissipates it" in damped["energy"].reason
    assert "springs to anchors" in damped["momentum"].reason
    windy = laws(f"{ball}\nfields: [{{type: wind, velocity: [3, 0, 0], coefficient: 0.1}}]")
    assert "wind does work" in windy["energy"].reason
    floor = laws(f"{ball}\ncolliders: [{{type: plane}}]")
    assert "collisions lose it" in floor["energy"].reason and "fixed colliders" in floor["momentum"].reason
    pucks = """
        materials: {{m: {{restitution: {e}, static_friction: 0, kinetic_friction: 0}}}}
        contacts: {{}}
        bodies:
          - {{name: a, position: [-1, 0, 0], velocity: [1, 0, 0], material: m}}
          - {{name: b, position: [1, 0, 0], velocity: [-1, 0, 0], material: m}}
    """
    elastic, inelastic = laws(pucks.format(e=1.0)), laws(pucks.format(e=0.5))
    assert all(law.conserved for law in elastic.values())
    assert not inelastic["energy"].conserved and inelastic["momentum"].conserved


def test_elastic_pucks_conserve_what_the_ledger_says_they_do():
    """Two pucks colliding elastically with no floor under RK45: energy, momentum and angular momentum drift by
    round-off only, through the impact."""
    _, trajectory = run("""
        duration: 2
        solver: {method: RK45, rtol: 1.0e-6}
        materials: {m: {restitution: 1, static_friction: 0, kinetic_friction: 0}}
        contacts: {}
        bodies:
          - {name: a, mass: 1, radius: 0.1, position: [-1, 0.05, 0], velocity: [1, 0, 0], material: m}
          - {name: b, mass: 3, radius: 0.1, position: [1, 0, 0], velocity: [-1, 0, 0], material: m}
    """)
    assert len(trajectory.solver_stats["impacts"]) == 1
    for entry in trajectory.ledger["conservation"].values():
        assert entry["conserved"] and entry["drift"] < 1e-12


# ------------------------------------------------------------------------------------------------ step and work


def test_a_fixed_step_that_does_not_divide_the_frame_is_reported_as_used():
    """dt = 7 ms at 24 fps: each frame takes 6 steps of (1/24)/6 = 6.944 ms; the ledger, the summary and 'info'
    say so, naming solver.dt. A dt that divides the frame (1/30 s at 30 fps) gets no note."""
    text = """
        duration: 0.5
        fps: 24
        solver: {method: verlet, dt: 0.007}
        bodies: [{name: ball}]
        fields: [{type: gravity}]
    """
    _, trajectory = run(text)
    step = trajectory.ledger["step"]
    assert step["dt"] == pytest.approx(1 / 24 / 6) and step["steps_per_frame"] == 6 and step["requested_dt"] == 0.007
    assert "6 steps of 0.006944 s per frame" in step["note"] and "solver.dt = 0.007 s" in step["note"]
    assert "dt 0.006944 s (solver.dt 0.007 s does not divide 1/fps)" in summary(trajectory.ledger)
    from animbatch.info import describe_model

    loaded = scene(text)
    assert "step       0.00694444 s used, 6 per frame: the largest step ≤ solver.dt = 0.007 s" in describe_model(
        api.plan(loaded))
    _, aligned = run(text.replace("fps: 24", "fps: 30").replace("dt: 0.007", "dt: 0.0333334"))
    assert "note" not in aligned.ledger["step"]


def falling_ball(fps: int, solver: str) -> str:
    """A ball falling for half a second at ``fps``, integrated with ``solver`` (a YAML mapping)."""
    return f"""
        duration: 0.5
        fps: {fps}
        solver: {solver}
        bodies: [{{name: ball}}]
        fields: [{{type: gravity}}]
    """


def test_a_default_step_that_does_not_divide_the_frame_is_not_blamed_on_solver_dt():
    """Without solver.dt the step bound is the 1 ms default; at 24 fps a frame (41.67 ms) takes 42 steps of
    0.992 ms. The ledger, the summary and 'info' name the default, not a solver.dt the user never wrote."""
    text = falling_ball(24, "{method: verlet}")
    _, trajectory = run(text)
    step = trajectory.ledger["step"]
    assert step["steps_per_frame"] == 42 and step["dt"] == pytest.approx(1 / 24 / 42)
    assert step["dt_given"] is False and step["requested_dt"] == 1e-3
    assert "the default step 0.001 s" in step["note"] and "solver.dt" not in step["note"]
    assert "(the default step 0.001 s does not divide 1/fps)" in summary(trajectory.ledger)
    from animbatch.info import describe_model

    described = describe_model(api.plan(scene(text)))
    assert "42 per frame: the largest step ≤ the default step 0.001 s" in described


def test_backward_euler_takes_one_step_per_frame_unless_given_a_dt_and_the_summary_says_where_each_step_came_from():
    """Without solver.dt, backward Euler (stable at any step) takes one step per frame; an explicit method takes the
    1 ms default; a given dt that divides the frame is solver.dt's. The summary line says which."""
    text = falling_ball(25, "{method: backward_euler}")
    assert api.plan(scene(text)).steps.frame_substeps == 1
    _, implicit = run(text)
    assert implicit.ledger["step"]["steps_per_frame"] == 1 and implicit.ledger["step"]["dt"] == pytest.approx(0.04)
    assert "backward_euler dt 0.04 s (default: one step per frame)" in summary(implicit.ledger)
    _, explicit = run(text.replace("backward_euler", "verlet"))
    assert explicit.ledger["step"]["steps_per_frame"] == 40 and "verlet dt 0.001 s (default):" in summary(explicit.ledger)
    _, given = run(text.replace("{method: backward_euler}", "{method: backward_euler, dt: 0.01}"))
    assert given.ledger["step"]["steps_per_frame"] == 4 and "backward_euler dt 0.01 s:" in summary(given.ledger)
    from animbatch.summary import describe_solver

    assert describe_solver(scene(text).spec.solver) == "backward_euler (fixed step, one step per frame)"


def test_a_step_written_to_a_few_digits_still_divides_the_frame():
    """dt = 0.008333333 s is 1/120 s to seven digits: four steps per 30 fps frame, not five (the bundled fountain
    took five, 25 % more work, and was told its dt did not divide 1/fps). A dt smaller by more than 1e-6 relative
    is a real request for smaller steps."""
    from animbatch.sim.integrators.step_plan import substeps

    assert substeps(1 / 30, 0.008333333) == 4
    assert substeps(1 / 30, 0.0333334) == 1
    assert substeps(1 / 30, 1 / 120 * (1 - 1e-5)) == 5
    _, trajectory = run("""
        duration: 0.5
        solver: {method: verlet, dt: 0.008333333}
        bodies: [{name: ball}]
        fields: [{type: gravity}]
    """)
    assert trajectory.ledger["step"]["steps_per_frame"] == 4 and "note" not in trajectory.ledger["step"]


def test_an_adaptive_run_reports_its_smallest_largest_and_mean_steps():
    """The mean step is the time integrated (to the last frame) over the steps taken, between the smallest and the
    largest accepted step."""
    _, trajectory = run("""
        duration: 2
        solver: {method: RK45, rtol: 1.0e-8}
        anchors: [{name: hook, position: [0, 0, 0]}]
        bodies: [{name: bob, position: [0.3, -1, 0]}]
        springs: [{between: [hook, bob], stiffness: 40, rest_length: 1}]
    """)
    step, work = trajectory.ledger["step"], trajectory.ledger["work"]["bodies"]
    assert step["mean"] == pytest.approx(trajectory.times[-1] / work["steps"])
    assert 0 < step["smallest"] <= step["mean"] <= step["largest"]
    assert work["steps"] == trajectory.solver_stats["steps"] and work["rhs_evaluations"] > work["steps"]


EMITTER = "emitters: [{name: spray, rate: 200, lifetime: 0.5, source: {type: point}, speed: 2}]"


@pytest.mark.slow
def test_every_part_of_a_run_reports_its_work():
    """A scene of emitters only reports its particles' steps (not "0 steps"); with a body too, both parts; an
    implicit method its factorisations. 0.5 s at 20 fps is 10 frames, 9 intervals of 5 steps of 0.01 s: 45 steps."""
    timeline = "duration: 0.5\nfps: 20\nsolver: {method: verlet, dt: 0.01}\n"
    _, alone = run(f"{timeline}{EMITTER}\nfields: [{{type: gravity}}]")
    work = alone.ledger["work"]
    assert "bodies" not in work and work["particles"]["steps"] == 45 and work["particles"]["rhs_evaluations"] > 0
    assert alone.ledger["step"]["dt"] == pytest.approx(0.01) and alone.ledger["step"]["steps_per_frame"] == 5
    assert "particles (verlet dt 0.01 s): 45 steps" in summary(alone.ledger) and "0 steps" not in summary(alone.ledger)
    _, both = run(f"{timeline}{EMITTER}\nbodies: [{{name: ball}}]\nfields: [{{type: gravity}}]")
    assert both.ledger["work"]["bodies"]["steps"] == both.ledger["work"]["particles"]["steps"] == 45
    assert "factorisations" not in both.ledger["work"]["bodies"]  # explicit: nothing to factor
    # backward Euler factors its step matrix once a step, on a spring of linear force (no corrections): 45 of them
    _, implicit = run("duration: 0.5\nfps: 20\nsolver: {method: backward_euler, dt: 0.01}\nanchors: [{name: top, position: [0, 0, 0]}]\n"
                      "bodies: [{name: bob, position: [0.3, -1, 0]}]\n"
                      "springs: [{between: [top, bob], stiffness: 50, rest_length: 0}]\n")
    assert implicit.ledger["work"]["bodies"]["factorisations"] == 45
    assert "45 steps, 45 RHS, 45 factorisations" in summary(implicit.ledger)


# ------------------------------------------------------------------------------------------------ quantities


def test_the_quantities_of_a_projectile_are_its_closed_form():
    """Kinetic energy ½ m |v₀ + g t|², potential m g y(t), momentum m (v₀ + g t), speed |v₀ + g t|, and angular
    momentum about the centre of mass zero, at every frame, in the CSV."""
    model, trajectory = run("""
        duration: 1
        fps: 20
        solver: {method: RK45, rtol: 1.0e-10, atol: 1.0e-12}
        bodies: [{name: ball, mass: 0.5, position: [0, 1, 0], velocity: [2, 3, 0]}]
        fields: [{type: gravity}]
    """)
    series = QuantitySeries.of_states(model, states(model, trajectory))
    rows = list(csv.DictReader(io.StringIO(series.csv())))
    t = np.array([float(row["time_s"]) for row in rows])
    assert np.allclose(t, np.arange(20) / 20)  # frames at k / fps for k / fps < duration
    velocity = np.stack([2 + 0 * t, 3 - G * t, 0 * t], axis=1)
    height = 1 + 3 * t - 0.5 * G * t**2
    column = {name: np.array([float(row[name]) for row in rows]) for name in rows[0]}
    assert np.allclose(column["kinetic_energy_J"], 0.25 * np.sum(velocity**2, axis=1), rtol=1e-9)
    assert np.allclose(column["potential_energy_J"], 0.5 * G * height, rtol=1e-9, atol=1e-12)
    assert np.allclose(column["total_energy_J"], column["total_energy_J"][0], rtol=1e-9)
    assert np.allclose(column["momentum_y_kg_m_s"], 0.5 * velocity[:, 1], atol=1e-9)
    assert np.allclose(column["speed_ball_m_s"], np.linalg.norm(velocity, axis=1), rtol=1e-9)
    assert np.allclose(column["angular_momentum_z_kg_m2_s"], 0.0, atol=1e-12)


def test_a_cloths_speed_is_that_of_its_centre_of_mass():
    """A cloth falling freely has one speed column, g t (its vertices all fall alike)."""
    model, trajectory = run("""
        duration: 0.5
        fps: 10
        solver: {method: verlet, dt: 1.0e-3}
        bodies:
          - {name: sheet, type: cloth, grid: {size: [1, 1], resolution: [4, 4]}, density: 0.2}
        fields: [{type: gravity}]
    """)
    series = QuantitySeries.of_states(model, states(model, trajectory))
    assert series.body_names == ("sheet",)
    assert np.allclose(series.speeds[:, 0], G * trajectory.times, rtol=1e-6)


@pytest.mark.slow
@pytest.mark.render
def test_render_with_plot_writes_the_quantities_and_the_ledger_beside_the_report(tmp_cwd):
    """render --plot: report.json holds the ledger; quantities.csv has one row per frame; quantities.png is a
    drawn picture (not blank) of the size the figure asks for."""
    import imageio.v3 as iio

    (tmp_cwd / "s.yaml").write_text("""
name: s
duration: 0.5
fps: 10
bodies: [{name: ball, position: [0, 1, 0], velocity: [1, 2, 0]}]
fields: [{type: gravity}]
render: {resolution: [64, 48]}
""")
    result = CliRunner().invoke(cli, ["render", "s.yaml", "--plot", "--no-progress"])
    assert result.exit_code == 0, result.output
    folder = tmp_cwd / "renders" / "s"
    report = json.loads((folder / "report.json").read_text())
    assert report["ledger"]["conservation"]["energy"]["conserved"] is True
    assert [Path(p).name for p in report["quantities"]] == ["quantities.csv", "quantities.png"]
    assert report["frame_count"] == 5 and len((folder / "quantities.csv").read_text().splitlines()) == 1 + 5
    image = iio.imread(folder / "quantities.png")
    assert image.shape[:2] == (1100, 900) and image[..., :3].std() > 10
    assert "drift: energy" in result.output


@pytest.mark.slow
def test_plot_command_draws_a_trajectory(tmp_cwd):
    """animbatch plot --trajectory writes the CSV and the PNG into renders/<scene>/ and prints the ledger."""
    (tmp_cwd / "s.yaml").write_text("name: s\nduration: 0.5\nbodies: [{name: ball}]\nfields: [{type: gravity}]\n")
    runner = CliRunner()
    assert runner.invoke(cli, ["simulate", "s.yaml", "-o", "run.npz", "--no-progress"]).exit_code == 0
    result = runner.invoke(cli, ["plot", "s.yaml", "--trajectory", "run.npz"])
    assert result.exit_code == 0, result.output
    assert (tmp_cwd / "renders" / "s" / "quantities.png").stat().st_size > 10_000
    assert "RK45" in result.output and "drift: energy" in result.output


def test_plot_of_a_scene_without_bodies_is_a_usage_error(tmp_cwd):
    """Emitted particles carry no energy series: the command says so (exit 2), no traceback."""
    (tmp_cwd / "e.yaml").write_text(f"name: e\nduration: 0.2\n{EMITTER}\n")
    result = CliRunner().invoke(cli, ["plot", "e.yaml"])
    assert result.exit_code == 2 and "has no bodies to plot" in result.output


def test_a_cached_bake_is_judged_again_with_a_new_threshold_without_simulating(tmp_path):
    """Changing solver.drift_warning reuses the bake (same cache file) and re-judges its ledger; reusing it tells
    its warnings again."""
    from animbatch.farm import bake

    text = KEPLER.format(duration=2.0, solver="{method: euler, dt: 1.0e-3}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = bake(scene(text), out_dir=tmp_path)
    assert not first.reused and first.trajectory.ledger["warnings"]
    again = bake(scene(text, "solver.drift_warning=0.9"), out_dir=tmp_path)
    assert again.reused and again.path == first.path
    assert again.trajectory.ledger["drift_warning"] == 0.9 and again.trajectory.ledger["warnings"] == []
    with pytest.warns(AccuracyWarning, match="the energy drifted by"):  # a reused bake tells its warnings again
        assert bake(scene(text), out_dir=tmp_path).reused


def test_drift_advice_never_suggests_the_method_already_in_use():
    from animbatch.sim.ledger import drift_advice

    for method in ("RK45", "DOP853", "LSODA"):
        advice = drift_advice(method, 0.05, 0.01, rtol=1e-6, dt=None)
        assert advice.startswith("tighten solver.rtol to ")
        assert ("use DOP853" in advice) is (method != "DOP853")
    assert "use verlet" in drift_advice("DOP853", 0.05, 0.01, rtol=1e-6, dt=None)
