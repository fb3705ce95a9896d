"""Compiled joint rows: the joined bodies' motion, every kind's rows (C, its Jacobian, J̇u), the motors' efforts,
and ``J u`` and ``Jᵀ λ``.

The compiled forms of :class:`animbatch.sim.joints.rows.JoinedMotion`, the row kinds of
:mod:`animbatch.sim.joints.kinds` (their derivations are there), :class:`animbatch.sim.joints.motors.Motors`, and
:func:`~animbatch.sim.joints.rows.apply` / :func:`~animbatch.sim.joints.rows.apply_transpose`, on the packed
tables of :mod:`animbatch.sim.kernels.tables`. Same formulas, so the two agree to round-off.

Slot arrays (S = J + M + 1: joined bodies, anchors on keyframes, the world): ``sx``, ``sv`` (S, 3) [m, m/s];
``srotation`` (S, 3, 3); ``somega`` (S, 3) [rad/s]; ``sinverse_inertia`` (S, 3, 3), world axes; ``sspin`` (S, 3)
[rad/s²], the torque-free ``−I⁻¹ (ω × L)``; ``sacceleration`` (S, 3) [m/s²], the anchors' prescribed ones. Rows
(R): ``violation`` C (R,), ``jac`` (R, 2, 6): per end, the linear part of the Jacobian then its angular part (one
array, so that the coupling matrix is assembled from six contiguous numbers per end), ``bias`` J̇u (R,).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels import tables as T
from animbatch.sim.kernels.rigid_motion import (
    blocks,
    column,
    cross,
    dot,
    minus,
    path_at,
    plus,
    quaternion_matrix,
    rotate,
    store,
    table,
    times,
    turned,
    vector,
    world_tensor,
)
from animbatch.sim.kernels.tables import ANGLE, AXIS, LOCK, POINT, SEGMENT, SLIDE

Vector = tuple[float, float, float]


@njit(cache=True, error_model="numpy")
def _identities(srotation: np.ndarray) -> None:
    for s in range(len(srotation)):
        for i in range(3):
            for j in range(3):
                srotation[s, i, j] = 1.0 if i == j else 0.0


@njit(cache=True, error_model="numpy")
def slot_motion(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray,
                v: np.ndarray, rotation: np.ndarray, omega: np.ndarray, sx: np.ndarray, sv: np.ndarray,
                srotation: np.ndarray, somega: np.ndarray, sinverse_inertia: np.ndarray, sspin: np.ndarray,
                sacceleration: np.ndarray) -> None:
    """The slots' motion from the points' (``x``, ``v`` (P, 3); rigid ``rotation`` (B, 3, 3), ``omega`` (B, 3)) at
    time ``t`` [s], as :meth:`Joints.motion`."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    slot_path = column(integers, layout, T.SLOT_PATH)
    inertia = blocks(floats, layout, T.INERTIA, 3, 3)
    inverse_inertia = blocks(floats, layout, T.INVERSE_INERTIA, 3, 3)
    sx[:] = 0.0
    sv[:] = 0.0
    somega[:] = 0.0
    sinverse_inertia[:] = 0.0
    sspin[:] = 0.0
    sacceleration[:] = 0.0
    _identities(srotation)
    tensor = np.empty((3, 3))
    for s in range(len(points)):
        store(sx, s, vector(x, points[s]))
        store(sv, s, vector(v, points[s]))
        k = slot_rigid[s]
        if k < 0:
            continue
        for i in range(3):
            for j in range(3):
                srotation[s, i, j] = rotation[k, i, j]
        store(somega, s, vector(omega, k))
        world_tensor(srotation[s], inverse_inertia[k], sinverse_inertia[s])
        world_tensor(srotation[s], inertia[k], tensor)
        spin = rotate(sinverse_inertia[s], cross(vector(somega, s), rotate(tensor, vector(somega, s))))
        store(sspin, s, times(-1.0, spin))
    for s in range(len(slot_path)):
        if slot_path[s] >= 0:
            position, velocity, acceleration = path_at(floats, integers, layout, slot_path[s], t)
            store(sx, s, position)
            store(sv, s, velocity)
            store(sacceleration, s, acceleration)


