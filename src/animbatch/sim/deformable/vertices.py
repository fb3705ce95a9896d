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

PARTICLE, ANCHOR, BODY_POINT = 0, 1, 2


@dataclass(frozen=True, eq=False)
class VertexMap:
    """V vertices: ``kind`` (V,) PARTICLE / ANCHOR / BODY_POINT; ``index`` (V,) the model point, anchor, or rigid body
    (0 … B-1); ``offset`` (V, 3) body axes from the centre of mass (body points only). ``point_count``: P, the
    model's points; ``first_rigid``: N."""

    kind: np.ndarray
    index: np.ndarray
    offset: np.ndarray
    point_count: int
    first_rigid: int
    # derived in __post_init__: the vertices of each kind, and the (P, V) matrix that scatters vertex forces
    _free: np.ndarray = field(init=False, repr=False)
    _on_anchor: np.ndarray = field(init=False, repr=False)
    _on_body: np.ndarray = field(init=False, repr=False)
    _scatter: sp.csr_matrix = field(init=False, repr=False)

    @property
    def count(self) -> int:
        return len(self.kind)

    def __post_init__(self) -> None:
        free = np.flatnonzero(self.kind == PARTICLE)
        # one sparse product scatters vertex forces onto particles
        scatter = sp.csr_matrix((np.ones(len(free)), (self.index[free], free)), shape=(self.point_count, self.count))
        object.__setattr__(self, "_scatter", scatter)
        object.__setattr__(self, "_on_body", np.flatnonzero(self.kind == BODY_POINT))
        object.__setattr__(self, "_on_anchor", np.flatnonzero(self.kind == ANCHOR))
        object.__setattr__(self, "_free", free)

    def free_vertices(self) -> np.ndarray:
        """Indices of the vertices that are particles."""
        return self._free

    def place(self, points: np.ndarray, rotations: np.ndarray | None, anchor_positions: np.ndarray) -> np.ndarray:
        """Vertex positions (V, 3) [m] from the points' positions (P, 3), the rigid bodies' rotations (B, 3, 3) and
        the anchors' positions (A, 3) (for drawing a frame from a trajectory)."""
        x = np.empty((self.count, 3))
        free = self._free
        x[free] = points[self.index[free]]
        pinned = self._on_anchor
        x[pinned] = anchor_positions[self.index[pinned]]
        attached = self._on_body
        if len(attached):
            assert rotations is not None
            rigid = self.index[attached]
            x[attached] = points[self.first_rigid + rigid] + np.einsum("kij,kj->ki", rotations[rigid],
                                                                       self.offset[attached])
        return x

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
            v[attached] = state.v[state.first_rigid + rigid] + cross(state.omega[rigid], lever)  # type: ignore[index]
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
    and ``hinges`` (H, 4) index that map; ``kind`` is 'cloth' or 'lattice'."""

    name: str
    kind: str
    vertices: slice
    triangles: np.ndarray
    hinges: np.ndarray
    radius: float


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
