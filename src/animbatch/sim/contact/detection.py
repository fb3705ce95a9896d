"""Finding contacts: which probes are near which solids (broad phase), and how far apart they are (narrow phase).

Broad phase: a k-d tree (``scipy.spatial.cKDTree``) over the probes' centres, queried once per solid, plus
trees over mesh triangles built once (:mod:`~animbatch.sim.contact.meshes`); so N bodies cost O(N log N), not O(N²).
Contacts closer than a margin are kept ("speculative" contacts): with the margin at least the distance a pair can
close in a step, the solver sees every obstacle a fast body could reach during the step, however thin (a swept
test: no tunnelling).

The distance a pair can close is the sum of what *both* its sides travel: a probe moving at v towards a fixed wall
closes v h, but two bodies moving towards each other at v each close 2 v h. So :func:`detect` takes each body's
``travel`` over the step and keeps a pair while its gap is below ``margin + travel[probe body] + travel[solid body]``
(fixed colliders travel nothing). With only the larger of the two travels, two bodies approaching each other were
looked for at half the distance they close, and passed through each other.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from animbatch.errors import SimulationError
from animbatch.sim.bodies import Kinematics
from animbatch.sim.contact.contacts import (
    BODY_BOX,
    BODY_BOX_FACE,
    BODY_EDGE,
    BODY_HULL,
    BODY_ROUND,
    BODY_SPHERE,
    HULL_EDGE,
    PLANE,
    PLANE_RIM,
    SIDE_EDGE,
    SIDE_ROUND,
    STATIC,
    STATIC_BOX,
    STATIC_BOX_FACE,
    STATIC_EDGE,
    STATIC_SPHERE,
    TRIANGLE,
    Contacts,
    make_contacts,
)
from animbatch.sim.contact.geometry import (
    BodyBoxes,
    BodyCylinders,
    Probes,
    StaticColliders,
    cylinder_support,
    separating_direction,
    to_box,
    to_box_face,
    to_face_plane,
    to_plane,
    to_round,
    to_sphere,
    to_triangles,
)
from animbatch.sim.contact.hulls import (
    BodyHull,
    compiled_edge_contacts,
    edge_contacts,
    edge_pairs,
    pack_rows,
    to_hull,
)
from animbatch.sim.contact.materials import MaterialTable
from animbatch.sim.contact.meshes import TriangleGroup
from animbatch.sim.contact.moving import MovingColliders
from animbatch.sim.contact.sides import compiled_side_contacts, side_contacts, side_pairs

#: For each kind of contact with a collider: which of MovingColliders' solid arrays its index runs over, and the
#: index's stride (a box face is 6 × box + face, a box edge 12 × box + edge).
MOVING_SOLIDS = {PLANE: ("plane", 1), PLANE_RIM: ("plane", 1), STATIC_SPHERE: ("sphere", 1), STATIC_BOX: ("box", 1),
                 STATIC_BOX_FACE: ("box", 6), STATIC_EDGE: ("box", 12), TRIANGLE: ("triangle", 1)}


@dataclass(frozen=True, eq=False)
class ContactWorld:
    """Everything contact detection needs that does not change during a run.

    ``body_material`` (P,) material index per body; ``collides`` (P,) bool; ``bodies_collide``: whether bodies touch
    each other (not only colliders); ``triangles``: the mesh colliders' triangles as groups searched through one k-d
    tree each (the fixed meshes together, each moving one alone); ``group`` (P,): bodies of one group ≥ 0 (the
    vertices of one cloth or lattice) never collide with each other, and do not bounce (restitution 0: a point of a
    sheet has no elastic rebound of its own; a lattice bounces through its springs). ``collider_source``: for the
    fixed solids of each kind (PLANE, STATIC_SPHERE, STATIC_BOX, TRIANGLE), the number of the scene collider each
    came from, to name it in messages. ``body_names`` and ``body_mass`` (P,) [kg] name a body in messages.
    """

    probes: Probes
    boxes: BodyBoxes
    statics: StaticColliders
    materials: MaterialTable
    body_material: np.ndarray
    collides: np.ndarray
    bodies_collide: bool
    triangles: tuple[TriangleGroup, ...]
    group: np.ndarray | None = None
    collider_source: dict[int, np.ndarray] | None = None
    body_names: tuple[str, ...] = ()
    body_mass: np.ndarray | None = None
    excluded: np.ndarray | None = None  # sorted keys a·P + b (a < b) of body pairs that never touch (jointed)
    moving: MovingColliders | None = None  # colliders on keyframes (kinematic solids)
    cylinders: BodyCylinders | None = None  # cylinders, rods and capsules moving with bodies (round solids)
    hulls: tuple[BodyHull, ...] = ()  # convex polyhedra moving with bodies (mesh shapes)

    def statics_at(self, t: float) -> StaticColliders:
        """The fixed solids at time t [s] (moving colliders where their paths put them)."""
        return self.statics if self.moving is None else self.moving.place(self.statics, t)

    def kinematic_slots(self, contacts: Contacts) -> np.ndarray | None:
        """For each contact, the moving collider (its path index) it touches, or −1; None without moving ones."""
        if self.moving is None:
            return None
        slots = self.moving.slots(contacts.solid_kind, contacts.solid_index, MOVING_SOLIDS)
        side = (contacts.solid_kind == SIDE_EDGE) & (contacts.solid_body == STATIC)  # a fixed box's edge
        slots[side] = self.moving.box[(contacts.solid_index[side] // 2 - 12 * self.boxes.count) // 12]
        return slots

    def allowed(self, first: np.ndarray | int, second: np.ndarray) -> np.ndarray:
        """Whether bodies ``first`` and ``second`` (K,) may touch: not a pair a joint joins (the joint holds them,
        and contact would fight it where their shapes meet at the joint)."""
        if self.excluded is None:
            return np.ones(np.shape(second), bool)
        low, high = np.minimum(first, second), np.maximum(first, second)
        return ~np.isin(low.astype(np.int64) * len(self.body_material) + high, self.excluded)


@dataclass(frozen=True)
class ContactSettings:
    """Solver settings: iterations per step, rest speed [m/s] (None: automatic), slop [m]."""

    iterations: int
    rest_speed: float | None
    slop: float


#: Positions [m] or distances moved in one step beyond this mean the run has diverged (scene numbers stay below 1e35).
RUNAWAY_SCALE = 1e100


def turn_angle(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """The angle [rad] between rotation matrices (..., 3, 3): cos θ = (trace(R0ᵀ R1) - 1) / 2."""
    trace = np.einsum("...ij,...ij->...", r0, r1)
    return np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0))


def points_moved(reach: np.ndarray, s0: Kinematics, s1: Kinematics) -> np.ndarray:
    """How far each body's points move between two states (P,) [m], for bodies reaching ``reach`` (P,) [m] from their
    centres of mass: the centre's move plus the reach times the angle turned (a point at r moves by at most
    ``|Δx| + |r| θ``)."""
    moved = np.linalg.norm(s1.x - s0.x, axis=1)
    if s0.rotation is not None and s1.rotation is not None:
        moved[s0.first_rigid:] += reach[s0.first_rigid:] * turn_angle(s0.rotation, s1.rotation)
    return moved


def check_scale(world: ContactWorld, state: Kinematics, travel: np.ndarray | None) -> None:
    """Stop a run whose bodies have left every physical scale (a feather-light body kicked by heavy ones, say)
    before the k-d tree search overflows on them: every method's contact search comes through here, and the
    per-frame or per-step divergence checks only catch values that are no longer finite."""
    within = float(np.abs(state.x).max(initial=0.0)) < RUNAWAY_SCALE  # (false for NaN)
    if travel is not None:
        within = within and float(travel.max(initial=0.0)) < RUNAWAY_SCALE
    if within:
        return
    size = np.max(np.abs(state.x), axis=1)
    if travel is not None:
        size = np.maximum(size, travel)
    body = int(np.argmax(np.where(np.isfinite(size), size, np.inf)))
    name = world.body_names[body] if world.body_names else f"number {body}"
    mass = f" (mass {float(world.body_mass[body]):.3g} kg)" if world.body_mass is not None else ""
    raise SimulationError(
        f"body {name!r}{mass} left every physical scale at t = {state.t:.6g} s (position "
        f"{np.max(np.abs(state.x[body])):.3g} m, speed {np.linalg.norm(state.v[body]):.3g} m/s): the simulation "
        "diverged, so no contact can be found. Check that body's mass against the bodies it hits and the forces on "
        "it, or take a smaller solver.dt or tighter solver.rtol", time=state.t, body=name)


def body_reach(world: ContactWorld, body_count: int) -> np.ndarray:
    """For each body (P,), how far its collision geometry reaches from its centre of mass [m]: the largest
    ``|offset| + radius`` of its probes (box faces lie within their corners). A turn by θ moves no point of the body
    further than ``reach θ``."""
    probes = world.probes
    reach = np.zeros(body_count)
    np.maximum.at(reach, probes.owner, np.linalg.norm(probes.offset, axis=1) + probes.radius)
    return reach


def probe_centres(world: ContactWorld, state: Kinematics) -> np.ndarray:
    """World positions (Q, 3) of all probes."""
    probes = world.probes
    centres = state.x[probes.owner]  # (a fancy index: a copy)
    found = _OFF_CENTRE.get(world)
    if found is None or found[0] != state.first_rigid:  # which probes a turn moves: the same every step
        on_rigid = np.flatnonzero((probes.owner >= state.first_rigid) & np.any(probes.offset != 0, axis=1))
        found = _OFF_CENTRE[world] = (state.first_rigid, on_rigid, probes.owner[on_rigid] - state.first_rigid,
                                      probes.offset[on_rigid])
    _, on_rigid, rigid, offset = found
    if len(on_rigid):
        centres[on_rigid] += state.lever(rigid, offset)
    return centres


#: For each world: the first rigid body's index, and its probes off their body's centre of mass (indices (Q',),
#: their rigid bodies (Q',) and offsets (Q', 3)), which move with the body's turn.
_OFF_CENTRE: weakref.WeakKeyDictionary[ContactWorld, tuple[int, np.ndarray, np.ndarray, np.ndarray]] = \
    weakref.WeakKeyDictionary()


def closing_margin(probe_body: np.ndarray, solid_body: np.ndarray, margin: float, travel: np.ndarray | None
                   ) -> np.ndarray:
    """How close (gap [m]) pairs (K,) of a probe (or another feature) on ``probe_body`` and a solid on
    ``solid_body`` must be to be kept: ``margin`` plus the distance both sides can travel (``travel`` (P,) per body,
    None: no travel; fixed solids, body -1, travel nothing)."""
    if travel is None:
        return np.full(len(probe_body), margin)
    solid = np.where(solid_body >= 0, travel[np.maximum(solid_body, 0)], 0.0)
    return margin + travel[probe_body] + solid


def _contacts(world: ContactWorld, probes: np.ndarray, centres: np.ndarray, distance: np.ndarray,
              normal: np.ndarray, solid_body: np.ndarray, solid_material: np.ndarray, margin: float,
              kind: int | np.ndarray, solid_index: np.ndarray, travel: np.ndarray | None = None) -> Contacts:
    """Contacts from probe indices (K,), their centres, distances of the centres to the solids and normals; those
    with a gap under the pair's :func:`closing_margin` are kept."""
    radius = world.probes.radius[probes]
    gap = distance - radius
    keep = gap < closing_margin(world.probes.owner[probes], solid_body, margin, travel)
    every = bool(keep.all())  # (the compiled search hands over only contacts: all of them)
    if every:  # the contacts' own arrays, contiguous, as the selections below make them
        probes, normal = probes.copy(), np.ascontiguousarray(normal)
    else:
        probes, gap, normal, radius = probes[keep], gap[keep], normal[keep], radius[keep]
        centres, solid_body, solid_material = centres[keep], solid_body[keep], solid_material[keep]
    owner = world.probes.owner[probes]
    point = centres - normal * (radius + 0.5 * gap)[:, None]  # midway between the two surfaces
    a, b = world.body_material[owner], solid_material
    table = world.materials
    restitution = table.restitution[a, b]
    if world.group is not None:
        restitution = np.where(world.group[owner] >= 0, 0.0, restitution)
    kinds, index = np.broadcast_to(np.asarray(kind, np.intp), keep.shape), np.broadcast_to(solid_index, keep.shape)
    return Contacts(owner, solid_body, point, normal, gap, restitution, table.static_friction[a, b],
                    table.kinetic_friction[a, b], probes, kinds.copy() if every else kinds[keep],
                    (index if every else index[keep]).astype(np.intp))


