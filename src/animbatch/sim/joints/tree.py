"""Joint trees in joint coordinates: chains and branching linkages of rigid bodies on hinges and sliders, stepped
by their joint positions (angles and travels).

A chain of bars on hinges has one degree of freedom per hinge. Maximal coordinates (:mod:`animbatch.sim.joints`)
carry six per bar and hold the other five with constraint forces, a projection after every fixed step and two
factorisations of the coupling per step. When the joints form a tree of hinges and sliders hanging from the world
(no loop, no limit, no motor, nothing else touching the bodies), a fixed step can instead advance the joint
positions q and rates q̇ directly, as MuJoCo and Featherstone's articulated-body algorithm do: the joints then hold
exactly by construction, and a step costs O(bodies) arithmetic.

The state stays the maximal one outside a call. A call of :func:`advance` takes the poses it is given as q = 0
(each body's orientation relative to its parent as it stands, and its centre from its parent's:
:func:`start_of`), reads q̇ from the bodies' velocities, takes its steps in (q, q̇), and writes the bodies'
positions, orientations and momenta back from q and q̇ (forward kinematics: a body on a hinge hangs from its
parent's pivot, turned about the axis; a body on a slider keeps its start's orientation and offset from its parent,
moved along the axis).

**The articulated-body algorithm** (Featherstone, *Rigid Body Dynamics Algorithms*, ch. 7), in frames at each
body's centre of mass with world axes, spatial vectors ``(angular; linear)``. Body k's accelerations ``A = (α, a)``
(angular, centre of mass) follow its parent's:

    A_k = X_k A_p + S_k q̈_k + c_k,    X_k = [[1, 0], [−[r]×, 1]],  r = x_k − x_p
    hinge:   S_k = (n; n × d),  d = x_k − pivot,  n the hinge's world axis
             c_k = (ω_p × n q̇;  ω_p × (ω_p × (pivot − x_p)) + (ω_p × n q̇) × d + ω_k × (ω_k × d))
    slider:  S_k = (0; n),  c_k = (0;  ω_p × (ω_p × r) + 2 q̇ ω_p × n)

and its Newton–Euler equations are ``f = M A + (ω × I ω − τ; −F)`` with ``M = diag(I_world, m 1)``, F and τ the
applied force and torque. The three passes: velocities and biases from the root out; articulated inertias
``I^A`` and bias forces ``p^A`` from the leaves in (``U = I^A S``, ``D = Sᵀ U``, ``u = −Sᵀ p^A``;
``I^A_p += Xᵀ (I^A − U Uᵀ/D) X``, ``p^A_p += Xᵀ (p^A + I^a c + U u/D)``); accelerations from the root out
(``q̈ = (u − Uᵀ (X A_p + c))/D``).

**Which methods.** Runge–Kutta tableaux and velocity Verlet step trees this way. Semi-implicit Euler does not: in
maximal coordinates its SHAKE projection keeps a whipping 20-bar chain's energy within ±0.13 J over 5 s at 1 ms,
where Euler on the angles (MuJoCo's) drifts by ±30–70 J. Verlet on the angles closes each step with q̈ at the end's
rates, corrected once: with the rates only predicted from the last q̈ (one evaluation, as in maximal coordinates)
the same chain goes unstable within 3 s; corrected, its energy stays within ±3.5 J against ±4.9 J for maximal
Verlet with its projection, at 1 ms.

This module is the numpy reference, written for reading; :mod:`animbatch.sim.kernels.joint_tree` is the compiled
form, compared with it to round-off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch import quaternion
from animbatch.quaternion import cross

#: ``forces(t, x, v, rotation, omega) -> (force, torque)``: the applied forces (B, 3) [N] and torques (B, 3) [N·m]
#: on the rigid bodies at positions x, velocities v (B, 3), rotations (B, 3, 3) and angular velocities ω (B, 3).
Forces = Callable[[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True, eq=False)
class JointTree:
    """K rigid bodies on K joints (hinges and sliders), each hanging from its parent (or the world), parents listed
    before children.

    ``body`` (K,): each body's rigid index; ``parent`` (K,): its parent's position in this order, −1 for the world;
    ``slider`` (K,): whether its joint is a slider (else a hinge); ``child_offset`` (K, 3) [m]: a hinge's point in
    the body's axes, from its centre of mass; ``parent_offset`` (K, 3) [m]: the same point in the parent's axes
    (from its centre of mass), or in the world for the world (both unused for sliders, which keep the offset they
    start a call at); ``axis`` (K, 3): the joint's unit axis in the body's axes; ``mass`` (K,) [kg] and ``inertia``
    (K, 3, 3) [kg·m²] in body axes, and its inverse ``inverse_inertia``."""

    body: np.ndarray
    parent: np.ndarray
    slider: np.ndarray
    child_offset: np.ndarray
    parent_offset: np.ndarray
    axis: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    inverse_inertia: np.ndarray

    @property
    def count(self) -> int:
        return len(self.body)


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def joint_tree(joints: Any, mass: np.ndarray, inertia: np.ndarray, inverse_inertia: np.ndarray, rigid_count: int,
               particle_count: int) -> JointTree | str:
    """The joint tree of a model's ``joints`` (:class:`~animbatch.sim.joints.Joints`), its rigid bodies' ``mass``
    (B,), body-axes ``inertia`` (B, 3, 3) and its inverse; or why its joints are not one (then they stay in maximal
    coordinates)."""
    from animbatch.sim.joints.kinds import AxisRows, LockRows, PointRows, SlideRows

    if particle_count:
        return "it has particles"
    if joints.motors is not None or joints.anchor_paths:
        return "its joints have motors or moving anchors"
    kinds = {type(kind): kind for kind in joints.kinds}
    plain = "its joints are not all hinges and sliders without limits"
    if not set(kinds) <= {PointRows, AxisRows, LockRows, SlideRows} or len(kinds) != len(joints.kinds):
        return plain
    # each joint's rows, by kind: a hinge is 3 point rows and 2 axis rows; a slider 3 lock rows and 2 slide rows
    # across its axis (a limit adds unilateral slide rows, a weld is point and lock rows)
    rows = np.zeros((joints.count, 4), np.int64)
    for column, kind in enumerate((PointRows, AxisRows, LockRows, SlideRows)):
        if kind in kinds:
            np.add.at(rows[:, column], kinds[kind].joint, 1)
    hinge = np.all(rows == (3, 2, 0, 0), axis=1)
    slider = np.all(rows == (0, 0, 3, 2), axis=1)
    if not np.all(hinge | slider):
        return plain
    if np.any(joints.points < joints.first_rigid) or len(joints.points) != rigid_count:
        return "not every body hangs on a joint"
    # each joint's two ends and where its data is: its first row of its kind
    pairs = np.empty((joints.count, 2), np.int64)
    first_row = np.empty(joints.count, np.int64)
    for kind, step, chosen in ((PointRows, 3, hinge), (LockRows, 3, slider)):
        if kind in kinds:
            number = kinds[kind].joint[::step]
            pairs[number] = kinds[kind].bodies[::step]
            first_row[number] = np.arange(len(number))
    world = joints.world
    # the tree from the world out: every body reached once, by one joint (K joints, K bodies, no loop)
    order: list[int] = []
    parent_of: dict[int, tuple[int, int]] = {}  # body → (parent body or world, its joint)
    frontier = [world]
    used = np.zeros(len(pairs), bool)
    while frontier:
        here = frontier.pop(0)
        for link in np.flatnonzero(~used & ((pairs[:, 0] == here) | (pairs[:, 1] == here))):
            other = int(pairs[link, 1] if pairs[link, 0] == here else pairs[link, 0])
            used[link] = True
            if other == world or other in parent_of:
                return "its joints close a loop"
            parent_of[other] = (here, int(link))
            order.append(other)
            frontier.append(other)
    if len(order) != len(joints.points) or not used.all():
        return "not every body hangs from the world by its joints"
    position = {body: k for k, body in enumerate(order)}
    count = len(order)
    child_offset, parent_offset, axis = np.zeros((count, 3)), np.zeros((count, 3)), np.empty((count, 3))
    parent = np.empty(count, np.int64)
    for k, body in enumerate(order):
        above, joint = parent_of[body]
        parent[k] = position.get(above, -1)
        first = pairs[joint, 0] == body  # the body is the joint's first end (its axis is kept in the second's)
        row = first_row[joint]
        if hinge[joint]:
            points, axes = kinds[PointRows], kinds[AxisRows]
            ends = (points.first_offset[row], points.second_offset[row])
            child_offset[k], parent_offset[k] = ends if first else ends[::-1]
            # the first body carries two directions across the axis, which span the plane normal to it
            axis[k] = _unit(np.cross(*axes.across[row])) if first else _unit(axes.axis[row])
        else:  # a slider's two directions across its axis are kept in the second body, R_second = R_first Q
            across = kinds[SlideRows].direction[kinds[SlideRows].joint == joint]
            along = _unit(np.cross(across[0], across[1]))
            axis[k] = kinds[LockRows].relative[row] @ along if first else along
    rigid = joints.points[np.array(order)] - joints.first_rigid
    return JointTree(rigid, parent, slider[np.array([parent_of[b][1] for b in order])], child_offset, parent_offset,
                     axis, mass[rigid], inertia[rigid], inverse_inertia[rigid])


@dataclass
class TreePose:
    """Forward kinematics of a tree at (q, q̇), world axes, in the tree's order: centres of mass ``x``, velocities
    ``v``, angular velocities ``omega`` (K, 3); orientations ``quat`` (K, 4) and ``rotation`` (K, 3, 3); each
    hinge's ``pivot`` (K, 3) and world ``axis`` (K, 3)."""

    x: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    quat: np.ndarray
    rotation: np.ndarray
    pivot: np.ndarray
    axis: np.ndarray


