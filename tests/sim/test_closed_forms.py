"""Motion checked against closed-form solutions: projectile, damped oscillator, linear/quadratic/Stokes drag, wind."""

from __future__ import annotations

import numpy as np
import pytest

from support.scenarios import oscillator_exact, oscillator_scene
from support.scenes import ADAPTIVE, FIXED_STEP, body, run

G = 9.81


def projectile(method: str, dt: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    solver = f"{{method: {method}, rtol: 1.0e-10, atol: 1.0e-12}}" if dt is None else f"{{method: {method}, dt: {dt}}}"
    _, trajectory = run(f"""
        duration: 1.5
        fps: 20
        solver: {solver}
        bodies: [{{name: ball, position: [1, 2, 3], velocity: [3, 7, -1]}}]
        fields: [{{type: gravity, g: [0, -9.81, 0]}}]
    """)
    x, v = body(trajectory, "ball")
    return trajectory.times, x, v


def projectile_exact(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.stack([1 + 3 * t, 2 + 7 * t - 0.5 * G * t**2, 3 - t], axis=1)
    v = np.stack([np.full_like(t, 3.0), 7 - G * t, np.full_like(t, -1.0)], axis=1)
    return x, v


@pytest.mark.parametrize("method", ADAPTIVE)
def test_projectile_adaptive_methods_follow_the_parabola(method):
    """Every adaptive method reproduces x = x0 + v0 t + g t²/2 at every frame."""
    t, x, v = projectile(method)
    x_exact, v_exact = projectile_exact(t)
    assert np.allclose(x, x_exact, atol=1e-7, rtol=0)
    assert np.allclose(v, v_exact, atol=1e-7, rtol=0)


@pytest.mark.parametrize("method", ["midpoint", "verlet"])
def test_second_order_fixed_step_methods_are_exact_under_constant_acceleration(method):
    """Midpoint and Verlet integrate a constant acceleration exactly (to round-off)."""
    t, x, v = projectile(method, dt=0.01)
    x_exact, v_exact = projectile_exact(t)
    assert np.allclose(x, x_exact, atol=1e-11, rtol=0)
    assert np.allclose(v, v_exact, atol=1e-11, rtol=0)


@pytest.mark.parametrize("method, sign", [("euler", +1), ("symplectic_euler", -1)])
def test_euler_variants_have_their_known_projectile_error(method, sign):
    """Explicit Euler lags the parabola by exactly +g h t / 2 in height, semi-implicit Euler leads by -g h t / 2."""
    h = 0.01  # divides 1/20 s, so it is the step actually used
    t, x, v = projectile(method, dt=h)
    x_exact, v_exact = projectile_exact(t)
    assert np.allclose(x[:, 1] - x_exact[:, 1], sign * G * h * t / 2, atol=1e-11)
    assert np.allclose(v, v_exact, atol=1e-11)
    assert np.allclose(x[:, [0, 2]], x_exact[:, [0, 2]], atol=1e-11)


# ------------------------------------------------------------------ damped oscillator


@pytest.mark.parametrize("zeta", [0.1, 1.0, 2.5], ids=["under-damped", "critically-damped", "over-damped"])
def test_damped_oscillator_matches_closed_form(zeta):
    """The spring-damper law of the notes gives x(t) of the under-, critically and over-damped oscillator."""
    _, trajectory = run(oscillator_scene(zeta))
    x, _ = body(trajectory, "mass")
    exact = oscillator_exact(trajectory.times, 0.2, np.sqrt(50.0 / 2.0), zeta)
    assert np.allclose(x[:, 0] - 1.0, exact, atol=1e-8, rtol=0)
    assert np.allclose(x[:, 1:], 0.0, atol=1e-12)


def test_under_damped_oscillator_period_and_decay():
    """Successive maxima are one damped period apart and shrink by exp(-ζ ω T_d)."""
    zeta, omega = 0.1, 5.0
    _, trajectory = run(oscillator_scene(zeta, fps=200, duration=3.0))
    x, _ = body(trajectory, "mass")
    u = x[:, 0] - 1.0
    peaks = [i for i in range(1, len(u) - 1) if u[i] > u[i - 1] and u[i] >= u[i + 1]]
    period = 2 * np.pi / (omega * np.sqrt(1 - zeta**2))
    t = trajectory.times
    assert t[peaks[1]] - t[peaks[0]] == pytest.approx(period, abs=1 / 200)
    assert u[peaks[1]] / u[peaks[0]] == pytest.approx(np.exp(-zeta * omega * period), rel=2e-3)


def test_vertical_spring_settles_at_rest_length_plus_mg_over_k():
    """A damped mass hanging from a spring comes to rest m g / k below the spring's rest length."""
    _, trajectory = run("""
        duration: 20
        fps: 5
        solver: {method: LSODA, rtol: 1.0e-9, atol: 1.0e-11}
        anchors: [{name: top, position: [0, 3, 0]}]
        bodies: [{name: bob, mass: 0.5, position: [0, 2, 0]}]
        springs: [{between: [top, bob], stiffness: 20, damping: 3, rest_length: 1.0}]
        fields: [{type: gravity}]
    """)
    x, v = body(trajectory, "bob")
    assert x[-1, 1] == pytest.approx(3 - 1.0 - 0.5 * G / 20, abs=1e-7)
    assert np.abs(v[-1]).max() < 1e-6


# ------------------------------------------------------------------ drag


def test_linear_drag_matches_closed_form_and_reaches_terminal_velocity():
    """v(t) = v_t + (v0 - v_t) e^{-Ct/m} with v_t = m g / C, and x(t) its integral."""
    mass, c = 0.5, 0.8
    _, trajectory = run(f"""
        duration: 8
        fps: 10
        solver: {{method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}}
        bodies: [{{name: ball, mass: {mass}, position: [0, 10, 0], velocity: [4, 3, 0]}}]
        fields:
          - {{type: gravity}}
          - {{type: drag, model: linear, coefficient: {c}}}
    """)
    x, v = body(trajectory, "ball")
    t = trajectory.times[:, None]
    v_terminal = np.array([0.0, -mass * G / c, 0.0])
    v0, x0, tau = np.array([4.0, 3.0, 0.0]), np.array([0.0, 10.0, 0.0]), mass / c
    decay = np.exp(-t / tau)
    assert np.allclose(v, v_terminal + (v0 - v_terminal) * decay, atol=1e-8)
    assert np.allclose(x, x0 + v_terminal * t + (v0 - v_terminal) * tau * (1 - decay), atol=1e-8)
    # the last frame (7.9 s) is 12.6 time constants in: the speed is within e^-12.6 ≈ 3e-6 of terminal
    assert np.abs(v[-1] - v_terminal).max() < 1e-4 * np.linalg.norm(v_terminal)


def test_quadratic_drag_fall_from_rest():
    """Falling from rest with f = -C|v|v: v = -v_t tanh(g t / v_t), y = y0 - (v_t²/g) ln cosh(g t / v_t)."""
    mass, c = 0.3, 0.02
    _, trajectory = run(f"""
        duration: 4
        fps: 20
        solver: {{method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}}
        bodies: [{{name: ball, mass: {mass}, position: [0, 100, 0]}}]
        fields: [{{type: gravity}}, {{type: drag, model: quadratic, coefficient: {c}}}]
    """)
    x, v = body(trajectory, "ball")
    t = trajectory.times
    v_terminal = np.sqrt(mass * G / c)
    assert np.allclose(v[:, 1], -v_terminal * np.tanh(G * t / v_terminal), atol=1e-8)
    assert np.allclose(x[:, 1], 100 - v_terminal**2 / G * np.log(np.cosh(G * t / v_terminal)), atol=1e-8)


def test_stokes_drag_uses_six_pi_eta_r():
    """Stokes drag on a sphere of radius r in a fluid of viscosity η is linear drag with C = 6 π η r."""
    mass, radius, eta = 0.01, 0.02, 0.05
    c = 6 * np.pi * eta * radius
    _, trajectory = run(f"""
        duration: 3
        fps: 10
        solver: {{method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}}
        bodies: [{{name: bead, mass: {mass}, radius: {radius}}}]
        fields: [{{type: gravity}}, {{type: drag, model: stokes, viscosity: {eta}}}]
    """)
    _, v = body(trajectory, "bead")
    t = trajectory.times
    v_terminal = mass * G / c
    assert np.allclose(v[:, 1], -v_terminal * (1 - np.exp(-c * t / mass)), atol=1e-9)


def test_wind_drives_a_particle_to_the_wind_velocity():
    """Linear drag relative to wind w: v(t) = w + (v0 - w) e^{-Ct/m}."""
    wind = np.array([5.0, 0.0, -2.0])
    _, trajectory = run("""
        duration: 3
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}
        bodies: [{name: leaf, mass: 0.1, velocity: [0, 1, 0]}]
        fields: [{type: wind, velocity: [5, 0, -2], model: linear, coefficient: 0.2}]
    """)
    _, v = body(trajectory, "leaf")
    t = trajectory.times[:, None]
    assert np.allclose(v, wind + (np.array([0.0, 1.0, 0.0]) - wind) * np.exp(-2.0 * t), atol=1e-9)


def test_quadratic_wind_relative_speed_decays_as_one_over_t():
    """With f = -C|u|u for u = v - w, the relative speed is u0 / (1 + C u0 t / m)."""
    _, trajectory = run("""
        duration: 2
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}
        bodies: [{name: kite, mass: 0.5}]
        fields: [{type: wind, velocity: [0, 0, 6], coefficient: 0.25}]
    """)
    _, v = body(trajectory, "kite")
    t = trajectory.times
    relative = -6.0 / (1 + 0.25 * 6.0 * t / 0.5)
    assert np.allclose(v[:, 2] - 6.0, relative, atol=1e-9)
    assert np.allclose(v[:, :2], 0.0, atol=1e-12)


def test_drag_acts_only_on_the_bodies_it_selects():
    """A field with 'bodies:' leaves the other bodies on their vacuum parabola."""
    _, trajectory = run("""
        duration: 1
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-12}
        bodies:
          - {name: free, velocity: [3, 3, 0]}
          - {name: slowed, velocity: [3, 3, 0], position: [0, 0, 1]}
        fields:
          - {type: gravity}
          - {type: drag, model: linear, coefficient: 0.5, bodies: [slowed]}
    """)
    free, _ = body(trajectory, "free")
    slowed, _ = body(trajectory, "slowed")
    t = trajectory.times
    assert np.allclose(free[:, 1], 3 * t - 0.5 * G * t**2, atol=1e-9)
    assert np.all(slowed[1:, 0] < free[1:, 0] - 1e-3)


@pytest.mark.parametrize("method", FIXED_STEP)
def test_fixed_step_methods_land_frames_on_exact_frame_times(method):
    """A step that does not divide 1/fps is shrunk so frames fall on steps; frames are exactly at k/fps."""
    model, trajectory = run("""
        duration: 1
        fps: 24
        bodies: [{name: ball, velocity: [1, 0, 0]}]
    """, f"solver.method={method}", "solver.dt=0.007")
    assert np.array_equal(trajectory.times, np.arange(24) / 24)
    stats = trajectory.solver_stats
    assert stats["dt"] <= 0.007 and stats["substeps_per_frame"] == 6
    assert stats["dt"] == pytest.approx(1 / 24 / 6)
    x, _ = body(trajectory, "ball")
    assert np.allclose(x[:, 0], trajectory.times, atol=1e-12)  # uniform motion is exact for every method
