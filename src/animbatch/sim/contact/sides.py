"""The sides of round solids (cylinders, rods, capsules) against other sides and against edges: the contacts that
probes miss.

Probes on a cylinder's rims, and the spheres at a capsule's cap centres, catch a round solid's ends; every other
body's probes meet its side through its signed distance (:func:`~animbatch.sim.contact.geometry.to_round`). What
neither sees is a side touching something between its ends with no probe there: two rods crossing, a log lying
across a stair's edge or a box's edge.

Both are a segment against a round solid: an edge (of a box, a fixed box or a hull), or the other round's axis
thickened by its radius. A convex solid's signed distance is convex along a segment, so a search that narrows a
grid onto its least value finds the segment's point nearest the solid, to 1e-5 of the segment, whatever the shape
(a cylinder's flat ends and rims included; :func:`nearest_stretch`). Where that point is within reach, the contact
is there, the normal the solid's at that point; where the segment runs along the solid (a log lying along a ridge,
two logs side by side) the stretch within reach is bracketed and held by a contact at each of its ends, so the body
rests on a line, not on a pivot. Against another round, points at its axis's ends are left out: its rims or caps
are probes, which hold those contacts (the other round is taken as its axis thickened, a capsule: exact along its
side, which is all that is kept).

Side contacts are found each step by the fixed-step methods (:class:`~animbatch.sim.contact.time_stepping.
ContactResolver`), like box edges. The adaptive methods' events follow them too (:func:`side_pairs`: a contact named
once is measured again at any state along the solver's path, for its impact time and, resting, its force).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import cKDTree

from animbatch.sim.bodies import Kinematics
from animbatch.sim.contact.contacts import SIDE_EDGE, SIDE_ROUND, STATIC, Contacts, make_contacts
from animbatch.sim.contact.geometry import (
    StaticColliders,
    round_distance,
    segment_closest,
    segment_distance,
    to_round,
)

if TYPE_CHECKING:
    from animbatch.sim.contact.detection import ContactWorld

# the 12 edges of a box as pairs of its corners, corners numbered 4 (x > 0) + 2 (y > 0) + (z > 0)
_BOX_EDGES = np.array([(a, a | bit) for bit in (4, 2, 1) for a in range(8) if not a & bit])
_CORNER_SIGNS = np.array([[1 if c & 4 else -1, 1 if c & 2 else -1, 1 if c & 1 else -1] for c in range(8)], float)


@dataclass(frozen=True, eq=False)
class EdgeSet:
    """Edges in world axes for one step: ``start``, ``end`` (E, 3) [m], ``body`` (E,) (−1 for fixed ones),
    ``material`` (E,), and ``number`` (E,): body box edges ``12 box + edge``, then the fixed boxes' after all the
    body boxes', then the hulls' edges in order."""

    start: np.ndarray
    end: np.ndarray
    body: np.ndarray
    material: np.ndarray
    number: np.ndarray


def box_edges(centres: np.ndarray, rotations: np.ndarray, halves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends (12 X, 3) of the edges of boxes (centres (X, 3), rotations (X, 3, 3), half sides (X, 3))."""
    corners = centres[:, None, :] + np.einsum("xij,xcj->xci", rotations, _CORNER_SIGNS[None] * halves[:, None, :])
    return corners[:, _BOX_EDGES[:, 0]].reshape(-1, 3), corners[:, _BOX_EDGES[:, 1]].reshape(-1, 3)


def edge_set(world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
             box_rotations: np.ndarray) -> EdgeSet:
    """Every edge a round's side can meet, where it is in ``state``."""
    boxes = world.boxes
    starts, ends, bodies, materials = [], [], [], []
    if boxes.count:
        s, e = box_edges(box_centres, box_rotations, boxes.half)
        starts.append(s)
        ends.append(e)
        bodies.append(np.repeat(boxes.owner, 12))
        materials.append(np.repeat(world.body_material[boxes.owner], 12))
    if len(statics.box_centre):
        s, e = box_edges(statics.box_centre, statics.box_rotation, statics.box_half)
        starts.append(s)
        ends.append(e)
        bodies.append(np.full(len(s), STATIC))
        materials.append(np.repeat(statics.box_material, 12))
    for hull in world.hulls:
        rigid = hull.owner - state.first_rigid
        assert state.rotation is not None
        corners = state.x[hull.owner] + hull.vertices @ state.rotation[rigid].T
        starts.append(corners[hull.edges[:, 0]])
        ends.append(corners[hull.edges[:, 1]])
        bodies.append(np.full(len(hull.edges), hull.owner))
        materials.append(np.full(len(hull.edges), world.body_material[hull.owner]))
    if not starts:
        z3 = np.zeros((0, 3))
        return EdgeSet(z3, z3, np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0, np.intp))
    start = np.concatenate(starts)
    return EdgeSet(start, np.concatenate(ends), np.concatenate(bodies).astype(np.intp),
                   np.concatenate(materials).astype(np.intp), np.arange(len(start)))