@njit(cache=True, error_model="numpy")
def rigid_slot_state(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, orientations: np.ndarray,
                     angular_momentum: np.ndarray, srotation: np.ndarray, somega: np.ndarray,
                     sinverse_inertia: np.ndarray) -> None:
    """The rigid slots' rotations, world inverse inertias and ω from orientations (B, 4) and angular momenta
    (B, 3) (the projection's view of a state)."""
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    inverse_inertia = blocks(floats, layout, T.INVERSE_INERTIA, 3, 3)
    for s in range(len(column(integers, layout, T.JOINT_POINTS))):
        k = slot_rigid[s]
        if k < 0:
            continue
        quaternion_matrix(orientations[k], srotation[s])
        world_tensor(srotation[s], inverse_inertia[k], sinverse_inertia[s])
        store(somega, s, turned(srotation[s], inverse_inertia[k], vector(angular_momentum, k)))


@njit(cache=True, error_model="numpy")
def point(slot: int, offset: Vector, sx: np.ndarray, sv: np.ndarray, srotation: np.ndarray,
          somega: np.ndarray) -> tuple[Vector, Vector, Vector, Vector]:
    """A body point at ``offset`` (body axes) of a slot: lever r, position, velocity ``v + ω × r`` and centripetal
    acceleration ``ω × (ω × r)`` (see :meth:`JoinedMotion.points`)."""
    lever = rotate(srotation[slot], offset)
    w = vector(somega, slot)
    spin = cross(w, lever)
    return lever, plus(vector(sx, slot), lever), plus(vector(sv, slot), spin), cross(w, spin)


@njit(cache=True, error_model="numpy")
def _segment_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, sx: np.ndarray,
                  sv: np.ndarray, srotation: np.ndarray, somega: np.ndarray, violation: np.ndarray,
                  jac: np.ndarray, bias: np.ndarray) -> None:
    """Rods, ropes and pulleys: ``C = sign (Σ |d| − length)`` (:class:`~animbatch.sim.joints.kinds.SegmentRows`)."""
    linear, angular = jac[:, :, :3], jac[:, :, 3:]
    ends = table(integers, layout, T.SEGMENT_ENDS, 5)
    offsets = blocks(floats, layout, T.SEGMENT_OFFSETS, 2, 3)
    rows = table(floats, layout, T.SEGMENT_ROWS, 2)
    for k in range(len(rows)):
        violation[first + k] = 0.0
        bias[first + k] = 0.0
    for s in range(len(ends)):
        row = first + ends[s, 0]
        sign = rows[ends[s, 0], 1]
        lever_a, point_a, velocity_a, centripetal_a = point(ends[s, 1], vector(offsets[s], 0), sx, sv, srotation,
                                                            somega)
        lever_b, point_b, velocity_b, centripetal_b = point(ends[s, 3], vector(offsets[s], 1), sx, sv, srotation,
                                                            somega)
        d = minus(point_a, point_b)
        distance = math.sqrt(dot(d, d))
        unit = (d[0] / distance, d[1] / distance, d[2] / distance)
        dv = minus(velocity_a, velocity_b)
        along = dot(unit, dv)
        violation[row] += distance
        bias[row] += (dot(dv, dv) - along**2) / distance + dot(unit, minus(centripetal_a, centripetal_b))
        near, far = ends[s, 2], ends[s, 4]
        turn_a = cross(lever_a, unit)
        for c in range(3):
            linear[row, near, c] += sign * unit[c]
            angular[row, near, c] += sign * turn_a[c]
        if far >= 0:
            turn_b = cross(lever_b, unit)
            for c in range(3):
                linear[row, far, c] -= sign * unit[c]
                angular[row, far, c] -= sign * turn_b[c]
    for k in range(len(rows)):
        violation[first + k] = rows[k, 1] * (violation[first + k] - rows[k, 0])
        bias[first + k] = rows[k, 1] * bias[first + k]


