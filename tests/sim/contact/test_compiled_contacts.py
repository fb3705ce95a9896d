"""The compiled contact search (animbatch.sim.kernels.hull_edges, …) against the numpy code it replaces: the same
contacts, in the same order, to round-off, over many states near touching; and a mutated kernel must fail."""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest

from animbatch.compile.model import compile_scene
from animbatch.sim.contact import contacts, hulls
from animbatch.sim.contact.contacts import Contacts, contact_codes
from animbatch.sim.contact.detection import body_box_poses, detect
from animbatch.sim.model.dynamics import Dynamics
from animbatch.stages import parse_scene

pytest.importorskip("numba", reason="numba is not installed: numpy finds every contact")
from animbatch.sim.kernels import probe_search  # noqa: E402  (needs numba)
from support.polyhedra import jittered_states, polyhedra_model, searched  # noqa: E402


@pytest.fixture(scope="module")
def polyhedra(tmp_path_factory):
    return polyhedra_model(tmp_path_factory.mktemp("meshes"))


def _edge_contacts(model, y: np.ndarray, compiled: bool) -> Contacts:
    return searched(model, y, hulls.compiled_edge_contacts if compiled else hulls.edge_contacts)


def _same(numpy_found: Contacts, compiled_found: Contacts) -> None:
    assert compiled_found.count == numpy_found.count
    for name in Contacts.FIELDS:
        numpy_value, compiled_value = getattr(numpy_found, name), getattr(compiled_found, name)
        assert compiled_value.shape == numpy_value.shape, name
        # a normal from a closest point a few µm away carries rounding of order ε |x| / gap: 1e-12 at 10 µm
        np.testing.assert_allclose(compiled_value, numpy_value, rtol=0, atol=1e-9 if name == "normal" else 1e-12,
                                   err_msg=name)


def test_crossing_edges_are_the_numpy_ones(polyhedra):
    """Every kind of edge pair (fixed box, box body, face on face, hull on hull, box on hull), at 60 states near
    touching: the same contacts in the same order."""
    found = 0
    kinds = set()
    for y in jittered_states(polyhedra, 60, 0.004):
        numpy_found = _edge_contacts(polyhedra, y, compiled=False)
        _same(numpy_found, _edge_contacts(polyhedra, y, compiled=True))
        found += numpy_found.count
        kinds |= set(numpy_found.solid_kind.tolist())
    assert found > 60  # the states do touch edge on edge
    assert kinds == {hulls.STATIC_EDGE, hulls.BODY_EDGE, hulls.HULL_EDGE}


def test_the_kernel_constants_are_the_numpy_ones():
    from animbatch.sim.kernels import hull_edges

    for name in ("END", "TIE", "PARALLEL", "MAX_EDGE_DIRECTIONS"):
        assert getattr(hull_edges, name) == getattr(hulls, name), name


def test_a_mutated_kernel_is_caught(polyhedra, monkeypatch):
    """The comparison can fail: a kernel whose normals point the wrong way, or that loses a contact, is caught."""
    original = hulls.compiled_edge_contacts
    y = jittered_states(polyhedra, 1, 0.0)[0]
    assert _edge_contacts(polyhedra, y, compiled=False).count

    def flipped(*args):
        found = original(*args)
        return Contacts(*(-found.normal if name == "normal" else getattr(found, name) for name in Contacts.FIELDS))

    def lossy(*args):
        found = original(*args)
        return found.select(np.arange(found.count) > 0)

    for mutant in (flipped, lossy):
        monkeypatch.setattr(hulls, "compiled_edge_contacts", mutant)
        with pytest.raises(AssertionError):
            _same(_edge_contacts(polyhedra, y, compiled=False), _edge_contacts(polyhedra, y, compiled=True))


