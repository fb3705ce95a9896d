"""Stopwatches: events found between frames to the accuracy of the motion, checked against closed forms (a fall, a
bounce, an oscillator's period), shown on the overlay and reported with the run."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import SceneError
from animbatch.render.frame_geometry import StopwatchReading
from animbatch.sim.events import plane_crossings
from support.scenes import scene

G = 9.81


def test_a_parabola_crosses_a_plane_exactly_where_the_closed_form_says_even_between_coarse_frames():
    """y = 2 + 3t - g t²/2 sampled at 10 fps: the Hermite cubic through positions and velocities is the parabola
    itself, so the crossings of y = 1 (upwards never; downwards once) are exact."""
    t = np.arange(0, 1.5, 0.1)
    y = 2 + 3 * t - G * t**2 / 2
    positions = np.stack([t, y, 0 * t], axis=1)
    velocities = np.stack([np.ones_like(t), 3 - G * t, 0 * t], axis=1)
    down = (3 + np.sqrt(9 + 2 * G)) / G  # 2 + 3t - g t²/2 = 1
    crossings = plane_crossings(t, positions, velocities, np.array([0, 1.0, 0]), np.array([0, 1.0, 0]))
    np.testing.assert_allclose(crossings, [down], atol=1e-12)
    assert len(plane_crossings(t, positions, velocities, np.array([0, 1.0, 0]), np.array([0, 1.0, 0]), "along")) == 0
    # the apex (y = 2 + 9/(2g) at t = 3/g) is touched, not crossed: a plane through it gives nothing
    apex = np.array([0, 2 + 9 / (2 * G), 0])
    assert len(plane_crossings(t, positions, velocities, apex, np.array([0, 1.0, 0]))) == 0
    # and a plane just under it is crossed twice within one frame interval, up then down
    below = plane_crossings(t, positions, velocities, apex - [0, 1e-3, 0], np.array([0, 1.0, 0]))
    np.testing.assert_allclose(below, 3 / G + np.array([-1, 1]) * np.sqrt(2e-3 / G), atol=1e-12)


def test_a_sine_crosses_zero_at_multiples_of_half_its_period_to_fourth_order_in_the_frame_spacing():
    period = 0.77  # crossings at multiples of 0.385 s fall between frames
    omega = 2 * np.pi / period
    errors = []
    for fps in (15, 30):
        t = np.arange(0, 2.0, 1 / fps)
        positions = np.stack([np.sin(omega * t), 0 * t, 0 * t], axis=1)
        velocities = np.stack([omega * np.cos(omega * t), 0 * t, 0 * t], axis=1)
        crossings = plane_crossings(t, positions, velocities, np.zeros(3), np.array([1.0, 0, 0]))
        np.testing.assert_allclose(crossings, period / 2 * np.arange(1, 6), atol=1e-3)
        errors.append(np.abs(crossings - period / 2 * np.arange(1, 6)).max())
    assert errors[0] / errors[1] > 10  # 2⁴ = 16 for a cubic interpolant


BOUNCE = """
    duration: 2.5
    fps: 30
    solver: {{method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}}
    materials: {{bouncy: {{restitution: 0.8, static_friction: 0, kinetic_friction: 0}}}}
    bodies: [{{name: ball, radius: 0.1, position: [0, 2.1, 0], material: bouncy}}]
    fields: [{{type: gravity}}]
    colliders: [{{type: plane, material: bouncy}}]
    stopwatches:
{watches}
"""


def readings(watches: str) -> dict[str, StopwatchReading]:
    loaded = scene(BOUNCE.format(watches=watches))
    trajectory = api.simulate(loaded)
    return {reading.name: reading for reading in api.stopwatch_readings(loaded.spec.stopwatches, trajectory)}


def test_a_stopwatch_times_a_fall_to_the_impact_and_the_flight_between_two_bounces():
    """From rest 2 m above the contact: t = √(2h/g). The ball leaves at e·√(2gh) and lands again 2 e √(2gh) / g
    later; a stop counted from the start (count: 1 after the first impact) times that flight."""
    watch = readings("""
      - {name: fall, stop: {body: ball, point: [0, 0.1, 0], direction: against}}
      - {name: flight, start: {body: ball, point: [0, 0.1, 0]}, stop: {body: ball, point: [0, 0.1, 0]}}
      - {name: third, start: {time: 0.5}, stop: {body: ball, point: [0, 0.1, 0], count: 2}}
    """)
    fall = np.sqrt(2 * 2.0 / G)
    flight = 2 * 0.8 * np.sqrt(2 * G * 2.0) / G
    assert watch["fall"].start == 0.0 and watch["fall"].elapsed == pytest.approx(fall, abs=1e-6)
    assert watch["flight"].start == pytest.approx(fall, abs=1e-6)
    assert watch["flight"].elapsed == pytest.approx(flight, abs=1e-5)
    assert watch["third"].stop == pytest.approx(fall + flight, abs=1e-5)  # the 2nd impact after t = 0.5 s


def test_what_the_stopwatch_shows_runs_from_its_start_and_holds_at_its_stop():
    reading = StopwatchReading("lap", 1.0, 2.5)
    assert [reading.at(t) for t in (0.0, 1.0, 1.75, 2.5, 3.9)] == [0.0, 0.0, 0.75, 1.5, 1.5]
    running = StopwatchReading("lap", 1.0, None)
    assert running.at(3.0) == 2.0 and running.elapsed is None
    assert "never stopped" in running.describe() and "never started" in StopwatchReading("x", None, None).describe()
    assert "error -0.1 s" in StopwatchReading("lap", 1.0, 2.5, expected=1.6).describe()


def test_a_stopwatch_times_an_oscillators_period_between_two_upward_crossings():
    """m = 0.5 kg on k = 20 N/m: T = 2π √(m/k), measured between the first two upward crossings of the rest point."""
    loaded = scene("""
        duration: 3
        fps: 30
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        anchors: [{name: wall, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 0.5, position: [1.3, 0, 0]}]
        springs: [{between: [wall, bob], stiffness: 20, rest_length: 1}]
        stopwatches:
          - name: period
            start: {body: bob, point: [1, 0, 0], normal: [1, 0, 0], direction: along}
            stop: {body: bob, point: [1, 0, 0], normal: [1, 0, 0], direction: along}
    """)
    trajectory = api.simulate(loaded)
    (reading,) = api.stopwatch_readings(loaded.spec.stopwatches, trajectory)
    period = 2 * np.pi * np.sqrt(0.5 / 20)
    assert reading.elapsed == pytest.approx(period, abs=2e-5)
    assert reading.start == pytest.approx(0.75 * period, abs=2e-5)  # from x = +A: the first upward pass is at 3T/4


@pytest.mark.slow
def test_the_overlay_shows_stopwatches_and_wall_times_and_the_run_reports_them(tmp_path):
    text = BOUNCE.format(watches="      - {name: fall, stop: {body: ball, point: [0, 0.1, 0]}, expected: 0.63855}")
    text += '    render: {time_label: "{stopwatch[fall]:.3f} s {wall_simulate:.1f} {wall_render:.1f} {wall_frame:.1f}"}\n'
    loaded = scene(text)
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    label = api.frame_geometry(api.plan(loaded, model=model), trajectory).label
    assert label.at(0.3)["stopwatch"]["fall"] == pytest.approx(0.3)
    assert label.at(2.0)["stopwatch"]["fall"] == pytest.approx(np.sqrt(4 / G), abs=1e-6)
    assert label.at(0.0)["wall_simulate"] > 0
    path = tmp_path / "drop.yaml"
    path.write_text(__import__("textwrap").dedent(text))
    from click.testing import CliRunner

    from animbatch.cli import cli

    result = CliRunner().invoke(cli, ["simulate", str(path), "-o", str(tmp_path / "d.npz")])
    assert result.exit_code == 0, result.output
    assert "stopwatch 'fall' 0.63855" in result.output and "expected 0.63855 s" in result.output


def test_stopwatches_do_not_change_the_physics_hash():
    with_one = scene(BOUNCE.format(watches="      - {name: a, stop: {time: 1}}"))
    with_other = scene(BOUNCE.format(watches="      - {name: b, stop: {time: 2}}"))
    assert api.scene_fingerprint(with_one) == api.scene_fingerprint(with_other)


@pytest.mark.parametrize("watches, fragment", [
    ("      - {name: a, stop: {body: bal}}", "unknown body 'bal'; did you mean 'ball'?"),
    ("      - {name: a, stop: {body: ball, time: 1}}", "give either time (an instant) or body"),
    ("      - {name: a, stop: {}}", "not neither"),
    ("      - {name: a}\n      - {name: a}", "already used by stopwatches[0]"),
])
def test_bad_stopwatches_are_refused_with_the_fix(watches, fragment):
    with pytest.raises(SceneError) as error:
        scene(BOUNCE.format(watches=watches))
    assert fragment in str(error.value) and "test.yaml:" in str(error.value)


def test_an_overlay_naming_an_unknown_stopwatch_is_refused():
    text = BOUNCE.format(watches="      - {name: fall}") + '    render: {time_label: "{stopwatch[fal]}"}\n'
    with pytest.raises(SceneError) as error:
        scene(text)
    assert "unknown stopwatch 'fal'; did you mean 'fall'?" in str(error.value)
