"""Finding contacts: which probes are near which solids (broad phase), and how far apart they are (narrow phase).

Broad phase: a k-d tree (``scipy.spatial.cKDTree``) over the probes' centres, queried once per solid, plus one
tree over mesh triangles built once; so N bodies cost O(N log N), not O(N²). Contacts closer than ``margin`` are kept
("speculative" contacts): with ``margin`` at least the distance a body moves in a step, the solver sees every
obstacle a fast body could reach during the step, however thin (a swept test: no tunnelling).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from animbatch.contact.geometry import BodyBoxes, Probes, StaticColliders, to_box, to_plane, to_sphere, to_triangles
from animbatch.contact.materials import MaterialTable
from animbatch.forces.base import Kinematics

STATIC = -1  # "solid body" index of fixed colliders


@dataclass(frozen=True, eq=False)
class ContactWorld:
    """Everything contact detection needs that does not change during a run.

    ``body_material`` (P,) material index per body; ``collides`` (P,) bool; ``bodies_collide``: whether bodies touch
    each other (not only colliders); ``triangle_tree``: k-d tree of static triangle centroids (or None) with the
    largest triangle's circumradius ``triangle_reach``.
    """

    probes: Probes
    boxes: BodyBoxes
    statics: StaticColliders
    materials: MaterialTable
    body_material: np.ndarray
    collides: np.ndarray
    bodies_collide: bool
    triangle_tree: cKDTree | None
    triangle_reach: float


@dataclass(frozen=True, eq=False)
class Contacts:
    """K contacts: ``probe_body``/``solid_body`` (K,) body indices (``solid_body`` is -1 for fixed colliders),
    ``point`` (K, 3) [m], ``normal`` (K, 3) unit, from the solid towards the probe, ``gap`` (K,) [m] (negative when
    overlapping), and the pair's ``restitution``, ``static_friction``, ``kinetic_friction`` (K,)."""

    probe_body: np.ndarray
    solid_body: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    restitution: np.ndarray
    static_friction: np.ndarray
    kinetic_friction: np.ndarray

    @property
    def count(self) -> int:
        return len(self.gap)

    @classmethod
    def concatenate(cls, parts: list[Contacts]) -> Contacts:
        if not parts:
            z3, z = np.zeros((0, 3)), np.zeros(0)
            return cls(np.zeros(0, np.intp), np.zeros(0, np.intp), z3, z3, z, z, z, z)
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in
                     ("probe_body", "solid_body", "point", "normal", "gap", "restitution", "static_friction",
                      "kinetic_friction")))


def probe_centres(world: ContactWorld, state: Kinematics) -> np.ndarray:
    """World positions (Q, 3) of all probes."""
    probes = world.probes
    centres = state.x[probes.owner].copy()
    on_rigid = (probes.owner >= state.first_rigid) & np.any(probes.offset != 0, axis=1)
    if on_rigid.any():
        centres[on_rigid] += state.lever(probes.owner[on_rigid] - state.first_rigid, probes.offset[on_rigid])
    return centres


def _contacts(world: ContactWorld, probes: np.ndarray, centres: np.ndarray, distance: np.ndarray,
              normal: np.ndarray, solid_body: np.ndarray, solid_material: np.ndarray, margin: float) -> Contacts:
    """Contacts from probe indices (K,), their centres, distances of the centres to the solids and normals."""
    radius = world.probes.radius[probes]
    gap = distance - radius
    keep = gap < margin
    probes, gap, normal, radius = probes[keep], gap[keep], normal[keep], radius[keep]
    centres, solid_body, solid_material = centres[keep], solid_body[keep], solid_material[keep]
    owner = world.probes.owner[probes]
    point = centres - normal * (radius + 0.5 * gap)[:, None]  # midway between the two surfaces
    a, b = world.body_material[owner], solid_material
    table = world.materials
    return Contacts(owner, solid_body, point, normal, gap, table.restitution[a, b], table.static_friction[a, b],
                    table.kinetic_friction[a, b])