#: Probes of every kind against every solid the compiled probe search takes: particles and balls on a plane, in a
#: fixed sphere's bowl and on a fixed box, a ball on a box body; box corners on boxes (fixed and moving, face on face and corner on face);
#: balls on a log, at its rim and on a pill; two balls joined (never touching) and a cloth (its vertices never touch one another).
PROBES = """
    duration: 0.1
    fps: 10
    bodies:
      - {name: p1, mass: 0.01, radius: 0.02, position: [0, 0.019, 0]}
      - {name: p2, mass: 0.01, radius: 0.005, position: [0.03, 0.004, 0]}
      - {name: ball1, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [0.3, 0.099, 0]}
      - {name: ball2, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [0.3, 0.297, 0]}
      - {name: ball3, type: rigid, shape: {type: sphere, radius: 0.05}, density: 500, position: [2, 1.45, 0]}
      - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500,
         position: [1, 0.6 , 0], orientation: {axis: [0, 1, 0], angle: 20}}
      - {name: lid, type: rigid, shape: {type: box, size: [0.3, 0.1, 0.3]}, density: 500, position: [1, 0.749, 0]}
      - {name: tip, type: rigid, shape: {type: box, size: [0.1, 0.1, 0.1]}, density: 500,
         position: [1, 0.86, 0], orientation: {axis: [1, 1, 0], angle: 40}}
      - {name: on_box, type: rigid, shape: {type: sphere, radius: 0.05}, density: 500, position: [1.22, 0.549, 0.22]}
      - {name: on_lid, type: rigid, shape: {type: sphere, radius: 0.03}, density: 500, position: [1.12, 0.828, 0.12]}
      - {name: log, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.3}, density: 500,
         position: [3, 0.2, 0], orientation: {axis: [0, 0, 1], angle: 90}}
      - {name: pill, type: rigid, shape: {type: capsule, radius: 0.04, length: 0.2}, density: 500,
         position: [3, 0.04, 0.3], orientation: {axis: [1, 0, 0], angle: 90}}
      - {name: on_log, type: rigid, shape: {type: sphere, radius: 0.03}, density: 500, position: [3.1, 0.279, 0]}
      - {name: at_rim, type: rigid, shape: {type: sphere, radius: 0.03}, density: 500, position: [3.03, 0.38, 0]}
      - {name: on_pill, type: rigid, shape: {type: sphere, radius: 0.03}, density: 500, position: [3, 0.109, 0.3]}
      - {name: joined, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [0.3, 0.495, 0]}
      - {name: sheet, type: cloth, grid: {size: [0.3, 0.3], resolution: [4, 4]}, density: 0.15, radius: 0.01,
         position: [-1, 0.01, 0], orientation: {axis: [1, 0, 0], angle: -90}}
    joints:
      - {type: distance, between: [ball2, joined]}
    colliders:
      - {type: plane}
      - {type: sphere, position: [2, 1, 0], radius: 0.4}
      - {type: box, position: [1, 0.25, 0], size: [0.6, 0.5, 0.6]}
    contacts: {}
    """


def _found(model, y: np.ndarray, compiled: bool) -> Contacts:
    system = Dynamics(model)
    state = system.kinematics(*system.split(np.array(y, float)), t=0.0, copy=True)
    found = detect(model.contact_world, state, 0.001, np.full(model.body_count, 0.003), edges=True,
                   compiled=compiled)
    return found.select(np.argsort(contact_codes(found), kind="stable"))


@pytest.fixture(scope="module", params=["probes", "polyhedra"])
def touching(request, polyhedra):
    return compile_scene(parse_scene(textwrap.dedent(PROBES), filename="probes.yaml").spec) \
        if request.param == "probes" else polyhedra


def test_probe_contacts_are_the_numpy_ones(touching):
    """Every contact of a step's search, at 40 states near touching: the same set (the order of the parts differs,
    and the contact solver does not depend on it)."""
    kinds = set()
    for y in jittered_states(touching, 40, 0.003):
        numpy_found = _found(touching, y, compiled=False)
        _same(numpy_found, _found(touching, y, compiled=True))
        kinds |= set(numpy_found.solid_kind.tolist())
    if touching.contact_world.statics.sphere_centre.size:  # the probes scene: every kind the kernel measures
        assert {probe_search.PLANE, probe_search.STATIC_SPHERE, probe_search.STATIC_BOX, probe_search.STATIC_BOX_FACE,
                probe_search.BODY_SPHERE, probe_search.BODY_BOX, probe_search.BODY_BOX_FACE,
                probe_search.BODY_ROUND} <= kinds
    else:  # the polyhedra: hull vertices on hulls (numpy both ways) beside the compiled edges
        assert {contacts.BODY_HULL, contacts.HULL_EDGE, contacts.BODY_EDGE} <= kinds


def test_the_probe_kernel_kinds_are_the_numpy_ones():
    for name in ("PLANE", "STATIC_SPHERE", "STATIC_BOX", "BODY_SPHERE", "BODY_BOX", "STATIC_BOX_FACE",
                 "BODY_BOX_FACE", "BODY_ROUND", "BODY_HULL", "STATIC"):
        assert getattr(probe_search, name) == getattr(contacts, name), name


def test_a_mutated_probe_search_is_caught(monkeypatch):
    """A probe search that loses a contact, or measures a gap a hair off, fails the comparison."""
    from animbatch.sim.contact import detection

    model = compile_scene(parse_scene(textwrap.dedent(PROBES), filename="probes.yaml").spec)
    original = detection._compiled_probe_contacts
    y = model.y0

    def lossy(*args):
        found = original(*args)
        return found.select(np.arange(found.count) > 0)

    def off(*args):
        found = original(*args)
        return Contacts(*(found.gap + 1e-9 if name == "gap" else getattr(found, name) for name in Contacts.FIELDS))

    for mutant in (lossy, off):
        monkeypatch.setattr(detection, "_compiled_probe_contacts", mutant)
        with pytest.raises(AssertionError):
            _same(_found(model, y, compiled=False), _found(model, y, compiled=True))


