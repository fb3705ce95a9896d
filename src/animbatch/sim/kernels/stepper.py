"""The compiled equations of motion of bodies and joints, and the fixed-step methods stepped in one call.

These are :class:`animbatch.sim.model.dynamics.Dynamics` (``rhs``, ``motion_rate``, ``project``; ``drift`` is
:func:`animbatch.sim.kernels.rigid_motion.drift`) and :class:`animbatch.sim.joints.Joints` (``loads``: the
constraint forces with Baumgarte stabilisation, and ``project``: the SHAKE/RATTLE-style projection after a fixed
step) on the packed tables of :mod:`animbatch.sim.kernels.tables`, built on
:mod:`~animbatch.sim.kernels.rigid_motion` (bodies and forces), :mod:`~animbatch.sim.kernels.joint_rows` (rows)
and :mod:`~animbatch.sim.kernels.sparse_ldl` (the coupling solve). :func:`advance` takes a whole run of fixed steps
(a frame's) in one call: an explicit Runge–Kutta method from its tableau, semi-implicit Euler or velocity Verlet,
each as its scheme in :mod:`animbatch.sim.integrators.fixed_step` takes it, so that one compiled stepper serves
every explicit method.

The numpy code is the reference: the same formulas in the same order, compared to round-off by
``tests/sim/test_compiled_dynamics.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from animbatch.sim.kernels import joint_rows, rigid_motion, sparse_ldl
from animbatch.sim.kernels import tables as T
from animbatch.sim.kernels.rigid_motion import column, rows_of, table

#: The fixed-step forms :func:`advance` knows.
FORM_RUNGE_KUTTA, FORM_SYMPLECTIC_EULER, FORM_VERLET = 0, 1, 2
#: As :mod:`animbatch.sim.joints`: Gauss–Newton steps of the position projection, its tolerance (times the joints'
#: scale), and the passes of dropping unilateral rows that pull.
PROJECTION_ITERATIONS = 8
PROJECTION_TOLERANCE = 1e-13
ACTIVE_SET_PASSES = 4
CHORD_CONTRACTION = 0.01
SHAKE_CONTRACTION = 0.5


@njit(cache=True, error_model="numpy")
def factor_cache_size(layout: np.ndarray) -> int:
    """The length of the factor cache (:func:`_solve`) of a model's joints."""
    rows = rows_of(layout, T.ROW_BODIES)
    return 1 + 12 * rows_of(layout, T.SLOT_RIGID) + rows + rows_of(layout, T.COLUMN_ROWS) + rows


@njit(cache=True, error_model="numpy")
def _solve(integers: np.ndarray, layout: np.ndarray, cache: np.ndarray, sx: np.ndarray, srotation: np.ndarray,
           row_bodies: np.ndarray, jac: np.ndarray, inverse_mass: np.ndarray, inverse_inertia: np.ndarray,
           active: np.ndarray, right: np.ndarray, out: np.ndarray) -> None:
    """λ (R,) with ``(J M⁻¹ Jᵀ) λ = right`` for rows with Jacobian ``jac`` (R, 2, 6) on slots of ``inverse_mass``
    (S,) and world ``inverse_inertia`` (S, 3, 3); rows not ``active`` held at zero.

    ``cache`` (:func:`factor_cache_size`) keeps the last factorisation with what it was made from: the slots'
    positions ``sx`` (S, 3) and rotations ``srotation`` (S, 3, 3), which the Jacobian and the inertias follow from,
    and the active rows. A step solves at the same positions twice (Verlet's rate at the drifted positions, then the
    projection's first Gauss–Newton step; a projection's velocity solve, then the next kick), and an equal matrix is
    not factored again. The comparison is exact, so results are the same bit for bit."""
    count, slots = len(right), len(inverse_inertia)
    values, diagonal = _factors(layout, cache, count, slots)
    if not _same_key(cache, sx, srotation, active):
        sparse_ldl.assemble(integers, layout, jac, row_bodies, inverse_mass, inverse_inertia, active, values,
                            diagonal)
        sparse_ldl.factor(integers, layout, values, diagonal)
        cache[0] = 1.0
    masked = np.empty(count)
    for r in range(count):
        masked[r] = right[r] if active[r] else 0.0
    sparse_ldl.solve(integers, layout, values, diagonal, masked, out)


