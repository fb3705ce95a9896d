"""The compiled, immutable model: bodies, anchors, springs, the force terms, the initial state.

A Model is built once (by :class:`~animbatch.sim.model.builder.ModelBuilder`, usually via
:func:`~animbatch.compile.model.compile_scene`) and never changes; its arrays are read-only. Everything that changes
during a run lives in the flat state vector described by ``layout``.

Bodies are numbered as *points*: the N particles first, then the B rigid bodies, each represented by its centre of
mass. Per-body arrays (trajectory files included) use this order; ``body_names`` gives it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from animbatch import quaternion
from animbatch.sim.deformable.vertices import DeformableSet
from animbatch.sim.forces import BodyTable, ForceTerm, SpringSet
from animbatch.sim.joints import Joints
from animbatch.sim.model.clocks import ProperClocks
from animbatch.sim.model.layout import StateLayout
from animbatch.sim.model.rigid_set import RigidBodySet
from animbatch.sim.motion import AnchorMotion, KinematicBodies

if TYPE_CHECKING:  # contacts sit above the model (they read it); only their types are named here
    from animbatch.sim.contact.detection import ContactSettings, ContactWorld


@dataclass(frozen=True, eq=False)
class Model:
    """A compiled scene.

    Attributes:
        bodies: every body as a point (names, masses [kg], radii [m]), particles first; ``bodies.rigid`` holds the
            rigid bodies' inertia and geometry, or None.
        anchor_names: names of the A fixed anchors.
        anchor_position: anchor positions [m], shape (A, 3).
        springs: spring topology and constants, or None when the scene has none.
        force_terms: the terms the right-hand side evaluates, in order; only declared effects appear here.
        layout: the layout of the flat state vector.
        y0: initial state, shape (layout.size,).
        frame_times: times at which frames are sampled [s], ``k / fps``, shape (F,).
        contact_world, contact_settings: collision geometry, materials and solver settings, or None when the scene
            has no colliders and no ``contacts`` section (then no contact code runs).
        anchors: where the anchors are at any time (fixed or following keyframes); ``anchor_position`` is where they
            start. ``anchor_visible`` (A,): drawn (cloth pins are anchors too, and are not).
        owners: (P,) the scene body each point belongs to: its own name, or the cloth or lattice of a vertex.
        clocks: the proper-time clocks some bodies carry, or None (then the state has no proper-time block).
        joints: rods and ropes over pulleys between particles, or None (then no constraint code runs).
        kinematic: the rigid bodies on keyframes, whose states their paths prescribe, or None.
        renormalise_every: with rotation matrices in the state (``layout.matrix_orientation``), fixed-step methods
            turn them back into rotations every this many steps; 0: never (the drift the notes warn of shows).
    """

    bodies: BodyTable
    anchor_names: tuple[str, ...]
    anchor_position: np.ndarray
    springs: SpringSet | None
    force_terms: tuple[ForceTerm, ...]
    layout: StateLayout
    y0: np.ndarray
    frame_times: np.ndarray
    anchors: AnchorMotion
    anchor_visible: np.ndarray
    owners: tuple[str, ...]
    contact_world: ContactWorld | None = None  # only when the scene has colliders or contacts
    contact_settings: ContactSettings | None = None  # likewise
    clocks: ProperClocks | None = None
    joints: Joints | None = None
    kinematic: KinematicBodies | None = None
    renormalise_every: int = 1

    @property
    def deformables(self) -> DeformableSet | None:
        return self.bodies.deformables

    @property
    def rigid(self) -> RigidBodySet | None:
        return self.bodies.rigid

    @property
    def particle_count(self) -> int:
        return self.bodies.first_rigid

    @property
    def rigid_count(self) -> int:
        return self.bodies.rigid_count

    @property
    def body_count(self) -> int:
        return self.bodies.count

    @property
    def body_names(self) -> tuple[str, ...]:
        return self.bodies.names

    @property
    def spring_count(self) -> int:
        return 0 if self.springs is None else self.springs.count

    @property
    def fps(self) -> float:
        return 1.0 / (self.frame_times[1] - self.frame_times[0]) if len(self.frame_times) > 1 else 0.0

    # ---------------------------------------------------------------- per-body views of states (n,) or (F, n)

    def _blocks(self, y: np.ndarray, particle: str, rigid: str, transform=None) -> np.ndarray:  # noqa: ANN001
        parts = []
        if self.layout.has(particle):
            parts.append(self.layout.view(y, particle))
        if self.layout.has(rigid):
            block = self.layout.view(y, rigid)
            parts.append(transform(block) if transform is not None else block)
        if not parts:  # no bodies (a scene of emitters only)
            return np.zeros((*y.shape[:-1], 0, 3))
        return np.concatenate(parts, axis=-2) if len(parts) > 1 else np.array(parts[0])

    @property
    def adds_energy(self) -> bool:
        """Whether something can put energy in: a force term (see :attr:`ForceTerm.adds_energy`), a joint motor, or
        a collider or rigid body moving along keyframes."""
        return (any(term.adds_energy for term in self.force_terms)
                or (self.joints is not None and self.joints.driven) or self.kinematic is not None
                or getattr(self.contact_world, "moving", None) is not None)

    def prescribe(self, y: np.ndarray, t: float) -> None:
        """Set the states of the rigid bodies on keyframes in a state (n,) to their paths' at time t [s], in place:
        centres of mass, orientations, and momenta from the paths' velocities and angular velocities."""
        kinematic, rigid = self.kinematic, self.rigid
        if kinematic is None or rigid is None:
            return
        x, rotation, v, omega = kinematic.at(t)
        index = kinematic.rigid
        self.layout.view(y, "rigid_position")[index] = x
        self.layout.view(y, "rigid_orientation")[index] = quaternion.from_matrix(rotation)
        self.layout.view(y, "rigid_momentum")[index] = v * rigid.mass[index, None]
        inertia = rotation @ rigid.inertia[index] @ np.transpose(rotation, (0, 2, 1))
        self.layout.view(y, "rigid_angular_momentum")[index] = np.einsum("kij,kj->ki", inertia, omega)

    def positions(self, y: np.ndarray) -> np.ndarray:
        """Centre-of-mass positions [m] of all bodies: (P, 3) or (F, P, 3)."""
        return self._blocks(y, "particle_position", "rigid_position")

    def velocities(self, y: np.ndarray) -> np.ndarray:
        """Centre-of-mass velocities [m/s] of all bodies (rigid: ``P / M``): (P, 3) or (F, P, 3)."""
        mass = self.rigid.mass[:, None] if self.rigid is not None else None
        return self._blocks(y, "particle_velocity", "rigid_momentum", lambda momentum: momentum / mass)

    def rotations(self, y: np.ndarray) -> np.ndarray:
        """The rigid bodies' orientations as the state holds them, as matrices (B, 3, 3) or (F, B, 3, 3): from the
        quaternions, or the integrated matrices themselves (not quite rotations unless renormalised)."""
        held = self.layout.view(y, "rigid_orientation")
        if self.layout.matrix_orientation:
            return held.reshape(*held.shape[:-1], 3, 3)
        return quaternion.to_matrix(held)

    def orientation_errors(self, y: np.ndarray) -> np.ndarray:
        """‖RᵀR − I‖ (Frobenius) of each rigid body's orientation, (B,) or (F, B): 0 for a rotation, round-off for
        quaternions (made unit by construction)."""
        rotation = self.rotations(y)
        gram = np.einsum("...ki,...kj->...ij", rotation, rotation) - np.eye(3)
        return np.sqrt(np.einsum("...ij,...ij->...", gram, gram))

    def orientations(self, y: np.ndarray) -> np.ndarray:
        """Unit quaternions [w, x, y, z] of all bodies (identity for particles): (P, 4) or (F, P, 4). Integrated
        matrices are shown as the rotation nearest them (their polar factor)."""
        result = np.zeros((*y.shape[:-1], self.body_count, 4))
        result[..., 0] = 1.0
        if self.rigid is not None:
            if self.layout.matrix_orientation:
                result[..., self.particle_count:, :] = quaternion.from_matrix(nearest_rotation(self.rotations(y)))
            else:
                result[..., self.particle_count:, :] = quaternion.normalized(self.layout.view(y, "rigid_orientation"))
        return result

    def angular_velocities(self, y: np.ndarray) -> np.ndarray:
        """Angular velocities ω [rad/s], world axes, of all bodies (zero for particles): (P, 3) or (F, P, 3)."""
        result = np.zeros((*y.shape[:-1], self.body_count, 3))
        if self.rigid is not None:
            rotation = self.rotations(y)
            momentum = self.layout.view(y, "rigid_angular_momentum")
            result[..., self.particle_count:, :] = world_inverse_inertia_times(rotation, self.rigid.inverse_inertia,
                                                                               momentum)
        return result

    def proper_times(self, y: np.ndarray) -> np.ndarray:
        """The clocks' proper times τ [s]: (K,) or (F, K); empty without clocks."""
        if self.clocks is None:
            return np.zeros((*y.shape[:-1], 0))
        return np.array(self.layout.view(y, "proper_time")[..., 0])

    def states_from(self, positions: np.ndarray, velocities: np.ndarray, orientations: np.ndarray | None = None,
                    angular_velocities: np.ndarray | None = None, proper_times: np.ndarray | None = None
                    ) -> np.ndarray:
        """The flat states (…, n) of per-body arrays (as in a trajectory file): the inverse of the views above.
        ``proper_times`` (…, K): the clocks' readings, when the model has clocks (default 0)."""
        y = np.zeros((*positions.shape[:-2], self.layout.size))
        if self.clocks is not None and proper_times is not None:
            y[..., self.layout.block("proper_time").span] = proper_times
        n = self.particle_count
        if self.layout.has("particle_position"):
            y[..., self.layout.block("particle_position").span] = positions[..., :n, :].reshape(*y.shape[:-1], -1)
            y[..., self.layout.block("particle_velocity").span] = velocities[..., :n, :].reshape(*y.shape[:-1], -1)
        if self.rigid is not None:
            assert orientations is not None and angular_velocities is not None
            q = orientations[..., n:, :]
            rotation = quaternion.to_matrix(q)
            momentum = np.einsum("...bij,bjk,...blk,...bl->...bi", rotation, self.rigid.inertia, rotation,
                                 angular_velocities[..., n:, :])  # L = R I Rᵀ ω
            held = rotation if self.layout.matrix_orientation else q
            for name, values in (("rigid_position", positions[..., n:, :]), ("rigid_orientation", held),
                                 ("rigid_momentum", velocities[..., n:, :] * self.rigid.mass[:, None]),
                                 ("rigid_angular_momentum", momentum)):
                y[..., self.layout.block(name).span] = values.reshape(*y.shape[:-1], -1)
        return y


def nearest_rotation(matrices: np.ndarray) -> np.ndarray:
    """The rotation nearest each matrix (…, 3, 3), its polar factor ``U Vᵀ`` (from ``M = U Σ Vᵀ``): how an
    integrated rotation matrix is drawn, and what renormalising turns it back into."""
    u, _, vt = np.linalg.svd(matrices)
    return u @ vt


def world_inverse_inertia_times(rotation: np.ndarray, inverse_inertia: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """``R I_body⁻¹ Rᵀ v`` for each body (…, B): with ``v = L`` this is ω = I(t)⁻¹ L."""
    body = np.einsum("...bji,...bj->...bi", rotation, vector)  # Rᵀ v
    body = np.einsum("bij,...bj->...bi", inverse_inertia, body)  # I_body⁻¹ Rᵀ v
    return np.einsum("...bij,...bj->...bi", rotation, body)  # R I_body⁻¹ Rᵀ v