def side_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
                  box_rotations: np.ndarray, margin: float, travel: np.ndarray | None) -> Contacts:
    """Contacts of round solids' sides with other rounds' sides (when bodies collide) and with edges, within
    ``margin`` [m] plus how far both sides can travel (``travel`` (P,) per body)."""
    rounds = world.cylinders
    assert rounds is not None and state.rotation is not None
    rigid = rounds.owner - state.first_rigid
    centre = state.x[rounds.owner] + state.lever(rigid, rounds.offset)
    axis = np.einsum("kij,kj->ki", state.rotation[rigid], rounds.axis)
    start, along = centre - rounds.half_length[:, None] * axis, 2 * rounds.half_length[:, None] * axis
    steps = travel if travel is not None else np.zeros(len(world.body_material))
    first = world.probes.count + 12 * world.boxes.count + rounds.count  # past the probes, box edges and rims
    parts = []
    edges = edge_set(world, state, statics, box_centres, box_rotations)
    if len(edges.start) and not world.bodies_collide:
        keep = edges.body == STATIC
        edges = EdgeSet(*(getattr(edges, name)[keep] for name in ("start", "end", "body", "material", "number")))
    size = rounds.half_length + rounds.radius
    largest = float(steps.max(initial=0.0))
    if len(edges.start):
        middle, half = 0.5 * (edges.start + edges.end), 0.5 * np.linalg.norm(edges.end - edges.start, axis=1)
        found = cKDTree(middle).query_ball_point(centre, size + float(half.max()) + margin + 2 * largest)
        k = np.repeat(np.arange(rounds.count), [len(f) for f in found])
        e = np.concatenate([np.asarray(f, np.intp) for f in found]) if len(k) else np.zeros(0, np.intp)
        parts.append(_touching(world, k, centre, axis, rounds.owner, edges.start[e], edges.end[e] - edges.start[e],
                               np.zeros(len(e)), edges.body[e], edges.material[e], first, SIDE_EDGE,
                               edges.number[e], margin, steps, ends=True))
    pairs = (cKDTree(centre).query_pairs(2 * float(size.max()) + margin + 2 * largest, output_type="ndarray")
             if world.bodies_collide and rounds.count > 1 else np.zeros((0, 2), np.intp))
    if len(pairs):
        k, j = pairs[:, 0], pairs[:, 1]
        # each pair both ways (the side of one against the other as a whole), but where both ways find the pair
        # touching, they found one contact twice: keep the first way's
        ways = [_touching(world, a, centre, axis, rounds.owner, start[b], along[b], rounds.radius[b],
                          rounds.owner[b], world.body_material[rounds.owner[b]], first, SIDE_ROUND, b, margin, steps,
                          ends=False) for a, b in ((k, j), (j, k))]
        pair_codes = [rounds.count * (ways[0].probe - first) + ways[0].solid_index // 2,
                      rounds.count * (ways[1].solid_index // 2) + (ways[1].probe - first)]
        parts += [ways[0], ways[1].select(~np.isin(pair_codes[1], pair_codes[0]))]
    return Contacts.concatenate(parts)


@dataclass(frozen=True, eq=False)
class _SideTables:
    """What the compiled side search takes that does not change in a run, typed as it takes it: the rounds'
    ``half_length``, ``radius``, ``rounded`` and ``owner`` (C,), every body's ``collides`` and ``material`` (P,),
    the ``excluded`` pair keys (sorted), the search ``grid`` and the first contact number."""

    half_length: np.ndarray
    radius: np.ndarray
    rounded: np.ndarray
    owner: np.ndarray
    collides: np.ndarray
    material: np.ndarray
    excluded: np.ndarray
    grid: np.ndarray
    first: int

    @classmethod
    def of_world(cls, world: ContactWorld) -> _SideTables:
        rounds = world.cylinders
        assert rounds is not None
        excluded = np.zeros(0, np.int64) if world.excluded is None else np.sort(np.asarray(world.excluded, np.int64))
        return cls(np.asarray(rounds.half_length, float), np.asarray(rounds.radius, float),
                   np.asarray(rounds.rounded, np.bool_), np.asarray(rounds.owner, np.int64),
                   np.asarray(world.collides, np.bool_), np.asarray(world.body_material, np.int64), excluded,
                   np.linspace(0.0, 1.0, GRID), world.probes.count + 12 * world.boxes.count + rounds.count)


_SIDE_TABLES: weakref.WeakKeyDictionary[ContactWorld, _SideTables] = weakref.WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class _EdgeLayout:
    """What :func:`edge_set` builds anew each step but that does not change in a run, in its order: the edges'
    ``body``, ``material`` and ``number`` (E,) (only the fixed boxes' where bodies do not collide); the fixed
    boxes' edges ``fixed_start``, ``fixed_end`` (12 S, 3) [m] (None where colliders move); and the hulls' vertices
    packed, each with its body, its rigid body and its offset ``hull_vertex`` (V, 3) [m] in the body frame, with
    ``hull_edge`` (H E, 2) indexing them."""

    body: np.ndarray
    material: np.ndarray
    number: np.ndarray
    fixed_start: np.ndarray | None
    fixed_end: np.ndarray | None
    hull_owner: np.ndarray
    hull_rigid: np.ndarray
    hull_vertex: np.ndarray
    hull_edge: np.ndarray
    first_rigid: int

    @classmethod
    def of_world(cls, world: ContactWorld, first_rigid: int) -> _EdgeLayout:
        statics, fixed_start, fixed_end = world.statics, None, None
        if world.moving is None:
            fixed_start, fixed_end = box_edges(statics.box_centre.reshape(-1, 3),
                                               statics.box_rotation.reshape(-1, 3, 3), statics.box_half.reshape(-1, 3))
        boxes, collide = world.boxes, world.bodies_collide
        hulls = world.hulls if collide else ()
        owners = np.concatenate([np.full(len(h.vertices), h.owner, np.intp) for h in hulls] or [np.zeros(0, np.intp)])
        first_vertex = np.cumsum([0] + [len(h.vertices) for h in hulls])
        edges = np.concatenate([h.edges + first_vertex[k] for k, h in enumerate(hulls)] or [np.zeros((0, 2), np.intp)])
        # edge_set's order: the body boxes' edges, the fixed boxes', the hulls'
        box_owner = np.repeat(boxes.owner, 12) if collide else np.zeros(0, np.intp)
        hull_owner = np.concatenate([np.full(len(h.edges), h.owner, np.intp) for h in hulls] or [np.zeros(0, np.intp)])
        body = np.concatenate([box_owner, np.full(12 * len(statics.box_centre), STATIC), hull_owner]).astype(np.intp)
        material = np.concatenate([world.body_material[box_owner], np.repeat(statics.box_material, 12),
                                   world.body_material[hull_owner]]).astype(np.intp)
        number = np.arange(len(body), dtype=np.intp) + (0 if collide else 12 * boxes.count)
        return cls(body, material, number, fixed_start, fixed_end, owners, owners - first_rigid,
                   np.concatenate([h.vertices for h in hulls] or [np.zeros((0, 3))]),
                   np.asarray(edges, np.intp).reshape(-1, 2), first_rigid)

    def edges(self, world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
              box_rotations: np.ndarray) -> EdgeSet:
        """:func:`edge_set` in ``state``, placing only what moves."""
        starts, ends = [], []
        if world.bodies_collide and world.boxes.count:
            s, e = box_edges(box_centres, box_rotations, world.boxes.half)
            starts.append(s)
            ends.append(e)
        if self.fixed_start is not None and self.fixed_end is not None:
            starts.append(self.fixed_start)
            ends.append(self.fixed_end)
        elif len(statics.box_centre):
            s, e = box_edges(statics.box_centre, statics.box_rotation, statics.box_half)
            starts.append(s)
            ends.append(e)
        if len(self.hull_edge):
            assert state.rotation is not None
            corners = state.x[self.hull_owner] + np.einsum("vij,vj->vi", state.rotation[self.hull_rigid],
                                                           self.hull_vertex)
            starts.append(corners[self.hull_edge[:, 0]])
            ends.append(corners[self.hull_edge[:, 1]])
        if not starts:
            return EdgeSet(np.zeros((0, 3)), np.zeros((0, 3)), self.body, self.material, self.number)
        return EdgeSet(np.concatenate(starts), np.concatenate(ends), self.body, self.material, self.number)


_EDGE_LAYOUTS: weakref.WeakKeyDictionary[ContactWorld, _EdgeLayout] = weakref.WeakKeyDictionary()


def moving_edge_set(world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
                    box_rotations: np.ndarray) -> EdgeSet:
    """The edges a round's side can meet in ``state``: :func:`edge_set`'s, only the fixed boxes' where bodies do
    not collide; what does not move is laid out once per world (for its first rigid body's index)."""
    layout = _EDGE_LAYOUTS.get(world)
    if layout is None or layout.first_rigid != state.first_rigid:
        layout = _EDGE_LAYOUTS[world] = _EdgeLayout.of_world(world, state.first_rigid)
    return layout.edges(world, state, statics, box_centres, box_rotations)


def compiled_side_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders,
                           box_centres: np.ndarray, box_rotations: np.ndarray, margin: float,
                           travel: np.ndarray | None) -> Contacts:
    """:func:`side_contacts` in one compiled call (:mod:`animbatch.sim.kernels.round_sides`): the same contacts to
    round-off, in another order."""
    from animbatch.sim.kernels import round_sides

    rounds = world.cylinders
    assert rounds is not None and state.rotation is not None
    tables = _SIDE_TABLES.get(world)
    if tables is None:
        tables = _SIDE_TABLES[world] = _SideTables.of_world(world)
    rigid = rounds.owner - state.first_rigid
    centre = state.x[rounds.owner] + state.lever(rigid, rounds.offset)
    axis = np.einsum("kij,kj->ki", state.rotation[rigid], rounds.axis)
    steps = travel if travel is not None else np.zeros(len(world.body_material))
    edges = moving_edge_set(world, state, statics, box_centres, box_rotations)
    search: Any = round_sides.side_contacts
    ints, floats = search(
        np.ascontiguousarray(centre, float), np.ascontiguousarray(axis, float), tables.half_length, tables.radius,
        tables.rounded, tables.owner, tables.collides, tables.material, np.asarray(steps, float), tables.excluded,
        np.ascontiguousarray(edges.start, float).reshape(-1, 3), np.ascontiguousarray(edges.end, float).reshape(-1, 3),
        np.asarray(edges.body, np.int64), np.asarray(edges.material, np.int64), np.asarray(edges.number, np.int64),
        bool(world.bodies_collide), float(margin), tables.first, tables.grid)
    if not len(ints):
        return Contacts.concatenate([])
    return make_contacts(world, ints[:, 0], ints[:, 1], floats[:, :3], floats[:, 3:6], floats[:, 6], ints[:, 2],
                         ints[:, 5], ints[:, 3], ints[:, 4])


def build_side_kernels() -> None:
    """Compile (or load from the disk cache) the side search on nothing, with the argument types of a run."""
    from animbatch.sim.kernels import round_sides

    f3, f, i, b = np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.bool_)
    search: Any = round_sides.side_contacts
    search(f3, f3, f, f, b, i, b, i, f, i, f3, f3, i, i, i, True, 0.0, 0, np.linspace(0.0, 1.0, GRID))


