"""Compiled kinematics, forces and drift of particles and rigid bodies, one body at a time on 3-vectors held as
tuples (registers, not arrays: a small array allocated per body costs more than its arithmetic).

The compiled forms of :meth:`animbatch.sim.model.dynamics.Dynamics.kinematics` (rotation matrices, ``ω = R I⁻¹ Rᵀ
L``), the force terms of the tables (constant forces, and springs with dampers at body points or anchors on
keyframes), ``Dynamics._config_rate`` (``dq/dt = ½ (0, ω) ⊗ q``) and ``Dynamics.drift`` (positions by ``h v``,
orientations by the exact rotation ``exp(h ω)`` at the half-turned ω), and the keyframe paths of
:mod:`animbatch.sim.motion` as piecewise cubics. Every formula is the numpy code's, so the two agree to round-off
(``tests/sim/test_compiled_dynamics.py`` compares them).

Tables: ``(floats, integers, layout)`` of :mod:`animbatch.sim.kernels.tables`, viewed by field with the ``*_of``
functions. State layout (:mod:`animbatch.sim.model.layout`), N particles then B rigid bodies: the configuration is
``[x (3N), x_rigid (3B), q (4B)]`` and the motion ``[v (3N), P (3B), L (3B)]``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels import tables as T

#: A 3-vector held as a tuple.
Vector = tuple[float, float, float]

# ------------------------------------------------------------------------------------------ the tables' fields


@njit(cache=True, error_model="numpy")
def rows_of(layout: np.ndarray, field: int) -> int:
    """The number of rows of a field."""
    return layout[field, 1]


@njit(cache=True, error_model="numpy")
def column(array: np.ndarray, layout: np.ndarray, field: int) -> np.ndarray:
    """A field of one column, (rows,), of the packed ``floats`` or ``integers``."""
    start = layout[field, 0]
    return array[start: start + layout[field, 1]]


@njit(cache=True, error_model="numpy")
def table(array: np.ndarray, layout: np.ndarray, field: int, width: int) -> np.ndarray:
    """A field of ``width`` columns, (rows, width)."""
    start, rows = layout[field, 0], layout[field, 1]
    return array[start: start + rows * width].reshape((rows, width))


@njit(cache=True, error_model="numpy")
def blocks(array: np.ndarray, layout: np.ndarray, field: int, height: int, width: int) -> np.ndarray:
    """A field of (height, width) blocks, (rows, height, width)."""
    start, rows = layout[field, 0], layout[field, 1]
    return array[start: start + rows * height * width].reshape((rows, height, width))


# ------------------------------------------------------------------------------------------ 3-vectors as tuples


@njit(cache=True, error_model="numpy")
def vector(array: np.ndarray, i: int) -> tuple[float, float, float]:
    """Row i of an (n, 3) array."""
    return array[i, 0], array[i, 1], array[i, 2]


@njit(cache=True, error_model="numpy")
def store(array: np.ndarray, i: int, value: tuple[float, float, float]) -> None:
    array[i, 0], array[i, 1], array[i, 2] = value


@njit(cache=True, error_model="numpy")
def cross(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy")
def dot(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def plus(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


@njit(cache=True, error_model="numpy")
def minus(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@njit(cache=True, error_model="numpy")
def times(s: float, a: tuple[float, float, float]) -> tuple[float, float, float]:
    return s * a[0], s * a[1], s * a[2]


@njit(cache=True, error_model="numpy")
def rotate(matrix: np.ndarray, a: tuple[float, float, float]) -> tuple[float, float, float]:
    """``M a`` for a (3, 3) matrix."""
    return (matrix[0, 0] * a[0] + matrix[0, 1] * a[1] + matrix[0, 2] * a[2],
            matrix[1, 0] * a[0] + matrix[1, 1] * a[1] + matrix[1, 2] * a[2],
            matrix[2, 0] * a[0] + matrix[2, 1] * a[1] + matrix[2, 2] * a[2])


@njit(cache=True, error_model="numpy")
def rotate_back(matrix: np.ndarray, a: tuple[float, float, float]) -> tuple[float, float, float]:
    """``Mᵀ a`` for a (3, 3) matrix."""
    return (matrix[0, 0] * a[0] + matrix[1, 0] * a[1] + matrix[2, 0] * a[2],
            matrix[0, 1] * a[0] + matrix[1, 1] * a[1] + matrix[2, 1] * a[2],
            matrix[0, 2] * a[0] + matrix[1, 2] * a[1] + matrix[2, 2] * a[2])


# ------------------------------------------------------------------------------------------ rotations


@njit(cache=True, error_model="numpy")
def quaternion_matrix(q: np.ndarray, out: np.ndarray) -> None:
    """The rotation matrix (3, 3) of a quaternion ``q`` (4,) [w, x, y, z], not necessarily unit, into ``out``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    scale = 2.0 / (w * w + x * x + y * y + z * z)
    xx, yy, zz = scale * x * x, scale * y * y, scale * z * z
    xy, xz, yz = scale * x * y, scale * x * z, scale * y * z
    wx, wy, wz = scale * w * x, scale * w * y, scale * w * z
    out[0, 0], out[0, 1], out[0, 2] = 1 - yy - zz, xy - wz, xz + wy
    out[1, 0], out[1, 1], out[1, 2] = xy + wz, 1 - xx - zz, yz - wx
    out[2, 0], out[2, 1], out[2, 2] = xz - wy, yz + wx, 1 - xx - yy


