"""Emitted particles against mesh colliders and rigid bodies (issue 22): a particle dropped on a mesh slab rises to
e² of its drop, as off a plane; snow sticks on a crate's top, a lying log's side and a ball's cap, never inside; a
paddle moving at V through particles at rest sends them off at (1 + e) V (restitution in the paddle's frame);
particles stuck to a moving body ride along with it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from animbatch import api
from animbatch.sim.contact.geometry import to_round

G = 9.81


def run(path, text: str):
    (path / "s.yaml").write_text(text)
    return api.simulate(api.load_scene(path / "s.yaml"))


def alive(frames, k: int) -> np.ndarray:
    return frames.serials[k] >= 0


@pytest.mark.slow
def test_a_particle_bounces_off_a_mesh_slab_as_off_a_plane(tmp_path):
    import trimesh

    trimesh.creation.box((1.0, 0.1, 1.0)).export(tmp_path / "slab.stl")  # top at y = 0.05 + 0.2
    trajectory = run(tmp_path, """duration: 0.9
fps: 200
solver: {method: verlet, dt: 0.0005}
materials: {bouncy: {restitution: 0.7, static_friction: 0.5, kinetic_friction: 0.3}}
emitters:
  - {name: drop, bursts: [{time: 0, count: 1}], source: {type: point, position: [0.1, 1.25, 0.05]}, speed: 0,
     radius: 0.001, lifetime: 10, material: bouncy}
fields: [{type: gravity}]
colliders: [{type: mesh, file: slab.stl, position: [0, 0.2, 0], material: bouncy}]
""")
    height = trajectory.particles[0].positions[:, 0, 1].astype(float) - 0.251  # above the slab's top, less r
    fall = math.sqrt(2 * 0.999 / G)
    after = height[trajectory.times > fall + 0.01]
    np.testing.assert_allclose(after.max(), 0.49 * 0.999, rtol=0.01)
    assert height.min() >= -1e-6  # never into the slab


@pytest.mark.slow
def test_snow_settles_on_a_crate_a_log_and_a_ball_and_never_inside_them(tmp_path):
    trajectory = run(tmp_path, """duration: 0.8
fps: 30
solver: {method: verlet, dt: 0.002}
bodies:
  - {name: crate, type: rigid, shape: {type: box, size: [0.4, 0.4, 0.4]}, density: 300, position: [-0.6, 0.2, 0]}
  - {name: log, type: rigid, shape: {type: cylinder, radius: 0.15, length: 0.6}, density: 300, position: [0, 0.15, 0]}
  - {name: ball, type: rigid, shape: {type: sphere, radius: 0.2}, density: 300, position: [0.6, 0.2, 0]}
emitters:
  - {name: snow, rate: 1500, source: {type: box, position: [0, 0.7, 0], size: [1.6, 0.05, 0.5]}, speed: 0,
     lifetime: 10, radius: 0.005, collision: stick}