@dataclass(frozen=True, eq=False)
class _Followed:
    """Followed side contacts (K,) at one state: the rounds ``k`` (K,) with every round's ``centre`` and ``axis``
    (C, 3), and the segments they meet, ``start + u along`` (K, 3), thickened by ``radius`` (K,), on ``body`` (K,)
    of ``material`` (K,)."""

    k: np.ndarray
    centre: np.ndarray
    axis: np.ndarray
    start: np.ndarray
    along: np.ndarray
    radius: np.ndarray
    body: np.ndarray
    material: np.ndarray

    @classmethod
    def of(cls, world: ContactWorld, state: Kinematics, box_centres: np.ndarray, box_rotations: np.ndarray,
           probe: np.ndarray, kind: np.ndarray, index: np.ndarray) -> _Followed:
        rounds = world.cylinders
        assert rounds is not None and state.rotation is not None
        rigid = rounds.owner - state.first_rigid
        centre = state.x[rounds.owner] + state.lever(rigid, rounds.offset)
        axis = np.einsum("kij,kj->ki", state.rotation[rigid], rounds.axis)
        first = world.probes.count + 12 * world.boxes.count + rounds.count
        other, count = index // 2, len(probe)
        start, along = np.zeros((count, 3)), np.zeros((count, 3))
        radius, body, material = np.zeros(count), np.full(count, STATIC), np.zeros(count, np.intp)
        sides = kind == SIDE_ROUND
        b = other[sides]
        start[sides] = centre[b] - rounds.half_length[b, None] * axis[b]
        along[sides] = 2 * rounds.half_length[b, None] * axis[b]
        radius[sides], body[sides] = rounds.radius[b], rounds.owner[b]
        material[sides] = world.body_material[rounds.owner[b]]
        if (~sides).any():
            edges = edge_set(world, state, world.statics_at(state.t), box_centres, box_rotations)
            e = other[~sides]
            start[~sides], along[~sides] = edges.start[e], edges.end[e] - edges.start[e]
            body[~sides], material[~sides] = edges.body[e], edges.material[e]
        return cls(probe - first, centre, axis, start, along, radius, body, material)

    def distance_at(self, world: ContactWorld) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """``gap(chosen, u)``: the gaps [m] of segments ``chosen`` at parameters u (as :func:`nearest_stretch`
        takes it)."""
        rounds = world.cylinders
        assert rounds is not None

        def gap(chosen: np.ndarray, u: np.ndarray) -> np.ndarray:
            r = self.k[chosen]
            return round_distance(self.start[chosen] + u[:, None] * self.along[chosen], self.centre[r],
                                  self.axis[r], rounds.half_length[r], rounds.radius[r], rounds.rounded[r]
                                  ) - self.radius[chosen]

        return gap