@njit(cache=True, error_model="numpy")
def turned(rotation: np.ndarray, inverse_inertia: np.ndarray,
           a: tuple[float, float, float]) -> tuple[float, float, float]:
    """``R I_body⁻¹ Rᵀ a``: with ``a = L``, ω."""
    return rotate(rotation, rotate(inverse_inertia, rotate_back(rotation, a)))


@njit(cache=True, error_model="numpy")
def world_tensor(rotation: np.ndarray, tensor: np.ndarray, out: np.ndarray) -> None:
    """``(R T) Rᵀ`` (3, 3) into ``out``: a body-axes tensor in world axes."""
    for i in range(3):
        p0 = rotation[i, 0] * tensor[0, 0] + rotation[i, 1] * tensor[1, 0] + rotation[i, 2] * tensor[2, 0]
        p1 = rotation[i, 0] * tensor[0, 1] + rotation[i, 1] * tensor[1, 1] + rotation[i, 2] * tensor[2, 1]
        p2 = rotation[i, 0] * tensor[0, 2] + rotation[i, 1] * tensor[1, 2] + rotation[i, 2] * tensor[2, 2]
        for j in range(3):
            out[i, j] = p0 * rotation[j, 0] + p1 * rotation[j, 1] + p2 * rotation[j, 2]


@njit(cache=True, error_model="numpy")
def turn_quaternion(q: np.ndarray, turn: tuple[float, float, float]) -> None:
    """``q ← exp(turn) ⊗ q`` in place: ``q`` (4,) turned by the rotation vector ``turn`` [rad] (world axes)."""
    angle = math.sqrt(turn[0] * turn[0] + turn[1] * turn[1] + turn[2] * turn[2])
    half = 0.5 * angle
    # sin(half)/angle -> 1/2 as angle -> 0; the series keeps tiny rotations accurate
    scale = math.sin(half) / angle if angle > 1e-8 else 0.5 - angle**2 / 48
    q[0], q[1], q[2], q[3] = hamilton((math.cos(half), scale * turn[0], scale * turn[1], scale * turn[2]),
                                      (q[0], q[1], q[2], q[3]))