@njit(cache=True, error_model="numpy")
def _point_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, sx: np.ndarray,
                sv: np.ndarray, srotation: np.ndarray, somega: np.ndarray, violation: np.ndarray, jac: np.ndarray,
                bias: np.ndarray) -> None:
    """Ball joints: ``C = p_a − p_b``, three rows each (:class:`~animbatch.sim.joints.kinds.PointRows`)."""
    linear, angular = jac[:, :, :3], jac[:, :, 3:]
    bodies = table(integers, layout, T.POINT_BODIES, 2)
    offsets = blocks(floats, layout, T.POINT_OFFSETS, 2, 3)
    for j in range(len(bodies)):
        row = first + 3 * j
        lever_a, point_a, _, centripetal_a = point(bodies[j, 0], vector(offsets[j], 0), sx, sv, srotation, somega)
        lever_b, point_b, _, centripetal_b = point(bodies[j, 1], vector(offsets[j], 1), sx, sv, srotation, somega)
        for i in range(3):
            violation[row + i] = point_a[i] - point_b[i]
            bias[row + i] = centripetal_a[i] - centripetal_b[i]
            linear[row + i, 0, i] = 1.0
            linear[row + i, 1, i] = -1.0
        # r × e_i, row by row
        angular[row, 0, 1], angular[row, 0, 2] = lever_a[2], -lever_a[1]
        angular[row + 1, 0, 0], angular[row + 1, 0, 2] = -lever_a[2], lever_a[0]
        angular[row + 2, 0, 0], angular[row + 2, 0, 1] = lever_a[1], -lever_a[0]
        angular[row, 1, 1], angular[row, 1, 2] = -lever_b[2], lever_b[1]
        angular[row + 1, 1, 0], angular[row + 1, 1, 2] = lever_b[2], -lever_b[0]
        angular[row + 2, 1, 0], angular[row + 2, 1, 1] = -lever_b[1], lever_b[0]


@njit(cache=True, error_model="numpy")
def _axis_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, srotation: np.ndarray,
               somega: np.ndarray, violation: np.ndarray, jac: np.ndarray, bias: np.ndarray) -> None:
    """Hinge axes: ``C_i = n · u_i``, two rows each (:class:`~animbatch.sim.joints.kinds.AxisRows`)."""
    angular = jac[:, :, 3:]
    bodies = table(integers, layout, T.AXIS_BODIES, 2)
    axes = table(floats, layout, T.AXIS_AXIS, 3)
    across = blocks(floats, layout, T.AXIS_ACROSS, 2, 3)
    for j in range(len(bodies)):
        a, b = bodies[j, 0], bodies[j, 1]
        n = rotate(srotation[b], vector(axes, j))
        omega_a, omega_b = vector(somega, a), vector(somega, b)
        turn_n = cross(omega_b, n)
        for i in range(2):
            row = first + 2 * j + i
            u = rotate(srotation[a], vector(across[j], i))
            turn_u = cross(omega_a, u)
            bias[row] = dot(cross(omega_b, turn_n), u) + 2 * dot(turn_n, turn_u) + dot(n, cross(omega_a, turn_u))
            u_cross_n = cross(u, n)
            for c in range(3):
                angular[row, 0, c] = u_cross_n[c]
                angular[row, 1, c] = -u_cross_n[c]
            violation[row] = dot(n, u)