#: The gap [m] of a followed side contact between two rounds whose nearest point has reached an end of the other's
#: axis: there the other's rim or cap probes hold the contact, and the side contact is gone (a resting one separates;
#: a gap this large never closes within a step).
SIDE_GONE = 1e3


def side_pairs(world: ContactWorld, state: Kinematics, box_centres: np.ndarray, box_rotations: np.ndarray,
               probe: np.ndarray, kind: np.ndarray, index: np.ndarray) -> Contacts:
    """The side contacts (K,) named by ``probe``, ``kind`` (SIDE_ROUND or SIDE_EDGE) and ``index`` (as
    :func:`side_contacts` numbers them), at ``state`` (its body boxes' centres and rotations given), however far
    apart: for following a contact between events. Each is at the segment's point nearest the round (whatever the
    ``index``'s end: a stretch's two ends depend on how far the search reaches, and a contact followed along a
    solver's path must be one continuous function of the state, the same when found and when followed); two rounds'
    whose nearest point is an end of the other's axis are :data:`SIDE_GONE` apart (:func:`side_contacts` leaves
    those points to the probes too)."""
    rounds = world.cylinders
    assert rounds is not None
    pairs = _Followed.of(world, state, box_centres, box_rotations, probe, kind, index)
    k = pairs.k
    # where the two axes (or the axis and the edge) come closest between their ends, the side's nearest point is
    # theirs, in closed form: continuous in the state, as the events' root searches need (a grid's nearest point
    # moves in steps, and the forces and mode functions with it); elsewhere (near an end, lying along each other)
    # the grid search's
    _, own, u = segment_closest(pairs.centre[k] - rounds.half_length[k, None] * pairs.axis[k],
                                2 * rounds.half_length[k, None] * pairs.axis[k], pairs.start, pairs.along)
    inside = (own > 1e-6) & (own < 1 - 1e-6) & (u > 1e-6) & (u < 1 - 1e-6)
    if not inside.all():
        rest = np.flatnonzero(~inside)
        distance_at = pairs.distance_at(world)
        u[rest] = nearest_point(lambda rows, at: distance_at(rest[rows], at), len(rest))[0]
    points = pairs.start + u[:, None] * pairs.along
    distance, normal = to_round(points, pairs.centre[k], pairs.axis[k], rounds.half_length[k], rounds.radius[k],
                                rounds.rounded[k])
    gap = distance - pairs.radius
    gap[(kind == SIDE_ROUND) & ((u <= 1e-6) | (u >= 1 - 1e-6))] = SIDE_GONE
    point = points - normal * (pairs.radius + 0.5 * gap)[:, None]
    return make_contacts(world, rounds.owner[k], pairs.body, point, -normal, gap, pairs.material, probe, kind, index)


