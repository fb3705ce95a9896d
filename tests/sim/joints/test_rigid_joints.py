"""Joints on rigid bodies (issue 22): ball joints, hinges (limits, motors), sliders (limits), welds and ropes, against
closed forms (physical pendulum, servo responses, a slide down an incline, free fall on a slack rope) and
invariants (energy, the vertical angular momentum of a top, the joints' drift)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipk

from animbatch import api
from animbatch.errors import AccuracyWarning
from animbatch.quaternion import to_matrix
from animbatch.stages import quantity_series
from support.scenes import scene

G = 9.81
ACCURATE = "{method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}"
# a bar 1 m long, 2 cm square, of water: mass 0.4 kg
BAR_LENGTH, BAR_WIDTH, BAR_DENSITY = 1.0, 0.02, 1000.0
BAR_MASS = BAR_DENSITY * BAR_LENGTH * BAR_WIDTH**2


def _v(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def hinged_bar(amplitude_deg: float, solver: str, duration: float = 6.0, extra: str = "") -> tuple:
    """A bar hanging from a hinge at its top end (world origin), released at rest ``amplitude_deg`` from the
    vertical; the stopwatch times a period between passes through the bottom moving +x."""
    theta = np.radians(amplitude_deg)
    centre = 0.5 * BAR_LENGTH * np.array([np.sin(theta), -np.cos(theta), 0.0])
    loaded = scene(f"""
        duration: {duration}
        fps: 50
        solver: {solver}
        bodies:
          - {{name: bar, type: rigid, shape: {{type: box, size: [{BAR_WIDTH}, {BAR_LENGTH}, {BAR_WIDTH}]}},
              density: {BAR_DENSITY}, position: {_v(centre)}, orientation: {{axis: [0, 0, 1], angle: {amplitude_deg}}}}}
        joints: [{{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]{extra}}}]
        fields: [{{type: gravity}}]
        stopwatches:
          - name: period
            start: {{body: bar, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
            stop: {{body: bar, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
    """)
    trajectory = api.simulate(loaded)
    (reading,) = api.stopwatch_readings(loaded.spec.stopwatches, trajectory)
    return trajectory, reading.elapsed, loaded


def physical_pendulum_period(amplitude_deg: float) -> float:
    """T = 4 √(I / (m g d)) K(sin²(θ₀/2)) for the bar about its end: I = m (L² + w²)/12 + m (L/2)², d = L/2."""
    inertia = (BAR_LENGTH**2 + BAR_WIDTH**2) / 12 + (BAR_LENGTH / 2) ** 2  # per unit mass
    return 4 * np.sqrt(inertia / (G * BAR_LENGTH / 2)) * ellipk(np.sin(np.radians(amplitude_deg) / 2) ** 2)


@pytest.mark.slow
@pytest.mark.parametrize("amplitude", [5.0, 120.0])
def test_a_bar_on_a_hinge_swings_with_the_physical_pendulums_period(amplitude):
    trajectory, period, loaded = hinged_bar(amplitude, ACCURATE)
    assert period == pytest.approx(physical_pendulum_period(amplitude), rel=1e-7)
    assert trajectory.ledger["joints"]["max_violation"] < 1e-9
    assert trajectory.ledger["conservation"]["energy"]["drift"] < 1e-8


@pytest.mark.slow
@pytest.mark.parametrize("method, dt, order", [("verlet", 2e-3, 2), ("symplectic_euler", 1e-3, 1),
                                              ("backward_euler", 1e-3, 1)])
def test_fixed_step_methods_hold_the_hinge_exactly_and_any_energy_change_is_their_error(method, dt, order):
    """Projected after every step (or, under Verlet, stepped in its angle), the hinge holds to rounding; the energy
    wanders by the method's error, which shrinks as dt^order (backward Euler steps rigid bodies by semi-implicit
    Euler, so it shares its order). Verlet on the angle loses energy rather than gaining it: the wander, not the
    gain, is what is measured."""
    rises = []
    for step in (dt, dt / 2):
        trajectory, period, loaded = hinged_bar(60.0, f"{{method: {method}, dt: {step}}}", duration=4.0)
        assert trajectory.ledger["joints"]["max_violation"] < 1e-12
        assert period == pytest.approx(physical_pendulum_period(60.0), rel=30 * step**order)
        total = quantity_series(api.compile_scene(loaded.spec), trajectory).total
        rises.append(max(float(np.max(np.abs(total - total[0]))), 1e-12))
    assert rises[1] < 1.2 * rises[0] / 2**order
    omega = 2 * np.pi / physical_pendulum_period(60.0)
    assert rises[0] < 10 * (omega * dt) ** order * BAR_MASS * G * BAR_LENGTH / 2  # of the energy's scale


def test_a_hanging_bar_is_held_by_its_weight_and_a_welded_cantilever_by_its_bending_moment():
    trajectory, _, _ = hinged_bar(0.0, ACCURATE, duration=0.5)
    np.testing.assert_allclose(trajectory.joint_forces[:, 0], np.tile([0, BAR_MASS * G, 0], (len(trajectory.times), 1)),
                               atol=1e-9)
    np.testing.assert_allclose(trajectory.joint_torques[:, 0], 0, atol=1e-9)
    loaded = scene(f"""
        duration: 1
        solver: {ACCURATE}
        bodies:
          - {{name: beam, type: rigid, shape: {{type: box, size: [{BAR_LENGTH}, {BAR_WIDTH}, {BAR_WIDTH}]}},
              density: {BAR_DENSITY}, position: [0.5, 0, 0]}}
        joints: [{{type: fixed, between: [beam], anchor: [0, 0, 0]}}]
        fields: [{{type: gravity}}]
    """)
    beam = api.simulate(loaded)
    np.testing.assert_allclose(beam.positions[:, 0], np.tile([0.5, 0, 0], (len(beam.times), 1)), atol=1e-9)
    np.testing.assert_allclose(beam.joint_forces[:, 0], np.tile([0, BAR_MASS * G, 0], (len(beam.times), 1)), atol=1e-9)
    # the wall holds the beam's weight at half its length from the wall: M = m g L/2, turning it up (+z)
    np.testing.assert_allclose(beam.joint_torques[:, 0], np.tile([0, 0, BAR_MASS * G * 0.5], (len(beam.times), 1)), atol=1e-9)
    # a caller that reads no reactions (grading) can skip them: the same motion, no reactions
    from animbatch import stages

    bare = stages.simulate(loaded, reactions=False)
    assert bare.joint_forces is None and bare.joint_torques is None
    np.testing.assert_array_equal(bare.positions, beam.positions)


@pytest.mark.slow
def test_a_chaotic_double_pendulum_of_hinged_bars_keeps_its_energy_and_joints():
    loaded = scene("""
        duration: 20
        fps: 25
        solver: {method: DOP853, rtol: 1.0e-8, atol: 1.0e-10}
        bodies:
          - {name: upper, type: rigid, shape: {type: box, size: [1, 0.04, 0.04]}, density: 500,
              position: [0.5, 0, 0]}
          - {name: lower, type: rigid, shape: {type: box, size: [1, 0.04, 0.04]}, density: 500,
              position: [1.5, 0, 0]}
        joints:
          - {type: hinge, between: [upper], anchor: [0, 0, 0], axis: [0, 0, 1]}
          - {type: hinge, between: [lower, upper], anchor: [1, 0, 0], axis: [0, 0, 1]}
        fields: [{type: gravity}]
    """)
    trajectory = api.simulate(loaded)
    joints = trajectory.ledger["joints"]
    assert joints["max_violation"] < 1e-6 and joints["max_angle_violation"] < 1e-6
    energy = trajectory.ledger["conservation"]["energy"]
    assert energy["conserved"] and energy["drift"] < 1e-6 * energy["scale"]
    assert np.ptp(trajectory.positions[:, 1, 1]) > 1.0  # it really swung


@pytest.mark.slow
def test_a_heavy_top_on_a_ball_joint_keeps_its_energy_and_its_vertical_angular_momentum():
    """A spinning disc on a ball joint, its axis tilted: gravity's torque about the pivot is horizontal, so the
    vertical component of the angular momentum about the pivot stays, as does the energy."""
    tilt = np.radians(30)
    axis = np.array([np.sin(tilt), np.cos(tilt), 0.0])
    spin = 60.0
    centre = 0.3 * axis
    loaded = scene(f"""
        duration: 2
        fps: 50
        solver: {{method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}}
        bodies:
          - {{name: top, type: rigid, shape: {{type: cylinder, radius: 0.2, length: 0.04}}, density: 800,
              position: {_v(centre)}, orientation: {{euler: [-90, 0, -30]}},
              angular_velocity: {_v(spin * axis)}}}
        joints: [{{type: ball, between: [top], anchor: [0, 0, 0]}}]
        fields: [{{type: gravity}}]
    """)
    model = api.compile_scene(loaded.spec)
    rigid = model.rigid
    trajectory = api.simulate(loaded, model=model)
    rotation = to_matrix(trajectory.orientations[:, 0])
    inertia = rotation @ rigid.inertia[0] @ np.transpose(rotation, (0, 2, 1))
    spin_momentum = np.einsum("fij,fj->fi", inertia, trajectory.angular_velocities[:, 0])
    mass = float(rigid.mass[0])
    about_pivot = spin_momentum + mass * np.cross(trajectory.positions[:, 0], trajectory.velocities[:, 0])
    assert np.ptp(about_pivot[:, 1]) < 1e-7 * np.abs(about_pivot[0]).max()
    assert np.ptp(about_pivot[:, 0]) > 1e-3 * np.abs(about_pivot[0]).max()  # it precesses
    np.testing.assert_allclose(np.linalg.norm(trajectory.positions[:, 0], axis=1), 0.3, atol=1e-9)
    energy = trajectory.ledger["conservation"]["energy"]
    assert energy["drift"] < 1e-8 * energy["scale"]


def wheel(motor: str, duration: float = 2.0) -> tuple:
    """A disc (radius 0.2 m, 5 cm thick, of water) on a hinge about its own axis, no gravity, driven by ``motor``;
    returns the trajectory, its angle θ(t) [rad] and its moment of inertia [kg·m²]."""
    loaded = scene(f"""
        duration: {duration}
        fps: 50
        solver: {ACCURATE}
        bodies: [{{name: disc, type: rigid, shape: {{type: cylinder, radius: 0.2, length: 0.05}}, density: 1000}}]
        joints: [{{type: hinge, between: [disc], axis: [0, 0, 1], motor: {motor}}}]
    """)
    trajectory = api.simulate(loaded)
    q = trajectory.orientations[:, 0]
    angle = np.unwrap(2 * np.arctan2(q[:, 3], q[:, 0]))
    mass = 1000 * np.pi * 0.2**2 * 0.05
    return trajectory, angle, 0.5 * mass * 0.2**2


def test_a_hinge_motor_reaches_its_target_angle_along_the_critically_damped_response():
    inertia = 0.5 * 1000 * np.pi * 0.2**2 * 0.05 * 0.2**2
    omega = 6.0  # rad/s: stiffness I ω², damping 2 I ω
    trajectory, angle, _ = wheel(f"{{target: 1.0, stiffness: {inertia * omega**2!r}, damping: {2 * inertia * omega!r}}}")
    t = trajectory.times
    np.testing.assert_allclose(angle, 1.0 * (1 - (1 + omega * t) * np.exp(-omega * t)), atol=1e-8)
    assert trajectory.motor_efforts.shape == (len(t), 1)
    assert trajectory.ledger["joints"]["max_angle_violation"] < 1e-9


def test_a_speed_servo_spins_up_exponentially_and_a_torque_limit_caps_its_acceleration():
    inertia = 0.5 * 1000 * np.pi * 0.2**2 * 0.05 * 0.2**2
    damping = 2 * inertia
    trajectory, angle, _ = wheel(f"{{speed: 3.0, damping: {damping!r}}}")
    t = trajectory.times
    spin = trajectory.angular_velocities[:, 0, 2]
    np.testing.assert_allclose(spin, 3.0 * (1 - np.exp(-damping * t / inertia)), atol=1e-8)
    limited, angle, _ = wheel(f"{{speed: 3.0, damping: {100 * inertia!r}, max_torque: {0.5 * inertia!r}}}")
    early = limited.times <= 1.0  # 0.5 rad/s² for 6 s would be needed: it is limited throughout
    np.testing.assert_allclose(angle[early], 0.25 * limited.times[early] ** 2, atol=1e-8)
    np.testing.assert_allclose(limited.motor_efforts[early, 0], 0.5 * inertia, rtol=1e-12)


def sliding_box(solver: str, extra: str = "", duration: float = 1.0) -> tuple:
    """A 1 kg box on a slider down a frictionless 30° incline (the axis points down the slope), under gravity."""
    slope = np.radians(30)
    down = np.array([np.cos(slope), -np.sin(slope), 0.0])
    loaded = scene(f"""
        duration: {duration}
        fps: 50
        solver: {solver}
        bodies: [{{name: box, type: rigid, shape: {{type: box, size: [0.1, 0.1, 0.1]}}, mass: 1.0,
                  orientation: {{axis: [0, 0, 1], angle: -30}}}}]
        joints: [{{type: slider, between: [box], axis: {_v(down)}{extra}}}]
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    return trajectory, trajectory.positions[:, 0] @ down, down


def test_a_box_on_a_slider_down_an_incline_accelerates_at_g_sin_theta_held_by_the_normal_force():
    trajectory, travel, down = sliding_box(ACCURATE)
    t = trajectory.times
    np.testing.assert_allclose(travel, 0.5 * G * np.sin(np.radians(30)) * t**2, atol=1e-8)
    across = trajectory.positions[:, 0] - np.outer(travel, down)
    np.testing.assert_allclose(across, 0, atol=1e-8)
    normal = np.array([np.sin(np.radians(30)), np.cos(np.radians(30)), 0.0])
    np.testing.assert_allclose(trajectory.joint_forces[:, 0], np.outer(np.full(len(t), G * np.cos(np.radians(30))),
                                                                        normal), atol=1e-5)
    np.testing.assert_allclose(trajectory.angular_velocities[:, 0], 0, atol=1e-9)  # it does not turn


@pytest.mark.parametrize("solver, slop", [(ACCURATE, 1e-7), ("{method: verlet, dt: 0.001}", 1e-9)])
def test_slider_limits_stop_the_box(solver, slop):
    trajectory, travel, _ = sliding_box(solver, ", limits: [-0.1, 0.5]", duration=1.5)
    assert travel.max() <= 0.5 + slop  # adaptive methods stop at the instant of reaching it (an event)
    assert travel[-1] == pytest.approx(0.5, abs=1e-3)  # and it rests against the stop
    assert travel[5] == pytest.approx(0.5 * G * 0.5 * trajectory.times[5] ** 2, abs=1e-6)  # free before


@pytest.mark.slow
@pytest.mark.parametrize("solver, slop", [(ACCURATE, 1e-7), ("{method: verlet, dt: 0.001}", 1e-9)])
def test_hinge_limits_stop_the_swing(solver, slop):
    trajectory, _, _ = hinged_bar(0.0, solver, duration=2.0, extra=", limits: [-0.5, 0.5]")
    assert np.all(np.abs(trajectory.orientations[:, 0, 3]) < 1e-12)  # at rest it stays at rest, inside the limits
    loaded = scene(f"""
        duration: 2
        fps: 50
        solver: {solver}
        bodies:
          - {{name: bar, type: rigid, shape: {{type: box, size: [{BAR_WIDTH}, {BAR_LENGTH}, {BAR_WIDTH}]}},
              density: {BAR_DENSITY}, position: [0, -0.5, 0], velocity: [3, 0, 0], angular_velocity: [0, 0, 6]}}
        joints: [{{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1], limits: [-0.5, 0.5]}}]
        fields: [{{type: gravity}}]
    """)
    swing = api.simulate(loaded)
    q = swing.orientations[:, 0]
    angle = 2 * np.arctan2(q[:, 3], q[:, 0])
    assert angle.max() <= 0.5 + slop  # without the limit it would swing past 1.6 rad
    assert angle.max() > 0.5 - 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("solver, slop", [(ACCURATE, 1e-7), ("{method: verlet, dt: 0.001}", 1e-9)])
def test_a_weight_on_a_slack_rope_falls_freely_until_the_rope_is_taut(solver, slop):
    loaded = scene(f"""
        duration: 1.5
        fps: 100
        solver: {solver}
        anchors: [{{name: hook, position: [0, 0, 0]}}]
        bodies: [{{name: weight, mass: 2.0, position: [0, -0.5, 0], velocity: [0.5, 0, 0]}}]
        joints: [{{type: rope, between: [hook, weight], length: 1.0}}]
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    t, position = trajectory.times, trajectory.positions[:, 0]
    distance = np.linalg.norm(position, axis=1)
    free = distance < 1.0 - 1e-6
    taut_at = t[np.argmin(free)]  # the first frame it is taut
    falling = t < taut_at - 0.01
    np.testing.assert_allclose(position[falling, 1], -0.5 - 0.5 * G * t[falling] ** 2, atol=1e-9)
    # free fall from (0, −0.5) at 0.5 m/s sideways reaches the circle of radius 1 when x² + y² = 1
    from scipy.optimize import brentq
    expected = brentq(lambda s: (0.5 * s) ** 2 + (0.5 + 0.5 * G * s**2) ** 2 - 1.0, 0.0, 1.0)
    assert taut_at == pytest.approx(expected, abs=0.011)
    assert distance.max() <= 1.0 + slop
    assert trajectory.joint_forces[-1, 0] @ position[-1] < 0  # a rope pulls the weight towards the hook


def test_a_hinge_motor_tracks_keyframes_with_the_closed_form_lag():
    """Keyframes rising at ω₀ give the servo a target angle ω₀t and speed ω₀: critically damped, the error
    e = target − θ obeys I ë + c ė + k e = 0 from e(0) = 0, ė(0) = ω₀, so θ(t) = ω₀ t − ω₀ t e^(−ωt)."""
    inertia = 0.5 * 1000 * np.pi * 0.2**2 * 0.05 * 0.2**2
    omega, rate = 8.0, 1.5
    trajectory, angle, _ = wheel(f"{{target: [{{time: 0, value: 0}}, {{time: 3, value: {3 * rate}}}], "
                                 f"interpolation: linear, stiffness: {inertia * omega**2!r}, "
                                 f"damping: {2 * inertia * omega!r}}}", duration=2.0)
    t = trajectory.times
    np.testing.assert_allclose(angle, rate * t - rate * t * np.exp(-omega * t), atol=1e-7)


def test_a_slider_motor_drives_the_box_to_its_target_critically_damped():
    mass, omega = 1.0, 5.0
    loaded = scene(f"""
        duration: 2
        fps: 50
        solver: {ACCURATE}
        bodies: [{{name: box, type: rigid, shape: {{type: box, size: [0.1, 0.1, 0.1]}}, mass: {mass}}}]
        joints: [{{type: slider, between: [box], axis: [1, 0, 0],
                  motor: {{target: 0.3, stiffness: {mass * omega**2}, damping: {2 * mass * omega}}}}}]
    """)
    trajectory = api.simulate(loaded)
    t = trajectory.times
    np.testing.assert_allclose(trajectory.positions[:, 0, 0], 0.3 * (1 - (1 + omega * t) * np.exp(-omega * t)),
                               atol=1e-8)
    np.testing.assert_allclose(trajectory.positions[:, 0, 1:], 0, atol=1e-9)


@pytest.mark.slow
def test_bodies_joined_to_each_other_keep_their_momentum_angular_momentum_and_energy():
    """Two boxes on a ball joint, and a third welded to the second, thrown spinning with no forces: the joints are
    internal, so the total momentum and angular momentum stay, and they do no work."""
    loaded = scene(f"""
        duration: 3
        fps: 30
        solver: {ACCURATE}
        bodies:
          - {{name: a, type: rigid, shape: {{type: box, size: [0.4, 0.1, 0.1]}}, density: 1000, position: [-0.2, 0, 0],
              velocity: [0.3, 1.0, 0], angular_velocity: [0, 0, 2]}}
          - {{name: b, type: rigid, shape: {{type: box, size: [0.4, 0.1, 0.1]}}, density: 600, position: [0.2, 0, 0],
              velocity: [0, -0.5, 0.2], angular_velocity: [1, 0, -1]}}
          - {{name: c, type: rigid, shape: {{type: box, size: [0.1, 0.3, 0.1]}}, density: 900, position: [0.45, 0.1, 0]}}
        joints:
          - {{type: ball, between: [b, a], anchor: [0, 0, 0]}}
          - {{type: fixed, between: [c, b]}}
    """)
    model = api.compile_scene(loaded.spec)
    trajectory = api.simulate(loaded, model=model)
    series = quantity_series(model, trajectory)
    np.testing.assert_allclose(series.momentum, np.broadcast_to(series.momentum[0], series.momentum.shape),
                               atol=1e-9)
    np.testing.assert_allclose(series.angular_momentum,
                               np.broadcast_to(series.angular_momentum[0], series.angular_momentum.shape), atol=1e-8)
    assert np.ptp(series.total) < 1e-8 * abs(series.kinetic[0])
    assert trajectory.ledger["conservation"]["momentum"]["conserved"]
    joints = trajectory.ledger["joints"]
    assert joints["max_violation"] < 1e-8 and joints["max_angle_violation"] < 1e-8


def test_a_box_hung_by_a_rod_from_its_corner_rests_with_its_centre_under_the_hook():
    """A rod from a hook to a box's corner: at rest when the rod's line passes through the centre of mass; the rod
    then carries the weight."""
    tilt = np.degrees(np.arctan(np.sqrt(2)))  # turns the (1, 1, 1) corner diagonal onto the vertical
    loaded = scene(f"""
        duration: 1
        solver: {ACCURATE}
        anchors: [{{name: hook, position: [0, 1, 0]}}]
        bodies:
          - {{name: box, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, mass: 2.0,
              orientation: {{axis: [1, 0, -1], angle: {-tilt}}}, position: [0, {0.5 - np.sqrt(3) * 0.1}, 0]}}
        joints: [{{type: distance, between: [box, hook], attach: [[0.1, 0.1, 0.1], null]}}]
        fields: [{{type: gravity}}]
    """)
    corner = to_matrix(api.simulate(loaded).orientations[0, 0]) @ np.array([0.1, 0.1, 0.1])
    np.testing.assert_allclose(corner / np.linalg.norm(corner), [0, 1, 0], atol=1e-12)  # the setup is right
    trajectory = api.simulate(loaded)
    np.testing.assert_allclose(trajectory.positions[:, 0], np.broadcast_to(trajectory.positions[0, 0],
                                                                           trajectory.positions[:, 0].shape), atol=1e-9)
    np.testing.assert_allclose(trajectory.joint_forces[:, 0], np.tile([0, 2.0 * G, 0], (len(trajectory.times), 1)),
                               atol=1e-8)
    assert trajectory.ledger["joints"]["max_violation"] < 1e-9


@pytest.mark.slow
def test_bodies_a_joint_joins_do_not_collide_with_each_other():
    """Two boxes that overlap where a hinge joins them (as a door's edge sits in its frame): contact between them
    would fight the joint, so jointed pairs never touch; a third, free box still collides with them."""
    loaded = scene("""
        duration: 1
        solver: {method: symplectic_euler, dt: 1.0e-3}
        bodies:
          - {name: post, type: rigid, shape: {type: box, size: [0.2, 1, 0.2]}, density: 500, position: [0, 0.5, 0]}
          - {name: door, type: rigid, shape: {type: box, size: [0.8, 1, 0.05]}, density: 500,
             position: [0.45, 0.5, 0], angular_velocity: [0, 1, 0]}
          - {name: ball, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [0.6, 2.0, 0]}
        joints:
          - {type: fixed, between: [post]}
          - {type: hinge, between: [door, post], anchor: [0.05, 0.5, 0], axis: [0, 1, 0]}
        contacts: {}
        fields: [{type: gravity}]
    """)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)  # an overlap between the post and the door would warn
        trajectory = api.simulate(loaded)
    q = trajectory.orientations[:, 1]
    angle = 2 * np.arctan2(q[:, 2], q[:, 0])
    assert angle[-1] > 0.3  # the door turned through the post's corner, unhindered
    assert trajectory.ledger["joints"]["max_violation"] < 1e-12
    assert trajectory.solver_stats["impacts"]  # the ball still lands on the door


def test_choosing_force_arrows_without_showing_forces_is_an_error_with_the_fix():
    from animbatch.errors import SceneError

    with pytest.raises(SceneError) as error:
        scene("duration: 1\nbodies: [{name: a}]\nrender: {arrows: {forces: [joint]}}")
    assert "show (velocity) does not draw forces: add it, e.g. show: [forces]" in str(error.value)


@pytest.mark.slow
@pytest.mark.parametrize("weight, plank", [(5.0, 0.5), (50.0, 0.5), (100.0, 0.1)])
def test_joints_and_contacts_are_solved_together_so_a_weight_on_a_stalk_cannot_press_a_plank_through_the_floor(
        weight, plank):
    """A heavy ball stands on a stalk (a ball joint 0.28 m below its centre) on a light plank lying on the floor,
    at mass ratios of 10, 100 and 1000 to 1. Its weight reaches the plank only through the joint, and the floor
    holds the plank up. Solved one after the other (contacts, then joints), the joint won every step and the plank
    sank 9 cm through the floor at 10:1; alternating them within the contact solve still let it sink 8 cm at 100:1
    and 19 cm at 1000:1. Solved as one system (contacts moving the bodies within the joints, the jointed contacts'
    normals solved directly), it stays on the floor, within the contact slop, and the audit finds no overlap."""
    loaded = scene(f"""
        duration: 1.0
        fps: 20
        solver: {{method: symplectic_euler, dt: 5.0e-3}}
        bodies:
          - {{name: plank, type: rigid, shape: {{type: box, size: [0.6, 0.02, 0.3]}}, mass: {plank},
             position: [0, 0.01, 0]}}
          - {{name: weight, type: rigid, shape: {{type: sphere, radius: 0.1}}, mass: {weight}, position: [0, 0.3, 0]}}
        joints: [{{type: ball, between: [weight, plank], anchor: [0, 0.02, 0]}}]
        colliders: [{{type: plane}}]
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    assert trajectory.ledger["contacts"]["missed"] is None
    assert trajectory.positions[:, 0, 1].min() > 0.01 - 2e-3
    np.testing.assert_allclose(trajectory.positions[-1, 1], [0, 0.3, 0], atol=2e-3)  # standing, balanced


def test_the_rows_kept_for_velocity_projections_follow_the_positions_not_the_last_call():
    """The joints keep the rows of the last positions for the velocity-level uses of a contact step: asked again
    at new positions (a bar turned on its hinge, then moved off it, then turned about its centre) they give the rows
    there, as joints that never kept any do; and projected velocities hold the hinge point still at each."""
    from animbatch.compile.model import compile_scene
    from animbatch.sim.model.dynamics import Dynamics

    loaded = scene("""
        bodies:
          - {name: bar, type: rigid, shape: {type: box, size: [1.0, 0.05, 0.05]}, mass: 2, position: [0.5, 0, 0]}
        joints: [{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]}]
        fields: [{type: gravity}]
    """)
    states = []
    for angle, shift in ((0.0, 0.0), (0.7, 0.0), (0.7, 0.1), (0.9, 0.1)):  # turned, moved alone, turned alone
        turn = np.array([np.cos(angle / 2), 0, 0, np.sin(angle / 2)])
        model = compile_scene(loaded.spec)
        system = Dynamics(model)
        config, motion = system.split(np.array(model.y0, float))
        config[:3] = 0.5 * np.array([np.cos(0.7 if shift else angle), np.sin(0.7 if shift else angle), 0.0]) + shift
        config[3:7] = turn
        motion[:] = [0.3, -0.2, 0.1, 0.4, 0.5, 1.5]  # momentum and angular momentum that break the hinge
        states.append(system.kinematics(config, motion, copy=True))
    joints = Dynamics(compile_scene(loaded.spec)).joints
    assert joints is not None
    for state in states:
        fresh = Dynamics(compile_scene(loaded.spec)).joints
        np.testing.assert_array_equal(joints.velocity_rows(state, 2).toarray(), fresh.velocity_rows(state, 2).toarray())
        v, omega = state.v.copy(), state.omega.copy()
        joints.project_velocities(state, v, omega)
        lever = state.rotation[0] @ np.array([-0.5, 0, 0])  # from the centre to the bar's hinge point
        np.testing.assert_allclose(v[0] + np.cross(omega[0], lever), 0.0, atol=1e-12)
    # a bob on a rod: its row's direction follows the bob's position alone (a particle does not turn)
    rod = scene("""
        anchors: [{name: pivot, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 1.0, position: [1.0, 0, 0], velocity: [0.4, 0.3, 0]}]
        joints: [{type: distance, between: [pivot, bob]}]
    """)
    joints = Dynamics(compile_scene(rod.spec)).joints
    assert joints is not None
    for place in ([1.0, 0, 0], [0.6, -0.8, 0]):
        model = compile_scene(rod.spec)
        system = Dynamics(model)
        config, motion = system.split(np.array(model.y0, float))
        config[:3] = place
        state = system.kinematics(config, motion, copy=True)
        fresh = Dynamics(compile_scene(rod.spec)).joints
        np.testing.assert_array_equal(joints.velocity_rows(state, 1).toarray(), fresh.velocity_rows(state, 1).toarray())
        v = state.v.copy()
        joints.project_velocities(state, v, None)
        assert abs(v[0] @ np.array(place)) < 1e-12  # no speed along the rod


@pytest.mark.parametrize("method", ["symplectic_euler", "backward_euler"])
def test_a_jointed_body_pushed_out_of_an_overlap_leaves_at_rest(method):
    """Two bars on a ball joint, no gravity, the first started 8 mm into the floor: the split impulse pushes it out
    through positions only, and the joint brings the second along, so both end at rest with the first on the floor
    (within the slop). The one-kick methods' SHAKE projection turns a joint correction into momentum, as the drift's
    doing; after a push it must not (it set both bars moving, and the energy check stopped the run)."""
    trajectory = api.simulate(scene(f"""
        duration: 0.3
        fps: 100
        solver: {{method: {method}, dt: 1.0e-3}}
        bodies:
          - {{name: a, type: rigid, shape: {{type: box, size: [0.4, 0.04, 0.04]}}, mass: 0.5, position: [0.2, 0.012, 0]}}
          - {{name: b, type: rigid, shape: {{type: box, size: [0.4, 0.04, 0.04]}}, mass: 0.5, position: [0.6, 0.3, 0]}}
        joints:
          - {{type: ball, between: [a, b], anchor: [0.4, 0.156, 0]}}
        colliders: [{{type: plane}}]
    """))
    assert np.abs(trajectory.velocities).max() < 1e-9 and np.abs(trajectory.angular_velocities).max() < 1e-9
    bottom = trajectory.positions[-1, 0, 1] - 0.02
    assert -1.02e-4 <= bottom <= 1e-6  # out, down to the slop (1e-4 m; pushes stop within 1 % of it)
    assert trajectory.ledger["joints"]["max_violation"] < 1e-10


@pytest.mark.parametrize("compiled", [False, True], ids=["numpy", "compiled"])
def test_a_limit_pushed_past_its_stop_is_projected_onto_it_and_stops_there(compiled):
    """An elbow (a hinge with limits between two bars, the upper one hinged to the world) bent 0.3 rad past its
    lower stop, twisted 0.2 rad off its axis and still bending on at 2 rad/s: the projection puts the limit back
    on its stop to the joints' tolerance (not merely inside it, where neither the velocity part of the projection
    nor the next contact solve counts it as reached, and a limb pressed by a contact at its limit went past it
    and was pulled back into the collider every step) and takes out the bending rate: an inelastic stop."""
    from animbatch import quaternion
    from animbatch.sim.kernels import stepper
    from animbatch.sim.model.compiled import CompiledDynamics
    from animbatch.sim.model.dynamics import Dynamics

    loaded = scene(f"""
        duration: 0.1
        fps: 10
        solver: {{method: verlet, dt: 0.001}}
        bodies:
          - {{name: upper, type: rigid, shape: {{type: box, size: [{BAR_WIDTH}, 0.3, {BAR_WIDTH}]}},
              density: {BAR_DENSITY}, position: [0, -0.15, 0]}}
          - {{name: lower, type: rigid, shape: {{type: box, size: [{BAR_WIDTH}, 0.3, {BAR_WIDTH}]}},
              density: {BAR_DENSITY}, position: [0, -0.45, 0]}}
        joints:
          - {{type: hinge, between: [upper], anchor: [0, 0, 0], axis: [0, 0, 1]}}
          - {{type: hinge, between: [lower, upper], anchor: [0, -0.3, 0], axis: [0, 0, 1], limits: [-0.05, 2.4]}}
    """)
    model = api.compile_model(loaded)
    system = CompiledDynamics(model) if compiled else Dynamics(model)
    measure = CompiledDynamics(model)  # the rows at a state, whichever system projected it
    y = model.y0.copy()
    config, motion = system.split(y)
    positions, orientations = config[:6].reshape(2, 3), config[6:].reshape(2, 4)
    momenta, angular_momenta = motion[:6].reshape(2, 3), motion[6:].reshape(2, 3)
    elbow = np.array([0.0, -0.3, 0.0])
    turn = quaternion.from_rotation_vector(np.array([0.2, 0.0, -0.35]))  # past the stop at −0.05 rad, and twisted
    orientations[1] = quaternion.normalized(quaternion.multiply(turn, orientations[1]))
    positions[1] = elbow + to_matrix(turn) @ (positions[1] - elbow)
    omega = np.array([0.0, 0.0, -2.0])  # bending on, past the stop
    rotation = to_matrix(orientations[1])
    angular_momenta[1] = rotation @ model.rigid.inertia[1] @ rotation.T @ omega
    momenta[1] = model.rigid.mass[1] * np.cross(omega, positions[1] - elbow)

    def rows(state: np.ndarray) -> np.ndarray:
        kinematics = measure.kinematics(*measure.split(state))
        count = len(measure.joints.row_is_unilateral)
        violation, jac = np.empty(count), np.empty((count, 2, 6))
        stepper.held_rows(0.0, *measure._packed[:3], np.ascontiguousarray(kinematics.x),
                          np.ascontiguousarray(kinematics.rotation), violation, jac)
        return violation

    unilateral = measure.joints.row_is_unilateral
    before = rows(y)
    stop = int(np.argmin(np.where(unilateral, before, np.inf)))
    assert before[stop] < -0.25  # the lower stop, 0.3 rad past
    system.project(y, t=0.0)
    after = rows(y)
    assert np.abs(after[~unilateral]).max() < 1e-12  # the joints hold
    assert abs(after[stop]) < 1e-12  # on the stop, to the joints' tolerance
    kinematics = measure.kinematics(*measure.split(y))
    axis = kinematics.rotation[0] @ np.array([0.0, 0.0, 1.0])
    bending = (kinematics.omega[1] - kinematics.omega[0]) @ axis
    assert bending > -1e-9  # no longer bending past it (it was −2 rad/s)


@pytest.mark.parametrize("method", ["RK45", "symplectic_euler"])
def test_a_limit_overshot_next_to_contacts_is_reported_with_the_joint_and_the_fix(method):
    """A bar hinged at one end, limits ±0.3 rad, falls from level onto its lower limit at ω ≈ 3.8 rad/s, while a
    ball rests on the floor. Next to contacts, RK45 holds the limit by its stabilisation alone (ω0 = 20/s), so the
    bar overshoots by about ω / (e ω0) ≈ 0.07 rad: the run says so, naming the joint and a method that holds it.
    Symplectic Euler meets the stop and projects the joint every step: nothing to say. (Before, the ledger held the
    overshoot and no warning told of it.)"""
    solver = "{method: RK45}" if method == "RK45" else "{method: symplectic_euler, dt: 1.0e-3}"
    loaded = scene(f"""
        duration: 0.6
        fps: 30
        solver: {solver}
        fields: [{{type: gravity}}]
        bodies:
          - {{name: bar, type: rigid, shape: {{type: box, size: [0.6, 0.05, 0.05]}}, density: 500, position: [0.3, 1, 0]}}
          - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.1}}, density: 500, position: [2, 0.1, 0]}}
        joints:
          - {{name: shoulder, type: hinge, between: [bar], anchor: [0, 1, 0], axis: [0, 0, 1], limits: [-0.3, 0.3]}}
        colliders: [{{type: plane}}]
    """)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        trajectory = api.simulate(loaded)
    said = [str(w.message) for w in caught if issubclass(w.category, AccuracyWarning) and "joints were" in str(w.message)]
    overshoot = trajectory.ledger["joints"]["max_angle_violation"]
    if method == "RK45":
        assert 0.03 < overshoot < 0.15
        assert len(said) == 1 and "'shoulder'" in said[0] and "symplectic_euler" in said[0], said
    else:
        assert overshoot < 1e-9 and not said


def test_contacts_on_free_bodies_next_to_joints_build_no_joint_response():
    """A ball on the floor beside a hinged bar: its contact moves only the ball, so the contacts are solved without
    the joints' rows (and may run compiled); a contact on the bar brings them in, with the bar's hinge row among
    them."""
    from animbatch.compile.model import compile_scene
    from animbatch.sim.contact.contacts import PLANE, STATIC, Contacts
    from animbatch.sim.contact.impulses import BodyVelocities
    from animbatch.sim.contact.time_stepping import joints_on
    from animbatch.sim.model.dynamics import Dynamics

    model = compile_scene(scene("""
        bodies:
          - {name: bar, type: rigid, shape: {type: box, size: [0.6, 0.05, 0.05]}, density: 500, position: [0.3, 1, 0]}
          - {name: ball, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [2, 0.1, 0]}
        joints: [{type: hinge, between: [bar], anchor: [0, 1, 0], axis: [0, 0, 1]}]
        colliders: [{type: plane}]
    """).spec, Path("."))
    system = Dynamics(model)
    state = system.kinematics(*system.split(model.y0), t=0.0, copy=True)
    bodies = BodyVelocities(np.zeros((3, 3)), np.zeros((3, 3)), np.array([1.0, 1.0, 0.0]), np.zeros((3, 3, 3)))

    def on(body: int) -> Contacts:
        return Contacts(np.array([body]), np.array([STATIC]), np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]),
                        np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1, np.intp), np.full(1, PLANE),
                        np.zeros(1, np.intp))

    assert joints_on(system, state, bodies, on(1)) == (None, None)
    couple, jointed = joints_on(system, state, bodies, on(0))
    assert couple is not None and jointed is not None and jointed.count == 5  # a hinge holds five rows
