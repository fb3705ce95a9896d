"""Convex polyhedra moving with bodies (the hulls of mesh shapes, and boxes): a hull's signed distance, and the
edge–edge contacts of two polyhedra (boxes among them).

A convex hull is the intersection of its faces' half-spaces ``n · x ≤ d``, so inside it a point's signed distance is
exactly the largest ``n · x - d`` (the nearest face). Outside, that largest value can fall short of the distance near
an edge or a corner, so points outside are measured to the hull's triangles instead.

Vertices against faces are found by the hull's vertices as probes, the same way as box corners. What vertex probes
miss is two edges crossing (a beam laid across a ridge, boxes turned 45° to each other). For two polyhedra the
separating-axis test runs over both hulls' face normals and the cross products of their edge directions; when an
edge pair's axis overlaps least, the contact is between the two edges that support the hulls along it. When an edge
axis only ties with a face's (two faces lying on each other, crossed, or one overhanging the other's edge), each
crossing of supporting edges is a contact: the corners of the patch where the faces overlap, where neither hull may
have a vertex (two planks crossed face on face). Hulls with more than :data:`MAX_EDGE_DIRECTIONS` edge directions
skip it: their vertices are dense enough that crossing edges cut in only as deep as the vertices are apart times
the edges' slope.

Edge contacts are found each step by the fixed-step methods (:class:`~animbatch.sim.contact.time_stepping.
ContactResolver`). The adaptive methods' events follow them too (:func:`edge_pairs`: a pair named once is measured
again at any state along the solver's path, in closed form, for its impact time and, resting, its force).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from animbatch.sim.bodies import Kinematics
from animbatch.sim.contact.contacts import BODY_EDGE, HULL_EDGE, STATIC, STATIC_EDGE, Contacts, make_contacts
from animbatch.sim.contact.geometry import StaticColliders, segment_closest, to_triangles
from animbatch.sim.rigid.polyhedra import convex_mesh

if TYPE_CHECKING:
    from animbatch.sim.contact.detection import ContactWorld

#: Hulls with more distinct edge directions than this leave edge–edge contact to their dense vertices.
MAX_EDGE_DIRECTIONS = 40
#: Crossings within this fraction of an edge's length from its end are left to the vertex there.
END = 1e-3
#: Overlaps within this [m] (times 1 + the hulls' reaches) count as equal: edges supporting a hull as far as one
#: another, and an edge axis as good as a face axis.
TIE = 1e-7
#: Edge directions this close to parallel (|sin angle|) count as one, and give no cross-product axis.
PARALLEL = 1e-6


@dataclass(frozen=True, eq=False)
class BodyHull:
    """A convex polyhedron fixed to body ``owner``, in body axes from its centre of mass: ``vertices`` (V, 3) [m],
    face planes ``normals`` (F, 3) (unit, outward) and ``offsets`` (F,) [m] (inside: ``n · x ≤ d``), ``triangles``
    (T, 3) vertex indices, ``edges`` (E, 2) vertex indices with their unit ``directions`` (E, 3), the distinct
    edge directions ``edge_axes`` (D, 3) (an edge and its parallels count once), and ``reach`` [m], the farthest
    vertex from the centre of mass."""

    owner: int
    vertices: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    triangles: np.ndarray
    edges: np.ndarray
    directions: np.ndarray
    edge_axes: np.ndarray
    reach: float

    @classmethod
    def of_points(cls, owner: int, points: np.ndarray) -> BodyHull:
        """The convex hull of points (V, 3), body axes from the centre of mass."""
        mesh = convex_mesh(points)  # outward-wound triangles over the hull's own vertices
        vertices, triangles = mesh.vertices, mesh.faces
        a, b, c = (vertices[triangles[:, k]] for k in range(3))
        normal = np.cross(b - a, c - a)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        equations = np.column_stack([normal, -np.einsum("ij,ij->i", normal, a)])  # n · x + e = 0 on the face
        # coplanar triangles share one face plane: keep each plane once
        planes = np.round(equations, 9)
        _, first = np.unique(planes, axis=0, return_index=True)
        normals, offsets = equations[first, :3], -equations[first, 3]
        # edges: triangle sides, leaving out the diagonals inside flat faces (between two coplanar triangles)
        sides = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
        face_of = np.tile(np.arange(len(triangles)), 3)
        key = np.sort(sides, axis=1)
        order = np.lexsort((key[:, 1], key[:, 0]))
        key, face_of = key[order], face_of[order]
        pair_first = np.flatnonzero(np.all(key[1:] == key[:-1], axis=1))
        flat = np.all(np.abs(planes[face_of[pair_first]] - planes[face_of[pair_first + 1]]) < 1e-8, axis=1)
        edges = key[pair_first[~flat]]
        directions = vertices[edges[:, 1]] - vertices[edges[:, 0]]
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        return cls(owner, vertices, normals, offsets, triangles, edges, directions, _distinct(directions),
                   float(np.max(np.linalg.norm(vertices, axis=1))))

    @classmethod
    def of_box(cls, owner: int, offset: np.ndarray, rotation: np.ndarray, half: np.ndarray) -> BodyHull:
        """A box (centre ``offset`` (3,), ``rotation`` (3, 3) box-to-body, half sides ``half`` (3,)) as a hull."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        return cls.of_points(owner, offset + (signs * half) @ rotation.T)



