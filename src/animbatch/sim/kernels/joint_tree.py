"""Compiled steps of a joint tree (hinges, sliders) in joint coordinates: the articulated-body algorithm on scalars.

The compiled form of :func:`animbatch.sim.joints.tree.advance` (read the formulas there): forward kinematics from
the joint positions, the applied forces of the tables (:func:`animbatch.sim.kernels.rigid_motion.add_forces`) and the
three passes of the articulated-body algorithm, for every stage of every step of a call, in work arrays allocated
once per call (a small array allocated per body and per step costs more than a step's arithmetic). Spatial vectors
are (6,) rows ``(angular; linear)`` at each body's centre of mass in world axes; spatial inertias (6, 6).

Tree tables: ``links`` (K, 3) each body's rigid index, its parent's position in the tree (−1: the world) and
whether its joint is a slider (1; else a hinge); ``offsets`` (K, 3, 3) a hinge's point in the body's axes, the same
point in the parent's axes (or the world), and the joint's unit axis in the body's axes; ``mass`` (K,) [kg];
``inertia`` and ``inverse_inertia`` (K, 3, 3) body axes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels import rigid_motion
from animbatch.sim.kernels.rigid_motion import cross, dot, minus, plus, rotate, store, times, vector
from animbatch.sim.kernels.stepper import FORM_RUNGE_KUTTA, FORM_SYMPLECTIC_EULER


@njit(cache=True, error_model="numpy")
def _multiply(p: np.ndarray, q: np.ndarray, out: np.ndarray) -> None:
    """The Hamilton product ``p ⊗ q`` of quaternions (4,) into ``out``."""
    out[0], out[1], out[2], out[3] = rigid_motion.hamilton((p[0], p[1], p[2], p[3]), (q[0], q[1], q[2], q[3]))


@njit(cache=True, error_model="numpy")
def start_of(links: np.ndarray, orientation: np.ndarray, position: np.ndarray, relative: np.ndarray,
             offset: np.ndarray, work: np.ndarray) -> None:
    """The pose taken as q = 0 (:func:`animbatch.sim.joints.tree.start_of`): each body's orientation relative to
    its parent's, ``q̄_parent ⊗ q_body`` (K, 4), into ``relative``, and its centre of mass from its parent's in the
    parent's axes (K, 3), into ``offset``; from the bodies' orientations (B, 4) (unit) and positions (B, 3).
    ``work`` (3, 3) scratch."""
    conjugate = np.empty(4)
    for k in range(len(links)):
        body, p = links[k, 0], links[k, 1]
        if p < 0:
            relative[k] = orientation[body]
            store(offset, k, vector(position, body))
            continue
        above = orientation[links[p, 0]]
        conjugate[0], conjugate[1], conjugate[2], conjugate[3] = above[0], -above[1], -above[2], -above[3]
        _multiply(conjugate, orientation[body], relative[k])
        rigid_motion.quaternion_matrix(above, work)
        store(offset, k, rigid_motion.rotate_back(work, minus(vector(position, body),
                                                              vector(position, links[p, 0]))))


@njit(cache=True, error_model="numpy")
def pose(links: np.ndarray, offsets: np.ndarray, relative: np.ndarray, offset: np.ndarray, q: np.ndarray,
         qd: np.ndarray, quat: np.ndarray, rotation: np.ndarray, x: np.ndarray, v: np.ndarray, omega: np.ndarray,
         pivot: np.ndarray, axis: np.ndarray, work: np.ndarray) -> None:
    """Forward kinematics at joint positions q (K,) [rad or m] and rates q̇ (K,) from the start ``relative`` and
    ``offset`` (:func:`start_of`): orientations ``quat`` (K, 4), ``rotation`` (K, 3, 3), centres of mass ``x``,
    velocities ``v``, angular velocities ``omega``, the hinges' ``pivot`` points (a slider's: its parent's centre)
    and the joints' world ``axis`` (K, 3); ``work`` (2, 4) scratch."""
    turn, base = work[0], work[1]
    for k in range(len(links)):
        p = links[k, 1]
        if links[k, 2]:  # a slider: the orientation as it started, the centre moved along the axis
            if p >= 0:
                _multiply(quat[p], relative[k], quat[k])
            else:
                quat[k] = relative[k]
            rigid_motion.quaternion_matrix(quat[k], rotation[k])
            n = rotate(rotation[k], vector(offsets[k], 2))
            store(axis, k, n)
            if p >= 0:
                origin = vector(x, p)
                store(pivot, k, origin)
                centre = plus(plus(origin, rotate(rotation[p], vector(offset, k))), times(q[k], n))
                wp = vector(omega, p)
                moving = plus(vector(v, p), cross(wp, minus(centre, origin)))
            else:
                store(pivot, k, (0.0, 0.0, 0.0))
                centre = plus(vector(offset, k), times(q[k], n))
                wp, moving = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
            store(x, k, centre)
            store(omega, k, wp)
            store(v, k, plus(moving, times(qd[k], n)))
            continue
        half = 0.5 * q[k]
        s = math.sin(half)
        turn[0], turn[1], turn[2], turn[3] = math.cos(half), s * offsets[k, 2, 0], s * offsets[k, 2, 1], \
            s * offsets[k, 2, 2]
        if p >= 0:
            _multiply(quat[p], relative[k], base)
        else:
            base[:] = relative[k]
        _multiply(base, turn, quat[k])
        rigid_motion.quaternion_matrix(quat[k], rotation[k])
        if p >= 0:
            lever = rotate(rotation[p], vector(offsets[k], 1))
            here = plus(vector(x, p), lever)
            moving = plus(vector(v, p), cross(vector(omega, p), lever))
            parent_omega = vector(omega, p)
        else:
            here, moving, parent_omega = vector(offsets[k], 1), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        store(pivot, k, here)
        centre = minus(here, rotate(rotation[k], vector(offsets[k], 0)))
        store(x, k, centre)
        n = rotate(rotation[k], vector(offsets[k], 2))
        store(axis, k, n)
        w = plus(parent_omega, times(qd[k], n))
        store(omega, k, w)
        store(v, k, plus(moving, cross(w, minus(centre, here))))


