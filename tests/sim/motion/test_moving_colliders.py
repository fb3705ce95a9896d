"""Colliders on keyframes (issue 22, kinematic solids): their paths, and contacts that act on the velocity relative
to their moving surface: a paddle bounces a ball at (1 + e) times its speed, a turning paddle at (1 + e) ω r, a
platform carries a crate by friction without slipping and lets it slip on ice."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from animbatch.compile.contacts import pose_path
from animbatch.errors import SceneError
from animbatch.stages import parse_scene
from support.scenes import assert_velocity_is_the_paths_derivative, scene

G = 9.81


def paddle(speed: float, restitution: float, keys: str | None = None, ball_at: str = "[0.5, 0, 0]") -> tuple:
    keys = keys or f"[{{time: 0, offset: [0, 0, 0]}}, {{time: 1, offset: [{speed}, 0, 0]}}]"
    loaded = scene(f"""
        duration: 0.5
        fps: 50
        solver: {{method: symplectic_euler, dt: 5.0e-4}}
        materials:
          bat: {{restitution: {restitution}, static_friction: 0, kinetic_friction: 0}}
        bodies:
          - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.05}}, density: 1000, position: {ball_at},
             material: bat}}
        colliders:
          - {{type: box, position: [0, 0, 0], size: [0.1, 0.4, 1.2], material: bat, interpolation: linear,
             keyframes: {keys}}}
    """)
    return api.simulate(loaded), loaded


@pytest.mark.slow
@pytest.mark.parametrize("restitution", [1.0, 0.5, 0.0])
def test_a_paddle_moving_at_v_sends_a_ball_at_rest_off_at_1_plus_e_times_v(restitution):
    trajectory, _ = paddle(2.0, restitution)
    np.testing.assert_allclose(trajectory.velocities[-1, 0], [(1 + restitution) * 2.0, 0, 0], atol=1e-9)
    assert trajectory.ledger["conservation"]["energy"]["conserved"] is False  # the paddle does work
    assert "moving colliders do work" in trajectory.ledger["conservation"]["energy"]["reason"]


@pytest.mark.slow
def test_a_turning_paddle_hits_with_the_speed_of_its_surface_there():
    """Turning at ω about its centre, the paddle's face at lever r moves at ω r: an elastic ball there leaves at
    about 2 ω r (the face has turned by a few degrees at the impact, so within 3 %)."""
    omega, lever = 2.0, 0.4  # rad/s about y; the ball sits 0.4 m along the paddle, 2 mm from its face
    keys = f"[{{time: 0}}, {{time: 1, rotation: {{axis: [0, 1, 0], angle: {float(np.degrees(omega))!r}}}}}]"
    trajectory, _ = paddle(0.0, 1.0, keys, ball_at=f"[0.102, 0, {lever}]")
    speed = np.linalg.norm(trajectory.velocities[-1, 0])
    assert speed == pytest.approx(2 * omega * lever, rel=0.03)


def crate_on_platform(friction: float, *, distance: float, span: float, method: str = "symplectic_euler") -> tuple:
    """A crate on a platform moved by ``distance`` [m] along x over ``span`` [s] (a clamped cubic), run for half a
    second more; the trajectory and the platform's offset at its frames."""
    loaded = scene(f"""
        duration: {span + 0.5}
        fps: 50
        solver: {{method: {method}, dt: 1.0e-3}}
        materials:
          pad: {{restitution: 0, static_friction: {friction}, kinetic_friction: {friction}}}
        bodies:
          - {{name: crate, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500,
             position: [0, 0.2, 0], material: pad}}
        colliders:
          - {{type: box, position: [0, 0.05, 0], size: [2.0, 0.1, 1.0], material: pad,
             keyframes: [{{time: 0, offset: [0, 0, 0]}}, {{time: {span}, offset: [{distance}, 0, 0]}}]}}
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    s = np.clip(trajectory.times / span, 0, 1)
    return trajectory, distance * (3 * s**2 - 2 * s**3)  # the clamped cubic between two keys


@pytest.mark.slow
@pytest.mark.parametrize("method", ["symplectic_euler", "verlet"])
def test_a_platform_carries_a_crate_by_friction_when_its_acceleration_is_below_mu_g(method):
    """Under verlet too, whose end-of-step re-projection once met the platform where it was at t = 0, at rest,
    and held the crate back there."""
    # largest acceleration 6 d / T² = 1.5 m/s² < 0.5 g
    trajectory, platform = crate_on_platform(0.5, distance=0.25, method=method, span=1.0)
    np.testing.assert_allclose(trajectory.positions[:, 0, 0], platform, atol=1e-3)  # within a step's travel
    np.testing.assert_allclose(trajectory.positions[:, 0, 1], 0.2, atol=2e-4)


@pytest.mark.slow
def test_on_ice_the_platform_slides_out_from_under_the_crate_which_lags_at_mu_g():
    # 0.5 m in 1 s: at first 6 d / T² = 3 m/s² > 0.05 g = 0.49 m/s²: it slips at once
    trajectory, platform = crate_on_platform(0.05, distance=0.5, span=1.0)
    early = trajectory.times <= 0.4  # slipping forwards relative to it: friction accelerates it at μ g
    np.testing.assert_allclose(trajectory.positions[early, 0, 0], 0.5 * 0.05 * G * trajectory.times[early] ** 2,
                               atol=2e-3)
    assert trajectory.positions[-1, 0, 0] < platform[-1] - 0.05


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_a_collider_path_holds_its_keys_and_its_velocity_is_the_paths_derivative(interpolation):
    loaded = parse_scene(f"""
        duration: 1
        solver: {{method: verlet}}
        bodies: [{{name: ball, position: [0, 1, 0]}}]
        colliders:
          - type: box
            position: [1, 0, 0]
            size: [1, 1, 1]
            interpolation: {interpolation}
            keyframes:
              - {{time: 0, offset: [0, 0, 0]}}
              - {{time: 1, offset: [1, 2, 0], rotation: {{axis: [0, 0, 1], angle: 90}}}}
              - {{time: 3, offset: [0, 0, 1], rotation: {{axis: [1, 0, 0], angle: 30}}}}
    """, filename="test.yaml")
    path = pose_path(loaded.spec.colliders[0])
    centre, turn = path.pose(1.0)
    np.testing.assert_allclose(centre, [2, 2, 0], atol=1e-12)
    np.testing.assert_allclose(turn @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    assert_velocity_is_the_paths_derivative(path, (0.3, 1.7, 2.4))
    between = path.turn(2.0)  # slerp's half-way turn, or the spline's: a rotation either way
    np.testing.assert_allclose(between @ between.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(path.velocity(5.0)[0], 0)  # held after the last key


def test_the_colliders_poses_asked_twice_at_a_time_are_the_paths_and_cannot_be_changed():
    """The poses and motion a contact step reads several times are remembered for the last time asked: at each time
    they are what the paths give, a new time gives its own, and no caller can write into what the next one reads."""
    from animbatch.compile.model import compile_scene

    loaded = parse_scene("""
        duration: 1
        solver: {method: verlet, dt: 1.0e-3}
        bodies: [{name: ball, position: [0, 1, 0]}]
        colliders:
          - {type: box, position: [1, 0, 0], size: [1, 1, 1],
             keyframes: [{time: 0}, {time: 1, offset: [1, 2, 0], rotation: {axis: [0, 0, 1], angle: 90}}]}
    """, filename="test.yaml")
    world = compile_scene(loaded.spec).contact_world
    moving = world.moving
    for t in (0.25, 0.25, 0.5, 0.25):
        for found, fresh in zip(moving.motion(t), moving._motion(t)):
            np.testing.assert_array_equal(found, fresh)
        placed, fresh_place = world.statics_at(t), moving._place(world.statics, t)
        np.testing.assert_array_equal(placed.box_centre, fresh_place.box_centre)
        np.testing.assert_array_equal(placed.box_rotation, fresh_place.box_rotation)
    centres, _, _ = moving.motion(0.25)
    with pytest.raises(ValueError, match="read-only"):
        centres[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        world.statics_at(0.25).box_centre[0, 0] = 1.0


def test_moving_colliders_are_refused_with_adaptive_methods():
    with pytest.raises(SceneError) as error:
        parse_scene("""
            duration: 1
            solver: {method: RK45}
            bodies: [{name: ball, position: [0, 1, 0]}]
            colliders: [{type: box, position: [0, 0, 0], size: [1, 1, 1], keyframes: [{time: 0}]}]
        """, filename="test.yaml")
    assert "colliders on keyframes need a fixed-step method; RK45 is adaptive" in str(error.value)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["box", "sphere"])
def test_a_moving_collider_sends_resting_particles_off_at_1_plus_e_times_its_speed(kind):
    """Particles hanging at rest (no gravity) in the path of a paddle collider moving at V = 2 m/s leave at
    (1 + e) V = 3 m/s for e = 0.5: the bounce is of the velocity relative to the paddle's surface."""
    shape = "size: [0.05, 1, 1]" if kind == "box" else "radius: 0.6"
    loaded = scene(f"""
        duration: 1.0
        fps: 50
        solver: {{method: verlet, dt: 1.0e-3}}
        materials: {{m: {{restitution: 0.5, static_friction: 0, kinetic_friction: 0}}}}
        colliders:
          - {{type: {kind}, position: [-1, 0, 0], {shape}, material: m, interpolation: linear,
             keyframes: [{{time: 0}}, {{time: 1, offset: [2, 0, 0]}}]}}
        emitters:
          - {{name: dust, bursts: [{{time: 0, count: 20}}], source: {{type: box, position: [0, 0, 0], size: [0.1, 0.1, 0.1]}},
             speed: 0, lifetime: 10, radius: 0.002, material: m}}
    """)
    trajectory = api.simulate(loaded)
    frames = trajectory.particles[0]
    last = frames.serials[-1] >= 0
    velocity = np.diff(frames.positions[-2:].astype(float), axis=0)[0] / np.diff(trajectory.times[-2:])[0]
    speed = np.linalg.norm(velocity[last], axis=1)
    if kind == "box":
        np.testing.assert_allclose(velocity[last], np.tile([3.0, 0, 0], (int(last.sum()), 1)), atol=3e-4)
    else:  # a sphere's surface at the hit point moves at V too (it does not turn): along its normal, (1 + e) V n·x̂
        assert np.all(speed > 0.5) and np.all(speed <= 3.0 + 1e-3)