@njit(cache=True, error_model="numpy")
def hamilton(p: tuple[float, float, float, float],
             q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The Hamilton product ``p ⊗ q`` of quaternions held as tuples [w, x, y, z]."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw)


@njit(cache=True, error_model="numpy")
def normalise(q: np.ndarray) -> None:
    """Divide a quaternion (4,) by its norm, in place."""
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for c in range(4):
        q[c] /= norm


# ------------------------------------------------------------------------------------------ bodies


@njit(cache=True, error_model="numpy")
def kinematics(config: np.ndarray, motion: np.ndarray, floats: np.ndarray, layout: np.ndarray, x: np.ndarray,
               v: np.ndarray, rotation: np.ndarray, omega: np.ndarray) -> None:
    """Positions ``x`` and velocities ``v`` (P, 3) of all points, and the rigid bodies' rotations (B, 3, 3) and
    angular velocities ``omega`` (B, 3), world axes, from a state's configuration and motion."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    inverse_mass = column(floats, layout, T.RIGID_INVERSE_MASS)
    inverse_inertia = blocks(floats, layout, T.INVERSE_INERTIA, 3, 3)
    for i in range(n):
        for c in range(3):
            x[i, c] = config[3 * i + c]
            v[i, c] = motion[3 * i + c]
    first_q, first_l = 3 * n + 3 * b, 3 * n + 3 * b
    for k in range(b):
        quaternion_matrix(config[first_q + 4 * k: first_q + 4 * k + 4], rotation[k])
        angular = (motion[first_l + 3 * k], motion[first_l + 3 * k + 1], motion[first_l + 3 * k + 2])
        store(omega, k, turned(rotation[k], inverse_inertia[k], angular))
        for c in range(3):
            x[n + k, c] = config[3 * n + 3 * k + c]
            v[n + k, c] = motion[3 * n + 3 * k + c] * inverse_mass[k]


@njit(cache=True, error_model="numpy")
def path_at(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, path: int,
            t: float) -> tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]:
    """Position [m], velocity [m/s] and acceleration [m/s²] of keyframe path ``path`` at time ``t`` [s]: held
    before the first key and after the last, at rest there; between keys the cubic and its derivatives."""
    keys = table(integers, layout, T.PATH_KEYS, 2)
    times = column(floats, layout, T.PATH_TIMES)
    coefficients = blocks(floats, layout, T.PATH_COEFFICIENTS, 4, 3)
    first, count = keys[path, 0], keys[path, 1]
    zero = (0.0, 0.0, 0.0)
    if count == 1:
        return vector(coefficients[first], 3), zero, zero
    start, end = times[first], times[first + count - 1]
    clamped = min(max(t, start), end)
    interval = 0
    while interval < count - 2 and times[first + interval + 1] <= clamped:
        interval += 1
    u = clamped - times[first + interval]
    c = coefficients[first + interval]
    position = (((c[0, 0] * u + c[1, 0]) * u + c[2, 0]) * u + c[3, 0],
                ((c[0, 1] * u + c[1, 1]) * u + c[2, 1]) * u + c[3, 1],
                ((c[0, 2] * u + c[1, 2]) * u + c[2, 2]) * u + c[3, 2])
    if not start <= t <= end:
        return position, zero, zero
    velocity = ((3.0 * c[0, 0] * u + 2.0 * c[1, 0]) * u + c[2, 0],
                (3.0 * c[0, 1] * u + 2.0 * c[1, 1]) * u + c[2, 1],
                (3.0 * c[0, 2] * u + 2.0 * c[1, 2]) * u + c[2, 2])
    acceleration = (6.0 * c[0, 0] * u + 2.0 * c[1, 0], 6.0 * c[0, 1] * u + 2.0 * c[1, 1],
                    6.0 * c[0, 2] * u + 2.0 * c[1, 2])
    return position, velocity, acceleration


@njit(cache=True, error_model="numpy")
def _spring_end(point: int, offset: Vector, n: int, x: np.ndarray, v: np.ndarray, rotation: np.ndarray,
                omega: np.ndarray) -> tuple[Vector, Vector, Vector]:
    """A spring end at body point ``offset`` (body axes) of ``point``: its lever from the centre of mass, its
    position and its velocity ``v + ω × r``."""
    if point < n:
        return (0.0, 0.0, 0.0), vector(x, point), vector(v, point)
    lever = rotate(rotation[point - n], offset)
    return lever, plus(vector(x, point), lever), plus(vector(v, point), cross(vector(omega, point - n), lever))


@njit(cache=True, error_model="numpy")
def add_forces(t: float, floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray,
               v: np.ndarray, rotation: np.ndarray, omega: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """Set ``force`` (P, 3) [N] and ``torque`` (B, 3) [N·m] to the forces of the terms at time ``t`` [s]: the
    constant ones, every spring ``f1 = −(ks (|L| − r) + kd (ṗ1 − ṗ2)·u) u`` on its first end (with its torque
    ``r × f1`` at a body point), ``−f1`` on its second, then the inverse-square pairs (:func:`add_pair_forces`)."""
    n = rows_of(layout, T.PARTICLE_INVERSE_MASS)
    # element by element: numba's array-to-array assignment compiles its shape error messages, several seconds
    constant_force = table(floats, layout, T.CONSTANT_FORCE, 3)
    constant_torque = table(floats, layout, T.CONSTANT_TORQUE, 3)
    for i in range(len(force)):
        store(force, i, vector(constant_force, i))
    for k in range(len(torque)):
        store(torque, k, vector(constant_torque, k))
    ends = table(integers, layout, T.SPRING_ENDS, 3)
    offsets = blocks(floats, layout, T.SPRING_OFFSETS, 2, 3)
    constants = table(floats, layout, T.SPRING_CONSTANTS, 3)
    anchor_rest = table(floats, layout, T.ANCHOR_REST, 3)
    anchor_path = column(integers, layout, T.ANCHOR_PATH)
    for s in range(len(ends)):
        i, j, anchored = ends[s, 0], ends[s, 1], ends[s, 2] != 0
        lever1, p1, w1 = _spring_end(i, vector(offsets[s], 0), n, x, v, rotation, omega)
        if anchored:
            lever2 = (0.0, 0.0, 0.0)
            if anchor_path[j] >= 0:
                p2, w2, _ = path_at(floats, integers, layout, anchor_path[j], t)
            else:
                p2, w2 = vector(anchor_rest, j), (0.0, 0.0, 0.0)
        else:
            lever2, p2, w2 = _spring_end(j, vector(offsets[s], 1), n, x, v, rotation, omega)
        axis = minus(p1, p2)
        length = math.sqrt(dot(axis, axis))
        if length <= 0.0:
            continue
        unit = (axis[0] / length, axis[1] / length, axis[2] / length)
        magnitude = constants[s, 0] * (length - constants[s, 2]) + constants[s, 1] * dot(minus(w1, w2), unit)
        f1 = times(-magnitude, unit)
        store(force, i, plus(vector(force, i), f1))
        if i >= n:
            store(torque, i - n, plus(vector(torque, i - n), cross(lever1, f1)))
        if not anchored:
            store(force, j, minus(vector(force, j), f1))
            if j >= n:
                store(torque, j - n, minus(vector(torque, j - n), cross(lever2, f1)))
    add_pair_forces(floats, integers, layout, x, force)
    add_buoyancy(floats, integers, layout, x, v, rotation, omega, force, torque)
    add_drag(floats, integers, layout, v, rotation, omega, force, torque)
    add_loads(floats, integers, layout, rotation, omega, force, torque)


@njit(cache=True, error_model="numpy")
def add_loads(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, rotation: np.ndarray, omega: np.ndarray,
              force: np.ndarray, torque: np.ndarray) -> None:
    """Add the applied loads (:mod:`animbatch.sim.forces.applied`) to ``force`` (P, 3) [N] and ``torque`` (B, 3)
    [N·m]: a constant force (turned with the body in body axes; at a body point r also the torque ``r × f``), a
    constant torque, angular drag ``τ = −c ω``."""
    points = table(integers, layout, T.LOAD_POINTS, 3)
    values = table(floats, layout, T.LOAD_VALUES, 7)
    for k in range(len(points)):
        i, rigid, kind = points[k, 0], points[k, 1], points[k, 2]
        load = (values[k, 0], values[k, 1], values[k, 2])
        if kind == T.ANGULAR_DRAG_LOAD:
            store(torque, rigid, minus(vector(torque, rigid), times(load[0], vector(omega, rigid))))
            continue
        if rigid >= 0 and values[k, 3] != 0.0:
            load = rotate(rotation[rigid], load)
        if kind == T.TORQUE_LOAD:
            store(torque, rigid, plus(vector(torque, rigid), load))
            continue
        store(force, i, plus(vector(force, i), load))
        offset = (values[k, 4], values[k, 5], values[k, 6])
        if rigid >= 0 and (offset[0] != 0.0 or offset[1] != 0.0 or offset[2] != 0.0):
            store(torque, rigid, plus(vector(torque, rigid), cross(rotate(rotation[rigid], offset), load)))


@njit(cache=True, error_model="numpy")
def add_drag(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, v: np.ndarray, rotation: np.ndarray,
             omega: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """Add each drag term's force ``−C u`` (linear) or ``−C |u| u`` (quadratic), ``u`` the velocity relative to the
    wind, at centres of mass, and at body points with the torque ``r × f`` (:class:`animbatch.sim.forces.drag.Drag`)
    to ``force`` (P, 3) [N] and ``torque`` (B, 3) [N·m]."""
    terms = table(floats, layout, T.DRAG_TERMS, 4)
    points = table(integers, layout, T.DRAG_POINTS, 3)
    shapes = table(floats, layout, T.DRAG_SHAPES, 4)
    for d in range(len(points)):
        i, rigid, term = points[d, 0], points[d, 1], points[d, 2]
        coefficient = shapes[d, 3]
        relative = vector(v, i)
        lever = (0.0, 0.0, 0.0)
        if rigid >= 0:
            lever = rotate(rotation[rigid], (shapes[d, 0], shapes[d, 1], shapes[d, 2]))
            relative = plus(relative, cross(vector(omega, rigid), lever))
        relative = minus(relative, (terms[term, 1], terms[term, 2], terms[term, 3]))
        if terms[term, 0] != 0.0:
            pulled = times(math.sqrt(dot(relative, relative)) * coefficient, times(-1.0, relative))
        else:
            pulled = times(-1.0, times(coefficient, relative))
        store(force, i, plus(vector(force, i), pulled))
        if rigid >= 0:
            store(torque, rigid, plus(vector(torque, rigid), cross(lever, pulled)))


@njit(cache=True, error_model="numpy")
def add_buoyancy(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray, v: np.ndarray,
                 rotation: np.ndarray, omega: np.ndarray, force: np.ndarray, torque: np.ndarray) -> None:
    """Add each buoyancy term's lift ``ρ g V_sub up`` (at the centre of buoyancy, a torque on a rigid body) and
    fluid damping (``−c f v`` and ``−c_ω f ω``, f the submerged fraction) to ``force`` (P, 3) [N] and ``torque``
    (B, 3) [N·m], the submerged volume of each sphere piece a spherical cap
    (:func:`animbatch.sim.forces.buoyancy.spherical_caps`, :class:`~animbatch.sim.forces.buoyancy.Buoyancy`)."""
    terms = table(floats, layout, T.BUOYANCY_TERMS, 7)
    spheres = table(integers, layout, T.BUOYANCY_SPHERES, 3)
    shapes = table(floats, layout, T.BUOYANCY_SHAPES, 4)
    bodies = table(integers, layout, T.BUOYANCY_BODIES, 2)
    volumes = column(floats, layout, T.BUOYANCY_VOLUMES)
    n = rows_of(layout, T.PARTICLE_INVERSE_MASS)
    if not len(terms):
        return
    volume, moment = np.empty(len(x)), np.empty((len(x), 3))
    for term in range(len(terms)):
        weight, level = terms[term, 0], terms[term, 1]
        up = (terms[term, 2], terms[term, 3], terms[term, 4])
        volume[:] = 0.0
        moment[:] = 0.0
        for k in range(len(spheres)):
            if spheres[k, 2] != term:
                continue
            owner, rigid, radius = spheres[k, 0], spheres[k, 1], shapes[k, 3]
            centre = vector(x, owner)
            offset = (shapes[k, 0], shapes[k, 1], shapes[k, 2])
            if rigid >= 0 and (offset[0] != 0.0 or offset[1] != 0.0 or offset[2] != 0.0):
                centre = plus(centre, rotate(rotation[rigid], offset))
            depth = min(max(level - (dot(centre, up) - radius), 0.0), 2 * radius)
            rest = 3 * radius - depth
            cap = math.pi * depth**2 * rest / 3
            below = 3 * (2 * radius - depth) ** 2 / (4 * max(rest, _TINY)) if depth > 0 else 0.0
            volume[owner] += cap
            for c in range(3):
                moment[owner, c] += cap * (centre[c] - below * up[c])
        for s in range(len(bodies)):
            if bodies[s, 1] != term:
                continue
            i = bodies[s, 0]
            lift = times(weight * volume[i], up)
            fraction = volume[i] / volumes[s] if volumes[s] > 0 else 0.0
            pushed = lift
            if terms[term, 5] != 0.0:
                pushed = minus(lift, times(terms[term, 5] * fraction, vector(v, i)))
            store(force, i, plus(vector(force, i), pushed))
            if i >= n:
                k = i - n
                centre = vector(x, i)
                if volume[i] > 0:
                    centre = (moment[i, 0] / volume[i], moment[i, 1] / volume[i], moment[i, 2] / volume[i])
                spin = cross(minus(centre, vector(x, i)), lift)
                if terms[term, 6] != 0.0:
                    spin = minus(spin, times(terms[term, 6] * fraction, vector(omega, k)))
                store(torque, k, plus(vector(torque, k), spin))


#: The smallest positive float (a dry sphere of no size divides by it, as numpy's code does).
_TINY = 2.2250738585072014e-308


@njit(cache=True, error_model="numpy")
def add_pair_forces(floats: np.ndarray, integers: np.ndarray, layout: np.ndarray, x: np.ndarray,
                    force: np.ndarray) -> None:
    """Add the inverse-square pair laws' forces (gravitation, Coulomb) to ``force`` (P, 3) [N]:
    ``f_i = κ s_i Σ_j s_j (x_j − x_i) / (|x_j − x_i|² + ε²)^(3/2)`` over the other points j of each term
    (:class:`~animbatch.sim.forces.gravitation.InverseSquarePairs`)."""
    terms = table(floats, layout, T.PAIR_TERMS, 2)
    start = column(integers, layout, T.PAIR_START)
    points = column(integers, layout, T.PAIR_POINTS)
    source = column(floats, layout, T.PAIR_SOURCE)
    for term in range(len(terms)):
        coupling, eps2 = terms[term, 0], terms[term, 1] ** 2
        for a in range(start[term], start[term + 1]):
            i = points[a]
            f0 = f1 = f2 = 0.0
            for b in range(start[term], start[term + 1]):
                if b == a:
                    continue
                j = points[b]
                d0, d1, d2 = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
                weight = source[b] * (d0 * d0 + d1 * d1 + d2 * d2 + eps2) ** -1.5
                f0 += weight * d0
                f1 += weight * d1
                f2 += weight * d2
            scale = coupling * source[a]
            force[i, 0] += f0 * scale
            force[i, 1] += f1 * scale
            force[i, 2] += f2 * scale


@njit(cache=True, error_model="numpy")
def motion_rate_from(force: np.ndarray, torque: np.ndarray, floats: np.ndarray, layout: np.ndarray,
                     out: np.ndarray) -> None:
    """``dm/dt = [F / m (particles), F (rigid), τ]``, flat, into ``out``."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    inverse_mass = column(floats, layout, T.PARTICLE_INVERSE_MASS)
    for i in range(n):
        for c in range(3):
            out[3 * i + c] = force[i, c] * inverse_mass[i]
    for k in range(b):
        for c in range(3):
            out[3 * n + 3 * k + c] = force[n + k, c]
            out[3 * n + 3 * b + 3 * k + c] = torque[k, c]


@njit(cache=True, error_model="numpy")
def config_rate(config: np.ndarray, motion: np.ndarray, layout: np.ndarray, v: np.ndarray, omega: np.ndarray,
                out: np.ndarray) -> None:
    """``dc/dt = [v, P / M, ½ (0, ω) ⊗ q]``, flat, into ``out``, given the points' velocities ``v`` (P, 3) and the
    rigid bodies' ω (B, 3)."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    for i in range(3 * n):
        out[i] = motion[i]
    first_q = 3 * n + 3 * b
    for k in range(b):
        for c in range(3):
            out[3 * n + 3 * k + c] = v[n + k, c]
        q = config[first_q + 4 * k: first_q + 4 * k + 4]
        wx, wy, wz = 0.5 * omega[k, 0], 0.5 * omega[k, 1], 0.5 * omega[k, 2]
        rate = out[first_q + 4 * k: first_q + 4 * k + 4]
        rate[0] = -wx * q[1] - wy * q[2] - wz * q[3]
        rate[1] = wx * q[0] + wy * q[3] - wz * q[2]
        rate[2] = -wx * q[3] + wy * q[0] + wz * q[1]
        rate[3] = wx * q[2] - wy * q[1] + wz * q[0]


@njit(cache=True, error_model="numpy")
def drift(config: np.ndarray, motion: np.ndarray, h: float, floats: np.ndarray, layout: np.ndarray) -> None:
    """Advance the configuration by ``h`` [s] with the motion held fixed, in place: positions by ``h v``,
    orientations by ``exp(h ω)`` with ω at the half-turned orientation (a midpoint rule, norm-preserving)."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    inverse_mass = column(floats, layout, T.RIGID_INVERSE_MASS)
    inverse_inertia = blocks(floats, layout, T.INVERSE_INERTIA, 3, 3)
    for i in range(3 * n):
        config[i] += h * motion[i]
    rotation = np.empty((3, 3))
    halfway = np.empty(4)
    first_q, first_l = 3 * n + 3 * b, 3 * n + 3 * b
    for k in range(b):
        for c in range(3):
            config[3 * n + 3 * k + c] += h * motion[3 * n + 3 * k + c] * inverse_mass[k]
        q = config[first_q + 4 * k: first_q + 4 * k + 4]
        angular = (motion[first_l + 3 * k], motion[first_l + 3 * k + 1], motion[first_l + 3 * k + 2])
        quaternion_matrix(q, rotation)
        for c in range(4):
            halfway[c] = q[c]
        turn_quaternion(halfway, times(0.5 * h, turned(rotation, inverse_inertia[k], angular)))
        quaternion_matrix(halfway, rotation)
        turn_quaternion(q, times(h, turned(rotation, inverse_inertia[k], angular)))


@njit(cache=True, error_model="numpy")
def normalise_quaternions(y: np.ndarray, layout: np.ndarray) -> None:
    """Re-normalise the rigid bodies' quaternions of a state (n,) in place."""
    n, b = rows_of(layout, T.PARTICLE_INVERSE_MASS), rows_of(layout, T.RIGID_INVERSE_MASS)
    for k in range(b):
        normalise(y[3 * n + 3 * b + 4 * k: 3 * n + 3 * b + 4 * k + 4])
