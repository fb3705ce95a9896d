"""Contact between any convex shapes (issue 22): cylinders, rods, capsules and convex meshes are solid to every other
body. Checked against the geometry they are (distances from their closed forms, rest heights from their sizes) and
against what they must do (a capsule rolls down an incline at the closed-form acceleration; crossed rods, a log on a
stair's edge or along a ridge, a ball on a lying cylinder and prisms crossed ridge on ridge rest where their shapes
say, where probes alone let them fall through); hollow meshes are refused as solids with the fix named."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch import api
from animbatch.errors import AccuracyWarning, SceneError
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import OrientationSpec
from animbatch.sim.contact.geometry import round_distance, segment_distance, to_round
from animbatch.sim.contact.hulls import BodyHull, hull_edge_contact, to_hull
from animbatch.sim.rigid import mass_properties as mp
from animbatch.sim.rigid.polyhedra import capsule_mesh, mesh_mass_properties
from support.paths import SCENES

HEADER = """duration: {duration}
fps: 50
solver: {{method: symplectic_euler, dt: 1.0e-3}}
materials: {{wood: {{restitution: 0.2, static_friction: 0.6, kinetic_friction: 0.5}}}}
fields: [{{type: gravity}}]
"""


def simulate(path, text: str, duration: float = 1.5):
    """Run a scene written to ``path`` / s.yaml, treating a missed contact or an overlap as an error."""
    (path / "s.yaml").write_text(HEADER.format(duration=duration) + text)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        return api.simulate(api.load_scene(path / "s.yaml"))


# ------------------------------------------------------------------------------------------------ geometry


def test_round_distances_match_their_closed_forms():
    centre, axis = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    half, radius = np.array([0.5]), np.array([0.1])
    cases = [  # point, cylinder distance, capsule distance
        ([0.3, 0.0, 0.0], 0.2, 0.2),  # beside the side
        ([0.0, 0.0, 0.8], 0.3, 0.2),  # beyond the end face, on the axis: 0.3 to the face, 0.3 - 0.1 to the cap
        ([0.4, 0.0, 0.9], np.hypot(0.3, 0.4), np.hypot(0.4, 0.4) - 0.1),  # off the rim, diagonally
        ([0.05, 0.0, 0.0], -0.05, -0.05),  # inside, nearest the side
        ([0.0, 0.0, 0.48], -0.02, -0.1),  # inside, nearest the end face; in the capsule, nearest its side
    ]
    for point, cylinder, capsule in cases:
        p = np.array([point])
        for rounded, expected in ((False, cylinder), (True, capsule)):
            d, n = to_round(p, centre, axis, half, radius, np.array([rounded]))
            assert d[0] == pytest.approx(expected, abs=1e-12), (point, rounded)
            assert round_distance(p, centre, axis, half, radius, np.array([rounded]))[0] == pytest.approx(expected)
            assert np.linalg.norm(n[0]) == pytest.approx(1.0)
            # the normal points the way the distance grows fastest: a small step along it adds its length
            step = to_round(p + 1e-6 * n, centre, axis, half, radius, np.array([rounded]))[0][0] - d[0]
            assert step == pytest.approx(1e-6, rel=1e-3)


@pytest.mark.slow
def test_round_distance_is_the_distance_to_the_surface_for_points_outside():
    """Against a dense sampling of the cylinder's surface: the sampled distance is never below the exact one, and
    exceeds it by no more than the sampling's spacing."""
    rng = np.random.default_rng(3)
    angles = np.linspace(0, 2 * np.pi, 181)[:-1]
    ring = np.stack([0.1 * np.cos(angles), 0.1 * np.sin(angles)], axis=1)
    zs = np.linspace(-0.5, 0.5, 201)
    side = np.concatenate([np.column_stack([ring, np.full(len(ring), z)]) for z in zs])
    radii = np.linspace(0, 0.1, 21)
    caps = np.concatenate([np.column_stack([np.outer(radii, np.cos(angles)).ravel(),
                                            np.outer(radii, np.sin(angles)).ravel(),
                                            np.full(len(radii) * len(angles), z)]) for z in (-0.5, 0.5)])
    surface = np.concatenate([side, caps])
    points = rng.uniform(-0.8, 0.8, (200, 3))
    d = round_distance(points, np.zeros((200, 3)), np.tile([0.0, 0.0, 1.0], (200, 1)), np.full(200, 0.5),
                       np.full(200, 0.1), np.zeros(200, bool))
    outside = d > 0
    sampled = np.min(np.linalg.norm(points[outside, None, :] - surface[None], axis=2), axis=1)
    assert np.all(sampled >= d[outside] - 1e-12)
    assert np.all(sampled - d[outside] < 5e-3)  # the sampling's spacing (3.5 mm around, 5 mm along)