def _distinct(directions: np.ndarray) -> np.ndarray:
    """Unit directions (E, 3) with parallel and opposite ones kept once (D, 3)."""
    found: list[np.ndarray] = []
    for d in directions:
        if not any(np.linalg.norm(np.cross(d, u)) < PARALLEL for u in found):
            found.append(d)
    return np.array(found).reshape(-1, 3)


def to_hull(points: np.ndarray, hull: BodyHull, centre: np.ndarray, rotation: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance [m] (K,) of points (K, 3) to a hull whose body is at ``centre`` (3,) turned by ``rotation``
    (3, 3), and outward unit normals (K, 3), world axes."""
    local = (points - centre) @ rotation  # Rᵀ (p - c), row-wise
    height = local @ hull.normals.T - hull.offsets  # (K, F) how far outside each face's plane
    face = np.argmax(height, axis=1)
    distance = height[np.arange(len(points)), face]
    normal = hull.normals[face].copy()
    outside = np.flatnonzero(distance > 0)
    if len(outside):  # to the nearest triangle: exact near edges and corners too
        triangles = hull.vertices[hull.triangles]  # (T, 3, 3)
        count = len(triangles)
        d, n = to_triangles(np.repeat(local[outside], count, axis=0), np.tile(triangles, (len(outside), 1, 1)))
        d, n = d.reshape(len(outside), count), n.reshape(len(outside), count, 3)
        nearest = np.argmin(d, axis=1)
        distance[outside] = d[np.arange(len(outside)), nearest]
        normal[outside] = n[np.arange(len(outside)), nearest]
    return distance, normal @ rotation.T


def hull_edge_contact(a: BodyHull, centre_a: np.ndarray, rotation_a: np.ndarray, b: BodyHull, centre_b: np.ndarray,
                      rotation_b: np.ndarray, reach: float) -> list[tuple[np.ndarray, np.ndarray, float, int, int]]:
    """The edge–edge contacts of hull A on hull B (each at its body's centre (3,) and rotation (3, 3)) within
    ``reach`` [m]: each a contact point (3,), unit normal from B towards A, gap [m] (negative when overlapping), and
    the two edges (indices into each hull's ``edges``). Empty unless an edge pair's axis overlaps least, or as
    little as the best face's (faces lying on faces: then the edges cross at the corners of the patch where they
    overlap, and each crossing is a contact, where no vertex may be)."""
    verts_a, verts_b = centre_a + a.vertices @ rotation_a.T, centre_b + b.vertices @ rotation_b.T
    faces = np.concatenate([a.normals @ rotation_a.T, b.normals @ rotation_b.T])
    world_a, world_b = a.edge_axes @ rotation_a.T, b.edge_axes @ rotation_b.T
    crosses = np.cross(world_a[:, None, :], world_b[None, :, :]).reshape(-1, 3)
    size = np.linalg.norm(crosses, axis=1)
    pair = np.flatnonzero(size > PARALLEL)  # i·D_b + j: the directions each axis crosses
    crosses = crosses[pair] / size[pair, None]

    def overlaps(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per axis: the overlap with A on the + side of B, and with A on the − side."""
        pa, pb = verts_a @ axes.T, verts_b @ axes.T
        return pb.max(axis=0) - pa.min(axis=0), pa.max(axis=0) - pb.min(axis=0)

    face_plus, face_minus = overlaps(faces)
    best_face = float(np.minimum(face_plus, face_minus).min())
    if best_face < -reach or not len(crosses):
        return []
    plus, minus = overlaps(crosses)
    depth = np.minimum(plus, minus)
    if depth.min() < -reach:
        return []  # an edge axis separates them
    tie = TIE * (1.0 + a.reach + b.reach)
    if depth.min() > best_face + tie:
        return []  # a face overlaps least: a vertex on a face, which the vertex probes hold
    found: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, float, int, int]] = {}
    for k in np.flatnonzero(depth <= depth.min() + tie):
        normal = crosses[k] if plus[k] <= minus[k] else -crosses[k]
        i, j = divmod(int(pair[k]), len(world_b))
        # the supporting edges, of the two directions the axis crosses: A's lowest along the normal, B's highest
        for edge_a in _supporting_edges(verts_a, a.edges, world_a[i], -normal, tie):
            for edge_b in _supporting_edges(verts_b, b.edges, world_b[j], normal, tie):
                start_a, end_a = verts_a[a.edges[edge_a]]
                start_b, end_b = verts_b[b.edges[edge_b]]
                s, u = segment_parameters(start_a, end_a - start_a, start_b, end_b - start_b)
                # near or beyond an edge's end, a vertex is the contact, and its probe holds it (a second contact
                # there would make the contact solver's iteration crawl)
                if END < s < 1.0 - END and END < u < 1.0 - END:
                    point_a, point_b = start_a + s * (end_a - start_a), start_b + u * (end_b - start_b)
                    found[(edge_a, edge_b)] = (0.5 * (point_a + point_b), normal,
                                               float((point_a - point_b) @ normal), edge_a, edge_b)
    return list(found.values())