def detect(world: ContactWorld, state: Kinematics, margin: float, travel: np.ndarray | None = None, *,
           edges: bool = False, compiled: bool = False) -> Contacts:
    """Every probe–solid pair whose gap is below ``margin`` [m] plus how far both sides can travel (``travel`` (P,)
    [m] per body, the most any of its points moves in the coming step; None: nothing moves), as contacts; with
    ``edges``, also the contacts that probes miss: edges crossing edges (:mod:`animbatch.sim.contact.hulls`),
    cylinders' rims on planes, and the sides of rounds (:mod:`animbatch.sim.contact.sides`). ``compiled``: search
    with the compiled kernels where there are some (the same contacts, to round-off)."""
    check_scale(world, state, travel)
    centres = probe_centres(world, state)
    active = world.collides[world.probes.owner]
    statics, parts = world.statics_at(state.t), []
    everywhere = np.flatnonzero(active)
    largest_travel = float(travel.max(initial=0.0)) if travel is not None else 0.0
    reach = margin + largest_travel + (float(world.probes.radius.max()) if world.probes.count else 0.0)
    box_centres, box_rotations = body_box_poses(world, state)
    by_kernel = compiled and world.probes.count <= COMPILED_PROBES
    # the compiled search tests every pair itself; the numpy one finds them through a k-d tree of the probes
    tree = cKDTree(centres) if world.probes.count and not by_kernel else None

    def near(centre: np.ndarray, radius: float) -> np.ndarray:
        if tree is None:  # no probes: nothing is near anything
            return np.zeros(0, np.intp)
        found = np.asarray(tree.query_ball_point(centre, radius + reach), dtype=np.intp)
        return found[active[found]] if len(found) else found

    if by_kernel:
        parts.append(_compiled_probe_contacts(world, state, statics, centres, active, margin, largest_travel,
                                              box_centres, box_rotations, travel))
    else:
        for k in range(len(statics.plane_point)):
            d, n = to_plane(centres[everywhere], statics.plane_point[k], statics.plane_normal[k])
            parts.append(_contacts(world, everywhere, centres[everywhere], d, np.array(n), np.full(len(d), STATIC),
                                   np.full(len(d), statics.plane_material[k]), margin, PLANE, np.full(len(d), k),
                                   travel))
        for k in range(len(statics.sphere_centre)):
            chosen = near(statics.sphere_centre[k], statics.sphere_radius[k])
            d, n = to_sphere(centres[chosen], np.broadcast_to(statics.sphere_centre[k], (len(chosen), 3)),
                             np.full(len(chosen), statics.sphere_radius[k]))
            parts.append(_contacts(world, chosen, centres[chosen], d, n, np.full(len(chosen), STATIC),
                                   np.full(len(chosen), statics.sphere_material[k]), margin, STATIC_SPHERE,
                                   np.full(len(chosen), k), travel))
        for k in range(len(statics.box_centre)):
            chosen = near(statics.box_centre[k], float(np.linalg.norm(statics.box_half[k])))
            parts.append(_box_contacts(world, chosen, centres, statics.box_centre[k], statics.box_rotation[k],
                                       statics.box_half[k], STATIC, statics.box_material[k], margin,
                                       (STATIC_BOX, STATIC_BOX_FACE), k, box_centres, box_rotations, travel))
    for group in world.triangles:
        points = centres[everywhere]
        if group.path >= 0:
            assert world.moving is not None
            points = world.moving.to_rest(group.path, points, state.t)
        which, triangles = group.near(points, reach)
        probes = everywhere[which]
        if len(probes):
            d, n = to_triangles(centres[probes], statics.triangles[triangles], state.x[world.probes.owner[probes]],
                                closing_margin(world.probes.owner[probes], np.full(len(probes), STATIC), margin,
                                               travel))
            parts.append(_contacts(world, probes, centres[probes], d, n, np.full(len(probes), STATIC),
                                   statics.triangle_material[triangles], margin, TRIANGLE, triangles, travel))
    if world.bodies_collide and tree is not None:
        parts += _between_bodies(world, state, centres, tree, active, margin, box_centres, box_rotations, travel)
    if edges and (world.boxes.count or world.hulls):
        search = compiled_edge_contacts if compiled else edge_contacts
        parts.append(search(world, state, statics, box_centres, box_rotations, margin, travel))
    if edges and world.cylinders is not None and len(statics.plane_point):
        parts.append(rim_contacts(world, state, statics, margin, travel))
    if edges and world.cylinders is not None:
        sides = compiled_side_contacts if compiled else side_contacts
        parts.append(sides(world, state, statics, box_centres, box_rotations, margin, travel))
    return Contacts.concatenate(parts)