@pytest.mark.slow
def test_segment_distance_matches_a_brute_force_search():
    rng = np.random.default_rng(5)
    sa, da, sb, db = (rng.normal(size=(100, 3)) for _ in range(4))
    u = np.linspace(0, 1, 401)
    brute = np.linalg.norm((sa[:, None, None] + u[None, :, None, None] * da[:, None, None])
                           - (sb[:, None, None] + u[None, None, :, None] * db[:, None, None]), axis=-1).min(axis=(1, 2))
    exact = segment_distance(sa, da, sb, db)
    assert np.all(exact <= brute + 1e-12) and np.all(brute - exact < 2e-4)


def test_capsule_mass_properties_match_its_surface_integrated():
    """The capsule's closed-form inertia against the divergence theorem over a fine capsule mesh (independent)."""
    mesh = mesh_mass_properties(capsule_mesh(0.1, 0.5, 160))
    exact = mp.capsule(mesh.mass, 0.1, 0.5)
    assert mesh.volume == pytest.approx(np.pi * 0.01 * 0.3 + 4 / 3 * np.pi * 0.001, rel=1e-3)
    np.testing.assert_allclose(np.diag(mesh.inertia), np.diag(exact.inertia), rtol=1e-3)
    assert exact.volume == pytest.approx(np.pi * 0.01 * 0.3 + 4 / 3 * np.pi * 0.001, rel=1e-12)


def test_hull_distance_is_exact_inside_and_outside():
    cube = BodyHull.of_box(0, np.zeros(3), np.eye(3), np.array([0.5, 0.5, 0.5]))
    points = np.array([[0.0, 0.0, 0.2], [0.0, 0.0, 0.9], [0.8, 0.9, 0.0], [0.7, 0.7, 0.7]])
    d, n = to_hull(points, cube, np.zeros(3), np.eye(3))
    np.testing.assert_allclose(d, [-0.3, 0.4, np.hypot(0.3, 0.4), np.sqrt(3) * 0.2], atol=1e-12)
    np.testing.assert_allclose(n[1], [0, 0, 1], atol=1e-12)
    turn = orientation_matrix(OrientationSpec(axis=[1, 1, 0], angle=33))  # the body turned and moved
    d2, n2 = to_hull(points @ turn.T + [1, 2, 3], cube, np.array([1.0, 2, 3]), turn)
    np.testing.assert_allclose(d2, d, atol=1e-12)
    np.testing.assert_allclose(n2, n @ turn.T, atol=1e-12)
    assert len(cube.normals) == 6 and len(cube.edges) == 12 and len(cube.edge_axes) == 3