def _supporting_edges(vertices: np.ndarray, edges: np.ndarray, along: np.ndarray, direction: np.ndarray,
                      tie: float) -> np.ndarray:
    """Of the edges parallel to ``along`` (3,), those farthest in ``direction`` (3,) (to ``tie`` [m])."""
    ends = vertices[edges]
    tangent = ends[:, 1] - ends[:, 0]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    height = np.where(np.linalg.norm(np.cross(tangent, along), axis=1) < 1e-6, ends.mean(axis=1) @ direction,
                      -np.inf)
    return np.flatnonzero(height >= height.max() - tie)


def segment_parameters(start_a: np.ndarray, along_a: np.ndarray, start_b: np.ndarray, along_b: np.ndarray
                       ) -> tuple[float, float]:
    """Parameters s, u of the closest points ``start_a + s along_a`` and ``start_b + u along_b`` of two
    non-parallel lines (not clamped to the segments)."""
    between = start_a - start_b
    aa, bb, ab = float(along_a @ along_a), float(along_b @ along_b), float(along_a @ along_b)
    da, db = float(along_a @ between), float(along_b @ between)
    denominator = aa * bb - ab * ab
    if denominator <= 1e-300:
        return np.inf, np.inf
    return (ab * db - bb * da) / denominator, (aa * db - ab * da) / denominator


@lru_cache(maxsize=256)
def _box_hull(half: tuple[float, float, float]) -> BodyHull:
    """A box of half sides ``half`` as a hull about its centre (body −1: a pose is given wherever it is used)."""
    return BodyHull.of_box(-1, np.zeros(3), np.eye(3), np.array(half))


def pack_rows(parts: list[np.ndarray], columns: int, dtype: type) -> tuple[np.ndarray, np.ndarray]:
    """Row tables (n_i, columns) one after the other, as one contiguous table and its start table (len + 1,): part
    i's rows are ``rows[start[i]:start[i + 1]]`` (how the compiled searches take a list of shapes)."""
    start = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
    rows: np.ndarray = np.concatenate(parts).astype(dtype) if parts else np.zeros((0, columns), dtype)
    return np.ascontiguousarray(rows.reshape(-1, columns)), start