@njit(cache=True, error_model="numpy")
def _carry(r: tuple[float, float, float], motion: np.ndarray, out: np.ndarray) -> None:
    """``X motion`` (6,): a parent's spatial motion at its centre of mass, carried to a point ``r`` from it."""
    angular = (motion[0], motion[1], motion[2])
    linear = plus((motion[3], motion[4], motion[5]), cross(angular, r))
    out[0], out[1], out[2], out[3], out[4], out[5] = angular[0], angular[1], angular[2], linear[0], linear[1], \
        linear[2]


@njit(cache=True, error_model="numpy")
def _add_carried_force(r: tuple[float, float, float], force: np.ndarray, out: np.ndarray) -> None:
    """``out += Xᵀ force`` (6,): a child's spatial force at a point ``r`` from its parent's centre of mass, about
    the parent's centre of mass."""
    linear = (force[3], force[4], force[5])
    moment = plus((force[0], force[1], force[2]), cross(r, linear))
    for c in range(3):
        out[c] += moment[c]
        out[3 + c] += linear[c]


@njit(cache=True, error_model="numpy")
def _add_carried_inertia(r: tuple[float, float, float], inertia: np.ndarray, work: np.ndarray,
                         out: np.ndarray) -> None:
    """``out += Xᵀ inertia X`` (6, 6), X carrying a parent's motion a point ``r`` from its centre of mass;
    ``work`` (6, 6) scratch."""
    # X = [[1, 0], [−[r]×, 1]]: X's lower-left block, row by row
    lower = ((0.0, r[2], -r[1]), (-r[2], 0.0, r[0]), (r[1], -r[0], 0.0))
    for i in range(6):  # work = inertia X
        for j in range(3):
            s = inertia[i, j]
            for m in range(3):
                s += inertia[i, 3 + m] * lower[m][j]
            work[i, j] = s
        for j in range(3, 6):
            work[i, j] = inertia[i, j]
    for j in range(6):  # out += Xᵀ work
        for i in range(3):
            s = work[i, j]
            for m in range(3):
                s += lower[m][i] * work[3 + m, j]
            out[i, j] += s
        for i in range(3, 6):
            out[i, j] += work[i, j]