fields: [{type: gravity}]
colliders: [{type: plane}]
""")
    frames = trajectory.particles[0]
    last = len(trajectory.times) - 1
    x = frames.positions[last][alive(frames, last)].astype(float)
    held = np.all(frames.positions[last] == frames.positions[last - 1], axis=1)[alive(frames, last)]  # stuck
    on_crate = (np.abs(x[:, 0] + 0.6) < 0.19) & (np.abs(x[:, 2]) < 0.19) & (x[:, 1] < 0.41) & held
    assert on_crate.sum() > 50
    np.testing.assert_allclose(x[on_crate, 1], 0.405, atol=1e-4)  # on its top, a radius up
    # none inside any body: distances from the log's axis, the ball's centre and the crate
    n = len(x)
    d_log, _ = to_round(x, np.tile([0, 0.15, 0], (n, 1)), np.tile([0, 0, 1.0], (n, 1)), np.full(n, 0.3),
                        np.full(n, 0.15), np.zeros(n, bool))
    assert d_log.min() > 0.005 - 1e-4
    assert np.linalg.norm(x - [0.6, 0.2, 0], axis=1).min() > 0.205 - 1e-4
    on_log = (d_log < 0.0052) & (np.abs(x[:, 2]) < 0.29)
    on_ball = np.abs(np.linalg.norm(x - [0.6, 0.2, 0], axis=1) - 0.205) < 2e-4
    assert on_log.sum() > 20 and on_ball.sum() > 20
    assert x[:, 1].min() > 0.005 - 1e-6  # and none under the floor


@pytest.mark.slow
@pytest.mark.parametrize("e", [1.0, 0.5])
def test_a_moving_paddle_sends_resting_particles_off_at_one_plus_e_times_its_speed(tmp_path, e):
    """A box body moving at V = 2 m/s (no gravity) sweeps through particles hanging at rest: each leaves at
    (1 + e) V, the restitution applied to the velocity relative to the paddle's face."""
    trajectory = run(tmp_path, f"""duration: 0.5
fps: 50
solver: {{method: verlet, dt: 0.001}}
materials: {{m: {{restitution: {e}, static_friction: 0.0, kinetic_friction: 0.0}}}}
bodies:
  - {{name: paddle, type: rigid, shape: {{type: box, size: [0.05, 1.0, 1.0]}}, density: 500, position: [-0.5, 0, 0],
     velocity: [2, 0, 0], material: m}}
emitters:
  - {{name: dust, bursts: [{{time: 0, count: 50}}], source: {{type: box, position: [0, 0, 0], size: [0.2, 0.6, 0.6]}},
     speed: 0, lifetime: 10, radius: 0.002, material: m}}
""")
    frames = trajectory.particles[0]
    last = len(trajectory.times) - 1
    x = frames.positions[last][alive(frames, last)].astype(float)
    # hit around t ≈ 0.25 s, then each flies at (1 + e) V: its x at the end fixes its speed with its hit time
    paddle = trajectory.positions[last, 0, 0] + 0.025  # the paddle's face
    assert np.all(x[:, 0] >= paddle + 0.002 - 1e-6)  # all ahead of it
    speed = np.diff(frames.positions[-2:, :, 0].astype(float), axis=0)[0] / np.diff(trajectory.times[-2:])[0]
    np.testing.assert_allclose(speed[alive(frames, last)], (1 + e) * 2.0, rtol=1e-5)  # positions are float32
    np.testing.assert_allclose(x[:, 1:], frames.positions[0][alive(frames, 0)][:, 1:].astype(float), atol=1e-5)


@pytest.mark.slow
def test_particles_stuck_to_a_moving_body_ride_along_with_it(tmp_path):
    """Dust fired at a crate gliding at constant velocity (no gravity) sticks to its face and then moves with it:
    between the last two frames every stuck particle moved exactly as far as the crate."""
    trajectory = run(tmp_path, """duration: 0.8
fps: 50
solver: {method: verlet, dt: 0.001}
bodies:
  - {name: crate, type: rigid, shape: {type: box, size: [0.4, 0.4, 0.4]}, density: 300, position: [0, 0, 0],
     velocity: [0, 0, 1.0], angular_velocity: [0, 1.0, 0]}
emitters:
  - {name: dust, rate: 200, source: {type: point, position: [-0.9, 0, 0.3]}, speed: 5, direction: {axis: [1, 0, 0], cone: 5},
     lifetime: 10, radius: 0.002, collision: stick}
""")
    frames = trajectory.particles[0]
    last = len(trajectory.times) - 1
    both = alive(frames, last) & (frames.serials[last] == frames.serials[last - 1])
    x0, x1 = frames.positions[last - 1][both].astype(float), frames.positions[last][both].astype(float)
    c0, c1 = trajectory.positions[last - 1, 0], trajectory.positions[last, 0]
    stuck = np.linalg.norm(x1 - x0 - (c1 - c0), axis=1) < 0.05  # moving with the crate, not flying at 5 m/s
    assert stuck.sum() > 20
    # riding a turning crate: each keeps its distance to the crate's centre
    np.testing.assert_allclose(np.linalg.norm(x1[stuck] - c1, axis=1), np.linalg.norm(x0[stuck] - c0, axis=1),
                               atol=1e-5)