def test_planks_crossed_face_on_face_touch_at_the_corners_of_their_overlap():
    """A plank lying across another, face on face: no corner of either lies on the other, and the four crossings of
    their edges (the corners of the square where they overlap) are the contacts."""
    plank = BodyHull.of_box(0, np.zeros(3), np.eye(3), np.array([0.5, 0.05, 0.1]))
    across = BodyHull.of_box(1, np.zeros(3), np.eye(3), np.array([0.1, 0.05, 0.5]))
    found = hull_edge_contact(plank, np.array([0, 0.099, 0]), np.eye(3), across, np.zeros(3), np.eye(3), 0.01)
    points = np.array(sorted(tuple(np.round(c[0], 12)) for c in found))
    np.testing.assert_allclose(points, [[-0.1, 0.0495, -0.1], [-0.1, 0.0495, 0.1], [0.1, 0.0495, -0.1],
                                        [0.1, 0.0495, 0.1]], atol=1e-12)
    for point, normal, gap, _, _ in found:
        np.testing.assert_allclose(normal, [0, 1, 0], atol=1e-12)
        assert gap == pytest.approx(-0.001, abs=1e-12)


# ------------------------------------------------------------------------------------------------ motion


@pytest.mark.slow
def test_a_capsule_rolls_down_an_incline_at_the_closed_form_acceleration(tmp_path):
    """A solid capsule lying across a 20° incline rolls without slipping: a = g sin θ / (1 + I_axis / (m r²)),
    with its axial moment from the cylinder and the two hemispheres."""
    theta = np.radians(20)
    r, length = 0.1, 0.6
    normal = [float(-np.sin(theta)), float(np.cos(theta)), 0.0]
    text = f"""bodies:
  - {{name: pill, type: rigid, shape: {{type: capsule, radius: {r}, length: {length}}}, density: 500,
     material: wood, position: [{r * normal[0]}, {r * normal[1]}, 0]}}
colliders: [{{type: plane, normal: {normal}, material: wood}}]
"""
    trajectory = simulate(tmp_path, text, duration=1.0)
    unit = mp.capsule(1.0, r, length)
    expected = 9.81 * np.sin(theta) / (1 + unit.inertia[2, 2] / r**2)
    down = np.array([-np.cos(theta), -np.sin(theta), 0.0])
    t = trajectory.times
    travelled = (trajectory.positions[:, 0] - trajectory.positions[0, 0]) @ down
    late = t > 0.2
    fitted = np.polyfit(t[late], travelled[late], 2)[0] * 2
    assert fitted == pytest.approx(expected, rel=5e-3)
    assert expected < 9.81 * np.sin(theta) / 1.4  # slower than a solid sphere's 5/7: most of its mass is the cylinder


@pytest.mark.slow
def test_round_sides_rest_on_each_other_and_on_edges(tmp_path):
    """Crossed rods, crossed capsules, a ball on a lying cylinder, a log across a stair's edge and a log along a
    ridge: each comes to rest where the shapes touch (no probe sits where these sides touch)."""
    text = """bodies:
  - {name: lower, type: rigid, shape: {type: cylinder, radius: 0.1, length: 1.0}, density: 500, material: wood, position: [0, 0.1, 0]}
  - {name: upper, type: rigid, shape: {type: cylinder, radius: 0.08, length: 1.0}, density: 500, material: wood, position: [0, 0.4, 0], orientation: {axis: [0, 1, 0], angle: 90}}
  - {name: log, type: rigid, shape: {type: cylinder, radius: 0.1, length: 1.0}, density: 500, material: wood, position: [2, 0.1, 0]}
  - {name: ball, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, material: wood, position: [2, 0.6, 0.2]}
  - {name: pill, type: rigid, shape: {type: capsule, radius: 0.1, length: 0.6}, density: 500, material: wood, position: [4, 0.5, 0], orientation: {axis: [0, 1, 0], angle: 90}}
  - {name: pill2, type: rigid, shape: {type: capsule, radius: 0.05, length: 0.6}, density: 500, material: wood, position: [4, 0.05, 0]}
  - {name: across, type: rigid, shape: {type: rod, radius: 0.03, length: 1.0}, density: 500, material: wood, position: [-2.2, 0.5, 0], orientation: {axis: [0, 1, 0], angle: 90}}
  - {name: along, type: rigid, shape: {type: cylinder, radius: 0.05, length: 1.0}, density: 500, material: wood, position: [6, 0.5, 0]}
colliders:
  - {type: plane, normal: [0, 1, 0], material: wood}
  - {type: box, position: [-2, 0.15, 0], size: [0.4, 0.3, 2.0], material: wood}
  - {type: box, position: [6, 0.0, 0], size: [0.4, 0.4, 0.4], orientation: {axis: [0, 0, 1], angle: 45}, material: wood}
"""
    trajectory = simulate(tmp_path, text, duration=2.0)
    heights = trajectory.positions[:, :, 1]
    rest = {"upper": 0.2 + 0.08, "ball": 0.2 + 0.1, "pill": 0.1 + 0.1, "along": 0.2 * np.sqrt(2) + 0.05}
    names = ["lower", "upper", "log", "ball", "pill", "pill2", "across", "along"]
    for name, height in rest.items():
        k = names.index(name)
        assert heights[:, k].min() > height - 3e-3, name  # never through
        assert heights[-1, k] == pytest.approx(height, abs=2e-3), name
    # the rod laid across the stair's edge, its middle 0.2 m beyond it, tips over the edge and pivots on it: while
    # it pivots its axis stays 3 cm from the edge, never nearer
    across = trajectory.positions[:, names.index("across")]
    edge = np.array([-2.2, 0.3])  # the stair's top edge nearest the rod's middle, seen along z
    turning = across[:, 1] < 0.33 + 1e-3
    assert np.all(np.hypot(across[:, 0] - edge[0], across[:, 1] - edge[1])[turning] > 0.03 - 3e-3)