@njit(cache=True, error_model="numpy")
def accelerations(links: np.ndarray, mass: np.ndarray, inertia: np.ndarray, x: np.ndarray, omega: np.ndarray,
                  rotation: np.ndarray, pivot: np.ndarray, axis: np.ndarray, qd: np.ndarray, force: np.ndarray,
                  torque: np.ndarray, qdd: np.ndarray, acceleration: np.ndarray, motion_axis: np.ndarray,
                  bias: np.ndarray, articulated: np.ndarray, bias_force: np.ndarray, across: np.ndarray,
                  pivot_work: np.ndarray, block: np.ndarray, block_work: np.ndarray) -> None:
    """The articulated-body algorithm: q̈ (K,) [rad/s²] and the bodies' accelerations (K, 6) under the applied
    ``force`` and ``torque`` (B, 3) (rigid indices) at a pose of :func:`pose`. Scratch: ``motion_axis``, ``bias``,
    ``bias_force``, ``across`` (K, 6), ``articulated`` (K, 6, 6), ``pivot_work`` (K, 2) (D and u), ``block`` and
    ``block_work`` (6, 6)."""
    count = len(links)
    for k in range(count):
        body, p = links[k, 0], links[k, 1]
        n, w, centre = vector(axis, k), vector(omega, k), vector(x, k)
        d = minus(centre, vector(pivot, k))
        if links[k, 2]:  # a slider: S = (0; n); c = (0; ω_p × (ω_p × r) + 2 q̇ ω_p × n), r from the parent's centre
            for c in range(3):
                motion_axis[k, c], motion_axis[k, 3 + c] = 0.0, n[c]
            turning = (0.0, 0.0, 0.0)
            if p >= 0:
                wp = vector(omega, p)
                linear = plus(cross(wp, cross(wp, d)), times(2.0 * qd[k], cross(wp, n)))
            else:
                linear = (0.0, 0.0, 0.0)
        else:
            nd = cross(n, d)
            for c in range(3):
                motion_axis[k, c], motion_axis[k, 3 + c] = n[c], nd[c]
            centripetal = cross(w, cross(w, d))
            if p >= 0:
                wp = vector(omega, p)
                turning = times(qd[k], cross(wp, n))
                linear = plus(plus(cross(wp, cross(wp, minus(vector(pivot, k), vector(x, p)))), cross(turning, d)),
                              centripetal)
            else:
                turning, linear = (0.0, 0.0, 0.0), centripetal
        for c in range(3):
            bias[k, c], bias[k, 3 + c] = turning[c], linear[c]
        rigid_motion.world_tensor(rotation[k], inertia[k], block)
        spin = cross(w, rotate(block, w))
        for i in range(6):
            for j in range(6):
                articulated[k, i, j] = 0.0
        for i in range(3):
            for j in range(3):
                articulated[k, i, j] = block[i, j]
            articulated[k, 3 + i, 3 + i] = mass[k]
            bias_force[k, i] = spin[i] - torque[body, i]
            bias_force[k, 3 + i] = -force[body, i]
    for k in range(count - 1, -1, -1):
        here = articulated[k]
        for i in range(6):
            s = 0.0
            for j in range(6):
                s += here[i, j] * motion_axis[k, j]
            across[k, i] = s
        diagonal, effort = 0.0, 0.0
        for i in range(6):
            diagonal += motion_axis[k, i] * across[k, i]
            effort -= motion_axis[k, i] * bias_force[k, i]
        pivot_work[k, 0], pivot_work[k, 1] = diagonal, effort
        p = links[k, 1]
        if p < 0:
            continue
        for i in range(6):
            for j in range(6):
                here[i, j] -= across[k, i] * across[k, j] / diagonal
        passed = block_work[0]  # a row of the scratch block: pA + Iᵃ c + U u / D
        for i in range(6):
            s = bias_force[k, i] + across[k, i] * effort / diagonal
            for j in range(6):
                s += here[i, j] * bias[k, j]
            passed[i] = s
        r = minus(vector(x, k), vector(x, p))
        _add_carried_force(r, passed, bias_force[p])
        _add_carried_inertia(r, here, block, articulated[p])
    carried = block_work[1]
    for k in range(count):
        p = links[k, 1]
        if p >= 0:
            _carry(minus(vector(x, k), vector(x, p)), acceleration[p], carried)
        else:
            for i in range(6):
                carried[i] = 0.0
        s = 0.0
        for i in range(6):
            carried[i] += bias[k, i]
            s += across[k, i] * carried[i]
        qdd[k] = (pivot_work[k, 1] - s) / pivot_work[k, 0]
        for i in range(6):
            acceleration[k, i] = carried[i] + motion_axis[k, i] * qdd[k]


