"""Self-collision and cloth–cloth contact: which surfaces of cloth and lattices are kept apart by their thickness.

The vertices of every deformable body with ``self_collision`` form one set: their triangles and edges collide with
each other, within one body and between bodies. A fixed-step scheme applies it as a velocity constraint between its
kick and its drift (after the contacts with solids; :mod:`animbatch.sim.contact.self_collision_step`): it
changes the particles' velocities so that the drift crosses no triangle pair (repulsion within the thickness, then
continuous collision passes, then rigid impact zones as the failsafe). A start free of crossings therefore stays
free of them at every step.

Vertices that are not particles (pinned to anchors, or points of rigid bodies) take part with infinite mass: the
cloth is pushed off them, they are not pushed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from animbatch.sim.deformable.topology import open_edges, unique_edges
from animbatch.sim.deformable.vertices import DeformableSet


@dataclass(frozen=True, eq=False)
class SelfCollisionSet:
    """The surfaces that collide with themselves and each other, as numbers: ``vertices`` (n,) index the vertex map;
    ``triangles`` (T, 3) and ``edges`` (E, 2) index ``vertices``; ``thickness`` (n,) [m] the distance each vertex's
    layers are kept apart; ``friction`` (n,) Coulomb's μ; ``cell`` [m] the spatial hash's cell; ``names`` the
    bodies."""

    vertices: np.ndarray
    triangles: np.ndarray
    edges: np.ndarray
    thickness: np.ndarray
    friction: np.ndarray
    cell: float
    names: tuple[str, ...]
    boundary: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))  # (B, 2) open edges

    def spread_out(self, start: np.ndarray, end: np.ndarray) -> bool:
        """Whether the set is one body spread out like a height field over a plane at both ``start`` and ``end``
        (n, 3) [m] of a step (see :func:`height_field`): it cannot then meet itself, and the step needs no filter."""
        pairs = self.border_pairs
        return len(self.names) == 1 and height_field(start, self.triangles, self.boundary, pairs) and height_field(
            end, self.triangles, self.boundary, pairs)

    @functools.cached_property
    def border_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The pairs of border edges that share no vertex (two (K,) index arrays into ``boundary``)."""
        return border_pairs(self.boundary)

    @classmethod
    def of(cls, deformables: DeformableSet) -> SelfCollisionSet | None:
        """The set of ``deformables``' bodies with self-collision on (None if there are none)."""
        chosen = [body for body in deformables.bodies if body.self_collision]
        if not chosen:
            return None
        vertices = np.concatenate([np.arange(body.vertices.start, body.vertices.stop) for body in chosen])
        local = np.full(deformables.vertex_map.count, -1, np.int64)
        local[vertices] = np.arange(len(vertices))
        triangles = local[np.concatenate([body.triangles for body in chosen])]
        edges = unique_edges(triangles)
        thickness = np.concatenate([np.full(body.vertices.stop - body.vertices.start, body.thickness)
                                    for body in chosen])
        friction = np.concatenate([np.full(body.vertices.stop - body.vertices.start, body.friction)
                                   for body in chosen])
        positions = deformables.initial_positions[vertices]
        lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
        # cells about an edge long hold a handful of primitives each; never thinner than the thickness they search
        cell = max(float(np.median(lengths)) if len(lengths) else 0.0, 2 * float(thickness.max()), 1e-6)
        return cls(vertices, triangles.astype(np.int64), edges.astype(np.int64), thickness, friction, cell,
                   tuple(body.name for body in chosen), open_edges(triangles).astype(np.int64))


#: Every triangle's normal within this angle [rad] of the sheet's mean normal makes it a height field (below 90°,
#: with room for the normals turning within the step).
HEIGHT_FIELD_ANGLE = np.radians(75.0)


def border_pairs(boundary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of edges of ``boundary`` (B, 2) that share no vertex, as two (K,) index arrays."""
    first, second = np.triu_indices(len(boundary), 1)
    apart = ~(boundary[first][:, :, None] == boundary[second][:, None, :]).any(axis=(1, 2))
    return first[apart], second[apart]


def height_field(x: np.ndarray, triangles: np.ndarray, boundary: np.ndarray,
                 pairs: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
    """Whether the open surface ``triangles`` (T, 3) at ``x`` (n, 3) [m] is a height field over the plane of its
    mean normal, and so cannot pass through itself (Volino & Magnenat-Thalmann 1994): every triangle faces within
    HEIGHT_FIELD_ANGLE of that normal, so the projection onto the plane is one-to-one near every point, and its
    border ``boundary`` (B, 2) projects to a curve that does not cross itself (its edges' ``pairs`` that share no
    vertex, :func:`border_pairs`), so it is one-to-one everywhere. A
    flat or rippling sheet passes (a bedsheet swinging, a flag); a fold, a heap or a closed surface does not."""
    if not len(boundary) or not len(triangles):
        return False
    a, b, c = x[triangles[:, 0]], x[triangles[:, 1]], x[triangles[:, 2]]
    normals = np.cross(b - a, c - a)
    axis = normals.sum(axis=0)
    size = float(np.linalg.norm(axis))
    if size == 0.0:
        return False
    axis /= size
    lengths = np.linalg.norm(normals, axis=1)
    if np.any(normals @ axis <= np.cos(HEIGHT_FIELD_ANGLE) * lengths):
        return False
    # the border in the plane: no two of its edges that share no vertex may cross
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    flat = np.stack([x @ u, x @ w], axis=1)
    p, q = flat[boundary[:, 0]], flat[boundary[:, 1]]
    first, second = pairs if pairs is not None else border_pairs(boundary)
    low, high = np.minimum(p, q), np.maximum(p, q)  # only edges whose boxes overlap can cross
    near = np.all((low[first] <= high[second]) & (low[second] <= high[first]), axis=1)
    first, second = first[near], second[near]

    def side(o: np.ndarray, e: np.ndarray, r: np.ndarray) -> np.ndarray:
        return (e[:, 0] - o[:, 0]) * (r[:, 1] - o[:, 1]) - (e[:, 1] - o[:, 1]) * (r[:, 0] - o[:, 0])

    crossing = ((side(p[first], q[first], p[second]) * side(p[first], q[first], q[second]) < 0)
                & (side(p[second], q[second], p[first]) * side(p[second], q[second], q[first]) < 0))
    return not bool(crossing.any())
