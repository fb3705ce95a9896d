"""The bodies as the physics sees them: the table of points (particles, then rigid bodies) and their kinematics at
one instant. Force terms, contacts, deformables and the model all read these; they sit below all of them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # types only: the rigid and deformable sets are built above this module
    from animbatch.sim.deformable.vertices import DeformableSet
    from animbatch.sim.model.rigid_set import RigidBodySet


@dataclass(frozen=True, eq=False)
class BodyTable:
    """The bodies as force terms see them (immutable).

    ``names``, ``mass`` [kg], ``radius`` [m]: per point, shape (P,); a rigid body's radius is that of the sphere of its
    volume. ``first_rigid``: index of the first rigid body (= number of particles). ``rigid``: the rigid bodies'
    inertia and geometry (a :class:`~animbatch.sim.model.rigid_set.RigidBodySet`), or None. ``deformables``: cloth and
    lattices, their triangles and where their vertices are (a
    :class:`~animbatch.sim.deformable.vertices.DeformableSet`), or None.
    """

    names: tuple[str, ...]
    mass: np.ndarray
    radius: np.ndarray
    first_rigid: int
    rigid: RigidBodySet | None = None
    deformables: DeformableSet | None = None

    @property
    def count(self) -> int:
        return len(self.names)

    @property
    def rigid_count(self) -> int:
        return self.count - self.first_rigid


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Where the bodies are and how they move, at one instant ``t`` [s].

    ``x``, ``v``: centre-of-mass positions [m] and velocities [m/s] of all points, shape (P, 3). For the B rigid bodies
    (points ``first_rigid …``): ``rotation`` (B, 3, 3) body-to-world matrices and ``omega`` (B, 3) angular velocities
    [rad/s], world axes; both None when there are no rigid bodies. ``t`` places moving anchors.
    """

    x: np.ndarray
    v: np.ndarray
    rotation: np.ndarray | None
    omega: np.ndarray | None
    first_rigid: int
    t: float = 0.0

    def lever(self, rigid_index: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """World vectors from the centres of mass of rigid bodies ``rigid_index`` (K,) to their body points
        ``offset`` (K, 3), given in body axes relative to the centre of mass."""
        assert self.rotation is not None
        return np.einsum("kij,kj->ki", self.rotation[rigid_index], offset)
