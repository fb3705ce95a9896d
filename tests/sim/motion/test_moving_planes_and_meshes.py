"""Planes and mesh colliders on keyframes (issue 22): a rising floor or a mesh paddle meets bodies, cloth and
emitted particles with the velocity of its own surface, and a tilting floor (a plane or a mesh tray) turns its
contact normal with it, so a block slides down it at the closed-form g (sin θ − μ cos θ)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from animbatch import api

G = 9.81


def run(path, text: str):
    (path / "s.yaml").write_text(text)
    return api.simulate(api.load_scene(path / "s.yaml"))


def paddle(path, kind: str) -> str:
    """A collider at x = −1 whose face towards +x is at x = −0.95, moving at 2 m/s along +x from t = 0."""
    if kind == "plane":
        return ("{type: plane, point: [-0.95, 0, 0], normal: [1, 0, 0], material: m, interpolation: linear, "
                "keyframes: [{time: 0}, {time: 1, offset: [2, 0, 0]}]}")
    trimesh.creation.box((0.1, 1.0, 1.0)).export(path / "paddle.stl")
    return ("{type: mesh, file: paddle.stl, position: [-1, 0, 0], material: m, interpolation: linear, "
            "keyframes: [{time: 0}, {time: 1, offset: [2, 0, 0]}]}")


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["plane", "mesh"])
@pytest.mark.parametrize("restitution", [1.0, 0.5])
def test_a_moving_plane_or_mesh_sends_a_ball_at_rest_off_at_1_plus_e_times_its_speed(tmp_path, kind, restitution):
    trajectory = run(tmp_path, f"""duration: 1
fps: 50
solver: {{method: symplectic_euler, dt: 5.0e-4}}
materials: {{m: {{restitution: {restitution}, static_friction: 0, kinetic_friction: 0}}}}
bodies:
  - {{name: ball, type: rigid, shape: {{type: sphere, radius: 0.05}}, density: 1000, position: [0, 0, 0],
     material: m}}
colliders:
  - {paddle(tmp_path, kind)}
""")
    np.testing.assert_allclose(trajectory.velocities[-1, 0], [(1 + restitution) * 2.0, 0, 0], atol=1e-9)
    assert trajectory.ledger["conservation"]["energy"]["conserved"] is False  # the collider does work


@pytest.mark.slow
def test_a_rising_floor_lifts_a_crate_and_a_cloth_lying_on_it(tmp_path):
    """The floor plane rises 0.5 m in 1 s along a clamped cubic (largest acceleration 6 · 0.5 m / (1 s)² = 3 m/s²,
    less than g, so nothing leaves it): the crate rides at the floor's height plus its half side; every cloth vertex stays on the
    floor, not through it, and the cloth ends lifted with it."""
    trajectory = run(tmp_path, """duration: 1.25
fps: 50
solver: {method: symplectic_euler, dt: 1.0e-3}
materials: {pad: {restitution: 0, static_friction: 0.5, kinetic_friction: 0.5}}
bodies:
  - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500, position: [-0.5, 0.1, 0],
     material: pad}
  - {name: sheet, type: cloth, grid: {size: [0.6, 0.6], resolution: [7, 7]}, position: [0.5, 0.01, 0],
     orientation: {axis: [1, 0, 0], angle: -90}, density: 0.15, radius: 0.01, structural: {stiffness: 100},
     material: pad}
colliders:
  - {type: plane, material: pad, keyframes: [{time: 0}, {time: 1, offset: [0, 0.5, 0]}]}
fields: [{type: gravity}]
""")
    s = np.clip(trajectory.times, 0, 1)
    floor = 0.5 * (3 * s**2 - 2 * s**3)  # the clamped cubic between two keys
    crate = trajectory.body_names.index("crate")
    np.testing.assert_allclose(trajectory.positions[:, crate, 1], floor + 0.1, atol=2e-4)
    vertices = [k for k, name in enumerate(trajectory.body_names) if name != "crate"]
    assert len(vertices) == 49
    sheet = trajectory.positions[:, vertices, 1]
    assert np.all(sheet > floor[:, None] + 0.01 - 2e-3)  # the vertex spheres rest on it, never through
    np.testing.assert_allclose(sheet[-1], 0.5 + 0.01, atol=2e-3)


def tray(path, kind: str) -> str:
    """A floor turning about the z axis through the origin by 30° between t = 0 and 1 s, then held."""
    keys = "keyframes: [{time: 0}, {time: 1, rotation: {axis: [0, 0, 1], angle: 30}}]"
    if kind == "plane":
        return f"{{type: plane, material: pad, {keys}}}"
    slab = trimesh.creation.box((8.0, 0.1, 1.0))  # long enough for the slide
    slab.apply_translation([0, -0.05, 0])  # top face at the file's origin
    slab.export(path / "tray.stl")
    return f"{{type: mesh, file: tray.stl, material: pad, {keys}}}"


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_on_a_floor_tilted_to_30_degrees_a_block_slides_at_g_sin_minus_mu_g_cos(tmp_path, kind):
    """Once the tilt is held, the block slides down the 30° slope at g (sin θ − μ cos θ) for μ = 0.2; with
    μ = 0.8 > tan 30° it stays where it was on the floor, turned with it."""
    text = """duration: 1.8