@dataclass(frozen=True, eq=False)
class PackedPolyhedra:
    """A world's polyhedra as :mod:`animbatch.sim.kernels.hull_edges` takes them: ``shapes`` (the packed vertex,
    edge, axis and face tables with their starts, and reaches), and per solid (the fixed boxes, then the moving boxes,
    then the hulls) ``solids``: shape, body, kind, base, probe base, material and size (see that module)."""

    shapes: tuple[np.ndarray, ...]
    solids: tuple[np.ndarray, ...]
    fixed_count: int
    excluded: np.ndarray  # sorted int64 keys of body pairs that never touch

    @classmethod
    def of_world(cls, world: ContactWorld) -> PackedPolyhedra:
        statics = world.statics
        rounds = world.cylinders.count if world.cylinders is not None else 0
        first_hull = world.probes.count + 12 * world.boxes.count + 2 * rounds
        edge_base = np.concatenate([[0], np.cumsum([len(h.edges) for h in world.hulls])]).astype(int)
        solids: list[tuple[BodyHull, int, int, int, int, int, float]] = []
        for j in range(len(statics.box_centre)):
            half = statics.box_half[j]
            solids.append((_box_hull(tuple(half)), STATIC, STATIC_EDGE, 12 * j, -1, int(statics.box_material[j]),
                           float(np.linalg.norm(half))))
        for k in range(world.boxes.count):
            half, body = world.boxes.half[k], int(world.boxes.owner[k])
            solids.append((_box_hull(tuple(half)), body, BODY_EDGE, 12 * k, world.probes.count + 12 * k,
                           int(world.body_material[body]), float(np.linalg.norm(half))))
        for k, hull in enumerate(world.hulls):
            solids.append((hull, hull.owner, HULL_EDGE, int(edge_base[k]), first_hull + int(edge_base[k]),
                           int(world.body_material[hull.owner]), hull.reach))
        hulls = [solid[0] for solid in solids]
        packed = pack_rows
        shapes = (*packed([h.vertices for h in hulls], 3, float), *packed([h.edges for h in hulls], 2, np.int64),
                  *packed([h.edge_axes for h in hulls], 3, float), *packed([h.normals for h in hulls], 3, float),
                  np.array([h.reach for h in hulls], float))
        columns = list(zip(*[solid[1:] for solid in solids])) or [()] * 6
        ints = tuple(np.array(column, np.int64) for column in columns[:5])
        excluded = np.zeros(0, np.int64) if world.excluded is None else np.asarray(world.excluded, np.int64)
        return cls(shapes, (np.arange(len(solids), dtype=np.int64), *ints, np.array(columns[5], float)),
                   len(statics.box_centre), np.sort(excluded))


_PACKED: weakref.WeakKeyDictionary[Any, PackedPolyhedra] = weakref.WeakKeyDictionary()


def compiled_edge_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders,
                           box_centres: np.ndarray, box_rotations: np.ndarray, margin: float,
                           travel: np.ndarray | None) -> Contacts:
    """:func:`edge_contacts` in one compiled call (:mod:`animbatch.sim.kernels.hull_edges`): the same contacts in
    the same order, to round-off."""
    from animbatch.sim.kernels import hull_edges

    packed = _PACKED.get(world)
    if packed is None:
        packed = _PACKED[world] = PackedPolyhedra.of_world(world)
    centres = [statics.box_centre.reshape(-1, 3), box_centres.reshape(-1, 3)]
    rotations = [statics.box_rotation.reshape(-1, 3, 3), box_rotations.reshape(-1, 3, 3)]
    if world.hulls:
        assert state.rotation is not None
        owners = np.array([hull.owner for hull in world.hulls])
        centres.append(state.x[owners])
        rotations.append(state.rotation[owners - state.first_rigid])
    steps = travel if travel is not None else np.zeros(len(world.body_material))
    search: Any = hull_edges.edge_contacts  # takes the packed tables unpacked
    ints, floats = search(
        *packed.shapes, *packed.solids, np.ascontiguousarray(np.concatenate(centres), float),
        np.ascontiguousarray(np.concatenate(rotations), float), packed.fixed_count, bool(world.bodies_collide),
        np.ascontiguousarray(world.collides, np.bool_), packed.excluded, np.asarray(steps, float), float(margin))
    return make_contacts(world, ints[:, 0], ints[:, 2], floats[:, :3], floats[:, 3:6], floats[:, 6], ints[:, 5],
                         ints[:, 1], ints[:, 3], ints[:, 4])


def build_edge_kernels() -> None:
    """Compile (or load from the disk cache) the edge search on nothing, with the argument types of a run."""
    from animbatch.sim.kernels import hull_edges

    floats, ints, starts = np.zeros((0, 3)), np.zeros((0, 2), np.int64), np.zeros(1, np.int64)
    none, no_ints = np.zeros(0), np.zeros(0, np.int64)
    hull_edges.edge_contacts(floats, starts, ints, starts, floats, starts, floats, starts, none, no_ints, no_ints,
                             no_ints, no_ints, no_ints, no_ints, none, floats, np.zeros((0, 3, 3)), 0, True,
                             np.zeros(0, np.bool_), no_ints, none, 0.0)


