"""The kinds of constraint rows joints are made of, each vectorised over all its rows.

A ball joint is three :class:`PointRows` (the two anchor points coincide); a hinge adds two :class:`AxisRows` (its
axis stays the same in both bodies) and may add :class:`AngleRows` (limits); a fixed joint is three point rows and
three :class:`LockRows` (the relative orientation stays); a slider is three lock rows and two :class:`SlideRows`
across its axis, and may add slide rows along it (limits); rods, ropes and pulleys are :class:`SegmentRows` (sums of
distances). Each kind gives, at a :class:`JoinedMotion`, the rows' violations C, their Jacobians and biases J̇u (see
:mod:`animbatch.sim.joints.rows`); the derivations are in the comments.

Ends: slot 0 is a joint's first body, slot 1 its second (or the world). Offsets are in body axes from the centre of
mass; for the world they are the world points themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.quaternion import cross
from animbatch.sim.joints.rows import JoinedMotion, Rows, accumulate

_AXES = np.eye(3)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...j,...j->...", a, b)


@dataclass(frozen=True, eq=False)
class RowKind:
    """Rows of one kind: their bodies (K, 2), owning joints (K,), whether each is unilateral (C ≥ 0 rather than
    C = 0) and the unit of C ('m' or 'rad')."""

    bodies: np.ndarray
    joint: np.ndarray
    unilateral: np.ndarray
    unit: str

    def rows(self, motion: JoinedMotion) -> Rows:
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class SegmentRows(RowKind):
    """Rods, ropes and pulleys: ``C_k = sign_k (Σ_s |d_s| − length_k)`` over the segments ``d_s`` of row k, each
    from a point of its near body to a point of its far body (or a fixed point). A rod or a taut pulley rope has
    sign +1 and is bilateral; a rope that can go slack has sign −1 and is unilateral (C ≥ 0: not longer than its
    length). A segment adds ``±n̂`` (and ``r × n̂``) to the slot of each of its ends; the far end of a pulley's
    segment is fixed and has slot −1 (nothing to add)."""

    segment_row: np.ndarray  # (S,)
    near_body: np.ndarray
    near_offset: np.ndarray  # (S, 3)
    near_slot: np.ndarray
    far_body: np.ndarray
    far_offset: np.ndarray
    far_slot: np.ndarray  # (S,) 0, 1, or −1 for a fixed far end
    length: np.ndarray  # (K,) [m]
    sign: np.ndarray  # (K,) ±1

    def geometry(self, motion: JoinedMotion) -> tuple[Any, ...]:
        near = motion.points(self.near_body, self.near_offset)
        far = motion.points(self.far_body, self.far_offset)
        d = near[1] - far[1]
        distance = np.linalg.norm(d, axis=1)
        return near, far, d / distance[:, None], distance

    def rows(self, motion: JoinedMotion) -> Rows:
        near, far, unit, distance = self.geometry(motion)
        count = len(self.length)
        per_row = lambda values: np.bincount(self.segment_row, weights=values, minlength=count)  # noqa: E731
        dv = near[2] - far[2]
        along = _dot(unit, dv)
        # d/dt (n̂ · Δv) = n̂̇ · Δv + n̂ · Δa, with n̂̇ · Δv = (|Δv|² − (n̂·Δv)²)/|d| and Δa's centripetal part
        bias = self.sign * per_row((_dot(dv, dv) - along**2) / distance + _dot(unit, near[3] - far[3]))
        sign = self.sign[self.segment_row][:, None]
        held = self.far_slot >= 0
        # each segment's ends add ±n̂ (and ±r × n̂) to their rows' slots: flat slot index 2·row + slot
        slots = np.concatenate([2 * self.segment_row + self.near_slot,
                                2 * self.segment_row[held] + self.far_slot[held]])
        linear = accumulate(slots, np.concatenate([sign * unit, -(sign * unit)[held]]), 2 * count)
        if motion.turning:
            angular = accumulate(slots, np.concatenate([sign * cross(near[0], unit),
                                                        -(sign * cross(far[0], unit))[held]]), 2 * count)
        else:  # particles and fixed points: no lever
            angular = np.zeros_like(linear)
        return Rows(self.sign * (per_row(distance) - self.length), linear.reshape(count, 2, 3),
                    angular.reshape(count, 2, 3), bias)

    def lines(self) -> tuple[np.ndarray, ...]:
        """The segments as drawn: near and far bodies and offsets."""
        return self.near_body, self.far_body, self.near_offset, self.far_offset


@dataclass(frozen=True, eq=False)
class PointRows(RowKind):
    """Ball joints (and the point part of hinges and welds): ``C = p_a − p_b`` (3 rows per joint, world axes), with
    ``p = x + R r``. Row i: ``l = ±e_i``, ``k = ±r × e_i``; bias ``ω_a × (ω_a × r_a) − ω_b × (ω_b × r_b)``."""

    first_offset: np.ndarray  # (J, 3)
    second_offset: np.ndarray

    def rows(self, motion: JoinedMotion) -> Rows:
        first, second = self.bodies[::3, 0], self.bodies[::3, 1]
        lever_a, point_a, _, centripetal_a = motion.points(first, self.first_offset)
        lever_b, point_b, _, centripetal_b = motion.points(second, self.second_offset)
        count = len(first)
        linear = np.zeros((count, 3, 2, 3))
        linear[:, :, 0] = _AXES
        linear[:, :, 1] = -_AXES
        angular = np.stack([cross(lever_a[:, None], _AXES), -cross(lever_b[:, None], _AXES)], axis=2)
        return Rows((point_a - point_b).ravel(), linear.reshape(-1, 2, 3), angular.reshape(-1, 2, 3),
                    (centripetal_a - centripetal_b).ravel())


@dataclass(frozen=True, eq=False)
class AxisRows(RowKind):
    """A hinge's axis stays put in both bodies: with n the axis fixed in the second body and u₁, u₂ two directions
    across it fixed in the first, ``C_i = n · u_i`` (2 rows per joint). ``Ċ = ω_a · (u × n) + ω_b · (n × u)``;
    bias ``(ω_b × (ω_b × n)) · u + 2 (ω_b × n) · (ω_a × u) + n · (ω_a × (ω_a × u))``."""

    axis: np.ndarray  # (J, 3), second body's axes
    across: np.ndarray  # (J, 2, 3), first body's axes

    def rows(self, motion: JoinedMotion) -> Rows:
        first, second = self.bodies[::2, 0], self.bodies[::2, 1]
        n = motion.directions(second, self.axis)[:, None]  # (J, 1, 3)
        u = np.einsum("kij,klj->kli", motion.rotation[first], self.across)  # (J, 2, 3)
        omega_a, omega_b = motion.omega[first][:, None], motion.omega[second][:, None]
        turn_n, turn_u = cross(omega_b, n), cross(omega_a, u)
        bias = _dot(cross(omega_b, turn_n), u) + 2 * _dot(turn_n, turn_u) + _dot(n, cross(omega_a, turn_u))
        u_cross_n = cross(u, n)
        angular = np.stack([u_cross_n, -u_cross_n], axis=2)
        return Rows(_dot(n, u).ravel(), np.zeros((2 * len(first), 2, 3)), angular.reshape(-1, 2, 3), bias.ravel())


@dataclass(frozen=True, eq=False)
class LockRows(RowKind):
    """The relative orientation stays (welds, sliders): with ``E = R_a Q Rᵀ_b`` (Q = R_aᵀ R_b at the start, so E = I
    while the joint holds), ``C = vee(skew(E))`` = sin θ times the axis of the error rotation (3 rows per joint).
    At E = I, ``Ė = [ω_a − ω_b]×``, so ``k = ±e_i``, and the bias is ``ω_b × ω_a``."""

    relative: np.ndarray  # (J, 3, 3)

    def rows(self, motion: JoinedMotion) -> Rows:
        first, second = self.bodies[::3, 0], self.bodies[::3, 1]
        error = motion.rotation[first] @ self.relative @ np.transpose(motion.rotation[second], (0, 2, 1))
        violation = 0.5 * np.stack([error[:, 2, 1] - error[:, 1, 2], error[:, 0, 2] - error[:, 2, 0],
                                    error[:, 1, 0] - error[:, 0, 1]], axis=1)
        count = len(first)
        angular = np.zeros((count, 3, 2, 3))
        angular[:, :, 0] = _AXES
        angular[:, :, 1] = -_AXES
        bias = cross(motion.omega[second], motion.omega[first])
        return Rows(violation.ravel(), np.zeros((3 * count, 2, 3)), angular.reshape(-1, 2, 3), bias.ravel())


@dataclass(frozen=True, eq=False)
class SlideRows(RowKind):
    """Sliders: the first body's point moves relative to the second's along directions n fixed in the second body,
    ``s = (p_a − p_b) · n``, and each row keeps ``C = sign (s − bound)`` at 0 (across the axis: bound 0) or ≥ 0
    (limits along it). With ``d = p_a − p_b``: ``Ċ/sign = n · (v_pa − v_pb) + d · (ω_b × n)``, so
    ``l_a = n, k_a = r_a × n, l_b = −n, k_b = −(r_b + d) × n``; bias
    ``2 (ω_b × n) · (v_pa − v_pb) + n · (c_a − c_b) + d · (ω_b × (ω_b × n))`` (c: centripetal accelerations)."""

    first_offset: np.ndarray  # (K, 3)
    second_offset: np.ndarray
    direction: np.ndarray  # (K, 3), second body's axes
    bound: np.ndarray  # (K,) [m]
    sign: np.ndarray  # (K,)

    def travel(self, motion: JoinedMotion) -> tuple[np.ndarray, ...]:
        """s (K,) [m] and its rate [m/s], with the geometry the rows use."""
        first, second = self.bodies[:, 0], self.bodies[:, 1]
        lever_a, point_a, velocity_a, centripetal_a = motion.points(first, self.first_offset)
        lever_b, point_b, velocity_b, centripetal_b = motion.points(second, self.second_offset)
        n = motion.directions(second, self.direction)
        d, dv = point_a - point_b, velocity_a - velocity_b
        turn = cross(motion.omega[second], n)
        return _dot(d, n), _dot(n, dv) + _dot(d, turn), n, d, dv, turn, lever_a, lever_b, centripetal_a - centripetal_b

    def rows(self, motion: JoinedMotion) -> Rows:
        s, _, n, d, dv, turn, lever_a, lever_b, centripetal = self.travel(motion)
        omega_b = motion.omega[self.bodies[:, 1]]
        bias = 2 * _dot(turn, dv) + _dot(n, centripetal) + _dot(d, cross(omega_b, turn))
        sign = self.sign[:, None]
        linear = np.stack([sign * n, -sign * n], axis=1)
        angular = np.stack([sign * cross(lever_a, n), -sign * cross(lever_b + d, n)], axis=1)
        return Rows(self.sign * (s - self.bound), linear, angular, self.sign * bias)


@dataclass(frozen=True, eq=False)
class AngleRows(RowKind):
    """Hinge limits: the hinge angle θ, the turn of the first body relative to the second about the axis n (fixed in
    the second body), from reference directions across the axis that coincide at the start; each row keeps
    ``C = sign (θ − bound) ≥ 0``. ``θ̇ = (ω_a − ω_b) · n``; bias ``sign (ω_a − ω_b) · (ω_b × n)``."""

    axis: np.ndarray  # (K, 3) second body's axes
    first_reference: np.ndarray  # (K, 3) first body's axes
    second_reference: np.ndarray  # (K, 3) second body's axes
    bound: np.ndarray  # (K,) [rad]
    sign: np.ndarray

    def rows(self, motion: JoinedMotion) -> Rows:
        first, second = self.bodies[:, 0], self.bodies[:, 1]
        angle, _, n = hinge_angle(motion, first, second, self.axis, self.first_reference, self.second_reference)
        relative = motion.omega[first] - motion.omega[second]
        sign = self.sign[:, None]
        angular = np.stack([sign * n, -sign * n], axis=1)
        bias = self.sign * _dot(relative, cross(motion.omega[second], n))
        return Rows(self.sign * (angle - self.bound), np.zeros_like(angular), angular, bias)


def hinge_angle(motion: JoinedMotion, first: np.ndarray, second: np.ndarray, axis: np.ndarray,
                first_reference: np.ndarray, second_reference: np.ndarray) -> tuple[np.ndarray, ...]:
    """θ (K,) [rad] in (−π, π], its rate θ̇ [rad/s] and the world axes n (K, 3) of hinges between bodies ``first``
    and ``second`` (see :class:`AngleRows`)."""
    n = motion.directions(second, axis)
    u_a = motion.directions(first, first_reference)
    u_b = motion.directions(second, second_reference)
    angle = np.arctan2(_dot(n, cross(u_b, u_a)), _dot(u_b, u_a))
    return angle, _dot(motion.omega[first] - motion.omega[second], n), n