def crossed(lower: str, upper: str, method: str, duration: float = 1.0) -> str:
    solver = "method: RK45" if method == "RK45" else f"method: {method}, dt: 1.0e-3"
    return HEADER.format(duration=duration).replace("method: symplectic_euler, dt: 1.0e-3", solver) + f"""bodies:
  - {{name: lower, type: rigid, density: 500, material: wood, {lower}}}
  - {{name: upper, type: rigid, density: 500, material: wood, {upper}}}
colliders: [{{type: plane, material: wood}}]
"""


#: A rod on the floor along x, and one dropped square across its middle (balanced there: crossed anywhere else, or
#: at another angle, it tips until an end reaches the floor).
RODS = ("shape: {type: rod, radius: 0.03, length: 1.0}, position: [0, 0.03, 0]",
        "shape: {type: rod, radius: 0.03, length: 1.0}, position: [0, 0.3, 0], orientation: {axis: [0, 1, 0], "
        "angle: 90}")


@pytest.mark.parametrize("method", ["verlet", "RK45"])
def test_crossed_rods_rest_on_each_other_under_rk45_as_under_verlet(tmp_path, method):
    """A rod dropped across another rests on its side, one diameter up (0.09 m), under a fixed-step method and under
    RK45, whose events follow the two sides' contact (no probe sits where they touch: probes are at the rods'
    ends); neither run finds the rods inside each other at any frame (the audit measures sides too)."""
    (tmp_path / "s.yaml").write_text(crossed(*RODS, method))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        trajectory = api.simulate(api.load_scene(tmp_path / "s.yaml"))
    height = trajectory.positions[:, 1, 1]
    assert height.min() > 0.09 - 1e-3
    assert height[-1] == pytest.approx(0.09, abs=5e-4)
    np.testing.assert_allclose(trajectory.positions[-1, 1, [0, 2]], [0.0, 0.0], atol=5e-3)  # it did not slide off


@pytest.mark.parametrize("method", ["verlet", "RK45"])
def test_a_stack_of_three_crossed_rods_rests_a_diameter_apart_under_rk45_as_under_verlet(tmp_path, method):
    """The bundled log-cabin corner: three rods dropped square across each other's middles, each resting on the side
    of the one below (0.03, 0.09, 0.15 m), the upper two held by side contacts alone."""
    trajectory = api.simulate(api.load_scene(SCENES / "crossed_rods.yaml",
                                             overrides=[] if method == "RK45" else
                                             ["solver.method=verlet", "solver.dt=0.001"]))
    np.testing.assert_allclose(trajectory.positions[-1, :, 1], [0.03, 0.09, 0.15], atol=5e-4)
    assert trajectory.positions[:, 1:, 1].min(axis=0) == pytest.approx([0.09, 0.15], abs=1e-3)