#: Scenes with at most this many probes search them with the compiled kernel (every pair tested: the k-d tree
#: pays beyond); more, the numpy search.
COMPILED_PROBES = 1000


@dataclass(frozen=True, eq=False)
class _ProbeTables:
    """What the compiled probe search takes that does not change in a run, typed as it takes it."""

    owner: np.ndarray
    box: np.ndarray
    radius: np.ndarray
    group: np.ndarray
    material: np.ndarray
    collides: np.ndarray
    excluded: np.ndarray
    box_owner: np.ndarray
    box_half: np.ndarray
    rounds: tuple[np.ndarray, ...]  # owner, half length, radius, capsule or not (C,)
    hulls: tuple[np.ndarray, ...]  # owner, reach (H,); packed vertices, triangles and planes with their starts
    fixed: tuple[np.ndarray, ...] | None  # the fixed solids' arguments (None where colliders move)

    @classmethod
    def of_world(cls, world: ContactWorld) -> _ProbeTables:
        probes, count, rounds = world.probes, len(world.body_material), world.cylinders
        group = np.full(count, -1, np.int64) if world.group is None else np.asarray(world.group, np.int64)
        excluded = np.zeros(0, np.int64) if world.excluded is None else np.sort(np.asarray(world.excluded, np.int64))
        return cls(np.asarray(probes.owner, np.int64), np.asarray(probes.box, np.int64),
                   np.asarray(probes.radius, float), group, np.asarray(world.body_material, np.int64),
                   np.asarray(world.collides, np.bool_), excluded, np.asarray(world.boxes.owner, np.int64),
                   np.ascontiguousarray(world.boxes.half, float).reshape(-1, 3),
                   (np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0, np.bool_)) if rounds is None else
                   (np.asarray(rounds.owner, np.int64), np.asarray(rounds.half_length, float),
                    np.asarray(rounds.radius, float), np.asarray(rounds.rounded, np.bool_)),
                   _packed_hulls(world.hulls), None if world.moving is not None else _static_arguments(world.statics))