@njit(cache=True, error_model="numpy")
def _rate(now: float, q: np.ndarray, qd: np.ndarray, links: np.ndarray, offsets: np.ndarray, mass: np.ndarray,
          inertia: np.ndarray, relative: np.ndarray, offset: np.ndarray, floats: np.ndarray, integers: np.ndarray,
          layout: np.ndarray, quat: np.ndarray, rotation: np.ndarray, x: np.ndarray, v: np.ndarray, omega: np.ndarray,
          pivot: np.ndarray, axis: np.ndarray, all_x: np.ndarray, all_v: np.ndarray, all_rotation: np.ndarray,
          all_omega: np.ndarray, force: np.ndarray, torque: np.ndarray, qdd: np.ndarray, acceleration: np.ndarray,
          spatial: np.ndarray, articulated: np.ndarray, pivot_work: np.ndarray, block: np.ndarray,
          block_work: np.ndarray) -> None:
    """q̈ (K,) at (q, q̇) and time ``now``: the pose, the applied forces on it, the articulated-body passes."""
    pose(links, offsets, relative, offset, q, qd, quat, rotation, x, v, omega, pivot, axis, block_work[:2, :4])
    for k in range(len(links)):
        body = links[k, 0]
        for c in range(3):
            all_x[body, c], all_v[body, c], all_omega[body, c] = x[k, c], v[k, c], omega[k, c]
            for m in range(3):
                all_rotation[body, c, m] = rotation[k, c, m]
    rigid_motion.add_forces(now, floats, integers, layout, all_x, all_v, all_rotation, all_omega, force, torque)
    accelerations(links, mass, inertia, x, omega, rotation, pivot, axis, qd, force, torque, qdd, acceleration,
                  spatial[0], spatial[1], articulated, spatial[2], spatial[3], pivot_work, block, block_work)