@pytest.mark.parametrize("rounded", [False, True])
def test_the_round_distance_is_the_numpy_one_everywhere(rounded):
    """Points all round a cylinder or capsule (outside, inside, on its axis, on its end planes, at its centre)."""
    from animbatch.sim.contact.geometry import to_round

    rng = np.random.default_rng(5)
    axis = np.array([0.3, 0.9, -0.2]) / np.linalg.norm([0.3, 0.9, -0.2])
    centre, half, radius = np.array([0.1, -0.2, 0.3]), 0.25, 0.1
    points = centre + rng.normal(scale=0.3, size=(400, 3))
    points[:40] = centre + rng.uniform(-0.4, 0.4, size=(40, 1)) * axis  # on the axis
    points[40:60] = centre + np.array([[-half], [half]]).repeat(10, axis=0) * axis + 0.05 * rng.normal(size=(20, 3))
    points[60] = centre
    count = len(points)
    distance, normal = to_round(points, np.tile(centre, (count, 1)), np.tile(axis, (count, 1)), np.full(count, half),
                                np.full(count, radius), np.full(count, rounded))
    for k in range(count):
        found = probe_search._to_round(points[k], centre, axis, half, radius, rounded)
        np.testing.assert_allclose(found, [distance[k], *normal[k]], rtol=0, atol=1e-13, err_msg=str(points[k]))


#: Round sides against everything they meet: two rods crossed, a log across a fixed box's edge, a log across a crate's
#: edge, two logs side by side (a stretch, held at both ends), a pill across a log, a capsule along a prism's ridge.
SIDES = """
    duration: 0.1
    fps: 10
    bodies:
      - {name: rod1, type: rigid, shape: {type: cylinder, radius: 0.02, length: 1.0}, density: 500,
         position: [0, 0.02, 0], orientation: {axis: [0, 1, 0], angle: 90}}
      - {name: rod2, type: rigid, shape: {type: cylinder, radius: 0.02, length: 1.0}, density: 500,
         position: [0, 0.0598, 0], orientation: {axis: [0, 1, 0], angle: 30}}
      - {name: log1, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.6}, density: 500,
         position: [3, 0.5498, 0]}
      - {name: crate, type: rigid, shape: {type: box, size: [0.3, 0.3, 0.3]}, density: 500, position: [6, 0.15, 0],
         orientation: {axis: [0, 0, 1], angle: 45}}
      - {name: log2, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.6}, density: 500,
         position: [6, 0.2619, 0]}
      - {name: log3, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.6}, density: 500,
         position: [9, 0.05, 0]}
      - {name: log4, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.6}, density: 500,
         position: [9, 0.05, 0.0999]}
      - {name: pill, type: rigid, shape: {type: capsule, radius: 0.04, length: 0.4}, density: 500,
         position: [9, 0.139, 0.05], orientation: {axis: [0, 1, 0], angle: 90}}
    colliders:
      - {type: plane}
      - {type: box, position: [3, 0.25, 0], size: [0.4, 0.5, 0.4], orientation: {axis: [1, 0, 0], angle: 45}}
    contacts: {}
    """


def _sides(model, y: np.ndarray, compiled: bool) -> Contacts:
    from animbatch.sim.contact import sides

    found = searched(model, y, sides.compiled_side_contacts if compiled else sides.side_contacts)
    return found.select(np.argsort(contact_codes(found), kind="stable"))


def test_round_sides_are_the_numpy_ones():
    """Side contacts at 40 states near touching: the same set (rods crossed, on edges, side by side)."""
    model = compile_scene(parse_scene(textwrap.dedent(SIDES), filename="sides.yaml").spec)
    found, kinds, stretches = 0, set(), 0
    for y in jittered_states(model, 40, 0.002):
        numpy_found = _sides(model, y, compiled=False)
        _same(numpy_found, _sides(model, y, compiled=True))
        found += numpy_found.count
        kinds |= set(numpy_found.solid_kind.tolist())
        stretches += int(np.sum(numpy_found.solid_index % 2 == 1))  # the far end of a stretch
    assert found > 80 and stretches > 10
    assert kinds == {contacts.SIDE_EDGE, contacts.SIDE_ROUND}


def test_the_side_kernel_constants_are_the_numpy_ones():
    from animbatch.sim.contact import sides
    from animbatch.sim.kernels import round_sides

    for name in ("NEAREST_PASSES", "END_PASSES", "SHORT_STRETCH"):
        assert getattr(round_sides, name) == getattr(sides, name), name
    assert (round_sides.SIDE_ROUND, round_sides.SIDE_EDGE) == (contacts.SIDE_ROUND, contacts.SIDE_EDGE)