def _static_arguments(statics: StaticColliders) -> tuple[np.ndarray, ...]:
    """The fixed solids as the compiled probe search takes them: planes' points, normals and materials, spheres'
    centres, radii and materials, boxes' centres, rotations, half sides and materials."""
    def floats3(rows: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(rows, float).reshape(-1, 3)

    def ints(values: np.ndarray) -> np.ndarray:
        return np.asarray(values, np.int64)

    return (floats3(statics.plane_point), floats3(statics.plane_normal), ints(statics.plane_material),
            floats3(statics.sphere_centre), np.asarray(statics.sphere_radius, float), ints(statics.sphere_material),
            floats3(statics.box_centre), np.ascontiguousarray(statics.box_rotation, float).reshape(-1, 3, 3),
            floats3(statics.box_half), ints(statics.box_material))


def _packed_hulls(hulls: tuple[BodyHull, ...]) -> tuple[np.ndarray, ...]:
    """Owners and reaches (H,), then vertices (V, 3), triangles (T, 3) and planes (F, 4) ``n, d``, each packed with
    its start table (H + 1,)."""
    packed = pack_rows
    return (np.array([h.owner for h in hulls], np.int64), np.array([h.reach for h in hulls], float),
            *packed([h.vertices for h in hulls], 3, float), *packed([h.triangles for h in hulls], 3, np.int64),
            *packed([np.column_stack([h.normals, h.offsets]) for h in hulls], 4, float))


_TABLES: weakref.WeakKeyDictionary[ContactWorld, _ProbeTables] = weakref.WeakKeyDictionary()


def _compiled_probe_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders, centres: np.ndarray,
                             active: np.ndarray, margin: float, largest_travel: float, box_centres: np.ndarray,
                             box_rotations: np.ndarray, travel: np.ndarray | None) -> Contacts:
    """The probes' contacts with planes, fixed spheres and boxes, other probes, body boxes and round solids,
    measured by one compiled call (:mod:`animbatch.sim.kernels.probe_search`): the numpy search's contacts, to
    round-off."""
    from animbatch.sim.kernels import probe_search

    tables = _TABLES.get(world)
    if tables is None:
        tables = _TABLES[world] = _ProbeTables.of_world(world)

    def floats3(rows: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(rows, float).reshape(-1, 3)

    rounds_at = ((np.zeros((0, 3)), np.zeros((0, 3))) if world.cylinders is None else
                 tuple(np.ascontiguousarray(a, float) for a in round_poses(world, state)))
    owners = tables.hulls[0]
    hull_poses = ((np.zeros((0, 3)), np.zeros((0, 3, 3))) if not len(owners) or state.rotation is None else
                  (np.ascontiguousarray(state.x[owners], float),
                   np.ascontiguousarray(state.rotation[owners - state.first_rigid], float)))
    steps = travel if travel is not None else np.zeros(len(world.body_material))
    search: Any = probe_search.probe_candidates
    found, measured = search(
        floats3(centres), tables.owner, tables.box, tables.radius, np.asarray(active, np.bool_), tables.group,
        tables.material, tables.collides, tables.excluded,
        *(tables.fixed if tables.fixed is not None else _static_arguments(statics)), tables.box_owner,
        floats3(box_centres),
        np.ascontiguousarray(box_rotations, float).reshape(-1, 3, 3), tables.box_half, tables.rounds[0],
        *rounds_at, *tables.rounds[1:], *tables.hulls[:2], *hull_poses, *tables.hulls[2:],
        bool(world.bodies_collide), float(margin), float(largest_travel), np.asarray(steps, float))
    probe = found[:, 0].astype(np.intp)
    return _contacts(world, probe, centres[probe], measured[:, 0], measured[:, 1:], found[:, 1].astype(np.intp),
                     found[:, 2].astype(np.intp), margin, found[:, 3].astype(np.intp), found[:, 4].astype(np.intp),
                     travel)


def build_probe_kernels() -> None:
    """Compile (or load from the disk cache) the probe search on nothing, with the argument types of a run."""
    from animbatch.sim.kernels import probe_search

    f3, f33, f, i, b = np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.bool_)
    search: Any = probe_search.probe_candidates
    search(f3, i, i, f, b, i, i, b, i, f3, f3, i, f3, f, i, f3, f33, f3, i, i, f3, f33, f3, i, f3, f3, f, f, b, i, f,
           f3, f33, f3, np.zeros(1, np.int64), np.zeros((0, 3), np.int64), np.zeros(1, np.int64), np.zeros((0, 4)),
           np.zeros(1, np.int64), True, 0.0, 0.0, f)


