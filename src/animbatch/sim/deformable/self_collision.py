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

from dataclasses import dataclass

import numpy as np

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
        edges = surface_edges(triangles)
        thickness = np.concatenate([np.full(body.vertices.stop - body.vertices.start, body.thickness)
                                    for body in chosen])
        friction = np.concatenate([np.full(body.vertices.stop - body.vertices.start, body.friction)
                                   for body in chosen])
        positions = deformables.initial_positions[vertices]
        lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
        # cells about an edge long hold a handful of primitives each; never thinner than the thickness they search
        cell = max(float(np.median(lengths)) if len(lengths) else 0.0, 2 * float(thickness.max()), 1e-6)
        return cls(vertices, triangles.astype(np.int64), edges.astype(np.int64), thickness, friction, cell,
                   tuple(body.name for body in chosen))


def surface_edges(triangles: np.ndarray) -> np.ndarray:
    """The distinct edges (E, 2) of ``triangles`` (T, 3), each once with its lower vertex first."""
    if not len(triangles):
        return np.zeros((0, 2), np.int64)
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    return np.unique(edges, axis=0)
