"""Hinge trees in joint coordinates: chains and branching linkages of rigid bodies on hinges, stepped by their angles.

A chain of bars on hinges has one degree of freedom per hinge. Maximal coordinates (:mod:`animbatch.sim.joints`)
carry six per bar and hold the other five with constraint forces, a projection after every fixed step and two
factorisations of the coupling per step. When the joints form a tree of hinges hanging from the world (no loop, no
limit, no motor, nothing else touching the bodies), a fixed step can instead advance the hinge angles q and rates q̇
directly, as MuJoCo and Featherstone's articulated-body algorithm do: the joints then hold exactly by construction,
and a step costs O(bodies) arithmetic.

The state stays the maximal one outside a call. A call of :func:`advance` takes the poses it is given as q = 0
(each body's orientation relative to its parent as it stands, :class:`TreeStart`), reads q̇ from the bodies'
angular velocities, takes its steps in (q, q̇), and writes the bodies' positions, orientations and momenta back from
q and q̇ (forward kinematics: every body hangs from its parent's pivot).

**The articulated-body algorithm** (Featherstone, *Rigid Body Dynamics Algorithms*, ch. 7), in frames at each
body's centre of mass with world axes, spatial vectors ``(angular; linear)``. Body k's accelerations ``A = (α, a)``
(angular, centre of mass) follow its parent's:

    A_k = X_k A_p + S_k q̈_k + c_k,    X_k = [[1, 0], [−[r]×, 1]],  r = x_k − x_p
    S_k = (n; n × d),  d = x_k − pivot,  n the hinge's world axis
    c_k = (ω_p × n q̇;  ω_p × (ω_p × (pivot − x_p)) + (ω_p × n q̇) × d + ω_k × (ω_k × d))

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
class HingeTree:
    """K rigid bodies on K hinges, each hanging from its parent (or the world), parents listed before children.

    ``body`` (K,): each body's rigid index; ``parent`` (K,): its parent's position in this order, −1 for the world;
    ``child_offset`` (K, 3) [m]: the hinge's point in the body's axes, from its centre of mass; ``parent_offset``
    (K, 3) [m]: the same point in the parent's axes (from its centre of mass), or in the world for the world;
    ``axis`` (K, 3): the hinge's unit axis in the body's axes; ``mass`` (K,) [kg] and ``inertia`` (K, 3, 3)
    [kg·m²] in body axes."""

    body: np.ndarray
    parent: np.ndarray
    child_offset: np.ndarray
    parent_offset: np.ndarray
    axis: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray

    @property
    def count(self) -> int:
        return len(self.body)


def hinge_tree(joints: Any, mass: np.ndarray, inertia: np.ndarray, rigid_count: int,
               particle_count: int) -> HingeTree | str:
    """The hinge tree of a model's ``joints`` (:class:`~animbatch.sim.joints.Joints`), its rigid bodies' ``mass``
    (B,) and body-axes ``inertia`` (B, 3, 3); or why its joints are not one (then they stay in maximal
    coordinates)."""
    from animbatch.sim.joints.kinds import AxisRows, PointRows

    if particle_count:
        return "it has particles"
    if joints.motors is not None or joints.anchor_paths:
        return "its joints have motors or moving anchors"
    kinds = {type(kind): kind for kind in joints.kinds}
    if set(kinds) != {PointRows, AxisRows} or len(joints.kinds) != 2:
        return "its joints are not all hinges without limits"
    points, axes = kinds[PointRows], kinds[AxisRows]
    if not np.array_equal(points.joint[::3], axes.joint[::2]) or len(points.joint) // 3 != joints.count:
        return "its joints are not all hinges without limits"
    if np.any(joints.points < joints.first_rigid) or len(joints.points) != rigid_count:
        return "not every body hangs on a hinge"
    world = joints.world
    pairs = points.bodies[::3]
    # the tree from the world out: every body reached once, by one hinge (K hinges, K bodies, no loop)
    order: list[int] = []
    parent_of: dict[int, tuple[int, int]] = {}  # body → (parent body or world, its hinge)
    frontier = [world]
    used = np.zeros(len(pairs), bool)
    while frontier:
        here = frontier.pop(0)
        for link in np.flatnonzero(~used & ((pairs[:, 0] == here) | (pairs[:, 1] == here))):
            other = int(pairs[link, 1] if pairs[link, 0] == here else pairs[link, 0])
            used[link] = True
            if other == world or other in parent_of:
                return "its hinges close a loop"
            parent_of[other] = (here, int(link))
            order.append(other)
            frontier.append(other)
    if len(order) != len(joints.points) or not used.all():
        return "not every body hangs from the world by hinges"
    position = {body: k for k, body in enumerate(order)}
    count = len(order)
    child_offset, parent_offset, axis = np.empty((count, 3)), np.empty((count, 3)), np.empty((count, 3))
    parent = np.empty(count, np.int64)
    for k, body in enumerate(order):
        above, hinge = parent_of[body]
        parent[k] = position.get(above, -1)
        first = pairs[hinge, 0] == body  # the body is the hinge's first end (its axis is kept in the second's)
        ends = (points.first_offset[hinge], points.second_offset[hinge])
        child_offset[k], parent_offset[k] = ends if first else ends[::-1]
        if first:  # the two directions across the axis that the first body carries span the plane normal to it
            across = axes.across[hinge]
            normal = np.cross(across[0], across[1])
            axis[k] = normal / np.linalg.norm(normal)
        else:
            axis[k] = axes.axis[hinge] / np.linalg.norm(axes.axis[hinge])
    rigid = joints.points[np.array(order)] - joints.first_rigid
    return HingeTree(rigid, parent, child_offset, parent_offset, axis, mass[rigid], inertia[rigid])


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


def relative_orientations(tree: HingeTree, quat: np.ndarray) -> np.ndarray:
    """Each body's orientation relative to its parent's (K, 4), ``q̄_parent ⊗ q_body``, from orientations (K, 4)
    in the tree's order: the pose that :func:`pose` takes as q = 0."""
    parents = np.where(tree.parent[:, None] >= 0, quat[tree.parent], quaternion.IDENTITY)
    conjugate = parents * np.array([1.0, -1.0, -1.0, -1.0])
    return quaternion.multiply(conjugate, quat)


