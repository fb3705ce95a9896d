"""Where the vertices of cloth and lattices are, from the motion of what holds them: numbers only, shared by the
simulation (:class:`animbatch.sim.deformable.vertices.VertexMap` extends it) and the renderer and exports, which
place a frame's vertices from a trajectory.

A vertex is a particle of the model (``PARTICLE``: its own state), a pinned anchor (``ANCHOR``), or a point of a
rigid body (``BODY_POINT``: at an offset in the body's axes from its centre of mass).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PARTICLE, ANCHOR, BODY_POINT = 0, 1, 2


@dataclass(frozen=True, eq=False)
class VertexPlacement:
    """V vertices: ``kind`` (V,) PARTICLE / ANCHOR / BODY_POINT; ``index`` (V,) the model point, anchor, or rigid body
    (0 … B-1); ``offset`` (V, 3) body axes from the centre of mass [m] (body points only); ``first_rigid``: N, the
    index of the first rigid body among the model's points."""

    kind: np.ndarray
    index: np.ndarray
    offset: np.ndarray
    first_rigid: int
    # derived in __post_init__: the vertices of each kind
    _free: np.ndarray = field(init=False, repr=False)
    _on_anchor: np.ndarray = field(init=False, repr=False)
    _on_body: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_free", np.flatnonzero(self.kind == PARTICLE))
        object.__setattr__(self, "_on_anchor", np.flatnonzero(self.kind == ANCHOR))
        object.__setattr__(self, "_on_body", np.flatnonzero(self.kind == BODY_POINT))

    @property
    def count(self) -> int:
        return len(self.kind)

    def free_vertices(self) -> np.ndarray:
        """Indices of the vertices that are particles."""
        return self._free

    def place(self, points: np.ndarray, rotations: np.ndarray | None, anchor_positions: np.ndarray) -> np.ndarray:
        """Vertex positions (V, 3) [m] from the points' positions (P, 3), the rigid bodies' rotations (B, 3, 3) and
        the anchors' positions (A, 3)."""
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