def _touching(world: ContactWorld, k: np.ndarray, centre: np.ndarray, axis: np.ndarray, owner: np.ndarray,
              other_start: np.ndarray, other_along: np.ndarray, other_radius: np.ndarray, other_body: np.ndarray,
              other_material: np.ndarray, first: int, kind: int, index: np.ndarray, margin: float,
              steps: np.ndarray, *, ends: bool) -> Contacts:
    """The contacts of rounds ``k`` (K,) (centres and axes (C, 3) of all rounds) with segments ``other_start +
    u other_along`` (K, 3), u in [0, 1], thickened by ``other_radius`` (K,), on ``other_body`` (K,): at the points
    of each segment that come within its reach of the round's solid (:func:`nearest_stretch`), counting the
    segment's ends only with ``ends``. Solid index ``2 index + 0`` for the nearest point or the stretch's near end,
    ``+ 1`` for its far end."""
    rounds = world.cylinders
    assert rounds is not None
    body = owner[k]
    keep = (body != other_body) & world.collides[body]
    keep &= np.where(other_body >= 0, world.collides[np.maximum(other_body, 0)], True)
    keep &= np.where(other_body >= 0, world.allowed(body, np.maximum(other_body, 0)), True)
    k, other_start, other_along, other_radius, other_body, other_material, index = (
        a[keep] for a in (k, other_start, other_along, other_radius, other_body, other_material, index))
    reach = margin + steps[owner[k]] + np.where(other_body >= 0, steps[np.maximum(other_body, 0)], 0.0)
    # a round lies inside the capsule around its axis: segments farther than reach from that capsule cannot touch
    bound = segment_distance(centre[k] - rounds.half_length[k, None] * axis[k],
                             2 * rounds.half_length[k, None] * axis[k], other_start, other_along)
    keep = bound - rounds.radius[k] - other_radius < reach
    if not keep.any():
        return Contacts.concatenate([])
    k, other_start, other_along, other_radius, other_body, other_material, index, reach = (
        a[keep] for a in (k, other_start, other_along, other_radius, other_body, other_material, index, reach))

    def distance_at(chosen: np.ndarray, u: np.ndarray) -> np.ndarray:
        r = k[chosen]
        return round_distance(other_start[chosen] + u[:, None] * other_along[chosen], centre[r], axis[r],
                              rounds.half_length[r], rounds.radius[r], rounds.rounded[r]) - other_radius[chosen]

    def gap_at(chosen: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Gaps (K',), the round's outward normals (K', 3) and the segment's points (K', 3) at parameters u."""
        r = k[chosen]
        points = other_start[chosen] + u[:, None] * other_along[chosen]
        distance, normal = to_round(points, centre[r], axis[r], rounds.half_length[r], rounds.radius[r],
                                    rounds.rounded[r])
        return distance - other_radius[chosen], normal, points

    stretch = np.concatenate(nearest_stretch(distance_at, len(k), reach))  # the first ends, then the second
    end = np.repeat([0, 1], len(k))
    chosen = np.flatnonzero(np.isfinite(stretch))
    if not ends:
        chosen = chosen[(stretch[chosen] > 1e-6) & (stretch[chosen] < 1 - 1e-6)]
    end, pair = end[chosen], chosen % len(k)
    gap, normal, points = gap_at(pair, stretch[chosen])
    # the segment's surface point nearest the round, and the contact midway between the two surfaces
    point = points - normal * (other_radius[pair] + 0.5 * gap)[:, None]
    return make_contacts(world, owner[k[pair]], other_body[pair], point, -normal, gap, other_material[pair],
                         first + k[pair], kind, 2 * index[pair] + end)


#: Points per pass of the grid searches along a segment, and passes: each pass looks at GRID points across the bracket
#: the last one left (2 grid spacings wide), so the nearest point is found to ~(2 / GRID)^PASSES / GRID of the
#: segment (1e-5), and a stretch's ends to (1 / GRID)^PASSES.
GRID, NEAREST_PASSES, END_PASSES = 17, 5, 4
#: A stretch shorter than this fraction of its segment is one point (crossing segments), not two ends.
SHORT_STRETCH = 1e-3


def _grid_search(gap: Callable[[np.ndarray, np.ndarray], np.ndarray]
                 ) -> Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """``looked_at(chosen, low, high)``: parameters (N, GRID) spread over each bracket of segments ``chosen`` (N,),
    and their gaps there."""
    spacing = np.linspace(0.0, 1.0, GRID)

    def looked_at(chosen: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = low[:, None] + (high - low)[:, None] * spacing
        return u, gap(np.repeat(chosen, GRID), u.ravel()).reshape(u.shape)

    return looked_at


def nearest_point(gap: Callable[[np.ndarray, np.ndarray], np.ndarray], count: int) -> tuple[np.ndarray, np.ndarray]:
    """For ``count`` segments, each against a convex solid (``gap`` as in :func:`nearest_stretch`), the parameter
    (K,) of each segment's point nearest its solid, to 1e-5 of the segment, and the least gap (K,) [m] there."""
    looked_at = _grid_search(gap)
    everyone, rows = np.arange(count), np.arange(count)
    low, high = np.zeros(count), np.ones(count)
    for _ in range(NEAREST_PASSES):
        u, f = looked_at(everyone, low, high)
        best = np.argmin(f, axis=1)
        low, high = u[rows, np.maximum(best - 1, 0)], u[rows, np.minimum(best + 1, GRID - 1)]
    return u[rows, best], f[rows, best]


def nearest_stretch(gap: Callable[[np.ndarray, np.ndarray], np.ndarray], count: int, reach: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """For ``count`` segments, each against a convex solid, where along the segment (u in [0, 1]) it comes within
    ``reach`` (K,) [m] of the solid: ``gap(chosen, u)`` gives the gaps of segments ``chosen`` at parameters u (both
    (N,)). The distance of a convex solid is a convex function along a segment, so a grid search that narrows onto
    the least value of :data:`GRID` points finds its least gap; where that is within reach, the ends of the stretch
    within ``least gap + slack`` (a tenth of the reach) are found the same way. All segments are searched at once,
    a few calls of ``gap`` in all. Returns (first, second) parameters (K,) each: the stretch's ends, or for a short
    stretch (crossing segments) its nearest point and NaN; both NaN where the segment stays out of reach."""
    looked_at = _grid_search(gap)
    nearest, least = nearest_point(gap, count)
    first, second = np.full(count, np.nan), np.full(count, np.nan)
    near = np.flatnonzero(least < reach)
    if not len(near):
        return first, second
    level = np.tile(least[near] + 0.1 * reach[near], 2)
    # both ends at once: from the segment's start up to the nearest point, and from its end back down to it
    chosen = np.tile(near, 2)
    outer = np.concatenate([np.zeros(len(near)), np.ones(len(near))])
    inner = np.tile(nearest[near], 2)
    ends_below = gap(chosen, outer) <= level  # the stretch reaches the segment's end
    rows = np.arange(len(chosen))
    for _ in range(END_PASSES):
        u, f = looked_at(chosen, outer, inner)  # from outside the stretch (above the level) inwards
        inside = np.argmax(f <= level[:, None], axis=1)  # the first point below the level (the inner end is)
        outer, inner = u[rows, np.maximum(inside - 1, 0)], u[rows, inside]
    ends = np.where(ends_below, np.concatenate([np.zeros(len(near)), np.ones(len(near))]), inner)
    start, stop = ends[:len(near)], ends[len(near):]
    short = stop - start < SHORT_STRETCH
    first[near] = np.where(short, nearest[near], start)
    second[near] = np.where(short, np.nan, stop)
    return first, second
