"""Kinematic solids in closed-form motion (issue 22, §2: "or the closed-form motions of the kinematic mode"): a
collider or rigid body with ``motion`` moves at a constant velocity, spins at a constant rate about its pivot and
oscillates, with its exact velocity at every contact. A shaker plate throws a resting ball exactly when its
downward acceleration A ω² exceeds g; a turntable carries a crate round at ω r; a body moving at V bats a ball off
at (1 + e) V."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.compile.contacts import pose_path
from animbatch.errors import SceneError
from support.scenes import assert_velocity_is_the_paths_derivative, scene

G = 9.81


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.8, 2.0])
def test_a_shaker_plate_throws_a_resting_ball_only_when_a_omega_squared_exceeds_g(ratio):
    """A plate oscillating vertically as A sin(ω t) accelerates downwards by up to A ω². Below g (ratio 0.8) the
    ball rests on it throughout, its bottom on the plate's top; above g (ratio 2) the plate drops away faster than
    the ball can fall, and the ball leaves it."""
    frequency = 10.0
    amplitude = ratio * G / (2 * np.pi * frequency) ** 2
    loaded = scene(f"""
        duration: 0.3
        fps: 100
        solver: {{method: symplectic_euler, dt: 2.0e-4}}
        materials: {{dead: {{restitution: 0, static_friction: 0.5, kinetic_friction: 0.5}}}}
        bodies:
          - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.02}}, density: 1000, position: [0, 0.02, 0],
             material: dead}}
        colliders:
          - {{type: box, position: [0, -0.05, 0], size: [0.4, 0.1, 0.4], material: dead,
             motion: {{oscillation: {{amplitude: [0, {amplitude!r}, 0], frequency: {frequency}}}}}}}
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    plate = amplitude * np.sin(2 * np.pi * frequency * trajectory.times)  # its top
    gap = trajectory.positions[:, 0, 1] - 0.02 - plate
    if ratio < 1:
        assert np.abs(gap).max() < 2e-4
    else:
        assert gap.max() > 5e-3  # thrown clear of the plate
        assert gap.min() > -1e-3


@pytest.mark.slow
def test_a_turntable_carries_a_crate_round_at_omega_r():
    """A disc spinning at ω = 1.5 rad/s about the vertical through its centre; a crate at r = 0.5 m with μ = 0.8
    (ω² r = 1.1 m/s² < μ g) is brought up to speed by friction, then rides round at ω r on its circle."""
    omega, radius = 1.5, 0.5
    loaded = scene(f"""
        duration: 1
        fps: 50
        solver: {{method: symplectic_euler, dt: 2.0e-3}}
        materials: {{pad: {{restitution: 0, static_friction: 0.8, kinetic_friction: 0.8}}}}
        bodies:
          - {{name: crate, type: rigid, shape: {{type: box, size: [0.1, 0.1, 0.1]}}, density: 500,
             position: [{radius}, 0.05, 0], material: pad}}
        colliders:
          - {{type: box, position: [0, -0.05, 0], size: [2, 0.1, 2], material: pad,
             motion: {{angular_velocity: [0, {omega}, 0]}}}}
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    late = trajectory.times >= 0.5
    x, z = trajectory.positions[late, 0, 0], trajectory.positions[late, 0, 2]
    lever = np.hypot(x, z)
    speed = np.linalg.norm(trajectory.velocities[late, 0], axis=1)
    np.testing.assert_allclose(speed, omega * lever, rtol=1e-2)
    assert np.ptp(lever) < 2e-3 and abs(lever.mean() - radius) < 0.02  # riding its circle, not slipping out
    np.testing.assert_allclose(trajectory.positions[late, 0, 1], 0.05, atol=2e-4)


@pytest.mark.slow
@pytest.mark.parametrize("restitution", [1.0, 0.5])
def test_a_body_moving_at_constant_velocity_bats_a_ball_at_1_plus_e_times_v(restitution):
    loaded = scene(f"""
        duration: 0.5
        fps: 50
        solver: {{method: symplectic_euler, dt: 5.0e-4}}
        materials: {{bat: {{restitution: {restitution}, static_friction: 0, kinetic_friction: 0}}}}
        bodies:
          - {{name: bat, type: rigid, shape: {{type: box, size: [0.1, 0.4, 1.2]}}, density: 700, position: [0, 0, 0],
             material: bat, motion: {{velocity: [2, 0, 0]}}}}
          - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.05}}, density: 1000, position: [0.5, 0, 0],
             material: bat}}
        contacts: {{}}
    """)
    trajectory = api.simulate(loaded)
    bat, ball = (trajectory.body_names.index(name) for name in ("bat", "ball"))
    np.testing.assert_allclose(trajectory.positions[:, bat, 0], 2.0 * trajectory.times, atol=1e-12)
    np.testing.assert_allclose(trajectory.velocities[-1, ball], [(1 + restitution) * 2.0, 0, 0], atol=1e-9)


def test_a_closed_form_path_has_its_exact_derivative_as_velocity():
    loaded = scene("""
        duration: 1
        solver: {method: verlet, dt: 1.0e-3}
        bodies: [{name: ball, position: [0, 1, 0]}]
        colliders:
          - type: sphere
            position: [1, 0, 0]
            radius: 0.5
            motion: {velocity: [0.5, 0, 0], angular_velocity: [0, 0, 2],
                     oscillation: {amplitude: [0, 0.1, 0.05], frequency: 3, phase: 30, damping: 0.7}}
    """)
    path = pose_path(loaded.spec.colliders[0])
    centre, turn = path.pose(0.0)
    np.testing.assert_allclose(centre, [1, 0.1 * 0.5, 0.05 * 0.5], atol=1e-12)  # sin 30° = 0.5
    assert_velocity_is_the_paths_derivative(path, (0.1, 0.45, 0.9), step=1e-6, atol=1e-6)


def test_keyframes_and_motion_together_are_refused():
    with pytest.raises(SceneError, match="give keyframes or motion, not both"):
        scene("""
            duration: 1
            solver: {method: verlet, dt: 1.0e-3}
            bodies: [{name: ball, position: [0, 1, 0]}]
            colliders: [{type: box, position: [0, 0, 0], size: [1, 1, 1], keyframes: [{time: 0}],
                         motion: {velocity: [1, 0, 0]}}]
        """)