def edge_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
                  box_rotations: np.ndarray, margin: float, travel: np.ndarray | None) -> Contacts:
    """Crossing-edge contacts of the polyhedra moving with bodies (boxes, and the hulls of mesh shapes) against fixed
    boxes and (when bodies collide) each other, within ``margin`` [m] plus how far the pair can travel.

    Kinds: STATIC_EDGE and BODY_EDGE (solid index ``12 box + edge``) and HULL_EDGE (solid index: the edge's number
    among all hulls' edges). Probe numbers: a body box's edges ``probes + 12 box + edge``; a hull's past the probes,
    box edges, rims and sides, one per hull edge."""
    assert state.rotation is not None or not (world.boxes.count or world.hulls)
    rounds = world.cylinders.count if world.cylinders is not None else 0
    first_hull = world.probes.count + 12 * world.boxes.count + 2 * rounds
    edge_base = np.concatenate([[0], np.cumsum([len(h.edges) for h in world.hulls])]).astype(int)
    steps = travel if travel is not None else np.zeros(len(world.body_material))
    # every moving polyhedron: (hull, centre, rotation, reach, body, kind and index base as a solid, its own probe
    # base, material)
    movers: list[tuple] = []
    for k in range(world.boxes.count):
        half, body = world.boxes.half[k], int(world.boxes.owner[k])
        movers.append((_box_hull(tuple(half)), box_centres[k], box_rotations[k], float(np.linalg.norm(half)), body,
                       BODY_EDGE, 12 * k, world.probes.count + 12 * k, int(world.body_material[body])))
    for k, hull in enumerate(world.hulls):
        assert state.rotation is not None
        movers.append((hull, state.x[hull.owner], state.rotation[hull.owner - state.first_rigid], hull.reach,
                       hull.owner, HULL_EDGE, int(edge_base[k]), first_hull + int(edge_base[k]),
                       int(world.body_material[hull.owner])))
    fixed = [(_box_hull(tuple(statics.box_half[j])), statics.box_centre[j], statics.box_rotation[j],
              float(np.linalg.norm(statics.box_half[j])), STATIC, STATIC_EDGE, 12 * j, -1,
              int(statics.box_material[j])) for j in range(len(statics.box_centre))]
    found: list[tuple] = []  # (owner, probe, solid body, kind, index, solid material, point, normal, gap)
    for number, (hull, centre, rotation, size, owner, _, _, probe_base, _) in enumerate(movers):
        if not world.collides[owner]:
            continue
        others = fixed + (movers[number + 1:] if world.bodies_collide else [])
        for other, other_centre, other_rotation, other_size, body, kind, base, _, material in others:
            if body == owner or (body >= 0 and (not world.collides[body]
                                                or not world.allowed(owner, np.array([body]))[0])):
                continue
            reach = margin + float(steps[owner] + (steps[body] if body >= 0 else 0.0))
            if np.linalg.norm(centre - other_centre) > size + other_size + reach:
                continue
            if len(hull.edge_axes) > MAX_EDGE_DIRECTIONS or len(other.edge_axes) > MAX_EDGE_DIRECTIONS:
                continue
            for point, normal, gap, edge, other_edge in hull_edge_contact(hull, centre, rotation, other,
                                                                          other_centre, other_rotation, reach):
                found.append((owner, probe_base + edge, body, kind, base + other_edge, material, point, normal, gap))
    if not found:
        return Contacts.concatenate([])
    owner_, probe, solid, kind_, index, material_, point_, normal_, gap_ = (np.array(c) for c in zip(*found))
    return make_contacts(world, owner_, solid, point_, normal_, gap_, material_, probe, kind_, index)


#: The gap [m] of a followed edge pair whose closest points have left either edge (past an end a vertex probe holds
#: the contact) or whose edges have turned parallel (no crossing): the pair is gone (a resting one separates; a gap
#: this large never closes within a step).
EDGE_GONE = 1e3