@njit(cache=True, error_model="numpy")
def _lock_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, srotation: np.ndarray,
               somega: np.ndarray, violation: np.ndarray, jac: np.ndarray, bias: np.ndarray) -> None:
    """Welds and sliders: ``C = vee(skew(R_a Q R_bᵀ))``, three rows each
    (:class:`~animbatch.sim.joints.kinds.LockRows`)."""
    angular = jac[:, :, 3:]
    bodies = table(integers, layout, T.LOCK_BODIES, 2)
    relative = blocks(floats, layout, T.LOCK_RELATIVE, 3, 3)
    product = np.empty((3, 3))
    error = np.empty((3, 3))
    for j in range(len(bodies)):
        row = first + 3 * j
        a, b = bodies[j, 0], bodies[j, 1]
        ra, rb, q = srotation[a], srotation[b], relative[j]
        for i in range(3):
            for m in range(3):
                product[i, m] = ra[i, 0] * q[0, m] + ra[i, 1] * q[1, m] + ra[i, 2] * q[2, m]
        for i in range(3):
            for m in range(3):
                error[i, m] = product[i, 0] * rb[m, 0] + product[i, 1] * rb[m, 1] + product[i, 2] * rb[m, 2]
        violation[row] = 0.5 * (error[2, 1] - error[1, 2])
        violation[row + 1] = 0.5 * (error[0, 2] - error[2, 0])
        violation[row + 2] = 0.5 * (error[1, 0] - error[0, 1])
        turn = cross(vector(somega, b), vector(somega, a))
        for i in range(3):
            angular[row + i, 0, i] = 1.0
            angular[row + i, 1, i] = -1.0
            bias[row + i] = turn[i]


@njit(cache=True, error_model="numpy")
def travel(offset_a: Vector, offset_b: Vector, direction: Vector, a: int, b: int, sx: np.ndarray, sv: np.ndarray,
           srotation: np.ndarray, somega: np.ndarray) -> tuple[float, float, Vector, Vector, Vector, Vector, Vector,
                                                               Vector, Vector]:
    """A slider's travel s [m] and its rate [m/s], with the geometry its rows use: n, d, Δv, ω_b × n, the levers
    and the difference of the centripetal accelerations (see :meth:`SlideRows.travel`)."""
    lever_a, point_a, velocity_a, centripetal_a = point(a, offset_a, sx, sv, srotation, somega)
    lever_b, point_b, velocity_b, centripetal_b = point(b, offset_b, sx, sv, srotation, somega)
    n = rotate(srotation[b], direction)
    d, dv = minus(point_a, point_b), minus(velocity_a, velocity_b)
    turn = cross(vector(somega, b), n)
    return (dot(d, n), dot(n, dv) + dot(d, turn), n, d, dv, turn, lever_a, lever_b,
            minus(centripetal_a, centripetal_b))


@njit(cache=True, error_model="numpy")
def _slide_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, sx: np.ndarray,
                sv: np.ndarray, srotation: np.ndarray, somega: np.ndarray, violation: np.ndarray, jac: np.ndarray,
                bias: np.ndarray) -> None:
    """Slider rows: ``C = sign (s − bound)``, ``s = (p_a − p_b) · n``
    (:class:`~animbatch.sim.joints.kinds.SlideRows`)."""
    linear, angular = jac[:, :, :3], jac[:, :, 3:]
    bodies = table(integers, layout, T.SLIDE_BODIES, 2)
    offsets = blocks(floats, layout, T.SLIDE_OFFSETS, 2, 3)
    directions = table(floats, layout, T.SLIDE_DIRECTION, 3)
    bounds = table(floats, layout, T.SLIDE_BOUNDS, 2)
    for k in range(len(bodies)):
        row = first + k
        a, b = bodies[k, 0], bodies[k, 1]
        s, _, n, d, dv, turn, lever_a, lever_b, centripetal = travel(
            vector(offsets[k], 0), vector(offsets[k], 1), vector(directions, k), a, b, sx, sv, srotation, somega)
        value = 2 * dot(turn, dv) + dot(n, centripetal) + dot(d, cross(vector(somega, b), turn))
        sign = bounds[k, 1]
        arm_a, arm_b = cross(lever_a, n), cross(plus(lever_b, d), n)
        for c in range(3):
            linear[row, 0, c] = sign * n[c]
            linear[row, 1, c] = -sign * n[c]
            angular[row, 0, c] = sign * arm_a[c]
            angular[row, 1, c] = -sign * arm_b[c]
        violation[row] = sign * (s - bounds[k, 0])
        bias[row] = sign * value


