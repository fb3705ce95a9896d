"""Joints: holonomic constraints between particles, rigid bodies and the world.

Formulation (the choice issue 22 asks to justify). animbatch integrates maximal coordinates (every body's own
position, orientation and momenta), and a joint is a few scalar constraints on them, ``C_i = 0`` or, for limits and
slack ropes, ``C_i ≥ 0`` (see :mod:`animbatch.sim.joints.kinds` for each kind's rows). Maximal coordinates with
constraint forces take loops (a four-bar linkage, a chain closed on itself) exactly as trees, and leave every
integrator, contact and force term as it is; reduced coordinates (Featherstone) are cheaper for trees and exact
by construction, but cannot close a loop and need a second state layout. So the state stays maximal, and a tree of
hinges and sliders alone is stepped in its joint coordinates by some fixed-step methods
(:mod:`animbatch.sim.joints.tree`).

* **Adaptive methods** integrate the index-1 form: at every right-hand side the multipliers λ solve
  ``J M⁻¹ Jᵀ λ = −(J a_free + J̇u + 2 ω Ċ + ω² C)`` (Baumgarte stabilisation, critically damped at ω), so that
  ``C̈ + 2 ω Ċ + ω² C = 0``: the drift that integration error feeds into C decays in ~1/ω instead of growing.
  ``a_free`` includes the torque-free ``−I⁻¹ (ω × L)`` of spinning bodies.
* **Fixed-step methods** take the same forces in their kicks, and after every step the state is projected back
  onto the constraints: positions and orientations by Gauss–Newton steps ``Δ = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ C`` until |C|
  is below a nanometre-scale tolerance, then velocities by the impulse ``Δu = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ J u``
  (orthogonal in the mass metric). After a one-kick step (symplectic and backward Euler) the position steps are
  SHAKE's instead: along the rows at the step's start, ``Δ = −M⁻¹ J₀ᵀ (J₀ M⁻¹ J₀ᵀ)⁻¹ C`` (chord steps on the
  coupling the kick was solved with), and the momenta change by the same impulse over the step, ``Δp = J₀ᵀ λ / h``:
  the state the step would have reached with that impulse in its kick. Moving the positions alone, the drift's
  centripetal error (about ½ h² ω² r outwards) was taken out of the positions but not of the velocities, which
  kept the speed the kick had given: (h ω)² of the kinetic energy gained at every step, without bound.
* **Unilateral rows** (limits, ropes) take part only while they are reached (C ≤ 0) and only while they push
  (λ ≥ 0): the rows that would pull are dropped and the rest solved again (an active set). Reaching a limit is an
  inelastic stop: fixed-step methods remove the approaching velocity in the projection; adaptive ones stop it
  within the Baumgarte response (overshoot ≈ speed / (e ω)).

Motors (:mod:`animbatch.sim.joints.motors`) are servo torques and forces, applied before the constraints are solved,
so the joint's reaction includes what holds the motor's reaction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from animbatch import quaternion
from animbatch.sim.bodies import Kinematics
from animbatch.sim.joints.kinds import (
    AngleRows,
    AxisRows,
    LockRows,
    PointRows,
    RowKind,
    SegmentRows,
    SlideRows,
    hinge_angle,
)
from animbatch.sim.joints.motors import Motors, MotorTarget
from animbatch.sim.joints.rows import Coupling, JoinedMotion, Rows, accumulate, apply, apply_transpose
from animbatch.sim.motion import KeyframePath

__all__ = ["AngleRows", "AxisRows", "JoinedMotion", "JointLoads", "Joints", "LockRows", "MotorTarget", "Motors",
           "PointRows", "RowKind", "Rows", "SegmentRows", "SlideRows", "hinge_angle"]

#: Baumgarte's stabilisation rate ω [1/s]: constraint drift decays as e^(−ω t) (critically damped).
STABILISATION_RATE = 20.0
#: Position projection stops when every row is within this fraction of the scene's joint scale (m, or rad for
#: angles), or after PROJECTION_ITERATIONS Gauss–Newton steps.
PROJECTION_TOLERANCE = 1e-13
PROJECTION_ITERATIONS = 8
#: A Gauss–Newton step of the projection reuses the last factorisation of ``J M⁻¹ Jᵀ`` (a chord step: the rows
#: barely turn over a step's correction) while the steps cut the violation to at most this fraction; else it
#: factors again at the current positions. Bilateral rows only (a unilateral row's activity may change).
CHORD_CONTRACTION = 0.01
#: A SHAKE step's chord steps (on the coupling at the step's start, whose rows have turned by the step's rotation
#: h ω since: each cuts the violation by about that fraction) go on while each at least halves the violation.
SHAKE_CONTRACTION = 0.5
#: At most this many passes of dropping unilateral rows that would pull.
ACTIVE_SET_PASSES = 4


@dataclass(frozen=True)
class JointLoads:
    """What the joints do at one instant: forces and torques (J, 3) [N, N·m] on the joined bodies (constraints
    and motors together), the rows' multipliers λ (R,) and the motors' efforts (M,)."""

    force: np.ndarray
    torque: np.ndarray
    multipliers: np.ndarray
    efforts: np.ndarray


@dataclass(frozen=True, eq=False)
class Joints:
    """K joints between J joined bodies (model points ``points``, particles below ``first_rigid``), made of row
    kinds; see the module notes.

    ``inverse_mass`` (J,) [1/kg]; ``inertia`` and ``inverse_inertia`` (J, 3, 3) in body axes (zero for particles);
    ``first_body`` (K,) and ``first_offset`` (K, 3): each joint's point on its first body (for reactions);
    ``names``, ``types`` and ``descriptions`` (K,) for messages and ``info``; ``scale`` [m]: the joints' size, for
    tolerances."""

    names: tuple[str, ...]
    types: tuple[str, ...]
    descriptions: tuple[str, ...]
    points: np.ndarray
    first_rigid: int
    inverse_mass: np.ndarray
    inertia: np.ndarray
    inverse_inertia: np.ndarray
    kinds: tuple[RowKind, ...]
    first_body: np.ndarray  # (K,) each joint's first body (index into the joined bodies)
    first_offset: np.ndarray  # (K, 3) the joint's point on it, body axes from its centre of mass
    motors: Motors | None = None
    scale: float = 1.0
    anchor_paths: tuple[KeyframePath, ...] = ()  # anchors on keyframes that joints hold on to (slots after the bodies)
    anchor_starts: np.ndarray | None = None  # (M, 3) [m] where they start
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        bodies = np.concatenate([kind.bodies for kind in self.kinds])
        self._cache.update(
            bodies=bodies, unilateral=np.concatenate([kind.unilateral for kind in self.kinds]),
            joint=np.concatenate([kind.joint for kind in self.kinds]),
            angular=np.concatenate([np.full(len(kind.bodies), kind.unit == "rad") for kind in self.kinds]),
            coupling=Coupling(bodies, len(self.points) + len(self.anchor_paths),
                              bool(np.any(self.points >= self.first_rigid))),
            rigid=np.flatnonzero(self.points >= self.first_rigid))

    @property
    def count(self) -> int:
        return len(self.names)

    @property
    def world(self) -> int:
        """The world's slot in :class:`JoinedMotion`: after the joined bodies and the moving anchors."""
        return len(self.points) + len(self.anchor_paths)

    @property
    def driven(self) -> bool:
        """Whether motors drive some joint (they do work no potential accounts for)."""
        return self.motors is not None

    @property
    def stopping(self) -> bool:
        """Whether some rows are limits or ropes, which stop bodies inelastically (they lose energy)."""
        return bool(self._cache["unilateral"].any())

    @property
    def anchored(self) -> bool:
        """Whether some joint holds on to the world or an anchor (so the joints are not internal to the bodies)."""
        return bool(np.any(self._cache["bodies"] >= len(self.points)))

    @property
    def row_joint(self) -> np.ndarray:
        """The joint (R,) each row belongs to."""
        return self._cache["joint"]

    @property
    def row_is_unilateral(self) -> np.ndarray:
        """Whether each row is a limit or rope (C ≥ 0) rather than an equality (R,)."""
        return self._cache["unilateral"]

    @property
    def row_is_angle(self) -> np.ndarray:
        """Whether each row's C is an angle [rad] rather than a length [m] (R,)."""
        return self._cache["angular"]

    def names_joining(self, point: int) -> tuple[str, ...]:
        """The names of the joints that hold model point ``point`` (to another body or to the world)."""
        bodies = self._cache["bodies"]  # (K, 2) joined-body indices; the anchors and the world come after them
        joined = np.flatnonzero(self.points == point)
        return tuple(name for k, name in enumerate(self.names) if np.isin(bodies[k], joined).any())

    def joined_pairs(self) -> np.ndarray:
        """The pairs of model points (K', 2) that some joint joins to each other (joints to the world left out)."""
        bodies = self._cache["bodies"]
        pairs = bodies[(bodies < len(self.points)).all(axis=1)]
        return np.unique(np.sort(self.points[pairs], axis=1), axis=0).reshape(-1, 2)

    def segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rods', ropes' and pulley ropes' straight pieces, for drawing: near and far model points (S,) (−1:
        a fixed point), and their offsets (S, 3) (body axes from the centre of mass; a fixed point's position)."""
        kinds = [kind for kind in self.kinds if isinstance(kind, SegmentRows)]
        if not kinds:
            return np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 3)), np.zeros((0, 3))
        near, far, near_offset, far_offset = kinds[0].lines()
        # compact body index → model point (−1 for the moving anchors and the world, which are fixed points to draw)
        model_point = np.concatenate([self.points, np.full(len(self.anchor_paths) + 1, -1)])
        far_offset = far_offset.copy()
        on_anchor = (far >= len(self.points)) & (far < self.world)
        if on_anchor.any():  # a moving anchor's point, where it starts (drawing finds the anchor by it)
            assert self.anchor_starts is not None
            far_offset[on_anchor] += self.anchor_starts[far[on_anchor] - len(self.points)]
        return model_point[near], model_point[far], near_offset, far_offset

    # ------------------------------------------------------------------------------------------ state

    def _anchors_at(self, x: np.ndarray, v: np.ndarray, t: float) -> None:
        """The moving anchors' slots of ``x`` and ``v`` at time ``t`` [s], in place."""
        first = len(self.points)
        for m, path in enumerate(self.anchor_paths):
            x[first + m], v[first + m] = path.position(t), path.velocity(t)

    def motion(self, state: Kinematics) -> JoinedMotion:
        """The joined bodies' :class:`JoinedMotion` from the model's kinematics."""
        count = len(self.points)
        slots = self.world + 1
        x = np.zeros((slots, 3))
        v = np.zeros((slots, 3))
        x[:count], v[:count] = state.x[self.points], state.v[self.points]
        self._anchors_at(x, v, state.t)
        rotation = np.broadcast_to(np.eye(3), (slots, 3, 3)).copy()
        omega = np.zeros((slots, 3))
        rigid = self._cache["rigid"]
        if len(rigid):
            assert state.rotation is not None and state.omega is not None
            index = self.points[rigid] - self.first_rigid
            rotation[rigid], omega[rigid] = state.rotation[index], state.omega[index]
        return self._motion(x, v, rotation, omega)

    def _motion(self, x: np.ndarray, v: np.ndarray, rotation: np.ndarray, omega: np.ndarray) -> JoinedMotion:
        count, slots = len(self.points), len(x)
        inverse_mass = np.zeros(slots)
        inverse_mass[:count] = self.inverse_mass
        inverse_inertia = np.zeros((slots, 3, 3))
        spin = np.zeros((slots, 3))
        rigid = self._cache["rigid"]
        if len(rigid):
            turn = rotation[rigid]
            turn_t = np.transpose(turn, (0, 2, 1))
            inverse_inertia[rigid] = turn @ self.inverse_inertia[rigid] @ turn_t
            momentum = np.einsum("kij,kj->ki", turn @ self.inertia[rigid] @ turn_t, omega[rigid])
            spin[rigid] = -np.einsum("kij,kj->ki", inverse_inertia[rigid], quaternion.cross(omega[rigid], momentum))
        return JoinedMotion(x, v, rotation, omega, inverse_mass, inverse_inertia, spin, bool(len(rigid)))

    def rows(self, motion: JoinedMotion) -> Rows:
        return Rows.concatenate([kind.rows(motion) for kind in self.kinds])

    def _held_rows(self, motion: JoinedMotion) -> Rows:
        """The rows at ``motion``'s positions for the velocity-level uses (projecting velocities, the contact
        solver's Jacobian), which read only their Jacobian and violation, both functions of the positions alone:
        kept for the last positions, since a contact step asks three times at the same ones. Their bias, which the
        velocities set, is left out (NaN), so that a use that needs it cannot take a stale one."""
        key = (motion.x.tobytes(), motion.rotation.tobytes())
        last = self._cache.get("held_rows")
        if last is not None and last[0] == key:
            return last[1]
        rows = self.rows(motion)
        held = Rows(rows.violation, rows.linear, rows.angular, np.full_like(rows.bias, np.nan))
        self._cache["held_rows"] = (key, held)
        return held

    def violation(self, motion: JoinedMotion) -> np.ndarray:
        """How far each row is from holding (R,) [m or rad], ≥ 0: |C| for bilateral rows, how far past its limit
        for unilateral ones (a slack rope, a hinge inside its limits: 0)."""
        c = self.rows(motion).violation
        return np.where(self._cache["unilateral"], np.maximum(-c, 0.0), np.abs(c))

    # ------------------------------------------------------------------------------------------ forces

    def _solve_active(self, rows: Rows, motion: JoinedMotion, right: np.ndarray, reached: np.ndarray) -> np.ndarray:
        """λ for ``A λ = right`` over the bilateral rows and the unilateral rows ``reached``, dropping unilateral
        rows whose λ would pull (λ < 0) and solving again."""
        unilateral = self._cache["unilateral"]
        active = ~unilateral | reached
        coupling: Coupling = self._cache["coupling"]
        for _ in range(ACTIVE_SET_PASSES):
            multiplier = coupling.solve(rows, motion, right, active if unilateral.any() else None)
            pulling = unilateral & active & (multiplier < 0)
            if not pulling.any():
                break
            active = active & ~pulling
        else:
            multiplier = np.where(unilateral & (multiplier < 0), 0.0, multiplier)
        return multiplier

    def loads(self, state: Kinematics, force: np.ndarray, torque: np.ndarray | None,
              engaged: np.ndarray | None = None, stabilisation: float = STABILISATION_RATE) -> JointLoads:
        """The joints' forces and torques on the joined bodies, given the other forces ``force`` (P, 3) and torques
        ``torque`` (B, 3) on all bodies, with Baumgarte stabilisation (see the module notes). ``engaged`` (R,):
        which unilateral rows act, as events decided (:mod:`animbatch.sim.joints.stops`); by default those at or
        past their stops that push. ``stabilisation``: Baumgarte's ω [1/s] (0 where a projection after every step
        keeps the joints instead, which the correction would only fight: a rope would bounce off its stop)."""
        motion = self.motion(state)
        count = len(self.points)
        applied_force = np.zeros((self.world + 1, 3))
        applied_torque = np.zeros((self.world + 1, 3))
        applied_force[:count] = force[self.points]
        rigid = self._cache["rigid"]
        if len(rigid) and torque is not None:
            applied_torque[rigid] = torque[self.points[rigid] - self.first_rigid]
        efforts = np.zeros(0)
        motor_force = motor_torque = None
        if self.motors is not None:
            motor_force, motor_torque, efforts = self.motors.loads(state.t, motion)
            applied_force += motor_force
            applied_torque += motor_torque
        bodies = self._cache["bodies"]
        rows = self.rows(motion)
        acceleration = applied_force * motion.inverse_mass[:, None]
        for m, path in enumerate(self.anchor_paths):  # an anchor's prescribed acceleration enters C̈ as it stands
            acceleration[count + m] = path.acceleration(state.t)
        angular_acceleration = np.einsum("kij,kj->ki", motion.inverse_inertia, applied_torque) + motion.spin
        rate = apply(rows, bodies, (motion.v, motion.omega))
        omega = stabilisation
        right = -(apply(rows, bodies, (acceleration, angular_acceleration)) + rows.bias + 2 * omega * rate
                  + omega**2 * rows.violation)
        if engaged is None:
            multiplier = self._solve_active(rows, motion, right, rows.violation <= 0)
        else:
            unilateral = self._cache["unilateral"]
            multiplier = self._cache["coupling"].solve(rows, motion, right,
                                                       (~unilateral | engaged) if unilateral.any() else None)
        joint_force, joint_torque = apply_transpose(rows, bodies, multiplier, self.world + 1)
        if motor_force is not None and motor_torque is not None:
            joint_force += motor_force
            joint_torque += motor_torque
        return JointLoads(joint_force[:count], joint_torque[:count], multiplier, efforts)

    def add_loads(self, state: Kinematics, force: np.ndarray, torque: np.ndarray | None,
                  engaged: np.ndarray | None = None, stabilisation: float = STABILISATION_RATE) -> JointLoads:
        """:meth:`loads`, added to ``force`` and ``torque`` in place."""
        loads = self.loads(state, force, torque, engaged, stabilisation)
        force[self.points] += loads.force
        rigid = self._cache["rigid"]
        if len(rigid) and torque is not None:
            torque[self.points[rigid] - self.first_rigid] += loads.torque[rigid]
        return loads

    def reactions(self, loads: JointLoads, motion: JoinedMotion) -> tuple[np.ndarray, np.ndarray]:
        """The force [N] and torque [N·m] (K, 3) each joint's constraint exerts on its first body, the torque about
        the joint's point on that body (a weld's bending moment), from the multipliers of ``loads`` at
        ``motion``."""
        rows = self.rows(motion)
        joint = self.row_joint
        force = accumulate(joint, loads.multipliers[:, None] * rows.linear[:, 0], self.count)
        torque = accumulate(joint, loads.multipliers[:, None] * rows.angular[:, 0], self.count)
        lever = motion.points(self.first_body, self.first_offset)[0]
        return force, torque - quaternion.cross(lever, force)

    # ------------------------------------------------------------------------------------------ projection

    def project_velocities(self, state: Kinematics, v: np.ndarray, omega: np.ndarray | None) -> None:
        """Take out of velocities ``v`` (P, 3) [m/s] and ``omega`` (B, 3) [rad/s] (world axes, in place) what breaks
        the joints at ``state``'s positions, by the impulse that does it in the mass metric (velocity rows only:
        the positions are taken as on the joints). For solving joints and contacts together within a step."""
        count = len(self.points)
        rigid = self._cache["rigid"]
        bodies = self._cache["bodies"]
        moving = Kinematics(state.x, v, state.rotation, omega, state.first_rigid, state.t)
        motion = self.motion(moving)
        rows = self._held_rows(motion)
        rate = apply(rows, bodies, (motion.v, motion.omega))
        reached = rows.violation <= PROJECTION_TOLERANCE * max(self.scale, 1.0)
        impulse = self._solve_active(rows, motion, -rate, reached & (rate < 0))
        force, torque = apply_transpose(rows, bodies, impulse, self.world + 1)
        v[self.points] += force[:count] * motion.inverse_mass[:count, None]
        if len(rigid):
            assert omega is not None
            omega[self.points[rigid] - self.first_rigid] += np.einsum("kij,kj->ki", motion.inverse_inertia[rigid],
                                                                      torque[rigid])

    def velocity_rows(self, state: Kinematics, size: int, *, dense: bool = False) -> sp.csr_matrix | np.ndarray:
        """The rows that hold at ``state`` (the bilateral ones, and unilateral ones at their stops) as a sparse
        Jacobian (R, 6 size) over a flat velocity ``V = [v.ravel(), ω.ravel()]`` of ``size`` bodies numbered as in
        the model (anchors and the world do not move in it): ``J V`` is each row's rate. For the contact solver,
        which solves contacts within the joints' constraints with it. ``dense``: as an array (a ragdoll's few
        dozen columns: a scipy.sparse construction costs more than the whole array)."""
        return self.held_matrix(self._held_rows(self.motion(state)), size, dense=dense)

    def held_matrix(self, rows: Rows, size: int, *, dense: bool = False) -> sp.csr_matrix | np.ndarray:
        """:meth:`velocity_rows` from the rows at the state's positions (their violation and Jacobian: the bias is
        not read)."""
        holding = ~self._cache["unilateral"] | (rows.violation <= PROJECTION_TOLERANCE * max(self.scale, 1.0))
        bodies = self._cache["bodies"][holding]
        count = len(self.points)
        real = bodies < count  # ends on joined bodies (not on an anchor or the world)
        body = self.points[np.where(real, bodies, 0)]
        row = np.broadcast_to(np.arange(len(bodies))[:, None, None], (*bodies.shape, 3))
        linear_columns = 3 * body[:, :, None] + np.arange(3)
        angular_columns = 3 * (size + body[:, :, None]) + np.arange(3)
        turning = real & (body >= self.first_rigid)
        keep_linear = np.broadcast_to(real[:, :, None], row.shape)
        keep_angular = np.broadcast_to(turning[:, :, None], row.shape)
        data = np.concatenate([rows.linear[holding][keep_linear], rows.angular[holding][keep_angular]])
        indices = np.concatenate([linear_columns[keep_linear], angular_columns[keep_angular]])
        where = np.concatenate([row[keep_linear], row[keep_angular]])
        if dense:  # summing repeated entries, as the sparse form does
            flat = np.bincount(where * (6 * size) + indices, weights=data, minlength=len(bodies) * 6 * size)
            return flat.reshape(len(bodies), 6 * size)
        return sp.csr_matrix((data, (where, indices)), shape=(len(bodies), 6 * size))

    def project(self, positions: np.ndarray, orientations: np.ndarray | None, linear: np.ndarray,
                angular_momentum: np.ndarray | None, *, reach: float = 0.0, t: float = 0.0,
                start: tuple[np.ndarray, np.ndarray | None] | None = None, step: float = 0.0) -> None:
        """Move a state back onto the joints, in place (see the module notes): ``positions`` (P, 3) [m] of all
        bodies, rigid ``orientations`` (B, 4), ``linear`` (P, 3): particles' velocities [m/s] then rigid momenta
        [kg·m/s], rigid ``angular_momentum`` (B, 3) [kg·m²/s], world axes. Unilateral rows within ``reach`` [m or
        rad] of their stops count as reached (their approaching velocity is removed). ``t`` [s]: the state's time
        (where moving anchors are).

        ``start`` (the positions (P, 3) and orientations (B, 4) at the start of a one-kick step of ``step`` [s]:
        symplectic or backward Euler) makes the position correction a SHAKE step: it moves the bodies along the
        rows' directions at the step's start, and the same impulse (divided by ``step``) changes the momenta, so
        the state is the one the step's drift would have reached with that impulse in its kick. Without it the
        positions move and the velocities stay, which gains kinetic energy at every step on a turning joint (about
        (h ω)² of it), so that a pendulum's energy grew without bound. Unilateral rows (limits, ropes) at their
        stops are then taken by the plain projection, whose stop is inelastic anyway."""
        count = len(self.points)
        rigid = self._cache["rigid"]
        index = self.points[rigid] - self.first_rigid
        bodies = self._cache["bodies"]
        coupling: Coupling = self._cache["coupling"]
        unilateral = self._cache["unilateral"]
        mass_of_linear = np.ones(count)  # linear = mass_of_linear · v
        mass_of_linear[rigid] = 1.0 / self.inverse_mass[rigid]

        slots = self.world + 1

        def joined(places: np.ndarray, turns: np.ndarray | None, at: float) -> JoinedMotion:
            x = np.zeros((slots, 3))
            v = np.zeros((slots, 3))
            x[:count] = places[self.points]
            v[:count] = linear[self.points] / mass_of_linear[:, None]
            self._anchors_at(x, v, at)
            rotation = np.broadcast_to(np.eye(3), (slots, 3, 3)).copy()
            omega = np.zeros((slots, 3))
            if len(rigid):
                assert turns is not None and angular_momentum is not None
                rotation[rigid] = quaternion.to_matrix(turns[index])
                turn = rotation[rigid]
                inverse = turn @ self.inverse_inertia[rigid] @ np.transpose(turn, (0, 2, 1))
                omega[rigid] = np.einsum("kij,kj->ki", inverse, angular_momentum[index])
            return self._motion(x, v, rotation, omega)

        def current() -> JoinedMotion:
            return joined(positions, orientations, t)

        def move(rows: Rows, motion: JoinedMotion, multipliers: np.ndarray, impulse_time: float) -> None:
            """Move the bodies by ``M⁻¹ Jᵀ λ`` (the rows' Jacobian and the masses of ``motion``), and with an
            ``impulse_time`` > 0 change the momenta by ``Jᵀ λ / impulse_time``."""
            force, torque = apply_transpose(rows, bodies, multipliers, slots)
            positions[self.points] += force[:count] * motion.inverse_mass[:count, None]
            if impulse_time > 0:
                linear[self.points] += force[:count] * (mass_of_linear * motion.inverse_mass[:count])[:, None] \
                    / impulse_time
            if len(rigid):
                assert orientations is not None
                turn = np.einsum("kij,kj->ki", motion.inverse_inertia[rigid], torque[rigid])
                orientations[index] = quaternion.normalized(
                    quaternion.multiply(quaternion.from_rotation_vector(turn), orientations[index]))
                if impulse_time > 0:
                    assert angular_momentum is not None
                    angular_momentum[index] += torque[rigid] / impulse_time

        tolerance = PROJECTION_TOLERANCE * max(self.scale, 1.0)
        settled = None  # the motion and rows at the final positions, once they hold (the velocities are unchanged)
        if start is not None and step > 0:
            # SHAKE: chord steps on the coupling at the step's start (the matrix its kick's forces were solved
            # with), each moving positions and momenta together, over the bilateral rows; the plain steps below
            # take limits and ropes at their stops, and finish if these stall
            bilateral = ~unilateral
            begun = joined(start[0], start[1], t - step)
            begun_rows = self.rows(begun)
            begun_factored = coupling.factored(begun_rows, begun, bilateral if unilateral.any() else None)
            previous = np.inf
            for _ in range(PROJECTION_ITERATIONS):
                motion = current()
                rows = self.rows(motion)
                largest = np.max(np.abs(np.where(bilateral, rows.violation, 0.0)), initial=0.0)
                if largest <= tolerance:
                    if not unilateral.any():
                        settled = motion, rows
                    break
                if largest > SHAKE_CONTRACTION * previous:
                    break  # not contracting: the plain projection takes over from here
                previous = largest
                move(begun_rows, begun, begun_factored.solve(-rows.violation), step)
        factored, previous = None, np.inf  # the last factorisation, and the violation it was last used at
        # unilateral rows moved back to their stops stay held there until the projection ends: released as soon as
        # a step overshoots into the free side (by the step's second-order error, up to microradians), they would
        # end off their stops by more than the tolerance, so neither the velocity part below nor the next step's
        # contact solve would count them as reached, and a limb at its limit would be pushed past it every step
        held = np.zeros(len(unilateral), bool)
        for _ in range(PROJECTION_ITERATIONS if settled is None else 0):
            motion = current()
            rows = self.rows(motion)
            violated = ~unilateral | (rows.violation < 0) | held
            largest = np.max(np.abs(np.where(violated, rows.violation, 0.0)), initial=0.0)
            if largest <= tolerance:
                settled = motion, rows
                break
            held |= violated & unilateral
            if factored is None or unilateral.any() or largest > CHORD_CONTRACTION * previous:
                factored = coupling.factored(rows, motion, violated if unilateral.any() else None)
            previous = largest
            move(rows, motion, factored.solve(-rows.violation), 0.0)
        if settled is not None:
            motion, rows = settled
        else:
            motion = current()
            rows = self.rows(motion)
        rate = apply(rows, bodies, (motion.v, motion.omega))
        reached = rows.violation <= max(tolerance, reach)
        # bilateral rows lose all their rate; reached unilateral rows only an approaching one (an inelastic stop)
        impulse = self._solve_active(rows, motion, -rate, reached & (rate < 0))
        force, torque = apply_transpose(rows, bodies, impulse, slots)
        linear[self.points] += force[:count] * (mass_of_linear * motion.inverse_mass[:count])[:, None]
        if len(rigid):
            assert angular_momentum is not None
            angular_momentum[index] += torque[rigid]