def detect(world: ContactWorld, state: Kinematics, margin: float) -> Contacts:
    """Every probe–solid pair closer than ``margin`` [m] (gap < margin), as contacts."""
    centres = probe_centres(world, state)
    active = world.collides[world.probes.owner]
    statics, parts = world.statics, []
    everywhere = np.flatnonzero(active)
    reach = margin + (float(world.probes.radius.max()) if world.probes.count else 0.0)
    tree = cKDTree(centres) if world.probes.count else None

    def near(centre: np.ndarray, radius: float) -> np.ndarray:
        found = np.asarray(tree.query_ball_point(centre, radius + reach), dtype=np.intp)
        return found[active[found]] if len(found) else found

    for k in range(len(statics.plane_point)):
        d, n = to_plane(centres[everywhere], statics.plane_point[k], statics.plane_normal[k])
        parts.append(_contacts(world, everywhere, centres[everywhere], d, np.array(n), np.full(len(d), STATIC),
                               np.full(len(d), statics.plane_material[k]), margin))
    for k in range(len(statics.sphere_centre)):
        chosen = near(statics.sphere_centre[k], statics.sphere_radius[k])
        d, n = to_sphere(centres[chosen], np.broadcast_to(statics.sphere_centre[k], (len(chosen), 3)),
                         np.full(len(chosen), statics.sphere_radius[k]))
        parts.append(_contacts(world, chosen, centres[chosen], d, n, np.full(len(chosen), STATIC),
                               np.full(len(chosen), statics.sphere_material[k]), margin))
    for k in range(len(statics.box_centre)):
        chosen = near(statics.box_centre[k], float(np.linalg.norm(statics.box_half[k])))
        d, n = to_box(centres[chosen], np.broadcast_to(statics.box_centre[k], (len(chosen), 3)),
                      np.broadcast_to(statics.box_rotation[k], (len(chosen), 3, 3)),
                      np.broadcast_to(statics.box_half[k], (len(chosen), 3)))
        parts.append(_contacts(world, chosen, centres[chosen], d, n, np.full(len(chosen), STATIC),
                               np.full(len(chosen), statics.box_material[k]), margin))
    if world.triangle_tree is not None and len(everywhere):
        found = world.triangle_tree.query_ball_point(centres[everywhere], world.triangle_reach + reach)
        probes = np.repeat(everywhere, [len(f) for f in found])
        triangles = np.concatenate([np.asarray(f, np.intp) for f in found]) if len(probes) else np.zeros(0, np.intp)
        if len(probes):
            d, n = to_triangles(centres[probes], statics.triangles[triangles])
            parts.append(_contacts(world, probes, centres[probes], d, n, np.full(len(probes), STATIC),
                                   statics.triangle_material[triangles], margin))
    if world.bodies_collide and tree is not None:
        parts += _between_bodies(world, state, centres, tree, active, margin)
    return Contacts.concatenate(parts)


def _between_bodies(world: ContactWorld, state: Kinematics, centres: np.ndarray, tree: cKDTree, active: np.ndarray,
                    margin: float) -> list[Contacts]:
    """Probe spheres against other bodies' probe spheres, and probes against other bodies' boxes."""
    probes, parts = world.probes, []
    pairs = tree.query_pairs(2 * float(probes.radius.max()) + margin, output_type="ndarray")
    if len(pairs):
        i, j = pairs[:, 0], pairs[:, 1]
        keep = (probes.owner[i] != probes.owner[j]) & active[i] & active[j] & (probes.radius[j] > 0)
        i, j = i[keep], j[keep]
        d, n = to_sphere(centres[i], centres[j], probes.radius[j])  # probe i against the sphere of probe j
        owner_j = probes.owner[j]
        parts.append(_contacts(world, i, centres[i], d, n, owner_j, world.body_material[owner_j], margin))
    boxes = world.boxes
    if boxes.count:
        owner = boxes.owner
        rigid = owner - state.first_rigid
        assert state.rotation is not None
        box_centres = state.x[owner] + state.lever(rigid, boxes.offset)
        box_rotations = state.rotation[rigid] @ boxes.rotation
        for k in range(boxes.count):
            if not world.collides[owner[k]]:
                continue
            found = np.asarray(tree.query_ball_point(box_centres[k], float(np.linalg.norm(boxes.half[k])) + margin
                                                     + float(probes.radius.max())), dtype=np.intp)
            chosen = found[(probes.owner[found] != owner[k]) & active[found]] if len(found) else found
            if not len(chosen):
                continue
            count = len(chosen)
            d, n = to_box(centres[chosen], np.broadcast_to(box_centres[k], (count, 3)),
                          np.broadcast_to(box_rotations[k], (count, 3, 3)), np.broadcast_to(boxes.half[k], (count, 3)))
            parts.append(_contacts(world, chosen, centres[chosen], d, n, np.full(count, owner[k]),
                                   np.full(count, world.body_material[owner[k]]), margin))
    return parts
