"""Rigid bodies on keyframes (issue 22, kinematic bodies): a body of any shape follows its path exactly (position,
orientation and the path's velocities), pushes other bodies with the velocity of its surface (a capsule bat moving
at V sends a ball off at (1 + e) V; a mesh-free log platform carries a crate by friction), is not pushed back, and
emitted particles bounce off it; adaptive methods and joints to it are refused with the fix named."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from animbatch import api
from animbatch.errors import SceneError
from support.scenes import scene

G = 9.81


def bat(shape: str, restitution: float, speed: float = 2.0):
    loaded = scene(f"""
        duration: 0.5
        fps: 50
        solver: {{method: symplectic_euler, dt: 5.0e-4}}
        materials:
          m: {{restitution: {restitution}, static_friction: 0, kinetic_friction: 0}}
        bodies:
          - {{name: bat, type: rigid, shape: {shape}, density: 700, position: [0, 0, 0], material: m,
             interpolation: linear, keyframes: [{{time: 0}}, {{time: 1, offset: [{speed}, 0, 0]}}]}}
          - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.05}}, density: 1000, position: [0.5, 0, 0],
             material: m}}
        contacts: {{}}
    """)
    return api.simulate(loaded)


@pytest.mark.slow
@pytest.mark.parametrize("restitution", [1.0, 0.5])
@pytest.mark.parametrize("shape", ["{type: box, size: [0.1, 0.4, 1.2]}",
                                   "{type: capsule, radius: 0.05, length: 1.2}"])
def test_a_bat_on_keyframes_sends_a_ball_off_at_1_plus_e_times_its_speed(shape, restitution):
    trajectory = bat(shape, restitution)
    np.testing.assert_allclose(trajectory.velocities[-1, 1], [(1 + restitution) * 2.0, 0, 0], atol=1e-9)
    # the bat kept to its path, unmoved by the impact: x = V t, at V
    np.testing.assert_allclose(trajectory.positions[:, 0, 0], 2.0 * trajectory.times, atol=1e-12)
    np.testing.assert_allclose(trajectory.velocities[:, 0], np.tile([2.0, 0, 0], (len(trajectory.times), 1)),
                               atol=1e-12)
    energy = trajectory.ledger["conservation"]["energy"]
    assert energy["conserved"] is False and "kinematic bodies (keyframes or motion) do work" in energy["reason"]


@pytest.mark.slow
def test_a_body_on_keyframes_turns_as_its_path_says_about_its_position():
    """A compound whose centre of mass is off its origin turns about the origin: its centre of mass goes round a
    circle and its angular velocity is the path's."""
    loaded = scene("""
        duration: 2
        fps: 20
        solver: {method: verlet, dt: 1.0e-3}
        bodies:
          - name: crank
            type: rigid
            density: 500
            shape: {type: compound, parts: [{shape: {type: box, size: [0.1, 0.1, 0.1]}, offset: [0.3, 0, 0]}]}
            position: [1, 2, 0]
            interpolation: linear
            keyframes: [{time: 0}, {time: 2, rotation: {axis: [0, 0, 1], angle: 90}}]
        fields: [{type: gravity}]
    """)
    trajectory = api.simulate(loaded)
    angle = np.pi / 4 * trajectory.times  # 90° in 2 s
    np.testing.assert_allclose(trajectory.positions[:, 0, 0], 1 + 0.3 * np.cos(angle), atol=1e-9)
    np.testing.assert_allclose(trajectory.positions[:, 0, 1], 2 + 0.3 * np.sin(angle), atol=1e-9)  # gravity ignored
    np.testing.assert_allclose(trajectory.angular_velocities[1:-1, 0, 2], np.pi / 4, rtol=1e-6)
    turned = Rotation.from_quat(trajectory.orientations[:, 0][:, [1, 2, 3, 0]]).as_rotvec()[:, 2]
    np.testing.assert_allclose(turned, angle, atol=1e-9)