fps: 50
solver: {{method: symplectic_euler, dt: 4.0e-3}}
materials: {{pad: {{restitution: 0, static_friction: {mu}, kinetic_friction: {mu}}}}}
bodies:
  - {{name: block, type: rigid, shape: {{type: box, size: [0.1, 0.1, 0.1]}}, density: 500, position: [0.5, 0.05, 0],
     material: pad}}
colliders:
  - {tray}
fields: [{{type: gravity}}]
"""
    sliding = run(tmp_path, text.format(mu=0.2, tray=tray(tmp_path, kind)))
    theta = np.radians(30)
    down = np.array([-np.cos(theta), -np.sin(theta), 0])
    held = sliding.times >= 1.2
    along = sliding.positions[held, 0] @ down
    times = sliding.times[held]
    acceleration = np.polyfit(times, along, 2)[0] * 2
    assert acceleration == pytest.approx(G * (np.sin(theta) - 0.2 * np.cos(theta)), rel=0.01)
    stuck = run(tmp_path, text.format(mu=0.8, tray=tray(tmp_path, kind)))
    turned = 0.5 * np.array([np.cos(theta), np.sin(theta), 0]) + 0.05 * np.array([-np.sin(theta), np.cos(theta), 0])
    np.testing.assert_allclose(stuck.positions[-1, 0], turned, atol=2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_a_moving_plane_or_mesh_sends_resting_particles_off_at_1_plus_e_times_its_speed(tmp_path, kind):
    """Particles hanging at rest (no gravity) in the path of the collider moving at V = 2 m/s leave at
    (1 + e) V = 3 m/s for e = 0.5."""
    trajectory = run(tmp_path, f"""duration: 1.0
fps: 50
solver: {{method: verlet, dt: 1.0e-3}}
materials: {{m: {{restitution: 0.5, static_friction: 0, kinetic_friction: 0}}}}
colliders:
  - {paddle(tmp_path, kind)}
emitters:
  - {{name: dust, bursts: [{{time: 0, count: 20}}], source: {{type: box, position: [0, 0, 0], size: [0.1, 0.1, 0.1]}},
     speed: 0, lifetime: 10, radius: 0.002, material: m}}
""")
    frames = trajectory.particles[0]
    last = frames.serials[-1] >= 0
    assert last.sum() == 20
    velocity = np.diff(frames.positions[-2:].astype(float), axis=0)[0] / np.diff(trajectory.times[-2:])[0]
    np.testing.assert_allclose(velocity[last], np.tile([3.0, 0, 0], (20, 1)), atol=3e-4)


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["{type: box, size: [0.1, 0.1, 0.1]}", "{type: cylinder, radius: 0.05, length: 0.1}"])
def test_a_crate_and_a_drum_rest_on_a_fixed_mesh_slab_and_do_not_sink_through_it(tmp_path, shape):
    """A mesh collider is solid from both faces, so a corner probe that sinks a hair below its top face must be
    pushed back up, not measured from below and let through (found with the tilting tray: a box fell through a
    fixed slab mesh at once)."""
    slab = trimesh.creation.box((3.0, 0.1, 1.0))
    slab.apply_translation([0, -0.05, 0])
    slab.export(tmp_path / "slab.stl")
    trajectory = run(tmp_path, f"""duration: 1
fps: 50
solver: {{method: symplectic_euler, dt: 1.0e-3}}
bodies:
  - {{name: crate, type: rigid, shape: {shape}, density: 500, position: [0.5, 0.05, 0],
     orientation: {{axis: [1, 0, 0], angle: 90}}}}
colliders:
  - {{type: mesh, file: slab.stl}}
fields: [{{type: gravity}}]
""")
    np.testing.assert_allclose(trajectory.positions[:, 0, 1], 0.05, atol=2e-4)


@pytest.mark.slow
def test_the_overlap_audit_sees_a_lowering_floor_where_its_path_puts_it(tmp_path):
    """A crate riding a floor that sinks 0.5 m in 1 s (at most 3 m/s², below g: the crate keeps up) is never inside
    it; an audit that put the floor where it starts (the old fault) found the crate 0.4 m under it."""
    scene_text = """duration: 1.2
fps: 25
solver: {method: symplectic_euler, dt: 1.0e-3}
bodies:
  - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500, position: [0, 0.1, 0]}
colliders:
  - {type: plane, keyframes: [{time: 0}, {time: 1, offset: [0, -0.5, 0]}]}
fields: [{type: gravity}]
"""
    trajectory = run(tmp_path, scene_text)
    assert trajectory.ledger["contacts"] == {"starts_inside": None, "missed": None}
    np.testing.assert_allclose(trajectory.positions[-1, 0, 1], -0.4, atol=2e-4)