@njit(cache=True, error_model="numpy")
def hinge_angle(a: int, b: int, axis: Vector, first_reference: Vector, second_reference: Vector,
                srotation: np.ndarray, somega: np.ndarray) -> tuple[float, float, Vector]:
    """θ [rad] in (−π, π], θ̇ [rad/s] and the world axis n of a hinge between slots a and b
    (:func:`~animbatch.sim.joints.kinds.hinge_angle`)."""
    n = rotate(srotation[b], axis)
    u_a = rotate(srotation[a], first_reference)
    u_b = rotate(srotation[b], second_reference)
    rate = dot(minus(vector(somega, a), vector(somega, b)), n)
    return math.atan2(dot(n, cross(u_b, u_a)), dot(u_b, u_a)), rate, n


@njit(cache=True, error_model="numpy")
def _angle_rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, first: int, srotation: np.ndarray,
                somega: np.ndarray, violation: np.ndarray, jac: np.ndarray, bias: np.ndarray) -> None:
    """Hinge limits: ``C = sign (θ − bound)`` (:class:`~animbatch.sim.joints.kinds.AngleRows`)."""
    angular = jac[:, :, 3:]
    bodies = table(integers, layout, T.ANGLE_BODIES, 2)
    axes = table(floats, layout, T.ANGLE_AXIS, 3)
    references = blocks(floats, layout, T.ANGLE_REFERENCES, 2, 3)
    bounds = table(floats, layout, T.ANGLE_BOUNDS, 2)
    for k in range(len(bodies)):
        row = first + k
        a, b = bodies[k, 0], bodies[k, 1]
        angle, _, n = hinge_angle(a, b, vector(axes, k), vector(references[k], 0), vector(references[k], 1),
                                  srotation, somega)
        sign = bounds[k, 1]
        for c in range(3):
            angular[row, 0, c] = sign * n[c]
            angular[row, 1, c] = -sign * n[c]
        relative = minus(vector(somega, a), vector(somega, b))
        bias[row] = sign * dot(relative, cross(vector(somega, b), n))
        violation[row] = sign * (angle - bounds[k, 0])


@njit(cache=True, error_model="numpy")
def rows(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, sx: np.ndarray, sv: np.ndarray,
         srotation: np.ndarray, somega: np.ndarray, violation: np.ndarray, jac: np.ndarray, bias: np.ndarray) -> None:
    """Every row's C, Jacobian (R, 2, 6: per end the linear part, then the angular part) and bias at the slots'
    motion, kind by kind."""
    jac[:] = 0.0
    first = column(integers, layout, T.KIND_ROWS)
    _segment_rows(floats, integers, layout, first[SEGMENT], sx, sv, srotation, somega, violation, jac, bias)
    _point_rows(floats, integers, layout, first[POINT], sx, sv, srotation, somega, violation, jac, bias)
    _axis_rows(floats, integers, layout, first[AXIS], srotation, somega, violation, jac, bias)
    _lock_rows(floats, integers, layout, first[LOCK], srotation, somega, violation, jac, bias)
    _slide_rows(floats, integers, layout, first[SLIDE], sx, sv, srotation, somega, violation, jac, bias)
    _angle_rows(floats, integers, layout, first[ANGLE], srotation, somega, violation, jac, bias)