#: For each world, its colliding cylinders and rods (indices into its round solids), for the rim search.
_PLAIN_CYLINDERS: weakref.WeakKeyDictionary[ContactWorld, np.ndarray] = weakref.WeakKeyDictionary()


def rim_contacts(world: ContactWorld, state: Kinematics, statics: StaticColliders, margin: float,
                 travel: np.ndarray | None) -> Contacts:
    """The exact contacts of cylinders with planes: at each cylinder's point deepest towards the plane (on a rim), so
    that a cylinder rolls on a plane as a circle, not as the polygon of its rim probes. Vectorised over cylinders,
    one pass per plane."""
    cylinders = world.cylinders
    assert cylinders is not None and state.rotation is not None
    plain = _PLAIN_CYLINDERS.get(world)
    if plain is None:  # the colliding cylinders and rods (a capsule's caps are probes), found once per world
        plain = _PLAIN_CYLINDERS[world] = np.flatnonzero(world.collides[cylinders.owner] & ~cylinders.rounded)
    if not len(plain):
        return Contacts.concatenate([])
    owners = cylinders.owner[plain]
    rigid = owners - state.first_rigid
    centres = state.x[owners] + state.lever(rigid, cylinders.offset[plain])
    axes = np.einsum("kij,kj->ki", state.rotation[rigid], cylinders.axis[plain])
    half_length, radius = cylinders.half_length[plain], cylinders.radius[plain]
    reach = margin + (travel[owners] if travel is not None else 0.0)
    first = world.probes.count + 12 * world.boxes.count  # "probe" numbers past the probes and the box edges
    parts = []
    for k in range(len(statics.plane_point)):
        normal = statics.plane_normal[k]
        point, found = cylinder_support(centres, axes, half_length, radius, -normal)
        depth = (point - statics.plane_point[k]) @ normal
        keep = found & (depth < reach)
        if not keep.any():
            continue
        owner, depth = owners[keep], depth[keep]
        touching = point[keep] - 0.5 * depth[:, None] * normal
        parts.append(make_contacts(world, owner, np.full(len(owner), STATIC), touching,
                                   np.broadcast_to(normal, (len(owner), 3)), depth,
                                   np.full(len(owner), statics.plane_material[k]), first + plain[keep],
                                   PLANE_RIM, np.full(len(owner), k)))
    return Contacts.concatenate(parts)



