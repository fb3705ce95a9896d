"""Where the vertices of cloth and lattices are: free particles, pinned anchors, or points of rigid bodies.

A free vertex is a particle of the model (it has a state). A pinned vertex is an anchor (fixed, or following
keyframes): it is not simulated at all, which is the exact constraint. A vertex attached to a rigid body is a body
point: springs to it pull on the body (force and torque), and it moves with the body.

Forces that act per face or per hinge (aerodynamics, dihedral springs) are computed on all vertices and then
scattered: onto particles, onto rigid bodies as force and torque ``r × f``, and dropped at anchors (the anchor takes
them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from animbatch.quaternion import cross
from animbatch.sim.bodies import Kinematics
from animbatch.sim.motion import AnchorMotion
from animbatch.vertex_placement import ANCHOR, BODY_POINT, PARTICLE, VertexPlacement

__all__ = ["ANCHOR", "BODY_POINT", "PARTICLE", "DeformableBody", "DeformableSet", "VertexMap"]


@dataclass(frozen=True, eq=False)
class VertexMap(VertexPlacement):
    """The vertices' placement (:class:`~animbatch.vertex_placement.VertexPlacement`: kind, index, offset,
    first_rigid) with what the simulation adds: ``point_count`` P, the model's points, and the (P, V) matrix that
    scatters vertex forces onto them."""

    point_count: int = 0
    _scatter: sp.csr_matrix = field(init=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        free = self._free
        # one sparse product scatters vertex forces onto particles
        scatter = sp.csr_matrix((np.ones(len(free)), (self.index[free], free)), shape=(self.point_count, self.count))
        object.__setattr__(self, "_scatter", scatter)

    def positions_velocities(self, state: Kinematics, anchors: AnchorMotion) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and velocities [m/s] of all vertices, (V, 3) each, at ``state`` (time ``state.t``)."""
        x = self.place(state.x, state.rotation, anchors.positions(state.t))
        v = np.zeros((self.count, 3))
        free = self._free
        v[free] = state.v[self.index[free]]
        pinned = self._on_anchor
        if len(pinned) and anchors.moving:
            v[pinned] = anchors.velocities(state.t)[self.index[pinned]]
        attached = self._on_body
        if len(attached):
            rigid = self.index[attached]
            lever = x[attached] - state.x[state.first_rigid + rigid]
            assert state.omega is not None  # a state with rigid bodies has their ω
            v[attached] = state.v[state.first_rigid + rigid] + cross(state.omega[rigid], lever)
        return x, v

    def scatter(self, vertex_force: np.ndarray, state: Kinematics, force: np.ndarray,
                torque: np.ndarray | None) -> None:
        """Add forces on vertices (V, 3) [N] to the model's points (P, 3), with torques (B, 3) for body points."""
        force += self._scatter @ vertex_force
        attached = self._on_body
        if len(attached):
            assert torque is not None
            rigid = self.index[attached]
            lever = state.lever(rigid, self.offset[attached])
            np.add.at(force, state.first_rigid + rigid, vertex_force[attached])
            np.add.at(torque, rigid, cross(lever, vertex_force[attached]))


@dataclass(frozen=True, eq=False)
class DeformableBody:
    """One cloth or lattice: its vertices are ``vertices`` (a slice of the model's vertex map), ``triangles`` (T, 3)
    and ``hinges`` (H, 4) index that map; ``kind`` is 'cloth' or 'lattice'. With ``self_collision`` its surface
    collides with itself and with the other such bodies' (:mod:`~animbatch.sim.deformable.self_collision`), its
    layers kept ``thickness`` [m] apart, sliding with Coulomb's ``friction``."""

    name: str
    kind: str
    vertices: slice
    triangles: np.ndarray
    hinges: np.ndarray
    radius: float
    self_collision: bool = False
    thickness: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True, eq=False)
class DeformableSet:
    """All deformable bodies of a model, their vertex map, the anchors their pins use, and where every vertex was at
    the start (V, 3) [m] (rest angles and lengths are measured there)."""

    bodies: tuple[DeformableBody, ...]
    vertex_map: VertexMap
    anchors: AnchorMotion
    initial_positions: np.ndarray

    @property
    def triangles(self) -> np.ndarray:
        """All surface triangles (T, 3), indexing the vertex map."""
        return np.concatenate([body.triangles for body in self.bodies]) if self.bodies else np.zeros((0, 3), np.intp)

    def body(self, name: str) -> DeformableBody:
        for body in self.bodies:
            if body.name == name:
                return body
        raise KeyError(name)


def triangle_share(triangles: np.ndarray, vertex_count: int) -> sp.csr_matrix:
    """(V, T): a third at each of a triangle's three vertices, so that ``share @ face_forces`` (T, 3) gives each
    vertex its part of the forces on the faces around it (wind, pressure)."""
    count = len(triangles)
    return sp.csr_matrix((np.full(3 * count, 1 / 3), (triangles.ravel(), np.repeat(np.arange(count), 3))),
                         shape=(vertex_count, count))