@njit(cache=True, error_model="numpy")
def motor_loads(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, sx: np.ndarray,
                sv: np.ndarray, srotation: np.ndarray, somega: np.ndarray, force: np.ndarray, torque: np.ndarray,
                efforts: np.ndarray) -> None:
    """The motors' efforts (Mo,) [N·m or N] at time ``t`` [s], and their forces and torques added to ``force``,
    ``torque`` (S, 3) on the slots (see :class:`~animbatch.sim.joints.motors.Motors`)."""
    bodies = table(integers, layout, T.MOTOR_BODIES, 2)
    kinds = table(integers, layout, T.MOTOR_KIND, 2)
    axes = table(floats, layout, T.MOTOR_AXIS, 3)
    references = blocks(floats, layout, T.MOTOR_REFERENCES, 2, 3)
    offsets = blocks(floats, layout, T.MOTOR_OFFSETS, 2, 3)
    gains = table(floats, layout, T.MOTOR_GAINS, 4)
    for m in range(len(bodies)):
        a, b = bodies[m, 0], bodies[m, 1]
        hinge = kinds[m, 0] != 0
        lever_a = lever_b = d = (0.0, 0.0, 0.0)
        if hinge:
            q, rate, n = hinge_angle(a, b, vector(axes, m), vector(references[m], 0), vector(references[m], 1),
                                     srotation, somega)
        else:
            q, rate, n, d, _, _, lever_a, lever_b, _ = travel(vector(offsets[m], 0), vector(offsets[m], 1),
                                                              vector(axes, m), a, b, sx, sv, srotation, somega)
        target, target_rate = 0.0, gains[m, 0]
        if kinds[m, 1] >= 0:
            goal, goal_rate, _ = path_at(floats, integers, layout, kinds[m, 1], t)
            target, target_rate = goal[0], goal_rate[0] + gains[m, 0]
        error = target - q
        if hinge:  # the short way round
            error = math.atan2(math.sin(error), math.cos(error))
        effort = gains[m, 1] * error + gains[m, 2] * (target_rate - rate)
        effort = min(max(effort, -gains[m, 3]), gains[m, 3])
        efforts[m] = effort
        push = times(effort, n)
        if hinge:
            store(torque, a, plus(vector(torque, a), push))
            store(torque, b, minus(vector(torque, b), push))
        else:
            store(force, a, plus(vector(force, a), push))
            store(torque, a, plus(vector(torque, a), cross(lever_a, push)))
            store(force, b, minus(vector(force, b), push))
            store(torque, b, minus(vector(torque, b), cross(plus(lever_b, d), push)))


@njit(cache=True, error_model="numpy")
def apply(row_bodies: np.ndarray, jac: np.ndarray, velocity: np.ndarray, omega: np.ndarray, out: np.ndarray) -> None:
    """``J u`` (R,) for slot velocities ``velocity``, ``omega`` (S, 3), into ``out``."""
    for r in range(len(out)):
        value = 0.0
        for end in range(2):
            s = row_bodies[r, end]
            value += (jac[r, end, 0] * velocity[s, 0] + jac[r, end, 1] * velocity[s, 1]
                      + jac[r, end, 2] * velocity[s, 2])
            value += (jac[r, end, 3] * omega[s, 0] + jac[r, end, 4] * omega[s, 1] + jac[r, end, 5] * omega[s, 2])
        out[r] = value


@njit(cache=True, error_model="numpy")
def apply_transpose(row_bodies: np.ndarray, jac: np.ndarray, multiplier: np.ndarray, force: np.ndarray,
                    torque: np.ndarray) -> None:
    """``Jᵀ λ``: the forces and torques (S, 3) that rows with multipliers λ (R,) exert on the slots, into ``force``,
    ``torque`` (overwritten)."""
    force[:] = 0.0
    torque[:] = 0.0
    for r in range(len(multiplier)):
        value = multiplier[r]
        for end in range(2):
            s = row_bodies[r, end]
            for c in range(3):
                force[s, c] += value * jac[r, end, c]
                torque[s, c] += value * jac[r, end, 3 + c]
