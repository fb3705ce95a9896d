"""Proper-time clocks, dτ = dt √(1 − v²/c²), against their closed forms: at rest, at constant speed, on a circle
and under constant acceleration; carried through trajectory files, quantities.csv and the overlay."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import SceneError, SimulationError
from animbatch.stages import quantity_series
from animbatch.trajectory import Trajectory
from support.scenes import ADAPTIVE, FIXED_STEP, run, scene


def clock(trajectory: Trajectory, name: str) -> np.ndarray:
    return trajectory.proper_times[:, trajectory.clock_names.index(name)]


def twins(solver: str) -> Trajectory:
    _, trajectory = run(f"""
        duration: 4
        fps: 10
        solver: {solver}
        clocks: {{c: 1.0}}
        bodies:
          - {{name: home}}
          - {{name: traveller, position: [0, 1, 0], velocity: [0.6, 0, 0.0]}}
          - {{name: crate, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 100, velocity: [0, 0.8, 0],
             angular_velocity: [0, 0, 3]}}
    """)
    return trajectory


@pytest.mark.slow
@pytest.mark.parametrize("solver", [f"{{method: {m}}}" for m in ADAPTIVE] + [f"{{method: {m}, dt: 0.01}}"
                                                                           for m in FIXED_STEP])
def test_a_clock_at_rest_keeps_coordinate_time_and_one_moving_steadily_runs_slow_by_gamma(solver):
    """β = 0.6 gives γ = 1.25, so τ = 0.8 t; a rigid body at β = 0.8 (spinning, which does not matter) τ = 0.6 t."""
    trajectory = twins(solver)
    t = trajectory.times
    np.testing.assert_allclose(clock(trajectory, "home"), t, atol=1e-12)
    np.testing.assert_allclose(clock(trajectory, "traveller"), 0.8 * t, atol=1e-12)
    np.testing.assert_allclose(clock(trajectory, "crate"), 0.6 * t, atol=1e-12)


def test_a_clock_on_a_circle_runs_slow_by_the_lorentz_factor_of_its_speed():
    """A charge circling in a magnetic field keeps its speed (here β = 0.5 with c = 2 m/s): τ = t / γ,
    γ = 1/√(1 − β²) = 1.1547."""
    _, trajectory = run("""
        duration: 6.3
        fps: 20
        solver: {method: DOP853, rtol: 1.0e-12, atol: 1.0e-14}
        clocks: {c: 2.0}
        bodies: [{name: ion, mass: 0.5, charge: 0.5, velocity: [1, 0, 0]}]
        fields: [{type: electromagnetic, B: [0, 0, 1]}]
    """)
    gamma = 1 / np.sqrt(1 - 0.5**2)
    np.testing.assert_allclose(clock(trajectory, "ion"), trajectory.times / gamma, atol=1e-10)


def accelerated(solver: str) -> tuple[np.ndarray, np.ndarray]:
    """From rest under a = 1 m/s² with c = 5 m/s, up to v = 4 m/s (β = 0.8)."""
    _, trajectory = run(f"""
        duration: 4
        fps: 10
        solver: {solver}
        clocks: {{c: 5.0}}
        bodies: [{{name: rocket}}]
        fields: [{{type: gravity, g: [1, 0, 0]}}]
    """)
    return trajectory.times, clock(trajectory, "rocket")


def accelerated_exact(t: np.ndarray, a: float = 1.0, c: float = 5.0) -> np.ndarray:
    """τ = ∫₀ᵗ √(1 − (a s / c)²) ds = (c / 2a) (β √(1 − β²) + arcsin β), β = a t / c."""
    beta = a * t / c
    return c / (2 * a) * (beta * np.sqrt(1 - beta**2) + np.arcsin(beta))


def test_a_clock_under_constant_acceleration_follows_the_closed_form_integral():
    t, tau = accelerated("{method: DOP853, rtol: 1.0e-12, atol: 1.0e-14}")
    np.testing.assert_allclose(tau, accelerated_exact(t), atol=1e-10)


@pytest.mark.parametrize("method, order", [("verlet", 2), ("symplectic_euler", 1), ("midpoint", 2)])
def test_fixed_step_methods_advance_the_clock_at_their_order(method, order):
    errors = [np.abs(accelerated(f"{{method: {method}, dt: {dt}}}")[1][-1] - accelerated_exact(np.array(3.9))).max()
              for dt in (0.02, 0.01)]
    assert errors[0] / errors[1] == pytest.approx(2**order, rel=0.15)


def test_a_body_reaching_the_speed_of_light_stops_the_run_naming_it():
    with pytest.raises(SimulationError) as error:
        run("""
            duration: 2
            clocks: {c: 1.0}
            bodies: [{name: probe}]
            fields: [{type: gravity, g: [1, 0, 0]}]
        """)
    assert "'probe'" in str(error.value) and "speed of light c = 1" in str(error.value)
    assert "clocks.c" in str(error.value)


def test_proper_times_travel_in_trajectory_files_and_quantities_csv(tmp_path):
    loaded = scene("""
        duration: 1
        fps: 10
        clocks: {c: 1.0, bodies: [traveller]}
        bodies: [{name: home}, {name: traveller, velocity: [0.6, 0, 0]}]
        render: {time_label: "{proper_time[traveller]:.2f}"}
    """)
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    assert trajectory.clock_names == ("traveller",)
    back = Trajectory.load(trajectory.save(tmp_path / "run.npz"))
    np.testing.assert_array_equal(back.proper_times, trajectory.proper_times)
    csv = quantity_series(model, back).csv().splitlines()
    assert csv[0].endswith(",proper_time_traveller_s")
    assert float(csv[-1].split(",")[-1]) == pytest.approx(0.8 * 0.9)
    label = api.frame_geometry(api.plan(loaded, model=model), trajectory).label
    assert label.at(0.5)["proper_time"]["traveller"] == pytest.approx(0.4)


def test_scenes_without_clocks_carry_no_proper_time():
    model, trajectory = run("bodies: [{name: a}]\nduration: 0.2")
    assert model.clocks is None and not model.layout.has("proper_time") and trajectory.proper_times is None


@pytest.mark.parametrize("text, fragment", [
    ("clocks: {bodies: [travler]}", "unknown body 'travler'; did you mean 'traveller'?"),
    ('render: {time_label: "{proper_time[traveller]}"}', "no body carries a clock; add 'clocks: {}'"),
    ('clocks: {bodies: [home]}\nrender: {time_label: "{proper_time[traveller]}"}', "'traveller' carries no clock"),
    ("clocks: {c: 0}", "clocks.c: must be > 0 m/s"),
])
def test_bad_clocks_are_refused_with_the_fix(text, fragment):
    with pytest.raises(SceneError) as error:
        scene("duration: 1\nbodies: [{name: home}, {name: traveller}]\n" + text)
    assert fragment in str(error.value) and "test.yaml:" in str(error.value)