def _edge_lines(world: ContactWorld, state: Kinematics, statics: StaticColliders, box_centres: np.ndarray,
                box_rotations: np.ndarray, kind: np.ndarray, number: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Edges (K,) named as :func:`edge_contacts` names a solid's edge (``kind`` STATIC_EDGE, BODY_EDGE or
    HULL_EDGE, ``number``: ``12 box + edge`` of the box's hull, or the edge's number among all hulls' edges) at
    ``state``: their starts and directions (K, 3) [m] in world axes, the centres (K, 3) of their solids, their
    bodies (K,) (STATIC for fixed boxes) and materials (K,)."""
    count = len(kind)
    start, along, centre = np.zeros((count, 3)), np.zeros((count, 3)), np.zeros((count, 3))
    body, material = np.full(count, STATIC), np.zeros(count, np.intp)
    edge_base = np.concatenate([[0], np.cumsum([len(h.edges) for h in world.hulls])]).astype(int)
    solid = np.where(kind == HULL_EDGE, np.searchsorted(edge_base, number, side="right") - 1, number // 12)
    for code, which in set(zip(kind.tolist(), solid.tolist())):  # each solid once: a handful of pairs
        rows = np.flatnonzero((kind == code) & (solid == which))
        if code == HULL_EDGE:
            hull = world.hulls[which]
            assert state.rotation is not None
            corner_at, rotation = state.x[hull.owner], state.rotation[hull.owner - state.first_rigid]
            edge = number[rows] - edge_base[which]
            owner, used = hull.owner, world.body_material[hull.owner]
        else:
            fixed = code == STATIC_EDGE
            half = statics.box_half[which] if fixed else world.boxes.half[which]
            corner_at = statics.box_centre[which] if fixed else box_centres[which]
            rotation = statics.box_rotation[which] if fixed else box_rotations[which]
            hull, edge = _box_hull(tuple(half)), number[rows] % 12
            owner = STATIC if fixed else int(world.boxes.owner[which])
            used = statics.box_material[which] if fixed else world.body_material[owner]
        ends = corner_at + hull.vertices[hull.edges[edge]] @ rotation.T  # (R, 2, 3)
        start[rows], along[rows], centre[rows] = ends[:, 0], ends[:, 1] - ends[:, 0], corner_at
        body[rows], material[rows] = owner, used
    return start, along, centre, body, material


def edge_pairs(world: ContactWorld, state: Kinematics, box_centres: np.ndarray, box_rotations: np.ndarray,
               probe: np.ndarray, kind: np.ndarray, index: np.ndarray) -> Contacts:
    """The edge–edge contacts (K,) named by ``probe`` (an edge of a moving box or hull, numbered as
    :func:`edge_contacts` numbers it), ``kind`` (STATIC_EDGE, BODY_EDGE or HULL_EDGE) and ``index`` (the other
    solid's edge), at ``state`` (its body boxes' centres and rotations given), however far apart: for following a
    contact between events.

    Each is where the two edges' lines come closest, in closed form: the gap is their distance along the common
    normal ``n ∝ a × b``, turned out of the other solid (away from its centre: where two convex solids touch edge
    on edge, the common normal is in the edge's cone of outward normals, so it points away from the solid's centre
    however deep the probe's solid has gone in), and the contact point midway. So the gap is a smooth function of
    the state while the edges cross, as the events' root searches and second differences need; a pair whose
    closest points reach within :data:`END` of an edge's end, or whose edges turn parallel, is :data:`EDGE_GONE`
    apart."""
    statics = world.statics_at(state.t)
    poses = (world, state, statics, box_centres, box_rotations)
    rounds = world.cylinders.count if world.cylinders is not None else 0
    first_hull = world.probes.count + 12 * world.boxes.count + 2 * rounds
    hull_edge = probe >= first_hull
    start_a, along_a, centre_a, body_a, _ = _edge_lines(
        *poses, np.where(hull_edge, HULL_EDGE, BODY_EDGE),
        np.where(hull_edge, probe - first_hull, probe - world.probes.count))
    start_b, along_b, centre_b, body_b, material = _edge_lines(*poses, kind, index)
    normal = np.cross(along_a, along_b)
    size = np.linalg.norm(normal, axis=1)
    crossing = size > PARALLEL * np.linalg.norm(along_a, axis=1) * np.linalg.norm(along_b, axis=1)
    normal /= np.where(crossing, size, 1.0)[:, None]
    outward = start_b + 0.5 * along_b - centre_b  # from the other solid's centre to its edge's middle
    normal *= np.where(np.einsum("ki,ki->k", normal, outward) < 0, -1.0, 1.0)[:, None]
    _, s, u = segment_closest(start_a, along_a, start_b, along_b)
    point_a, point_b = start_a + s[:, None] * along_a, start_b + u[:, None] * along_b
    gap = np.einsum("ki,ki->k", point_a - point_b, normal)
    inside = crossing & (s > END) & (s < 1 - END) & (u > END) & (u < 1 - END)
    gap[~inside] = EDGE_GONE
    return make_contacts(world, body_a, body_b, 0.5 * (point_a + point_b), normal, gap, material, probe, kind,
                         index)