@njit(cache=True, error_model="numpy")
def _same_key(cache: np.ndarray, sx: np.ndarray, srotation: np.ndarray, active: np.ndarray) -> bool:
    """Whether the factorisation ``cache`` (:func:`_solve`) holds was made from these slot positions (S, 3),
    rotations (S, 3, 3) and active rows (R,); if not, they become its key. Compared until the first difference (a
    step's new positions differ in the first number), written only when they differ."""
    slots, count = len(sx), len(active)
    key = cache[1: 1 + 12 * slots + count]
    positions, rotations = sx.reshape(-1), srotation.reshape(-1)
    same = cache[0] == 1.0
    if same:
        for k in range(3 * slots):
            if key[k] != positions[k]:
                same = False
                break
    if same:
        for k in range(9 * slots):
            if key[3 * slots + k] != rotations[k]:
                same = False
                break
    if same:
        for r in range(count):
            if key[12 * slots + r] != (1.0 if active[r] else 0.0):
                same = False
                break
    if not same:
        key[: 3 * slots] = positions
        key[3 * slots: 12 * slots] = rotations
        for r in range(count):
            key[12 * slots + r] = 1.0 if active[r] else 0.0
    return same


@njit(cache=True, error_model="numpy")
def _factors(layout: np.ndarray, cache: np.ndarray, count: int, slots: int) -> tuple[np.ndarray, np.ndarray]:
    """The factor L (its values) and D (``count``,) that ``cache`` (:func:`_solve`) holds, as views."""
    start = 1 + 12 * slots + count
    entries = rows_of(layout, T.COLUMN_ROWS)
    return cache[start: start + entries], cache[start + entries: start + entries + count]


@njit(cache=True, error_model="numpy")
def _solve_factored(integers: np.ndarray, layout: np.ndarray, cache: np.ndarray, slots: int, right: np.ndarray,
                    out: np.ndarray) -> None:
    """λ (R,) with the factorisation ``cache`` holds, whatever rows it was made at (a chord step)."""
    values, diagonal = _factors(layout, cache, len(right), slots)
    sparse_ldl.solve(integers, layout, values, diagonal, right, out)


@njit(cache=True, error_model="numpy")
def _solve_active(integers: np.ndarray, layout: np.ndarray, cache: np.ndarray, sx: np.ndarray,
                  srotation: np.ndarray, row_bodies: np.ndarray, jac: np.ndarray, inverse_mass: np.ndarray,
                  inverse_inertia: np.ndarray, right: np.ndarray, reached: np.ndarray, out: np.ndarray) -> None:
    """λ over the bilateral rows and the unilateral rows ``reached``, dropping unilateral rows whose λ would pull
    and solving again (``Joints._solve_active``)."""
    unilateral = column(integers, layout, T.ROW_UNILATERAL)
    count = len(right)
    active = np.empty(count, np.bool_)
    for r in range(count):
        active[r] = unilateral[r] == 0 or reached[r]
    for _ in range(ACTIVE_SET_PASSES):
        _solve(integers, layout, cache, sx, srotation, row_bodies, jac, inverse_mass, inverse_inertia, active, right,
               out)
        pulling = False
        for r in range(count):
            if unilateral[r] != 0 and active[r] and out[r] < 0:
                active[r] = False
                pulling = True
        if not pulling:
            return
    for r in range(count):
        if unilateral[r] != 0 and out[r] < 0:
            out[r] = 0.0