def test_the_hull_distance_is_the_numpy_one_everywhere():
    """Points inside a random convex hull, outside near its faces, edges and corners, and far away."""
    from animbatch.sim.contact.detection import _packed_hulls
    from animbatch.sim.contact.hulls import BodyHull, to_hull

    rng = np.random.default_rng(9)
    hull = BodyHull.of_points(0, rng.normal(size=(30, 3)) * [0.3, 0.2, 0.1])
    owners, reaches, vertices, _, triangles, _, planes, _ = _packed_hulls((hull,))
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    turn *= np.linalg.det(turn)
    centre = np.array([0.5, -0.1, 0.2])
    points = centre + np.concatenate([rng.normal(scale=0.05, size=(100, 3)), rng.normal(scale=0.3, size=(200, 3)),
                                      (hull.vertices * 1.01) @ turn.T])
    distance, normal = to_hull(points, hull, centre, turn)
    assert (distance < 0).sum() > 50 and (distance > 0).sum() > 100
    for k in range(len(points)):
        found = probe_search._to_hull(points[k], centre, turn, vertices, triangles, planes)
        np.testing.assert_allclose(found, [distance[k], *normal[k]], rtol=0, atol=1e-13, err_msg=str(points[k]))


def test_the_compiled_contact_rows_are_the_numpy_ones():
    """Directions, lever arms, responses and split effective masses of 60 random contacts among 8 bodies (particles,
    rigid bodies, the fixed body last), normals along every axis (both tangent-basis branches)."""
    from animbatch.sim.contact.impulses import BodyVelocities, ContactRows
    from animbatch.sim.kernels import contact_impulses

    rng = np.random.default_rng(4)
    count, size = 60, 8
    inverse_mass = np.concatenate([rng.uniform(0.2, 5.0, size - 1), [0.0]])
    inverse_inertia = np.zeros((size, 3, 3))
    for body in range(3, size - 1):  # bodies 0-2 are particles
        turn = rng.normal(size=(3, 3))
        inverse_inertia[body] = turn @ turn.T + np.eye(3)
    bodies = BodyVelocities(rng.normal(size=(size, 3)), rng.normal(size=(size, 3)), inverse_mass, inverse_inertia)
    normal = rng.normal(size=(count, 3))
    normal[:5] = [[1, 0, 0], [0, 1, 0], [0, 0, -1], [0.6, 0.8, 0], [-1, 0, 0]]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    first = rng.integers(0, size - 1, count)
    second = np.where(rng.random(count) < 0.3, -1, (first + rng.integers(1, size - 1, count)) % (size - 1))
    z = np.zeros(count)
    found = Contacts(first, second, rng.normal(size=(count, 3)), normal, z, z, z, z, np.arange(count),
                     np.zeros(count, np.intp), np.zeros(count, np.intp))
    x = rng.normal(size=(size, 3))
    rows = ContactRows(found, bodies, x)
    directions = (rows.normal_row, rows.first_row, rows.second_row)  # in the kernel's order, stacked as it returns
    numpy_rows = (rows.a, rows.b, *(np.stack([getattr(row, name) for row in directions])
                                    for name in ("d", "ang_a", "ang_b", "lin_a", "lin_b", "turn_a", "turn_b")),
                  np.stack([rows.w_n, rows.w_1, rows.w_2]))
    a, b = first.astype(np.int64), np.where(second < 0, size - 1, second).astype(np.int64)
    compiled_rows = (a, b, *contact_impulses.contact_rows(a, b, normal, found.point, x, inverse_mass,
                                                          inverse_inertia))
    assert len(numpy_rows) == len(compiled_rows) == 10
    for numpy_value, compiled_value in zip(numpy_rows, compiled_rows):
        np.testing.assert_allclose(compiled_value, numpy_value, rtol=1e-12, atol=1e-14)