def rim_pairs(world: ContactWorld, state: Kinematics, probe: np.ndarray, index: np.ndarray) -> Contacts:
    """The rim contacts (K,) named by ``probe`` (a cylinder's, numbered as :func:`rim_contacts` numbers it) and
    ``index`` (:func:`rim_index`: a plane and which end's rim), at ``state``, however far apart: for following a
    contact between events. Each is at the rim's point deepest towards the plane, in closed form, so its gap is a
    smooth function of the state (standing on that end, the point is the end face's centre, as low as its rim). A
    cylinder lying on its side rests on both ends' rims, a line, not a point that jumps from end to end; the plain
    index (the plane alone, :func:`rim_contacts`' name) follows the deepest point of either."""
    cylinders = world.cylinders
    assert cylinders is not None and state.rotation is not None
    statics = world.statics_at(state.t)
    k = probe - (world.probes.count + 12 * world.boxes.count)
    plane, end = index % len(statics.plane_point), index // len(statics.plane_point) - 1
    owners = cylinders.owner[k]
    rigid = owners - state.first_rigid
    centres = state.x[owners] + state.lever(rigid, cylinders.offset[k])
    axes = np.einsum("kij,kj->ki", state.rotation[rigid], cylinders.axis[k])
    normal = statics.plane_normal[plane]
    # each end's rim point deepest towards the plane: the end's centre, then the radius across the axis, downwards
    across = -normal + np.einsum("ki,ki->k", normal, axes)[:, None] * axes
    size = np.linalg.norm(across, axis=1)
    across /= np.where(size > 1e-12, size, 1.0)[:, None]
    half = cylinders.half_length[k, None, None] * np.array([-1.0, 1.0])[None, :, None]  # (K, 2, 1)
    rims = centres[:, None] + half * axes[:, None] + cylinders.radius[k, None, None] * across[:, None]  # (K, 2, 3)
    heights = np.einsum("kei,ki->ke", rims - statics.plane_point[plane][:, None], normal)
    chosen = np.where(end >= 0, end, np.argmin(heights, axis=1))  # the plain name: the deeper of the two
    rows = np.arange(len(k))
    deepest, gap = rims[rows, chosen], heights[rows, chosen]
    return make_contacts(world, owners, np.full(len(k), STATIC), deepest - 0.5 * gap[:, None] * normal, normal, gap,
                         statics.plane_material[plane], probe, PLANE_RIM, index)


def rim_index(world: ContactWorld, plane: np.ndarray, end: int) -> np.ndarray:
    """The index (K,) that names the rim of one ``end`` of a cylinder (0: at −axis, 1: at +axis) on planes ``plane``
    (K,) for :func:`rim_pairs`: past the planes' own numbers (which name the deepest point of either rim)."""
    return plane + (1 + end) * len(world.statics.plane_point)