def pose(tree: HingeTree, relative: np.ndarray, q: np.ndarray, qd: np.ndarray) -> TreePose:
    """The bodies' poses and velocities at hinge angles q (K,) [rad] from the ``relative`` orientations and rates
    q̇ (K,) [rad/s]: each body turned by q about its axis, hung from its parent's pivot."""
    count = tree.count
    result = TreePose(x=np.zeros((count, 3)), v=np.zeros((count, 3)), omega=np.zeros((count, 3)),
                      quat=np.zeros((count, 4)), rotation=np.zeros((count, 3, 3)), pivot=np.zeros((count, 3)),
                      axis=np.zeros((count, 3)))
    for k in range(count):
        p = tree.parent[k]
        turn = np.concatenate([[np.cos(q[k] / 2)], np.sin(q[k] / 2) * tree.axis[k]])
        base = result.quat[p] if p >= 0 else quaternion.IDENTITY
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


def accelerations(tree: HingeTree, at: TreePose, qd: np.ndarray, force: np.ndarray,
                  torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """q̈ (K,) [rad/s²] under applied ``force`` and ``torque`` (K, 3) (world axes, at the centres of mass, in the
    tree's order), and each body's acceleration (K, 6): (α [rad/s²]; centre of mass [m/s²]). See the module notes."""
    count = tree.count
    motion_axis, bias = np.zeros((count, 6)), np.zeros((count, 6))
    inertia, bias_force = np.zeros((count, 6, 6)), np.zeros((count, 6))
    for k in range(count):
        p, n, w = tree.parent[k], at.axis[k], at.omega[k]
        d = at.x[k] - at.pivot[k]
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


def _loads(tree: HingeTree, forces: Forces, t: float, at: TreePose,
           bodies: int) -> tuple[np.ndarray, np.ndarray]:
    """The applied forces and torques (K, 3) at a pose, in the tree's order."""
    x, v, omega = np.zeros((bodies, 3)), np.zeros((bodies, 3)), np.zeros((bodies, 3))
    rotation = np.broadcast_to(np.eye(3), (bodies, 3, 3)).copy()
    x[tree.body], v[tree.body], omega[tree.body], rotation[tree.body] = at.x, at.v, at.omega, at.rotation
    force, torque = forces(t, x, v, rotation, omega)
    return force[tree.body], torque[tree.body]


def advance(tree: HingeTree, form: tuple[str, Any], y: np.ndarray, t: float, h: float, steps: int,
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
    world_inverse = rotation @ np.linalg.inv(tree.inertia) @ np.transpose(rotation, (0, 2, 1))
    omega = np.einsum("kij,kj->ki", world_inverse, angular[tree.body])
    relative = relative_orientations(tree, quaternion.normalized(orientation[tree.body]))
    parent_omega = np.where(tree.parent[:, None] >= 0, omega[tree.parent], 0.0)
    q = np.zeros(count)
    qd = np.einsum("ki,ki->k", np.einsum("kij,kj->ki", rotation, tree.axis), omega - parent_omega)

    def rate(now: float, angles: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, TreePose, np.ndarray]:
        at = pose(tree, relative, angles, rates)
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
            qdd, *last = rate(t + (step + 1) * h, q, qd + 0.5 * h * qdd)  # type: ignore[assignment]
            evaluations += 2
            qd = qd + 0.5 * h * qdd
    final = pose(tree, relative, q, qd)
    position[tree.body], orientation[tree.body] = final.x, quaternion.normalized(final.quat)
    momentum[tree.body] = tree.mass[:, None] * final.v
    inertia_world = final.rotation @ tree.inertia @ np.transpose(final.rotation, (0, 2, 1))
    angular[tree.body] = np.einsum("kij,kj->ki", inertia_world, final.omega)
    if name == "verlet" and last is not None:
        _motion_rate(tree, *last, data, bodies)
    return evaluations


def _motion_rate(tree: HingeTree, at: TreePose, acceleration: np.ndarray, out: np.ndarray, bodies: int) -> None:
    """dm/dt (the motion's size) of bodies with accelerations (K, 6) at a pose: dP/dt = m a and
    dL/dt = I α + ω × I ω."""
    inertia_world = at.rotation @ tree.inertia @ np.transpose(at.rotation, (0, 2, 1))
    spin = np.einsum("kij,kj->ki", inertia_world, at.omega)
    out[: 3 * bodies].reshape(bodies, 3)[tree.body] = tree.mass[:, None] * acceleration[:, 3:]
    out[3 * bodies:].reshape(bodies, 3)[tree.body] = (np.einsum("kij,kj->ki", inertia_world, acceleration[:, :3])
                                                      + cross(at.omega, spin))