@njit(cache=True, error_model="numpy")
def advance(y: np.ndarray, t: float, h: float, steps: int, form: int, a: np.ndarray, weights: np.ndarray,
            nodes: np.ndarray, rate: np.ndarray, links: np.ndarray, offsets: np.ndarray, mass: np.ndarray,
            inertia: np.ndarray, inverse_inertia: np.ndarray, floats: np.ndarray, integers: np.ndarray,
            layout: np.ndarray) -> int:
    """``steps`` fixed steps of ``h`` [s] from ``t`` [s] of a state ``y`` of B rigid bodies on a joint tree, in
    joint coordinates, in place; returns the right-hand sides evaluated (:func:`animbatch.sim.joints.tree.advance`,
    with ``form`` and the tableau ``a``, ``weights``, ``nodes`` as :func:`animbatch.sim.kernels.stepper.advance`
    takes them; Verlet's ``rate`` (6B,) is left at the last evaluation's dm/dt)."""
    count = len(links)
    bodies = len(y) // 13
    position, orientation = y[: 3 * bodies].reshape((bodies, 3)), y[3 * bodies: 7 * bodies].reshape((bodies, 4))
    momentum = y[7 * bodies: 10 * bodies].reshape((bodies, 3))
    angular = y[10 * bodies:].reshape((bodies, 3))
    # work arrays, once per call
    quat, rotation = np.empty((count, 4)), np.empty((count, 3, 3))
    x, v, omega, pivot, axis = (np.empty((count, 3)), np.empty((count, 3)), np.empty((count, 3)),
                                np.empty((count, 3)), np.empty((count, 3)))
    all_x, all_v, all_omega = np.zeros((bodies, 3)), np.zeros((bodies, 3)), np.zeros((bodies, 3))
    all_rotation = np.zeros((bodies, 3, 3))
    force, torque = np.empty((bodies, 3)), np.empty((bodies, 3))
    acceleration, spatial = np.zeros((count, 6)), np.empty((4, count, 6))
    articulated, pivot_work = np.empty((count, 6, 6)), np.empty((count, 2))
    block, block_work = np.empty((6, 6)), np.empty((6, 6))
    relative, offset = np.empty((count, 4)), np.empty((count, 3))
    # the start: q = 0 at the poses as they stand; a hinge's q̇ from the angular velocities, a slider's from the
    # velocity relative to its parent's frame
    unit = orientation.copy()
    for body in range(bodies):
        rigid_motion.normalise(unit[body])
    start_of(links, unit, position, relative, offset, block)
    q, qd, qdd = np.zeros(count), np.empty(count), np.empty(count)
    for k in range(count):
        body, p = links[k, 0], links[k, 1]
        rigid_motion.quaternion_matrix(unit[body], rotation[k])
        store(omega, k, rigid_motion.turned(rotation[k], inverse_inertia[k], vector(angular, body)))
        store(v, k, times(1.0 / mass[k], vector(momentum, body)))
        n = rotate(rotation[k], vector(offsets[k], 2))
        if links[k, 2] and p >= 0:
            lever = minus(vector(position, body), vector(position, links[p, 0]))
            qd[k] = dot(n, minus(minus(vector(v, k), vector(v, p)), cross(vector(omega, p), lever)))
        elif links[k, 2]:
            qd[k] = dot(n, vector(v, k))
        else:
            qd[k] = dot(n, minus(vector(omega, k), vector(omega, p)) if p >= 0 else vector(omega, k))
    args = (links, offsets, mass, inertia, relative, offset, floats, integers, layout, quat, rotation, x, v, omega,
            pivot, axis, all_x, all_v, all_rotation, all_omega, force, torque, qdd, acceleration, spatial,
            articulated, pivot_work, block, block_work)
    evaluations = 0
    if form == FORM_RUNGE_KUTTA:
        stages = len(weights)
        k_q, k_qd = np.empty((stages, count)), np.empty((stages, count))
        stage_q, stage_qd = np.empty(count), np.empty(count)
        for step in range(steps):
            now = t + step * h
            for i in range(stages):
                for m in range(count):
                    stage_q[m], stage_qd[m] = q[m], qd[m]
                for j in range(i):
                    if a[i, j] != 0.0:
                        for m in range(count):
                            stage_q[m] += (h * a[i, j]) * k_q[j, m]
                            stage_qd[m] += (h * a[i, j]) * k_qd[j, m]
                _rate(now + nodes[i] * h, stage_q, stage_qd, *args)
                for m in range(count):
                    k_q[i, m], k_qd[i, m] = stage_qd[m], qdd[m]
            evaluations += stages
            for i in range(stages):
                if weights[i] != 0.0:
                    for m in range(count):
                        q[m] += (h * weights[i]) * k_q[i, m]
                        qd[m] += (h * weights[i]) * k_qd[i, m]
    elif form == FORM_SYMPLECTIC_EULER:
        for step in range(steps):
            _rate(t + step * h, q, qd, *args)
            evaluations += 1
            for m in range(count):
                qd[m] += h * qdd[m]
                q[m] += h * qd[m]
    else:
        predicted = np.empty(count)
        _rate(t, q, qd, *args)
        evaluations += 1
        for step in range(steps):
            for m in range(count):
                predicted[m] = qd[m] + h * qdd[m]
                qd[m] += 0.5 * h * qdd[m]
                q[m] += h * qd[m]
            # the closing half kick at the end's rates: predicted from the last q̈, then corrected once (with the
            # prediction alone, a whipping chain's centripetal terms go unstable)
            _rate(t + (step + 1) * h, q, predicted, *args)
            for m in range(count):
                predicted[m] = qd[m] + 0.5 * h * qdd[m]
            _rate(t + (step + 1) * h, q, predicted, *args)
            evaluations += 2
            for m in range(count):
                qd[m] += 0.5 * h * qdd[m]
        if steps > 0:  # dm/dt at the last evaluation: dP/dt = m a, dL/dt = I α + ω × I ω
            for k in range(count):
                body = links[k, 0]
                rigid_motion.world_tensor(rotation[k], inertia[k], block)
                w = vector(omega, k)
                alpha = (acceleration[k, 0], acceleration[k, 1], acceleration[k, 2])
                change = plus(rotate(block, alpha), cross(w, rotate(block, w)))
                for c in range(3):
                    rate[3 * body + c] = mass[k] * acceleration[k, 3 + c]
                    rate[3 * bodies + 3 * body + c] = change[c]
    pose(links, offsets, relative, offset, q, qd, quat, rotation, x, v, omega, pivot, axis, block_work[:2, :4])
    for k in range(count):
        body = links[k, 0]
        rigid_motion.normalise(quat[k])
        rigid_motion.world_tensor(rotation[k], inertia[k], block)
        spin = rotate(block, vector(omega, k))
        for c in range(3):
            position[body, c] = x[k, c]
            momentum[body, c] = mass[k] * v[k, c]
            angular[body, c] = spin[c]
        for c in range(4):
            orientation[body, c] = quat[k, c]
    return evaluations
