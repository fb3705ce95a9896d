"""Loads the scene applies directly: a constant force at a body point, a constant torque, rotational damping.

A force ``f`` applied at a point ``r`` from a rigid body's centre of mass also turns it with the torque ``τ = r × f``
(lecture notes, "force producing torque"). In ``frame: body`` the vector turns with the body (``R f``), like a
thruster; in ``frame: world`` it keeps its direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from animbatch.quaternion import cross
from animbatch.sim.forces.term import (
    BodyTable,
    ForceTerm,
    Kinematics,
    TimeScale,
    fastest_spin_decay,
    rigid_selection,
    selection_text,
    vector_text,
)


def _in_world(vector: np.ndarray, frame: str, rotation: np.ndarray | None, rigid: np.ndarray) -> np.ndarray:
    """The vector (3,) for each of the rigid bodies ``rigid``, in world axes, shape (K, 3)."""
    if frame == "body":
        assert rotation is not None
        return rotation[rigid] @ vector
    return np.broadcast_to(vector, (len(rigid), 3))


@dataclass(frozen=True, eq=False)
class AppliedForce(ForceTerm):
    """``force`` on particles ``particles`` (at their centre) and rigid bodies ``rigid`` (at ``offset``, body axes
    from each centre of mass, giving torque)."""

    kind = "force"

    force: np.ndarray
    frame: Literal["world", "body"]
    particles: np.ndarray
    rigid: np.ndarray
    offset: np.ndarray  # (K, 3)
    first_rigid: int
    names: tuple[str, ...]

    @property
    def dissipative(self) -> bool:
        return True  # it does work

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        if len(self.particles):
            force[self.particles] += self.force  # a particle has no body axes: body frame = world frame
        if len(self.rigid):
            assert torque is not None
            applied = _in_world(self.force, self.frame, state.rotation, self.rigid)
            force[self.rigid + self.first_rigid] += applied
            if np.any(self.offset):
                torque[self.rigid] += cross(state.lever(self.rigid, self.offset), applied)

    def describe(self) -> str:
        bodies = np.concatenate([self.particles, self.rigid + self.first_rigid])
        return (f"f = {vector_text(self.force)} N ({self.frame} axes) on {selection_text(np.sort(bodies), self.names)}"
                + (" off their centres of mass" if np.any(self.offset) else ""))


def build_force(bodies: BodyTable, index: np.ndarray | None, *, force: np.ndarray, frame: Literal["world", "body"],
                at: np.ndarray | None = None) -> AppliedForce:
    """A constant ``force`` [N] (3,) in ``frame`` ('world' or 'body') axes on the selected points; on rigid bodies
    at the shape-frame point ``at`` [m] (3,) when given, else at their centres of mass."""
    points = np.arange(bodies.count) if index is None else np.asarray(index)
    rigid = rigid_selection(bodies, index)
    if at is not None and len(rigid) and bodies.rigid is not None:
        offset = np.asarray(at, float)[None, :] - bodies.rigid.centre[rigid]
    else:
        offset = np.zeros((len(rigid), 3))
    return AppliedForce(np.asarray(force, float), frame, points[points < bodies.first_rigid], rigid, offset,
                        bodies.first_rigid, bodies.names)


@dataclass(frozen=True, eq=False)
class _RigidLoad(ForceTerm):
    """A load on rigid bodies only: ``rigid`` (K,) indices among the rigid bodies (points ``first_rigid + k``)."""

    rigid: np.ndarray
    first_rigid: int
    names: tuple[str, ...]

    @property
    def dissipative(self) -> bool:
        return True  # it does work on the bodies

    def on_bodies(self) -> str:
        return selection_text(self.rigid + self.first_rigid, self.names)


@dataclass(frozen=True, eq=False, kw_only=True)
class AppliedTorque(_RigidLoad):
    """A constant torque on the selected rigid bodies."""

    kind = "torque"

    torque: np.ndarray
    frame: Literal["world", "body"]

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        if torque is not None and len(self.rigid):
            torque[self.rigid] += _in_world(self.torque, self.frame, state.rotation, self.rigid)

    def describe(self) -> str:
        return f"τ = {vector_text(self.torque)} N·m ({self.frame} axes) on {self.on_bodies()}"


def build_torque(bodies: BodyTable, index: np.ndarray | None, *, torque: np.ndarray,
                 frame: Literal["world", "body"]) -> AppliedTorque:
    """A constant ``torque`` [N·m] (3,) in ``frame`` axes on the selected rigid bodies."""
    return AppliedTorque(rigid_selection(bodies, index), bodies.first_rigid, bodies.names,
                         torque=np.asarray(torque, float), frame=frame)


@dataclass(frozen=True, eq=False, kw_only=True)
class AngularDrag(_RigidLoad):
    """``τ = -c ω`` on the selected rigid bodies."""

    kind = "angular_drag"

    coefficient: float

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        if torque is not None and len(self.rigid):
            assert state.omega is not None
            torque[self.rigid] -= self.coefficient * state.omega[self.rigid]

    @property
    def adds_energy(self) -> bool:
        return False  # τ = -c ω only takes energy

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        return fastest_spin_decay(self.coefficient, self.rigid, bodies, "angular drag")

    def describe(self) -> str:
        return f"c = {self.coefficient:g} N·m·s on {self.on_bodies()}"


def build_angular_drag(bodies: BodyTable, index: np.ndarray | None, *, coefficient: float) -> AngularDrag:
    """``τ = -c ω`` with ``coefficient`` c [N·m·s] on the selected rigid bodies."""
    return AngularDrag(rigid_selection(bodies, index), bodies.first_rigid, bodies.names, coefficient=coefficient)