def test_crossed_beams_rest_ridge_on_ridge_under_rk45_as_under_a_fixed_step_method(tmp_path):
    """Two square beams turned 45° about their long axes and crossed, edge on edge, the upper one dropped: no corner
    is where they touch, so only an edge pair holds it. RK45's events follow that pair as symplectic Euler's steps
    find it: both runs rest the upper beam ridge on ridge, 3 half-diagonals up, never lower, and agree frame by
    frame while it falls (before: RK45 let it through to the floor)."""
    lower = ("shape: {type: box, size: [1.0, 0.1, 0.1]}, position: [0, 0.0707, 0], "
             "orientation: {axis: [1, 0, 0], angle: 45}")
    upper = ("shape: {type: box, size: [0.1, 0.1, 1.0]}, position: [0, 0.4, 0], "
             "orientation: {axis: [0, 0, 1], angle: 45}")
    rest = 3 * 0.05 * np.sqrt(2)  # the lower beam's centre, its half diagonal and the upper's
    heights = {}
    for method in ("symplectic_euler", "RK45"):
        (tmp_path / "s.yaml").write_text(crossed(lower, upper, method))
        with warnings.catch_warnings():
            warnings.simplefilter("error", AccuracyWarning)  # an overlap or a missed contact would warn
            heights[method] = api.simulate(api.load_scene(tmp_path / "s.yaml")).positions[:, 1, 1]
        assert heights[method].min() > rest - 1e-3, method
        assert heights[method][-1] == pytest.approx(rest, abs=3e-3 if method == "symplectic_euler" else 1e-6)
    # in free fall the two agree to the fixed step's error (g dt t ≈ 3 mm by the time it lands at 0.26 s)
    falling = heights["RK45"] > rest + 1e-3
    np.testing.assert_allclose(heights["RK45"][falling], heights["symplectic_euler"][falling], atol=4e-3)


@pytest.mark.slow
def test_prisms_crossed_ridge_on_ridge_rest_edge_on_edge(tmp_path):
    """A triangular prism (a convex mesh) laid ridge down across another's ridge: their edges cross and hold it, at
    the sum of their apex heights; the vertices alone would let it fall through."""
    height, width, length = 0.2, 0.2, 1.0
    vertices = [(-length / 2, 0, -width / 2), (-length / 2, 0, width / 2), (-length / 2, height, 0),
                (length / 2, 0, -width / 2), (length / 2, 0, width / 2), (length / 2, height, 0)]
    faces = [(1, 2, 3), (4, 6, 5), (1, 4, 5), (1, 5, 2), (2, 5, 6), (2, 6, 3), (3, 6, 4), (3, 4, 1)]
    (tmp_path / "prism.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in vertices)
                                        + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))
    text = """bodies:
  - {name: ridge, type: rigid, shape: {type: mesh, file: prism.obj}, density: 500, material: wood,
     orientation: {axis: [0, 1, 0], angle: 90}}
  - {name: beam, type: rigid, shape: {type: mesh, file: prism.obj}, density: 500, material: wood,
     position: [0, 0.45, 0], orientation: {axis: [1, 0, 0], angle: 180}}
joints: [{type: fixed, between: [ridge]}]
contacts: {}
"""
    trajectory = simulate(tmp_path, text)
    # the beam's centre of mass is a third of the way up from its base; upside down, its ridge is 2/3 height below
    apex = trajectory.positions[:, 1, 1] - 2 / 3 * height
    assert apex.min() > height - 3e-3
    assert apex[-1] == pytest.approx(height, abs=2e-3)