def random_solve(seed: int, count: int = 40, size: int = 8):
    """K random contacts among bodies (particles, rigid bodies, a moving collider, the fixed body last): some
    approaching fast, some resting, some in the air within the step's reach, some overlapping past the slop; with a
    warm start. Returns (contacts, bodies, x, warm, kinematic slots)."""
    from animbatch.sim.contact.impulses import BodyVelocities

    rng = np.random.default_rng(seed)
    inverse_mass = np.concatenate([rng.uniform(0.2, 5.0, size - 2), [0.0, 0.0]])  # a moving collider, the fixed body
    inverse_inertia = np.zeros((size, 3, 3))
    for body in range(2, size - 2):  # bodies 0-1 are particles
        turn = rng.normal(size=(3, 3))
        inverse_inertia[body] = turn @ turn.T + np.eye(3)
    v, omega = rng.normal(size=(size, 3)), rng.normal(size=(size, 3)) * 0.3
    omega[[0, 1, size - 1]] = 0.0  # particles do not turn
    v[-1] = 0.0  # nor does the fixed body move
    driven = np.arange(size) == size - 2  # the moving collider's velocity is prescribed
    bodies = BodyVelocities(v, omega, inverse_mass, inverse_inertia, driven)
    normal = rng.normal(size=(count, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    first = rng.integers(0, size - 2, count)
    second = np.where(rng.random(count) < 0.4, -1, (first + rng.integers(1, size - 2, count)) % (size - 2))
    gap = rng.choice([-3e-3, -5e-5, 0.0, 2e-4, 5e-3], count) * rng.uniform(0.5, 1.5, count)
    found = Contacts(first, second, rng.normal(size=(count, 3)) * 0.2, normal, gap,
                     rng.uniform(0, 0.9, count), rng.uniform(0.2, 1.0, count), rng.uniform(0.1, 0.5, count),
                     np.arange(count), np.zeros(count, np.intp), np.zeros(count, np.intp))
    warm = rng.uniform(0, 0.05, count), rng.normal(size=(count, 3)) * 0.01
    kinematic = np.where(rng.random(count) < 0.15, size - 2, -1)
    return found, bodies, rng.normal(size=(size, 3)), warm, kinematic


@pytest.mark.parametrize("h, bounce", [(1e-3, True), (1e-3, False), (0.0, True)])
def test_the_compiled_impulse_solve_is_the_numpy_one(h, bounce, monkeypatch):
    """One impulse solve of random contacts (impacts, resting, speculative and overlapping ones, a moving collider,
    a warm start), compiled in one call and in numpy: the same impulses, impacts, arrival times, velocities and
    pushes, to round-off."""
    import copy

    from animbatch.sim import kernels
    from animbatch.sim.contact import impulses

    for seed in range(3):
        found, bodies, x, warm, kinematic = random_solve(seed)
        settings = dict(iterations=300, rest_speed=0.01, slop=1e-4, bounce=bounce, warm=warm, kinematic=kinematic)
        compiled_bodies = copy.deepcopy(bodies)
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
        expected = impulses.solve_impulses(found, bodies, x, h, **settings)
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
        result = impulses.solve_impulses(found, compiled_bodies, x, h, long_run=True, **settings)
        assert expected.numpy_sweeps > 0 and result.numpy_sweeps == 0  # one of each
        scale = max(1.0, float(np.abs(expected.normal_impulse).max()))
        for name in ("normal_impulse", "tangent_impulse", "tangent_vector", "arrival"):
            np.testing.assert_allclose(getattr(result, name), getattr(expected, name), rtol=0, atol=1e-9 * scale,
                                       err_msg=name)
        assert np.array_equal(result.impact, expected.impact) and (expected.impact.any() or not bounce or not h)
        # and both say alike whether the sweeps met every target, and how far off they left them
        assert result.unconverged == expected.unconverged
        np.testing.assert_allclose(result.residual, expected.residual, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(compiled_bodies.v, bodies.v, rtol=0, atol=1e-9)
        np.testing.assert_allclose(compiled_bodies.omega, bodies.omega, rtol=0, atol=1e-9)
        assert (result.pseudo_v is None) == (expected.pseudo_v is None) == (h == 0)
        if h:
            np.testing.assert_allclose(result.pseudo_v, expected.pseudo_v, rtol=0, atol=1e-9)
            np.testing.assert_allclose(result.pseudo_omega, expected.pseudo_omega, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_the_compiled_jointed_sweeps_are_the_numpy_ones(monkeypatch):
    """Every impulse solve of a jointed scene (a plank on the floor under a weight on a stalk, joined by a hinge, and
    a ball-jointed pair tumbling onto them): the compiled sweeps on the row arrays, with the jointed contacts'
    normals solved at once every few sweeps, give the numpy sweeps' impulses and velocities."""
    from animbatch import api
    from animbatch.sim.contact import impulses
    from animbatch.sim.kernels import contact_impulses
    from support.scenes import scene

    text = """
        duration: 0.4
        fps: 10
        solver: {method: symplectic_euler, dt: 0.001}
        bodies:
          - {name: plank, type: rigid, shape: {type: box, size: [0.6, 0.04, 0.2]}, density: 300, position: [0, 0.02, 0]}
          - {name: weight, type: rigid, shape: {type: sphere, radius: 0.08}, density: 8000, position: [0.25, 0.3, 0]}
          - {name: upper, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.3, 0.05], angular_velocity: [1, 0, 2]}
          - {name: lower, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.1, 0.05]}
        joints:
          - {type: hinge, between: [weight, plank], anchor: [0.25, 0.04, 0], axis: [0, 0, 1]}
          - {type: ball, between: [upper, lower], anchor: [-0.1, 0.2, 0.05]}
        colliders: [{type: plane}]
        fields: [{type: gravity}]
        contacts: {iterations: 60}  # seven of the block's solves a step at most, compared sweep for sweep
    """
    original, compared, in_contact_space = impulses._sweeps, [], []

    def both(rows, contacts, velocity, *rest):
        start = velocity.copy()
        found = original(rows, contacts, velocity, *rest)
        if rows.dense:
            compiled_velocity = start.copy()
            copied = [np.array(r) if isinstance(r, np.ndarray) else r for r in rest]
            compiled = impulses._compiled_dense_sweeps(rows, contacts, compiled_velocity, *copied)
            scale = max(1.0, float(np.abs(found[0]).max()))
            np.testing.assert_allclose(compiled[0], found[0], rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(compiled[1], found[1], rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(compiled_velocity, velocity, rtol=0, atol=1e-9)
            assert compiled[2] == found[2]  # the same sweeps, leaving the same violation
            np.testing.assert_allclose(compiled[3], found[3], rtol=1e-6, atol=1e-9)
            compared.append(rest[-3] is not None)  # whether the jointed normals' block took part
            # whether the compiled sweeps went on in contact space (the Delassus matrix) for part of the solve
            in_contact_space.append(compiled[2] > contact_impulses._contact_space_after(contacts.count,
                                                                                       len(velocity)))
        return found

    monkeypatch.setattr(impulses, "_sweeps", both)
    monkeypatch.setenv("ANIMBATCH_KERNELS", "numpy")
    api.simulate(scene(text))
    assert len(compared) > 100 and any(compared)
    assert sum(in_contact_space) >= 10


def test_the_compiled_jointed_pushes_out_of_overlaps_are_the_numpy_ones(monkeypatch):
    """A ball-jointed pair of capsules and a hinged plank started 15 mm into the floor: the split impulse's sweeps
    that push them out, compiled on the row arrays, give the numpy sweeps' pseudo-velocities, and the push does lift
    them (a push that changed nothing would compare equal too)."""
    from animbatch import api
    from animbatch.sim.contact import impulses
    from support.scenes import scene

    text = """
        duration: 0.1
        fps: 20
        solver: {method: symplectic_euler, dt: 0.001}
        bodies:
          - {name: plank, type: rigid, shape: {type: box, size: [0.6, 0.04, 0.2]}, density: 300, position: [0, 0.005, 0]}
          - {name: weight, type: rigid, shape: {type: sphere, radius: 0.08}, density: 800, position: [0.25, 0.289, 0]}
          - {name: upper, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.375, 0.3]}
          - {name: lower, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.115, 0.3]}
        joints:
          - {type: hinge, between: [weight, plank], anchor: [0.25, 0.029, 0], axis: [0, 0, 1]}
          - {type: ball, between: [upper, lower], anchor: [-0.1, 0.245, 0.3]}
        colliders: [{type: plane}]
        fields: [{type: gravity}]
    """
    original, lifted = impulses._pushes, []

    def both(rows, pseudo, push_target, enough, iterations):
        start = pseudo.copy()
        original(rows, pseudo, push_target, enough, iterations)
        if rows.dense:
            compiled = start.copy()
            impulses._compiled_dense_pushes(rows, compiled, push_target.copy(), enough, iterations)
            np.testing.assert_allclose(compiled, pseudo, rtol=0, atol=1e-12 * max(1.0, float(np.abs(pseudo).max())))
            lifted.append(float(np.abs(pseudo).max()))

    monkeypatch.setattr(impulses, "_pushes", both)
    monkeypatch.setenv("ANIMBATCH_KERNELS", "numpy")
    api.simulate(scene(text))
    assert len(lifted) >= 3 and max(lifted) > 1e-3


@pytest.mark.slow
def test_a_run_whose_contacts_cost_more_than_estimated_goes_compiled_partway_and_the_same_way_every_time(
        monkeypatch):
    """A box held by friction on a floor that tilts to 30°: the estimate (one contact search at the start) calls it
    short, so it starts in numpy, but its four redundant corners take many sweeps a step. By the counted numpy cost
    the rest of the run goes compiled, at the same step on every run in a fresh process (two runs agree exactly), and
    ends where a run in numpy all the way puts the box. Where the process has loaded the contact kernels already,
    the switch comes ten times sooner (the same box, near enough)."""
    from animbatch.compile.integrator import make_integrator
    from animbatch.sim import kernels
    from animbatch.sim.contact import time_stepping

    monkeypatch.setenv("ANIMBATCH_KERNELS", "auto")
    loaded = parse_scene("""
        duration: 0.6
        fps: 20
        solver: {method: symplectic_euler, dt: 2.0e-3}
        materials: {pad: {restitution: 0, static_friction: 0.8, kinetic_friction: 0.8}}
        bodies:
          - {name: block, type: rigid, shape: {type: box, size: [0.1, 0.1, 0.1]}, density: 500,
             position: [0.5, 0.05, 0], material: pad}
        colliders:
          - {type: plane, material: pad, keyframes: [{time: 0}, {time: 0.5, rotation: {axis: [0, 0, 1], angle: 30}}]}
        fields: [{type: gravity}]
    """, filename="tilt.yaml")
    model = compile_scene(loaded.spec)

    switches = []
    original = time_stepping.ContactResolver._count_numpy_work

    def counted(resolver, sweeps):
        original(resolver, sweeps)
        if resolver.system.long_run and not switches[-1]:
            switches[-1] = resolver._steps_counted
        resolver._steps_counted = getattr(resolver, "_steps_counted", 0) + 1

    monkeypatch.setattr(time_stepping.ContactResolver, "_count_numpy_work", counted)

    def run(fresh: bool = True) -> tuple[bool, np.ndarray]:
        if fresh:
            monkeypatch.setattr(kernels, "_loaded", set())
        switches.append(0)
        system = Dynamics(model)
        assert not system.long_run  # as the estimate left it
        result = make_integrator(loaded.spec.solver, model).integrate(system, model.y0, model.frame_times)
        return system.long_run, result.states[-1]

    (switched, end), (again, end_again) = run(), run()
    assert switched and again and switches[0] == switches[1] > 0
    np.testing.assert_array_equal(end, end_again)
    soon, soon_end = run(fresh=False)  # the kernels are loaded now
    assert soon and 0 < switches[-1] < switches[0] / 5
    np.testing.assert_allclose(model.positions(soon_end)[0], model.positions(end)[0], atol=1e-4)
    monkeypatch.setattr(time_stepping, "COMPILE_CONTACTS_AFTER", np.inf)  # numpy all the way: the same box, near enough
    stayed, numpy_end = run()
    assert not stayed
    np.testing.assert_allclose(model.positions(numpy_end)[0], model.positions(end)[0], atol=1e-4)


@pytest.mark.parametrize("compiled", [False, True])
def test_the_contacts_a_search_returns_are_contiguous_even_when_one_kind_finds_them_all(compiled):
    """A log lying across a fixed box's top, its ends over the sides, touches its two edges and nothing else: the side search alone finds contacts. The contacts
    handed to the impulse kernels are C-contiguous arrays whichever search found them (a view of a search's result
    columns would make numba compile the solver once more, for strided arrays, in the middle of a run)."""
    model = compile_scene(parse_scene(textwrap.dedent("""
        duration: 0.1
        bodies:
          - {name: log, type: rigid, shape: {type: cylinder, radius: 0.05, length: 1.6}, density: 500,
             position: [0, 0.5501, 0]}
        colliders:
          - {type: box, position: [0, 0.25, 0], size: [0.6, 0.5, 0.6]}
        """), filename="log.yaml").spec)
    system = Dynamics(model)
    state = system.kinematics(*system.split(np.array(model.y0, float)), t=0.0, copy=True)
    found = detect(model.contact_world, state, 0.01, edges=True, compiled=compiled)
    assert found.count and set(found.solid_kind) == {contacts.SIDE_EDGE}
    for name in Contacts.FIELDS:
        assert getattr(found, name).flags.c_contiguous, name


@pytest.mark.slow
def test_a_short_run_resting_on_its_contacts_is_estimated_by_its_solve_and_goes_compiled_from_the_start(monkeypatch):
    """A ball resting on a 25° slope for 1 s at 1 ms: one contact search costs a fraction of a millisecond, but each
    numpy contact step also builds rows and sweeps (some 2 ms in all, measured). The estimate counts that solve for
    the contact the search finds at the start, so its 1000 steps come to more than COMPILE_AFTER and the run is
    compiled from its first step (the timed searches alone come to about 0.1 s here: numpy all the way)."""
    from animbatch import api, stages
    from animbatch.sim.contact.time_stepping import NUMPY_CONTACT_STEP, measure_contact_search, numpy_contact_solve
    from animbatch.sim.model.compiled import COMPILE_AFTER

    monkeypatch.setenv("ANIMBATCH_KERNELS", "auto")
    theta = np.radians(25)
    normal = [-float(np.sin(theta)), float(np.cos(theta)), 0.0]
    loaded = parse_scene(textwrap.dedent(f"""
        duration: 1
        fps: 20
        solver: {{method: symplectic_euler, dt: 0.001}}
        materials: {{m: {{restitution: 0, static_friction: 0.5, kinetic_friction: 0.3}}}}
        bodies: [{{name: ball, radius: 0.05, position: {(0.05 * np.array(normal)).tolist()}, material: m}}]
        colliders: [{{type: plane, normal: {normal}, material: m}}]
        fields: [{{type: gravity}}]
    """), filename="slope.yaml")
    model = compile_scene(loaded.spec)
    _, touching = measure_contact_search(Dynamics(model))
    assert touching == 1
    assert numpy_contact_solve(touching) >= NUMPY_CONTACT_STEP and numpy_contact_solve(0) == 0.0
    chosen = []
    original = stages.dynamics_for
    monkeypatch.setattr(stages, "dynamics_for", lambda model, seconds: chosen.append(
        (seconds, original(model, seconds))) or chosen[-1][1])
    trajectory = api.simulate(loaded, model=model)
    (estimated, system), = chosen
    assert estimated >= 1000 * NUMPY_CONTACT_STEP > COMPILE_AFTER and system.long_run
    assert np.abs(trajectory.positions[:, 0] - trajectory.positions[0, 0]).max() < 1e-12  # μs > tan 25°: it stays


def test_an_adaptive_run_solves_its_resting_forces_compiled_once_they_have_cost_enough(monkeypatch):
    """A box sliding down a 20° slope under RK45 rests on four corners the whole way, a force solve per right-hand
    side. Counted in numpy cost, a long run's solves go compiled partway (here after 40 of them: the threshold is
    lowered), and the box ends where a run in numpy all the way puts it; with the threshold out of reach no solve is
    compiled."""
    from animbatch.compile.integrator import make_integrator
    from animbatch.sim import kernels
    from animbatch.sim.contact import impact_events, time_stepping
    from animbatch.sim.contact.impulses import build_contact_kernels
    from animbatch.sim.kernels import resting_forces
    from support.scenes import counting

    monkeypatch.setenv("ANIMBATCH_KERNELS", "auto")
    loaded = parse_scene("""
        duration: 0.5
        fps: 10
        solver: {method: RK45, rtol: 1.0e-8}
        bodies:
          - {name: block, type: rigid, shape: {type: box, size: [0.2, 0.1, 0.2]}, density: 500, material: ice,
             position: [0.0171010072, 0.0469846310, 0], orientation: {axis: [0, 0, 1], angle: -20}}
        colliders: [{type: plane, normal: [0.3420201433, 0.9396926208, 0], material: wood}]
        fields: [{type: gravity}]
    """, filename="slope.yaml")
    model = compile_scene(loaded.spec)
    assert build_contact_kernels() is None  # built before counting (the build calls each kernel once)
    compiled_calls = counting(monkeypatch, resting_forces, "resting_forces")
    numpy_calls = counting(monkeypatch, impact_events, "solve_forces")

    def run(threshold: float) -> np.ndarray:
        monkeypatch.setattr(kernels, "_loaded", set())
        monkeypatch.setattr(time_stepping, "COMPILE_CONTACTS_AFTER", threshold)
        compiled_calls.clear()
        numpy_calls.clear()
        system = Dynamics(model)
        return make_integrator(loaded.spec.solver, model).integrate(system, model.y0, model.frame_times).states[-1]

    end = run(39.5 * impact_events.NUMPY_FORCE_SOLVE)
    solves, compiled = len(numpy_calls), len(compiled_calls)
    assert solves > 60 and compiled == solves - 39  # the 40th solve and every one after it
    numpy_end = run(np.inf)
    assert not compiled_calls and len(numpy_calls) == solves
    np.testing.assert_allclose(model.positions(end)[0], model.positions(numpy_end)[0], rtol=0, atol=1e-12)
    moved = np.linalg.norm(model.positions(end)[0] - model.positions(model.y0)[0])
    assert moved > 0.05  # it slid: ice on wood at 20°


@pytest.mark.parametrize("scene", ["polyhedra", "sides", "sides apart"])
def test_the_edges_placed_each_step_are_edge_sets(scene, polyhedra):
    """The edge set laid out once and placed each step (body boxes, fixed boxes, hulls) is edge_set's, row for
    row, at states near touching; with bodies apart, only the fixed boxes' edges."""
    from animbatch.sim.contact import sides

    model = polyhedra if scene == "polyhedra" else compile_scene(
        parse_scene(textwrap.dedent(SIDES), filename="sides.yaml").spec)
    world, system = model.contact_world, Dynamics(model)
    if scene == "sides apart":
        world = dataclasses.replace(world, bodies_collide=False)
    assert world.boxes.count and (world.hulls or scene != "polyhedra")
    for y in jittered_states(model, 5, 0.01):
        state = system.kinematics(*system.split(np.array(y, float)), t=0.0, copy=True)
        centres, rotations = body_box_poses(world, state)
        expected = sides.edge_set(world, state, world.statics_at(0.0), centres, rotations)
        if not world.bodies_collide:
            keep = expected.body == sides.STATIC
            expected = sides.EdgeSet(*(getattr(expected, name)[keep] for name in sides.EdgeSet.__dataclass_fields__))
        found = sides.moving_edge_set(world, state, world.statics_at(0.0), centres, rotations)
        for name in ("start", "end", "body", "material", "number"):
            np.testing.assert_allclose(getattr(found, name), getattr(expected, name), rtol=0, atol=1e-14,
                                       err_msg=name)
        moving = 12 * world.boxes.count + sum(len(h.edges) for h in world.hulls) if world.bodies_collide else 0
        assert len(found.start) == len(found.body) == moving + 12 * len(world.statics.box_centre) > 0