@njit(cache=True, error_model="numpy")
def add_joint_loads(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray,
                    x: np.ndarray,
                    v: np.ndarray, rotation: np.ndarray, omega: np.ndarray, force: np.ndarray, torque: np.ndarray,
                    engaged: np.ndarray, use_engaged: bool, stabilisation: float) -> None:
    """Add the joints' forces and torques to ``force`` (P, 3) and ``torque`` (B, 3), given the other loads there
    and the bodies' kinematics: ``J M⁻¹ Jᵀ λ = −(J a_free + J̇u + 2 ω Ċ + ω² C)`` with Baumgarte's ω =
    ``stabilisation`` [1/s], over the rows ``engaged`` (R,) when ``use_engaged``, else the active set of those at or
    past their stops that push (``Joints.loads``). Motors act besides."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    slot_path = column(integers, layout, T.SLOT_PATH)
    inverse_mass = column(floats, layout, T.SLOT_INVERSE_MASS)
    row_bodies = table(integers, layout, T.ROW_BODIES, 2)
    unilateral = column(integers, layout, T.ROW_UNILATERAL)
    slots, rows, count = len(slot_rigid), len(row_bodies), len(points)
    sx, sv, somega = np.empty((slots, 3)), np.empty((slots, 3)), np.empty((slots, 3))
    sspin, sacceleration = np.empty((slots, 3)), np.empty((slots, 3))
    srotation, sinverse_inertia = np.empty((slots, 3, 3)), np.empty((slots, 3, 3))
    joint_rows.slot_motion(t, floats, integers, layout, x, v, rotation, omega, sx, sv, srotation, somega,
                           sinverse_inertia, sspin, sacceleration)
    applied_force, applied_torque = np.zeros((slots, 3)), np.zeros((slots, 3))
    for s in range(count):
        rigid_motion.store(applied_force, s, rigid_motion.vector(force, points[s]))
        if slot_rigid[s] >= 0:
            rigid_motion.store(applied_torque, s, rigid_motion.vector(torque, slot_rigid[s]))
    motor_force, motor_torque = np.zeros((slots, 3)), np.zeros((slots, 3))
    motors = rows_of(layout, T.MOTOR_BODIES)
    if motors:
        joint_rows.motor_loads(t, floats, integers, layout, sx, sv, srotation, somega, motor_force, motor_torque,
                               np.empty(motors))
        for s in range(slots):
            for c in range(3):
                applied_force[s, c] += motor_force[s, c]
                applied_torque[s, c] += motor_torque[s, c]
    violation, bias = np.empty(rows), np.empty(rows)
    jac = np.empty((rows, 2, 6))
    joint_rows.rows(floats, integers, layout, sx, sv, srotation, somega, violation, jac, bias)
    acceleration, angular_acceleration = np.empty((slots, 3)), np.empty((slots, 3))
    for s in range(slots):
        for c in range(3):
            acceleration[s, c] = applied_force[s, c] * inverse_mass[s]
        if slot_path[s] >= 0:  # an anchor's prescribed acceleration enters C̈ as it stands
            rigid_motion.store(acceleration, s, rigid_motion.vector(sacceleration, s))
        turn = rigid_motion.rotate(sinverse_inertia[s], rigid_motion.vector(applied_torque, s))
        rigid_motion.store(angular_acceleration, s, rigid_motion.plus(turn, rigid_motion.vector(sspin, s)))
    rate, pushed, right = np.empty(rows), np.empty(rows), np.empty(rows)
    joint_rows.apply(row_bodies, jac, sv, somega, rate)
    joint_rows.apply(row_bodies, jac, acceleration, angular_acceleration, pushed)
    w = stabilisation
    for r in range(rows):
        right[r] = -(pushed[r] + bias[r] + 2 * w * rate[r] + w**2 * violation[r])
    multipliers = np.empty(rows)
    active = np.empty(rows, np.bool_)
    if use_engaged:
        for r in range(rows):
            active[r] = unilateral[r] == 0 or engaged[r]
        _solve(integers, layout, cache, sx, srotation, row_bodies, jac, inverse_mass, sinverse_inertia, active, right,
               multipliers)
    else:
        for r in range(rows):
            active[r] = violation[r] <= 0
        _solve_active(integers, layout, cache, sx, srotation, row_bodies, jac, inverse_mass, sinverse_inertia, right,
                      active,
                      multipliers)
    joint_force, joint_torque = np.empty((slots, 3)), np.empty((slots, 3))
    joint_rows.apply_transpose(row_bodies, jac, multipliers, joint_force, joint_torque)
    for s in range(count):
        for c in range(3):
            force[points[s], c] += joint_force[s, c] + motor_force[s, c]
        if slot_rigid[s] >= 0:
            for c in range(3):
                torque[slot_rigid[s], c] += joint_torque[s, c] + motor_torque[s, c]


@njit(cache=True, error_model="numpy")
def _loads(t: float, config: np.ndarray, motion: np.ndarray, floats: np.ndarray, integers: np.ndarray,
           layout: np.ndarray, cache: np.ndarray, engaged: np.ndarray, use_engaged: bool, stabilisation: float,
           v: np.ndarray, omega: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """The kinematics (the points' velocities ``v`` (P, 3) and the rigid bodies' ω (B, 3)) and the total loads
    ``force`` (P, 3) [N] and ``torque`` (B, 3) [N·m] at a state, joints included."""
    points, b = len(v), len(omega)
    x, rotation = np.empty((points, 3)), np.empty((b, 3, 3))
    rigid_motion.kinematics(config, motion, floats, layout, x, v, rotation, omega)
    rigid_motion.add_forces(t, floats, integers, layout, x, v, rotation, omega, force, torque)
    if rows_of(layout, T.ROW_BODIES):
        add_joint_loads(t, floats, integers, layout, cache, x, v, rotation, omega, force, torque, engaged, use_engaged,
                        stabilisation)


@njit(cache=True, error_model="numpy")
def motion_rate(t: float, config: np.ndarray, motion: np.ndarray, floats: np.ndarray, integers: np.ndarray,
                layout: np.ndarray, cache: np.ndarray, engaged: np.ndarray, use_engaged: bool, stabilisation: float,
                out: np.ndarray) -> None:
    """``dm/dt`` (the motion's size) into ``out``: ``F / m`` for particles, F and τ for rigid bodies, with the
    joints' forces."""
    points, b = len(motion) // 3 - rows_of(layout, T.RIGID_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    v, omega = np.empty((points, 3)), np.empty((b, 3))
    force, torque = np.empty((points, 3)), np.empty((b, 3))
    _loads(t, config, motion, floats, integers, layout, cache, engaged, use_engaged, stabilisation, v, omega, force,
           torque)
    rigid_motion.motion_rate_from(force, torque, floats, layout, out)


@njit(cache=True, error_model="numpy")
def rhs(t: float, y: np.ndarray, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray,
        config_size: int,
        engaged: np.ndarray, use_engaged: bool, stabilisation: float, out: np.ndarray) -> None:
    """``dy/dt`` (n,) into ``out``."""
    config, motion = y[:config_size], y[config_size:]
    b = rows_of(layout, T.RIGID_INVERSE_MASS)
    points = len(motion) // 3 - b
    v, omega = np.empty((points, 3)), np.empty((b, 3))
    force, torque = np.empty((points, 3)), np.empty((b, 3))
    _loads(t, config, motion, floats, integers, layout, cache, engaged, use_engaged, stabilisation, v, omega, force,
           torque)
    rigid_motion.config_rate(config, motion, layout, v, omega, out[:config_size])
    rigid_motion.motion_rate_from(force, torque, floats, layout, out[config_size:])


@njit(cache=True, error_model="numpy")
def _projection_motion(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, positions: np.ndarray,
                       orientations: np.ndarray, linear: np.ndarray, angular_momentum: np.ndarray,
                       mass_of_linear: np.ndarray, t: float, sx: np.ndarray, sv: np.ndarray, srotation: np.ndarray,
                       somega: np.ndarray, sinverse_inertia: np.ndarray) -> None:
    """The slots' motion at a state being projected (``current()`` of ``Joints.project``)."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_path = column(integers, layout, T.SLOT_PATH)
    sx[:] = 0.0
    sv[:] = 0.0
    somega[:] = 0.0
    sinverse_inertia[:] = 0.0
    for s in range(len(srotation)):
        for i in range(3):
            for j in range(3):
                srotation[s, i, j] = 1.0 if i == j else 0.0
    for s in range(len(points)):
        for c in range(3):
            sx[s, c] = positions[points[s], c]
            sv[s, c] = linear[points[s], c] / mass_of_linear[s]
    for s in range(len(slot_path)):
        if slot_path[s] >= 0:
            position, velocity, _ = rigid_motion.path_at(floats, integers, layout, slot_path[s], t)
            rigid_motion.store(sx, s, position)
            rigid_motion.store(sv, s, velocity)
    joint_rows.rigid_slot_state(floats, integers, layout, orientations, angular_momentum, srotation, somega,
                                sinverse_inertia)


@njit(cache=True, error_model="numpy")
def _move(integers: np.ndarray, layout: np.ndarray, inverse_mass: np.ndarray, row_bodies: np.ndarray,
          jac: np.ndarray, sinverse_inertia: np.ndarray, multipliers: np.ndarray, mass_of_linear: np.ndarray,
          impulse_time: float, positions: np.ndarray, orientations: np.ndarray, linear: np.ndarray,
          angular_momentum: np.ndarray, joint_force: np.ndarray, joint_torque: np.ndarray) -> None:
    """Move the bodies by ``M⁻¹ Jᵀ λ`` (rows ``jac``, slots' world ``sinverse_inertia``), and with an
    ``impulse_time`` [s] > 0 change the momenta by ``Jᵀ λ / impulse_time`` (``move`` of ``Joints.project``)."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    joint_rows.apply_transpose(row_bodies, jac, multipliers, joint_force, joint_torque)
    for s in range(len(points)):
        for c in range(3):
            positions[points[s], c] += joint_force[s, c] * inverse_mass[s]
        if impulse_time > 0:
            scale = mass_of_linear[s] * inverse_mass[s]
            for c in range(3):
                linear[points[s], c] += joint_force[s, c] * scale / impulse_time
        k = slot_rigid[s]
        if k >= 0:
            q = orientations[k]
            rigid_motion.turn_quaternion(q, rigid_motion.rotate(sinverse_inertia[s],
                                                                rigid_motion.vector(joint_torque, s)))
            rigid_motion.normalise(q)
            if impulse_time > 0:
                for c in range(3):
                    angular_momentum[k, c] += joint_torque[s, c] / impulse_time


@njit(cache=True, error_model="numpy")
def project_joints(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray,
                   positions: np.ndarray,
                   orientations: np.ndarray, linear: np.ndarray, angular_momentum: np.ndarray, reach: float,
                   t: float, start_positions: np.ndarray, start_orientations: np.ndarray, step: float) -> None:
    """Move a state back onto the joints, in place (``Joints.project``): ``positions`` (P, 3) [m], ``orientations``
    (B, 4), ``linear`` (P, 3) (particles' velocities, then rigid momenta), ``angular_momentum`` (B, 3); first the
    positions by Gauss–Newton steps ``Δ = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ C``, then the velocities by the impulse that takes
    out ``J u`` (unilateral rows within ``reach`` [m or rad] of their stops lose only an approaching rate). With a
    ``step`` [s] > 0, the positions (P, 3) and orientations (B, 4) at the start of that one-kick step make the
    position correction a SHAKE step first: chord steps along the rows at the start, the momenta changed by the
    same impulse over the step."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    inverse_mass = column(floats, layout, T.SLOT_INVERSE_MASS)
    row_bodies = table(integers, layout, T.ROW_BODIES, 2)
    unilateral = column(integers, layout, T.ROW_UNILATERAL)
    slots, rows, count = len(slot_rigid), len(row_bodies), len(points)
    any_unilateral = False
    for r in range(rows):
        any_unilateral = any_unilateral or unilateral[r] != 0
    mass_of_linear = np.ones(count)
    for s in range(count):
        if slot_rigid[s] >= 0:
            mass_of_linear[s] = 1.0 / inverse_mass[s]
    tolerance = PROJECTION_TOLERANCE * max(column(floats, layout, T.JOINT_SCALE)[0], 1.0)
    sx, sv, somega = np.empty((slots, 3)), np.empty((slots, 3)), np.empty((slots, 3))
    srotation, sinverse_inertia = np.empty((slots, 3, 3)), np.empty((slots, 3, 3))
    violation, bias = np.empty(rows), np.empty(rows)
    jac = np.empty((rows, 2, 6))
    joint_force, joint_torque = np.empty((slots, 3)), np.empty((slots, 3))
    active = np.ones(rows, np.bool_)
    right, multipliers = np.empty(rows), np.empty(rows)
    settled = False
    if step > 0:  # SHAKE over the bilateral rows; the plain steps below take limits and ropes at their stops
        for r in range(rows):
            active[r] = unilateral[r] == 0
        bsx, bsv, bsomega = np.empty((slots, 3)), np.empty((slots, 3)), np.empty((slots, 3))
        bsrotation, bsinverse_inertia = np.empty((slots, 3, 3)), np.empty((slots, 3, 3))
        bviolation, bbias, bjac = np.empty(rows), np.empty(rows), np.empty((rows, 2, 6))
        _projection_motion(floats, integers, layout, start_positions, start_orientations, linear, angular_momentum,
                           mass_of_linear, t - step, bsx, bsv, bsrotation, bsomega, bsinverse_inertia)
        joint_rows.rows(floats, integers, layout, bsx, bsv, bsrotation, bsomega, bviolation, bjac, bbias)
        previous = np.inf
        for _ in range(PROJECTION_ITERATIONS):
            _projection_motion(floats, integers, layout, positions, orientations, linear, angular_momentum,
                               mass_of_linear, t, sx, sv, srotation, somega, sinverse_inertia)
            joint_rows.rows(floats, integers, layout, sx, sv, srotation, somega, violation, jac, bias)
            largest = 0.0
            for r in range(rows):
                if active[r]:
                    largest = max(largest, abs(violation[r]))
                right[r] = -violation[r]
            if largest <= tolerance:
                settled = not any_unilateral
                break
            if largest > SHAKE_CONTRACTION * previous:
                break
            previous = largest
            _solve(integers, layout, cache, bsx, bsrotation, row_bodies, bjac, inverse_mass, bsinverse_inertia,
                   active, right, multipliers)
            _move(integers, layout, inverse_mass, row_bodies, bjac, bsinverse_inertia, multipliers, mass_of_linear,
                  step, positions, orientations, linear, angular_momentum, joint_force, joint_torque)
    factored, previous = False, np.inf  # a factorisation made here, and the violation it was last used at
    held = np.zeros(rows, np.bool_)  # unilateral rows moved to their stops: held there (``Joints.project``)
    for _ in range(0 if settled else PROJECTION_ITERATIONS):
        _projection_motion(floats, integers, layout, positions, orientations, linear, angular_momentum,
                           mass_of_linear, t, sx, sv, srotation, somega, sinverse_inertia)
        joint_rows.rows(floats, integers, layout, sx, sv, srotation, somega, violation, jac, bias)
        largest = 0.0
        for r in range(rows):
            active[r] = unilateral[r] == 0 or violation[r] < 0 or held[r]
            if active[r]:
                largest = max(largest, abs(violation[r]))
            right[r] = -violation[r]
        if largest <= tolerance:
            settled = True
            break
        for r in range(rows):
            held[r] = held[r] or (unilateral[r] != 0 and active[r])
        if not any_unilateral:
            active[:] = True
        if not factored or any_unilateral or largest > CHORD_CONTRACTION * previous:
            _solve(integers, layout, cache, sx, srotation, row_bodies, jac, inverse_mass, sinverse_inertia, active,
                   right, multipliers)
            factored = True
        else:
            _solve_factored(integers, layout, cache, slots, right, multipliers)
        previous = largest
        _move(integers, layout, inverse_mass, row_bodies, jac, sinverse_inertia, multipliers, mass_of_linear, 0.0,
              positions, orientations, linear, angular_momentum, joint_force, joint_torque)
    if not settled:
        _projection_motion(floats, integers, layout, positions, orientations, linear, angular_momentum,
                           mass_of_linear, t, sx, sv, srotation, somega, sinverse_inertia)
        joint_rows.rows(floats, integers, layout, sx, sv, srotation, somega, violation, jac, bias)
    _velocity_impulse(floats, integers, layout, cache, sx, sv, srotation, somega, sinverse_inertia, violation, jac,
                      max(tolerance, reach), joint_force, joint_torque)
    for s in range(count):
        scale = mass_of_linear[s] * inverse_mass[s]
        for c in range(3):
            linear[points[s], c] += joint_force[s, c] * scale
        if slot_rigid[s] >= 0:
            for c in range(3):
                angular_momentum[slot_rigid[s], c] += joint_torque[s, c]


@njit(cache=True, error_model="numpy")
def _velocity_impulse(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray, sx: np.ndarray,
                      sv: np.ndarray, srotation: np.ndarray, somega: np.ndarray, sinverse_inertia: np.ndarray,
                      violation: np.ndarray, jac: np.ndarray, reach: float, force: np.ndarray,
                      torque: np.ndarray) -> None:
    """The impulse (``force`` and ``torque`` (S, 3) per slot) that takes out of the slots' velocities what the rows
    (``violation`` (R,), ``jac`` (R, 2, 6)) do not allow, in the mass metric: all of a bilateral row's rate, and a
    unilateral row's only within ``reach`` of its stop and approaching it (``Joints.project``'s velocity part)."""
    inverse_mass = column(floats, layout, T.SLOT_INVERSE_MASS)
    row_bodies = table(integers, layout, T.ROW_BODIES, 2)
    rows = len(row_bodies)
    rate, right, impulse = np.empty(rows), np.empty(rows), np.empty(rows)
    joint_rows.apply(row_bodies, jac, sv, somega, rate)
    reached = np.empty(rows, np.bool_)
    for r in range(rows):
        reached[r] = violation[r] <= reach and rate[r] < 0  # reached, and approaching
        right[r] = -rate[r]
    _solve_active(integers, layout, cache, sx, srotation, row_bodies, jac, inverse_mass, sinverse_inertia, right,
                  reached, impulse)
    joint_rows.apply_transpose(row_bodies, jac, impulse, force, torque)


@njit(cache=True, error_model="numpy")
def _rows_at(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray, v: np.ndarray,
             rotation: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                               np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The slots' motion at a kinematic state (``x``, ``v`` (P, 3); ``rotation`` (B, 3, 3), ``omega`` (B, 3)) and
    the rows there: ``sx``, ``sv``, ``srotation``, ``somega``, ``sinverse_inertia``, ``violation`` (R,), ``jac``
    (R, 2, 6) and ``bias`` (R,)."""
    slots, rows = rows_of(layout, T.SLOT_RIGID), rows_of(layout, T.ROW_BODIES)
    sx, sv, somega = np.empty((slots, 3)), np.empty((slots, 3)), np.empty((slots, 3))
    sspin, sacceleration = np.empty((slots, 3)), np.empty((slots, 3))
    srotation, sinverse_inertia = np.empty((slots, 3, 3)), np.empty((slots, 3, 3))
    joint_rows.slot_motion(t, floats, integers, layout, x, v, rotation, omega, sx, sv, srotation, somega,
                           sinverse_inertia, sspin, sacceleration)
    violation, bias, jac = np.empty(rows), np.empty(rows), np.empty((rows, 2, 6))
    joint_rows.rows(floats, integers, layout, sx, sv, srotation, somega, violation, jac, bias)
    return sx, sv, srotation, somega, sinverse_inertia, violation, jac, bias


@njit(cache=True, error_model="numpy")
def held_rows(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray,
              rotation: np.ndarray, violation: np.ndarray, jac: np.ndarray) -> None:
    """The joints' rows at positions ``x`` (P, 3) [m] and rotations ``rotation`` (B, 3, 3): ``violation`` (R,) and
    Jacobian ``jac`` (R, 2, 6), which the velocities do not enter (``Joints.velocity_rows``' rows)."""
    found = _rows_at(t, floats, integers, layout, x, np.zeros((len(x), 3)), rotation,
                     np.zeros((len(rotation), 3)))
    violation[:] = found[5]
    jac[:] = found[6]


@njit(cache=True, error_model="numpy")
def project_velocities(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray,
                       x: np.ndarray, rotation: np.ndarray, v: np.ndarray, omega: np.ndarray) -> None:
    """Take out of velocities ``v`` (P, 3) [m/s] and ``omega`` (B, 3) [rad/s] (world axes, in place) what breaks the
    joints at positions ``x`` (P, 3) [m] and rotations ``rotation`` (B, 3, 3), by the impulse that does it in the
    mass metric (``Joints.project_velocities``, the joints' share of a contact solve)."""
    points = column(integers, layout, T.JOINT_POINTS)
    slot_rigid = column(integers, layout, T.SLOT_RIGID)
    inverse_mass = column(floats, layout, T.SLOT_INVERSE_MASS)
    sx, sv, srotation, somega, sinverse_inertia, violation, jac, _ = _rows_at(t, floats, integers, layout, x, v,
                                                                             rotation, omega)
    tolerance = PROJECTION_TOLERANCE * max(column(floats, layout, T.JOINT_SCALE)[0], 1.0)
    joint_force, joint_torque = np.empty((len(sx), 3)), np.empty((len(sx), 3))
    _velocity_impulse(floats, integers, layout, cache, sx, sv, srotation, somega, sinverse_inertia, violation, jac,
                      tolerance, joint_force, joint_torque)
    for s in range(len(points)):
        for c in range(3):
            v[points[s], c] += joint_force[s, c] * inverse_mass[s]
        k = slot_rigid[s]
        if k >= 0:
            turn = rigid_motion.rotate(sinverse_inertia[s], rigid_motion.vector(joint_torque, s))
            for c in range(3):
                omega[k, c] += turn[c]


@njit(cache=True, error_model="numpy")
def project(y: np.ndarray, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, cache: np.ndarray,
            config_size: int, reach: float, t: float, start: np.ndarray, step: float) -> None:
    """``Dynamics.project`` of a state (n,) in place: back onto the joints, then the quaternions re-normalised;
    ``start``: the configuration at the start of a one-kick step of ``step`` [s] > 0 (a SHAKE projection), or
    empty."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    if rows_of(layout, T.ROW_BODIES):
        points = n + b
        positions = y[: 3 * points].reshape((points, 3))
        orientations = y[3 * points: 3 * points + 4 * b].reshape((b, 4))
        linear = y[config_size: config_size + 3 * points].reshape((points, 3))
        angular_momentum = y[config_size + 3 * points:].reshape((b, 3))
        begun = start if len(start) else y[:config_size]
        project_joints(floats, integers, layout, cache, positions, orientations, linear, angular_momentum, reach, t,
                       begun[: 3 * points].reshape((points, 3)),
                       begun[3 * points: 3 * points + 4 * b].reshape((b, 4)), step if len(start) else 0.0 * step)
    rigid_motion.normalise_quaternions(y, layout)


@njit(cache=True, error_model="numpy")
def advance(y: np.ndarray, t: float, h: float, steps: int, form: int, a: np.ndarray, weights: np.ndarray,
            nodes: np.ndarray, rate: np.ndarray, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray,
            cache: np.ndarray, config_size: int) -> int:
    """``steps`` fixed steps of ``h`` [s] from time ``t`` [s], in place, each followed by the projection; returns
    the right-hand sides evaluated. ``form``: an explicit Runge–Kutta method with tableau ``a`` (s, s), ``weights``
    b (s,) and ``nodes`` c (s,); semi-implicit Euler (kick, drift); or velocity Verlet (half kick, drift, half kick
    with the rate at the predicted motion; ``rate`` (the motion's size) holds the rate at the start and is left at
    the end's, as the scheme keeps it). Joints are held by the projection alone, without Baumgarte's term, as the
    fixed-step integrator sets."""
    size = len(y)
    engaged = np.zeros(0, np.bool_)
    # computed, not written as constants: numba compiles a function once more for each constant argument it is
    # called with (a literal False or 0.0), and these functions are the largest
    unused, no_stabilisation = steps < 0, 0.0 * h
    no_start = np.empty(0)  # the projection after a step of Runge–Kutta or Verlet is not SHAKE's
    evaluations = 0
    config, motion = y[:config_size], y[config_size:]
    if form == FORM_RUNGE_KUTTA:
        stages = len(weights)
        k = np.empty((stages, size))
        stage = np.empty(size)
        for step in range(steps):
            now = t + step * h
            for i in range(stages):
                for m in range(size):
                    stage[m] = y[m]
                for j in range(i):
                    if a[i, j] != 0.0:
                        for m in range(size):
                            stage[m] = stage[m] + (h * a[i, j]) * k[j, m]
                rhs(now + nodes[i] * h, stage, floats, integers, layout, cache, config_size, engaged, unused,
                    no_stabilisation, k[i])
            evaluations += stages
            for i in range(stages):
                if weights[i] != 0.0:
                    for m in range(size):
                        y[m] += (h * weights[i]) * k[i, m]
            project(y, floats, integers, layout, cache, config_size, no_stabilisation, now + h, no_start,
                    no_stabilisation)
    elif form == FORM_SYMPLECTIC_EULER:
        kick = np.empty(len(motion))
        start = np.empty(config_size)
        for step in range(steps):
            now = t + step * h
            start[:] = config
            motion_rate(now, config, motion, floats, integers, layout, cache, engaged, unused, no_stabilisation, kick)
            evaluations += 1
            for m in range(len(motion)):
                motion[m] += kick[m] * h
            rigid_motion.drift(config, motion, h, floats, layout)
            project(y, floats, integers, layout, cache, config_size, no_stabilisation, now + h, start, h)
    else:
        predicted = np.empty(len(motion))
        following = np.empty(len(motion))
        for step in range(steps):
            now = t + step * h
            for m in range(len(motion)):
                predicted[m] = motion[m] + rate[m] * h
                motion[m] += rate[m] * (0.5 * h)
            rigid_motion.drift(config, motion, h, floats, layout)
            motion_rate(now + h, config, predicted, floats, integers, layout, cache, engaged, unused, no_stabilisation,
                        following)
            evaluations += 1
            for m in range(len(motion)):
                motion[m] += following[m] * (0.5 * h)
            project(y, floats, integers, layout, cache, config_size, no_stabilisation, now + h, no_start,
                    no_stabilisation)
            for m in range(len(motion)):
                rate[m] = following[m]
    return evaluations