@pytest.mark.slow
def test_mesh_bodies_rest_on_a_box_body_and_carry_one(tmp_path):
    """A tetrahedron (a convex mesh) dropped onto a box body lies on a face, its centre of mass a quarter of its
    height over the table (its vertices against the box); a box-shaped mesh slab beside it carries a box dropped on
    it (the box's corners against the hull) at the slab's top plus the box's half height."""
    a = 0.3
    apex_height = a * np.sqrt(2 / 3)
    base = [(0, 0, a / np.sqrt(3)), (a / 2, 0, -a / (2 * np.sqrt(3))), (-a / 2, 0, -a / (2 * np.sqrt(3)))]
    vertices = [*base, (0, apex_height, 0)]
    (tmp_path / "tetra.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in vertices)
                                        + "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    import trimesh

    trimesh.creation.box((0.6, 0.1, 0.6)).export(tmp_path / "slab.stl")
    text = """bodies:
  - {name: table, type: rigid, shape: {type: box, size: [2, 0.2, 1]}, density: 500, material: wood, position: [0, 0.1, 0]}
  - {name: tetra, type: rigid, shape: {type: mesh, file: tetra.obj}, density: 500, material: wood, position: [-0.5, 0.25, 0]}
  - {name: slab, type: rigid, shape: {type: mesh, file: slab.stl}, density: 500, material: wood, position: [0.5, 0.3, 0]}
  - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500, material: wood, position: [0.5, 0.6, 0], orientation: {axis: [0, 1, 0], angle: 30}}
colliders: [{type: plane, material: wood}]
"""
    trajectory = simulate(tmp_path, text, duration=1.5)
    final = trajectory.positions[-1]
    assert final[1, 1] == pytest.approx(0.2 + apex_height / 4, abs=2e-3)  # its centre of mass over its face
    assert final[2, 1] == pytest.approx(0.25, abs=2e-3)
    assert final[3, 1] == pytest.approx(0.3 + 0.1, abs=2e-3)
    assert np.abs(trajectory.velocities[-1]).max() < 1e-2


def test_a_hollow_mesh_body_is_refused_as_a_solid_and_taken_as_its_hull_when_asked(tmp_path):
    # an L-shaped block: a third of its hull is hollow
    vertices = [(0, 0, 0), (2, 0, 0), (2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0)]
    top = [(x, y, 0.5) for x, y, _ in vertices]
    lines = [f"v {x} {y} {z}\n" for x, y, z in vertices + top]
    faces = [(1, 3, 2), (1, 4, 3), (1, 6, 4), (4, 6, 5),  # bottom (wound outward: -z)
             (7, 8, 9), (7, 9, 10), (7, 10, 12), (10, 11, 12)]
    for i in range(6):  # sides
        j = (i + 1) % 6
        faces += [(i + 1, j + 1, j + 7), (i + 1, j + 7, i + 7)]
    (tmp_path / "ell.obj").write_text("".join(lines) + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))
    body = "{name: ell, type: rigid, shape: {type: mesh, file: ell.obj, scale: 0.1%s}, density: 500, position: [0, 0.3, 0]}"
    text = HEADER.format(duration=0.2) + f"bodies:\n  - {body % ''}\n  - {{name: ball, radius: 0.05, position: [1, 1, 0]}}\ncolliders: [{{type: plane}}]\n"
    (tmp_path / "s.yaml").write_text(text)
    with pytest.raises(SceneError, match=r"s\.yaml:\d+:\d+.*bodies\[0\]\.shape.*not convex.*17 %.*convex_hull: true"):
        api.load_scene(tmp_path / "s.yaml")
    (tmp_path / "s.yaml").write_text(text.replace("scale: 0.1", "scale: 0.1, convex_hull: true"))
    api.simulate(api.load_scene(tmp_path / "s.yaml"))
    # bodies that never touch each other need no solid: the mesh's own vertices meet the floor
    (tmp_path / "s.yaml").write_text(text + "contacts: {bodies: false}\n")
    api.simulate(api.load_scene(tmp_path / "s.yaml"))