def start_of(tree: JointTree, quat: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pose that :func:`pose` takes as q = 0, from orientations (K, 4) and centres of mass (K, 3) in the tree's
    order: each body's orientation relative to its parent's (K, 4), ``q̄_parent ⊗ q_body``, and its centre of mass
    in its parent's axes from the parent's (K, 3) (in the world for the world; sliders keep it, moved along their
    axis)."""
    parents = np.where(tree.parent[:, None] >= 0, quat[tree.parent], quaternion.IDENTITY)
    conjugate = parents * np.array([1.0, -1.0, -1.0, -1.0])
    offset = x - np.where(tree.parent[:, None] >= 0, x[tree.parent], 0.0)
    offset = np.einsum("kji,kj->ki", quaternion.to_matrix(parents), offset)
    return quaternion.multiply(conjugate, quat), offset


def pose(tree: JointTree, start: tuple[np.ndarray, np.ndarray], q: np.ndarray, qd: np.ndarray) -> TreePose:
    """The bodies' poses and velocities at joint positions q (K,) [rad or m] and rates q̇ (K,) from the ``start``
    of :func:`start_of`: each body on a hinge turned by q about its axis and hung from its parent's pivot, each on a
    slider moved by q along its axis."""
    relative, offset = start
    count = tree.count
    result = TreePose(x=np.zeros((count, 3)), v=np.zeros((count, 3)), omega=np.zeros((count, 3)),
                      quat=np.zeros((count, 4)), rotation=np.zeros((count, 3, 3)), pivot=np.zeros((count, 3)),
                      axis=np.zeros((count, 3)))
    for k in range(count):
        p = tree.parent[k]
        base = result.quat[p] if p >= 0 else quaternion.IDENTITY
        if tree.slider[k]:  # the orientation as it started, the centre moved along the axis
            result.quat[k] = quaternion.multiply(base, relative[k])
            result.rotation[k] = quaternion.to_matrix(result.quat[k])
            n = result.axis[k] = result.rotation[k] @ tree.axis[k]
            if p >= 0:
                result.pivot[k] = result.x[p]
                result.x[k] = result.x[p] + result.rotation[p] @ offset[k] + q[k] * n
                result.omega[k] = result.omega[p]
                result.v[k] = result.v[p] + cross(result.omega[p], result.x[k] - result.x[p]) + qd[k] * n
            else:
                result.x[k], result.v[k] = offset[k] + q[k] * n, qd[k] * n
            continue
        turn = np.concatenate([[np.cos(q[k] / 2)], np.sin(q[k] / 2) * tree.axis[k]])
        result.quat[k] = quaternion.multiply(quaternion.multiply(base, relative[k]), turn)
        result.rotation[k] = quaternion.to_matrix(result.quat[k])
        if p >= 0:
            pivot = result.x[p] + result.rotation[p] @ tree.parent_offset[k]
            pivot_velocity = result.v[p] + cross(result.omega[p], pivot - result.x[p])
            parent_omega = result.omega[p]
        else:
            pivot, pivot_velocity, parent_omega = tree.parent_offset[k], np.zeros(3), np.zeros(3)
        result.pivot[k] = pivot
        result.x[k] = pivot - result.rotation[k] @ tree.child_offset[k]
        result.axis[k] = result.rotation[k] @ tree.axis[k]
        result.omega[k] = parent_omega + result.axis[k] * qd[k]
        result.v[k] = pivot_velocity + cross(result.omega[k], result.x[k] - pivot)
    return result


def _transform(r: np.ndarray) -> np.ndarray:
    """X (6, 6) taking a parent's spatial motion at its centre of mass to a child's at ``r`` from it."""
    x = np.eye(6)
    x[3:, :3] = -np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return x


def accelerations(tree: JointTree, at: TreePose, qd: np.ndarray, force: np.ndarray,
                  torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """q̈ (K,) [rad/s²] under applied ``force`` and ``torque`` (K, 3) (world axes, at the centres of mass, in the
    tree's order), and each body's acceleration (K, 6): (α [rad/s²]; centre of mass [m/s²]). See the module notes."""
    count = tree.count
    motion_axis, bias = np.zeros((count, 6)), np.zeros((count, 6))
    inertia, bias_force = np.zeros((count, 6, 6)), np.zeros((count, 6))
    for k in range(count):
        p, n, w = tree.parent[k], at.axis[k], at.omega[k]
        d = at.x[k] - at.pivot[k]
        if tree.slider[k]:  # S = (0; n); c = (0; ω_p × (ω_p × r) + 2 q̇ ω_p × n), r from the parent's centre
            motion_axis[k, 3:] = n
            if p >= 0:
                wp = at.omega[p]
                bias[k, 3:] = cross(wp, cross(wp, at.x[k] - at.x[p])) + 2 * qd[k] * cross(wp, n)
        else:
            motion_axis[k] = np.concatenate([n, cross(n, d)])
            centripetal = cross(w, cross(w, d))
            if p >= 0:
                wp = at.omega[p]
                turning = cross(wp, n) * qd[k]
                bias[k] = np.concatenate([turning, cross(wp, cross(wp, at.pivot[k] - at.x[p])) + cross(turning, d)
                                          + centripetal])
            else:
                bias[k, 3:] = centripetal
        rotational = at.rotation[k] @ tree.inertia[k] @ at.rotation[k].T
        inertia[k, :3, :3], inertia[k, 3:, 3:] = rotational, tree.mass[k] * np.eye(3)
        bias_force[k] = np.concatenate([cross(w, rotational @ w) - torque[k], -force[k]])
    u, d_, across = np.zeros(count), np.zeros(count), np.zeros((count, 6))
    for k in range(count - 1, -1, -1):
        across[k] = inertia[k] @ motion_axis[k]
        d_[k] = motion_axis[k] @ across[k]
        u[k] = -motion_axis[k] @ bias_force[k]
        p = tree.parent[k]
        if p >= 0:
            articulated = inertia[k] - np.outer(across[k], across[k]) / d_[k]
            passed = bias_force[k] + articulated @ bias[k] + across[k] * u[k] / d_[k]
            x = _transform(at.x[k] - at.x[p])
            inertia[p] += x.T @ articulated @ x
            bias_force[p] += x.T @ passed
    qdd, acceleration = np.zeros(count), np.zeros((count, 6))
    for k in range(count):
        p = tree.parent[k]
        carried = (_transform(at.x[k] - at.x[p]) @ acceleration[p] if p >= 0 else 0.0) + bias[k]
        qdd[k] = (u[k] - across[k] @ carried) / d_[k]
        acceleration[k] = carried + motion_axis[k] * qdd[k]
    return qdd, acceleration


def _loads(tree: JointTree, forces: Forces, t: float, at: TreePose,
           bodies: int) -> tuple[np.ndarray, np.ndarray]:
    """The applied forces and torques (K, 3) at a pose, in the tree's order."""
    x, v, omega = np.zeros((bodies, 3)), np.zeros((bodies, 3)), np.zeros((bodies, 3))
    rotation = np.broadcast_to(np.eye(3), (bodies, 3, 3)).copy()
    x[tree.body], v[tree.body], omega[tree.body], rotation[tree.body] = at.x, at.v, at.omega, at.rotation
    force, torque = forces(t, x, v, rotation, omega)
    return force[tree.body], torque[tree.body]


def advance(tree: JointTree, form: tuple[str, Any], y: np.ndarray, t: float, h: float, steps: int,
            forces: Forces) -> int:
    """``steps`` fixed steps of ``h`` [s] from time ``t`` [s] of a state ``y`` (n,) of rigid bodies only, in
    joint coordinates, in place; returns the right-hand sides evaluated. ``form`` as
    :meth:`~animbatch.sim.integrators.fixed_step.Scheme.compiled_form`: an explicit Runge–Kutta tableau on
    (q, q̇), semi-implicit Euler (kick q̇, drift q) or velocity Verlet (half kick, drift, and the closing half kick
    with q̈ at the end's rates: predicted as q̇ + h q̈, corrected once, two evaluations); Verlet's ``rate`` (the
    motion's size) is left at the last evaluation's dm/dt (its q̈ is taken anew at each call's start)."""
    bodies = len(y) // 13
    position, orientation = y[: 3 * bodies].reshape(bodies, 3), y[3 * bodies: 7 * bodies].reshape(bodies, 4)
    momentum, angular = y[7 * bodies: 10 * bodies].reshape(bodies, 3), y[10 * bodies:].reshape(bodies, 3)
    count = tree.count
    rotation = quaternion.to_matrix(orientation[tree.body])
    world_inverse = rotation @ tree.inverse_inertia @ np.transpose(rotation, (0, 2, 1))
    omega = np.einsum("kij,kj->ki", world_inverse, angular[tree.body])
    x, v = position[tree.body], momentum[tree.body] / tree.mass[:, None]
    start = start_of(tree, quaternion.normalized(orientation[tree.body]), x)
    # q̇: a hinge's from the angular velocities, a slider's from the velocity relative to its parent's frame
    above = tree.parent[:, None] >= 0
    parent_omega = np.where(above, omega[tree.parent], 0.0)
    carried = np.where(above, v[tree.parent] + cross(parent_omega, x - x[tree.parent]), 0.0)
    axis = np.einsum("kij,kj->ki", rotation, tree.axis)
    q = np.zeros(count)
    qd = np.einsum("ki,ki->k", axis, np.where(tree.slider[:, None], v - carried, omega - parent_omega))

    def rate(now: float, angles: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, TreePose, np.ndarray]:
        at = pose(tree, start, angles, rates)
        qdd, acceleration = accelerations(tree, at, rates, *_loads(tree, forces, now, at, bodies))
        return qdd, at, acceleration

    name, data = form
    evaluations = 0
    last: tuple[TreePose, np.ndarray] | None = None
    if name == "runge_kutta":
        a, weights, nodes = data
        for step in range(steps):
            now = t + step * h
            k_q, k_qd = np.zeros((len(weights), count)), np.zeros((len(weights), count))
            for i in range(len(weights)):
                stage_q, stage_qd = q + h * (a[i, :i] @ k_q[:i]), qd + h * (a[i, :i] @ k_qd[:i])
                k_q[i] = stage_qd
                k_qd[i] = rate(now + nodes[i] * h, stage_q, stage_qd)[0]
            evaluations += len(weights)
            q, qd = q + h * (weights @ k_q), qd + h * (weights @ k_qd)
    elif name == "symplectic_euler":
        for step in range(steps):
            qdd, *_ = rate(t + step * h, q, qd)
            evaluations += 1
            qd = qd + h * qdd
            q = q + h * qd
    else:
        qdd, *_ = rate(t, q, qd)
        evaluations += 1
        for step in range(steps):
            predicted = qd + h * qdd
            qd = qd + 0.5 * h * qdd
            q = q + h * qd
            # the closing half kick at the end's rates: predicted from the last q̈, then corrected once (with the
            # prediction alone, a whipping chain's centripetal terms go unstable)
            qdd, *_ = rate(t + (step + 1) * h, q, predicted)
            qdd, *last = rate(t + (step + 1) * h, q, qd + 0.5 * h * qdd)  # type: ignore[assignment]  # (q̈, rest)
            evaluations += 2
            qd = qd + 0.5 * h * qdd
    final = pose(tree, start, q, qd)
    position[tree.body], orientation[tree.body] = final.x, quaternion.normalized(final.quat)
    momentum[tree.body] = tree.mass[:, None] * final.v
    inertia_world = final.rotation @ tree.inertia @ np.transpose(final.rotation, (0, 2, 1))
    angular[tree.body] = np.einsum("kij,kj->ki", inertia_world, final.omega)
    if name == "verlet" and last is not None:
        _motion_rate(tree, *last, data, bodies)
    return evaluations


def _motion_rate(tree: JointTree, at: TreePose, acceleration: np.ndarray, out: np.ndarray, bodies: int) -> None:
    """dm/dt (the motion's size) of bodies with accelerations (K, 6) at a pose: dP/dt = m a and
    dL/dt = I α + ω × I ω."""
    inertia_world = at.rotation @ tree.inertia @ np.transpose(at.rotation, (0, 2, 1))
    spin = np.einsum("kij,kj->ki", inertia_world, at.omega)
    out[: 3 * bodies].reshape(bodies, 3)[tree.body] = tree.mass[:, None] * acceleration[:, 3:]
    out[3 * bodies:].reshape(bodies, 3)[tree.body] = (np.einsum("kij,kj->ki", inertia_world, acceleration[:, :3])
                                                      + cross(at.omega, spin))