@pytest.mark.slow
def test_a_moving_log_carries_a_crate_by_friction():
    """A log (a cylinder body on keyframes) lying under a crate moves 0.25 m along its axis in 1 s with a smooth
    start and stop; its acceleration (at most 1.5 m/s²) stays below μ g, so the crate rides along without slipping."""
    loaded = scene("""
        duration: 1.3
        fps: 50
        solver: {method: symplectic_euler, dt: 1.0e-3}
        materials:
          pad: {restitution: 0, static_friction: 0.5, kinetic_friction: 0.5}
        bodies:
          - {name: log, type: rigid, shape: {type: cylinder, radius: 0.1, length: 2.0}, density: 500, material: pad,
             position: [0, 0.1, 0], orientation: {axis: [0, 1, 0], angle: 90},
             keyframes: [{time: 0}, {time: 1, offset: [0.25, 0, 0]}]}
          - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500,
             position: [0, 0.3, 0], material: pad}
        fields: [{type: gravity}]
        contacts: {}
    """)
    trajectory = api.simulate(loaded)
    s = np.clip(trajectory.times, 0, 1)
    path = 0.25 * (3 * s**2 - 2 * s**3)
    np.testing.assert_allclose(trajectory.positions[:, 0, 0], path, atol=1e-12)  # the log's path
    np.testing.assert_allclose(trajectory.positions[:, 1, 0], path, atol=2e-3)
    np.testing.assert_allclose(trajectory.positions[:, 1, 1], 0.3, atol=5e-4)


@pytest.mark.slow
def test_particles_bounce_off_a_body_on_keyframes():
    loaded = scene("""
        duration: 1.0
        fps: 50
        solver: {method: verlet, dt: 1.0e-3}
        materials: {m: {restitution: 1.0, static_friction: 0, kinetic_friction: 0}}
        bodies:
          - {name: bat, type: rigid, shape: {type: box, size: [0.05, 1, 1]}, density: 500, position: [-1, 0, 0],
             material: m, interpolation: linear, keyframes: [{time: 0}, {time: 1, offset: [2, 0, 0]}]}
        emitters:
          - {name: dust, bursts: [{time: 0, count: 20}], source: {type: box, position: [0, 0, 0], size: [0.1, 0.5, 0.5]},
             speed: 0, lifetime: 10, radius: 0.002, material: m}
    """)
    trajectory = api.simulate(loaded)
    frames = trajectory.particles[0]
    speed = np.diff(frames.positions[-2:, :, 0].astype(float), axis=0)[0] / np.diff(trajectory.times[-2:])[0]
    np.testing.assert_allclose(speed[frames.serials[-1] >= 0], 4.0, rtol=1e-5)


def test_bodies_on_keyframes_refuse_adaptive_methods_joints_and_a_velocity_of_their_own():
    body = ("{name: bat, type: rigid, shape: {type: box, size: [0.1, 0.1, 0.1]}, density: 500%s, "
            "keyframes: [{time: 0}, {time: 1, offset: [1, 0, 0]}]}")
    with pytest.raises(SceneError, match=r"bodies\[0\]\.keyframes.*need a fixed-step method.*symplectic_euler"):
        scene(f"solver: {{method: RK45}}\nbodies: [{body % ''}]\n")
    refusal = r"joints\[0\]\.between\[0\].*is kinematic \(keyframes or motion\).*anchor on keyframes"
    with pytest.raises(SceneError, match=refusal):
        scene(f"solver: {{method: verlet, dt: 0.001}}\nbodies: [{body % ''}]\n"
                            "joints: [{type: ball, between: [bat]}]\n")
    with pytest.raises(SceneError, match=r"bodies\[0\]\.velocity.*moves as its path says"):
        scene(f"solver: {{method: verlet, dt: 0.001}}\nbodies: [{body % ', velocity: [1, 0, 0]'}]\n")