def body_box_poses(world: ContactWorld, state: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """World centres (X, 3) and rotations (X, 3, 3) of the boxes moving with bodies."""
    boxes = world.boxes
    if not boxes.count:
        return np.zeros((0, 3)), np.zeros((0, 3, 3))
    assert state.rotation is not None
    rigid = boxes.owner - state.first_rigid
    return state.x[boxes.owner] + state.lever(rigid, boxes.offset), state.rotation[rigid] @ boxes.rotation


def _box_contacts(world: ContactWorld, chosen: np.ndarray, centres: np.ndarray, box_centre: np.ndarray,
                  box_rotation: np.ndarray, box_half: np.ndarray, solid_body: int, material: int, margin: float,
                  kinds: tuple[int, int], box: int, box_centres: np.ndarray, box_rotations: np.ndarray,
                  travel: np.ndarray | None = None) -> Contacts:
    """Contacts of probes ``chosen`` with one box: corners of other boxes against the face their separating axis
    picks, everything else against the box as a whole. ``kinds``: (whole box, face) contact kinds."""
    count = len(chosen)
    points = centres[chosen]
    centre, rotation, half = (np.broadcast_to(a, (count, *np.shape(a))) for a in (box_centre, box_rotation,
                                                                                    box_half))
    distance, normal = to_box(points, centre, rotation, half)
    kind, index = np.full(count, kinds[0]), np.full(count, box)
    corner_of = world.probes.box[chosen]
    corners = np.flatnonzero(corner_of >= 0)
    if len(corners):
        own = corner_of[corners]
        direction = separating_direction(box_centres[own], box_rotations[own], world.boxes.half[own],
                                         centre[corners], rotation[corners], half[corners])
        tolerance = margin + (2 * float(travel.max(initial=0.0)) if travel is not None else 0.0)
        face_distance, face_normal, face, on_face = to_box_face(points[corners], centre[corners], rotation[corners],
                                                                half[corners], direction, tolerance)
        use = corners[on_face]
        distance[use], normal[use] = face_distance[on_face], face_normal[on_face]
        kind[use], index[use] = kinds[1], 6 * box + face[on_face]
    return _contacts(world, chosen, points, distance, normal, np.full(count, solid_body),
                     np.full(count, material), margin, kind, index, travel)


def _between_bodies(world: ContactWorld, state: Kinematics, centres: np.ndarray, tree: cKDTree, active: np.ndarray,
                    margin: float, box_centres: np.ndarray, box_rotations: np.ndarray,
                    travel: np.ndarray | None) -> list[Contacts]:
    """Probe spheres against other bodies' probe spheres, and probes against other bodies' boxes, round solids and
    hulls, found through the k-d ``tree`` of the probes' centres (the numpy search; the compiled one tests them
    all itself)."""
    probes, parts = world.probes, []
    closing = margin + 2 * (float(travel.max(initial=0.0)) if travel is not None else 0.0)  # both sides move
    pairs = tree.query_pairs(2 * float(probes.radius.max()) + closing, output_type="ndarray")
    if len(pairs):
        i, j = pairs[:, 0], pairs[:, 1]
        keep = (probes.owner[i] != probes.owner[j]) & active[i] & active[j] & (probes.radius[j] > 0)
        keep &= world.allowed(probes.owner[i], probes.owner[j])
        if world.group is not None:
            group_i, group_j = world.group[probes.owner[i]], world.group[probes.owner[j]]
            keep &= (group_i < 0) | (group_i != group_j)
        i, j = i[keep], j[keep]
        d, n = to_sphere(centres[i], centres[j], probes.radius[j])  # probe i against the sphere of probe j
        owner_j = probes.owner[j]
        parts.append(_contacts(world, i, centres[i], d, n, owner_j, world.body_material[owner_j], margin,
                               BODY_SPHERE, j, travel))
    boxes = world.boxes
    for k in range(boxes.count):
        owner = boxes.owner[k]
        if not world.collides[owner]:
            continue
        found = np.asarray(tree.query_ball_point(box_centres[k], float(np.linalg.norm(boxes.half[k])) + closing
                                                 + float(probes.radius.max())), dtype=np.intp)
        chosen = (found[(probes.owner[found] != owner) & active[found] & world.allowed(owner, probes.owner[found])]
                  if len(found) else found)
        if len(chosen):
            parts.append(_box_contacts(world, chosen, centres, box_centres[k], box_rotations[k], boxes.half[k],
                                       owner, world.body_material[owner], margin, (BODY_BOX, BODY_BOX_FACE), k,
                                       box_centres, box_rotations, travel))
    widest = float(probes.radius.max())

    def near_solid(owner: int, centre: np.ndarray, size: float) -> np.ndarray:
        """Other bodies' active probes within reach of a solid of ``owner`` around ``centre``."""
        if not world.collides[owner]:
            return np.zeros(0, np.intp)
        found = np.asarray(tree.query_ball_point(centre, size + closing + widest), dtype=np.intp)
        if not len(found):
            return found
        return found[(probes.owner[found] != owner) & active[found] & world.allowed(owner, probes.owner[found])]

    if world.cylinders is not None:
        rounds = world.cylinders
        centre, axis = round_poses(world, state)
        for k in range(rounds.count):
            owner = int(rounds.owner[k])
            chosen = near_solid(owner, centre[k], float(rounds.half_length[k] + rounds.radius[k]))
            if len(chosen):
                count = len(chosen)
                d, normal = to_round(centres[chosen], np.broadcast_to(centre[k], (count, 3)),
                                     np.broadcast_to(axis[k], (count, 3)), np.full(count, rounds.half_length[k]),
                                     np.full(count, rounds.radius[k]), np.full(count, rounds.rounded[k]))
                parts.append(_contacts(world, chosen, centres[chosen], d, normal, np.full(count, owner),
                                       np.full(count, world.body_material[owner]), margin, BODY_ROUND,
                                       np.full(count, k), travel))
    for k, hull in enumerate(world.hulls):
        chosen = near_solid(hull.owner, state.x[hull.owner], hull.reach)
        if len(chosen):
            assert state.rotation is not None
            d, normal = to_hull(centres[chosen], hull, state.x[hull.owner],
                                state.rotation[hull.owner - state.first_rigid])
            count = len(chosen)
            parts.append(_contacts(world, chosen, centres[chosen], d, normal, np.full(count, hull.owner),
                                   np.full(count, world.body_material[hull.owner]), margin, BODY_HULL,
                                   np.full(count, k), travel))
    return parts


def round_poses(world: ContactWorld, state: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """World centres (C, 3) and unit axes (C, 3) of the round solids (cylinders, rods, capsules)."""
    rounds = world.cylinders
    assert rounds is not None and state.rotation is not None
    rigid = rounds.owner - state.first_rigid
    return (state.x[rounds.owner] + state.lever(rigid, rounds.offset),
            np.einsum("kij,kj->ki", state.rotation[rigid], rounds.axis))


#: The contacts beyond probes' that can be followed from state to state (:func:`evaluate_pairs`): the sides of rounds
#: against other rounds' sides and against edges (:func:`~animbatch.sim.contact.sides.side_pairs`), edges crossing
#: edges (:func:`~animbatch.sim.contact.hulls.edge_pairs`), and cylinders' rims on planes (:func:`rim_pairs`).
SIDE_KINDS, EDGE_KINDS = (SIDE_ROUND, SIDE_EDGE), (STATIC_EDGE, BODY_EDGE, HULL_EDGE)
FOLLOWED_KINDS = (*SIDE_KINDS, *EDGE_KINDS, PLANE_RIM)


def evaluate_pairs(world: ContactWorld, state: Kinematics, probe: np.ndarray, kind: np.ndarray,
                   index: np.ndarray) -> Contacts:
    """The contacts of given probe–solid pairs (K,) at ``state``, whatever their distance (for tracking contacts
    between events); pairs of :data:`FOLLOWED_KINDS` too."""
    followed = np.isin(kind, FOLLOWED_KINDS)
    if not followed.any():
        centres, distance, normal, solid_body, material = _pair_geometry(world, state, probe, kind, index)
        return _contacts(world, probe, centres, distance, normal, solid_body, material, np.inf, kind, index)
    parts = [evaluate_pairs(world, state, probe[~followed], kind[~followed], index[~followed]),
             _followed_pairs(world, state, probe[followed], kind[followed], index[followed])]
    asked = np.concatenate([np.flatnonzero(~followed), np.flatnonzero(followed)])  # the pairs in the parts' order
    return Contacts.concatenate(parts).select(np.argsort(asked))


def _followed_pairs(world: ContactWorld, state: Kinematics, probe: np.ndarray, kind: np.ndarray,
                    index: np.ndarray) -> Contacts:
    """:func:`evaluate_pairs` for pairs (K,) of :data:`FOLLOWED_KINDS` alone, in their order."""
    poses = body_box_poses(world, state)
    parts, asked = [], []
    for kinds, follow in ((SIDE_KINDS, lambda p, k, i: side_pairs(world, state, *poses, p, k, i)),
                          (EDGE_KINDS, lambda p, k, i: edge_pairs(world, state, *poses, p, k, i)),
                          ((PLANE_RIM,), lambda p, k, i: rim_pairs(world, state, p, i))):
        chosen = np.flatnonzero(np.isin(kind, kinds))
        if len(chosen):
            parts.append(follow(probe[chosen], kind[chosen], index[chosen]))
            asked.append(chosen)
    if len(parts) == 1:
        return parts[0]
    return Contacts.concatenate(parts).select(np.argsort(np.concatenate(asked)))


def pair_gaps(world: ContactWorld, state: Kinematics, probe: np.ndarray, kind: np.ndarray,
              index: np.ndarray) -> np.ndarray:
    """The gaps (K,) [m] of given probe–solid pairs at ``state``: :func:`evaluate_pairs`'s, without building the
    contacts (the event search asks for gaps alone, a root search many times over)."""
    followed = np.isin(kind, FOLLOWED_KINDS)
    gaps = np.zeros(len(kind))
    if followed.any():
        gaps[followed] = _followed_pairs(world, state, probe[followed], kind[followed], index[followed]).gap
        if followed.all():
            return gaps
    _, distance, *_ = _pair_geometry(world, state, probe[~followed], kind[~followed], index[~followed])
    gaps[~followed] = distance - world.probes.radius[probe[~followed]]
    return gaps


def _pair_geometry(world: ContactWorld, state: Kinematics, probe: np.ndarray, kind: np.ndarray, index: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For given probe–solid pairs (K,) at ``state``: the probes' centres (K, 3), the distances of the centres to
    the solids (K,) [m] and the solids' normals there (K, 3), the solids' bodies (K,) (``STATIC`` for colliders)
    and their materials (K,)."""
    all_centres = probe_centres(world, state)
    centres = all_centres[probe]
    statics, probes = world.statics_at(state.t), world.probes
    distance = np.zeros(len(probe))
    normal = np.zeros((len(probe), 3))
    solid_body = np.full(len(probe), STATIC)
    material = np.zeros(len(probe), np.intp)
    for code in np.unique(kind):
        k = kind == code
        i, c = index[k], centres[k]
        if code == PLANE:
            distance[k] = np.einsum("ij,ij->i", c - statics.plane_point[i], statics.plane_normal[i])
            normal[k] = statics.plane_normal[i]
            material[k] = statics.plane_material[i]
        elif code == STATIC_SPHERE:
            distance[k], normal[k] = to_sphere(c, statics.sphere_centre[i], statics.sphere_radius[i])
            material[k] = statics.sphere_material[i]
        elif code == STATIC_BOX:
            distance[k], normal[k] = to_box(c, statics.box_centre[i], statics.box_rotation[i], statics.box_half[i])
            material[k] = statics.box_material[i]
        elif code == STATIC_BOX_FACE:
            box = i // 6
            distance[k], normal[k] = to_face_plane(c, statics.box_centre[box], statics.box_rotation[box],
                                                   statics.box_half[box], i % 6)
            material[k] = statics.box_material[box]
        elif code == TRIANGLE:
            distance[k], normal[k] = to_triangles(c, statics.triangles[i], state.x[probes.owner[probe[k]]])
            material[k] = statics.triangle_material[i]
        elif code == BODY_SPHERE:
            distance[k], normal[k] = to_sphere(c, all_centres[i], probes.radius[i])
            solid_body[k] = probes.owner[i]
            material[k] = world.body_material[probes.owner[i]]
        elif code == BODY_ROUND:
            rounds = world.cylinders
            assert rounds is not None
            round_centre, round_axis = round_poses(world, state)
            distance[k], normal[k] = to_round(c, round_centre[i], round_axis[i], rounds.half_length[i],
                                              rounds.radius[i], rounds.rounded[i])
            solid_body[k] = rounds.owner[i]
            material[k] = world.body_material[rounds.owner[i]]
        elif code == BODY_HULL:
            assert state.rotation is not None
            for hull_number in np.unique(i):
                hull = world.hulls[hull_number]
                chosen = np.flatnonzero(k)[i == hull_number]
                distance[chosen], normal[chosen] = to_hull(
                    centres[chosen], hull, state.x[hull.owner], state.rotation[hull.owner - state.first_rigid])
                solid_body[chosen] = hull.owner
                material[chosen] = world.body_material[hull.owner]
        else:  # BODY_BOX, BODY_BOX_FACE
            box = i // 6 if code == BODY_BOX_FACE else i
            box_centres, box_rotations = body_box_poses(world, state)
            centre, rotation, half = box_centres[box], box_rotations[box], world.boxes.half[box]
            if code == BODY_BOX_FACE:
                distance[k], normal[k] = to_face_plane(c, centre, rotation, half, i % 6)
            else:
                distance[k], normal[k] = to_box(c, centre, rotation, half)
            owner = world.boxes.owner[box]
            solid_body[k] = owner
            material[k] = world.body_material[owner]
    return centres, distance, normal, solid_body, material
