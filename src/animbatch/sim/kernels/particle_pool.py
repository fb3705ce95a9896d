"""A pool of emitted particles stepped in one compiled pass: fields, the step, fixed colliders and ageing, fused.

This is the compiled form of :meth:`animbatch.sim.particles.simulate.EmitterRun.step` for the common case of
particles under gravity, drag, wind and buoyancy, meeting fixed colliders (planes, spheres, boxes: floors, walls,
crates) or nothing, stepped with explicit Euler, semi-implicit Euler or velocity Verlet. Each particle is
independent of the others, so a thread takes each particle through all the steps of a call: its row of the pool's
arrays is read and written once a step, not once per operation as in the numpy code (which also goes through the
whole pool for each). With births during a frame the pool is stepped one step per call (births come between
steps), by :func:`advance_one`, a loop made lean for that; without, a whole frame's steps are one call of
:func:`advance_pool`.

Every operation is the numpy code's, in the same order, so the two agree to round-off (the tests compare them); but
drag divides by the mass once per particle, not per component, and a table of gravities and at most one drag (the
common emitter) is read once per call into scalars (:func:`field_summary`), its gravities summed first:

* fields, in the order declared (``FIELD_GRAVITY``: ``a += g``; ``FIELD_DRAG``: ``a -= (s / m) u`` with
  ``u = v - w`` and s = C (linear), C |u| (quadratic) or 6 π η r (Stokes); ``FIELD_BUOYANCY``: ``a += ρ g V_sub up / m``
  and the fluid's damping ``-c v V_sub / (V m)``);
* the step (:mod:`animbatch.sim.integrators.particle_kernels`);
* the path ``x0 → x1`` against every collider grown by the radius (planes, then spheres, then boxes; the earliest
  crossing first, ties to the first listed); a bounce (:func:`animbatch.sim.particles.collisions.bounce`) sends the
  particle on for the rest of its step, up to ``MAX_BOUNCES`` times; stick and die stop it at the surface;
* particles found inside a collider are put back on it and their motion into it removed, collider by collider;
* a particle whose age reached its lifetime at the step's end dies.

Arrays (C = the pool's capacity): ``x``, ``v``, ``a`` (C, 3) [m], [m/s], [m/s²], updated in place; ``alive``,
``stuck`` (C,) bool, updated in place; ``mass`` [kg], ``radius`` [m], ``birth``, ``lifetime`` [s] (C,). The
emitter's fields are one table ``fields`` (F, FIELD_COLUMNS): kind, drag law, C, η, whether there is a wind, the g,
wind or up vector, and a fluid's density, g, surface level and damping; its colliders one table ``solids``
(S, SOLID_COLUMNS): kind, restitution, static and kinetic friction against the particles, and a plane's point and
unit normal, a sphere's centre and radius, or a box's centre, half sides and rotation.

A step's path is first tested against the colliders cheaply (:func:`_planes_clear`, :func:`_clear`): a path clear
of them all is the motion alone, and only the others go through the collision code, in a separate call. The planes
come in their own small table, and the spheres and boxes in another that is None when there are none: numba then
compiles the kernel twice, and the common emitter (a floor, walls) runs a loop without the code for round solids,
which costs it about a fifth of its speed (measured) even when that code never runs. Ages are read only in calls
where a particle may die (the caller knows the earliest death, which each ageing pass returns).

The functions run on every particle at every step (fields, planes) are inlined (``inline="always"``): a call per
particle-step costs more than their arithmetic. Spheres and boxes are called, not inlined: inlining is done by numba
and is what the first compilation on a machine spends its time on (cached on disk after that).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: Field kinds in the field table, and its columns.
FIELD_GRAVITY, FIELD_DRAG, FIELD_BUOYANCY = 0, 1, 2
KIND, LAW, COEFFICIENT, VISCOSITY, HAS_WIND, VECTOR = 0, 1, 2, 3, 4, 5
DENSITY, BUOYANCY_G, LEVEL, DAMPING = 8, 9, 10, 11
FIELD_COLUMNS = 12
#: Solid kinds in the solid table, and its columns (a plane's point, a sphere's or box's centre in CENTRE; a box's
#: rotation, box-to-world, row by row in ROTATION).
SOLID_PLANE, SOLID_SPHERE, SOLID_BOX = 0, 1, 2
SOLID, RESTITUTION, STATIC_FRICTION, KINETIC_FRICTION = 0, 1, 2, 3
CENTRE, NORMAL, RADIUS, HALF, ROTATION = 4, 7, 10, 11, 14
SOLID_COLUMNS = 23
#: Drag laws.
LAW_LINEAR, LAW_QUADRATIC, LAW_STOKES = 0, 1, 2
#: Step methods.
METHOD_EULER, METHOD_SYMPLECTIC_EULER, METHOD_VERLET = 0, 1, 2
METHOD_CODES = {"euler": METHOD_EULER, "symplectic_euler": METHOD_SYMPLECTIC_EULER, "verlet": METHOD_VERLET}
#: What a particle does at a plane.
MODE_BOUNCE, MODE_STICK, MODE_DIE, MODE_PASS = 0, 1, 2, 3
MODE_CODES = {"bounce": MODE_BOUNCE, "stick": MODE_STICK, "die": MODE_DIE, "pass": MODE_PASS}


@njit(cache=True, inline="always")
def _acceleration(fields, x0, x1, x2, v0, v1, v2, mass, radius):
    """a(x, v) [m/s²] of one particle under the field table."""
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for f in range(fields.shape[0]):
        kind = fields[f, KIND]
        if kind == FIELD_GRAVITY:
            a0 += fields[f, VECTOR]
            a1 += fields[f, VECTOR + 1]
            a2 += fields[f, VECTOR + 2]
        elif kind == FIELD_DRAG:
            u0, u1, u2 = v0, v1, v2
            if fields[f, HAS_WIND]:
                u0 -= fields[f, VECTOR]
                u1 -= fields[f, VECTOR + 1]
                u2 -= fields[f, VECTOR + 2]
            law = fields[f, LAW]
            if law == LAW_QUADRATIC:
                scale = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2) * fields[f, COEFFICIENT]
            elif law == LAW_STOKES:
                scale = 6.0 * np.pi * fields[f, VISCOSITY] * radius
            else:
                scale = fields[f, COEFFICIENT]
            per_mass = scale / mass  # one division, not three: the divisions are what a particle-step waits on
            a0 -= per_mass * u0
            a1 -= per_mass * u1
            a2 -= per_mass * u2
        else:  # buoyancy: ρ g V_sub up / m, V_sub the sphere's cap under the surface; damping -c v V_sub / V
            up0, up1, up2 = fields[f, VECTOR], fields[f, VECTOR + 1], fields[f, VECTOR + 2]
            depth = min(max(fields[f, LEVEL] - ((x0 * up0 + x1 * up1 + x2 * up2) - radius), 0.0), 2 * radius)
            volume = np.pi * depth**2 * (3 * radius - depth) / 3
            lift = fields[f, DENSITY] * fields[f, BUOYANCY_G] * volume / mass
            a0 += lift * up0
            a1 += lift * up1
            a2 += lift * up2
            if fields[f, DAMPING]:
                slowing = fields[f, DAMPING] * (volume / (4.0 / 3.0 * np.pi * radius**3)) / mass
                a0 -= slowing * v0
                a1 -= slowing * v1
                a2 -= slowing * v2
    return a0, a1, a2


@njit(cache=True)
def field_summary(fields):
    """The field table in scalars, when it is gravity and at most one drag (the common emitter): whether it is, and
    (g0, g1, g2, q, l, s, w0, w1, w2): the gravities summed, and the drag's scale s(u) = q |u| + l + s r per law
    (quadratic: q = C; linear: l = C; Stokes: s = 6 π η; all 0 without drag) and its wind (0 without). Read once per
    call, so that the particle loop holds them in registers (it cannot keep a table's entries there: every store to
    the pool might, for all the compiler knows, change the table), and branch-free: one sum serves every law."""
    g0 = g1 = g2 = 0.0
    quadratic = linear = stokes = w0 = w1 = w2 = 0.0
    drags = 0
    simple = True
    for f in range(fields.shape[0]):
        kind = fields[f, KIND]
        if kind == FIELD_GRAVITY:
            g0 += fields[f, VECTOR]
            g1 += fields[f, VECTOR + 1]
            g2 += fields[f, VECTOR + 2]
        elif kind == FIELD_DRAG and drags == 0:
            drags += 1
            law = fields[f, LAW]
            if law == LAW_QUADRATIC:
                quadratic = fields[f, COEFFICIENT]
            elif law == LAW_STOKES:
                stokes = 6.0 * np.pi * fields[f, VISCOSITY]
            else:
                linear = fields[f, COEFFICIENT]
            if fields[f, HAS_WIND]:
                w0, w1, w2 = fields[f, VECTOR], fields[f, VECTOR + 1], fields[f, VECTOR + 2]
        else:
            simple = False
    return simple, (g0, g1, g2, quadratic, linear, stokes, w0, w1, w2)


@njit(cache=True, inline="always")
def _summary_acceleration(summary, v0, v1, v2, mass, radius):
    """a(v) [m/s²] of one particle under the fields of :func:`field_summary`."""
    g0, g1, g2, quadratic, linear, stokes, w0, w1, w2 = summary
    u0, u1, u2 = v0 - w0, v1 - w1, v2 - w2
    per_mass = (math.sqrt(u0 * u0 + u1 * u1 + u2 * u2) * quadratic + linear + stokes * radius) / mass
    return g0 - per_mass * u0, g1 - per_mass * u1, g2 - per_mass * u2


@njit(cache=True, inline="always")
def _field_acceleration(fields, simple, summary, x0, x1, x2, v0, v1, v2, mass, radius):
    """a(x, v) [m/s²] of one particle: from the summary when the table has one, else from the table. ``fields`` None:
    the summary alone (None is a type: numba then compiles the table's code out of the caller)."""
    if fields is None:
        return _summary_acceleration(summary, v0, v1, v2, mass, radius)
    if simple:
        return _summary_acceleration(summary, v0, v1, v2, mass, radius)
    return _acceleration(fields, x0, x1, x2, v0, v1, v2, mass, radius)


@njit(cache=True)
def _sphere_fraction(solids, k, p0, p1, p2, q0, q1, q2, radius):
    """Where the path p → q first meets sphere ``k`` grown by ``radius`` from outside (fraction, outward normal), or
    inf (see collisions.first_hits)."""
    grown = solids[k, RADIUS] + radius
    o0, o1, o2 = p0 - solids[k, CENTRE], p1 - solids[k, CENTRE + 1], p2 - solids[k, CENTRE + 2]
    d0, d1, d2 = q0 - p0, q1 - p1, q2 - p2
    a = d0 * d0 + d1 * d1 + d2 * d2
    b = d0 * o0 + d1 * o1 + d2 * o2
    c = o0 * o0 + o1 * o1 + o2 * o2 - grown * grown
    disc = b * b - a * c
    if not (c >= 0.0 and disc >= 0.0 and a > 0.0):
        return np.inf, 0.0, 0.0, 0.0
    fraction = (-b - math.sqrt(max(disc, 0.0))) / a
    if not (0.0 <= fraction <= 1.0):
        return np.inf, 0.0, 0.0, 0.0
    t0, t1, t2 = o0 + fraction * d0, o1 + fraction * d1, o2 + fraction * d2
    length = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    return fraction, t0 / length, t1 / length, t2 / length


@njit(cache=True)
def _box_fraction(solids, k, p0, p1, p2, q0, q1, q2, radius):
    """Where the path p → q first meets box ``k`` grown by ``radius`` from outside (fraction, outward normal of the
    face it enters), or inf (slabs, as collisions.first_hits)."""
    entry = -np.inf
    leave = np.inf
    axis = 0
    outside = False
    direction = 0.0
    for m in range(3):
        grown = solids[k, HALF + m] + radius
        start = ((p0 - solids[k, CENTRE]) * solids[k, ROTATION + m] + (p1 - solids[k, CENTRE + 1])
                 * solids[k, ROTATION + 3 + m] + (p2 - solids[k, CENTRE + 2]) * solids[k, ROTATION + 6 + m])
        d = ((q0 - p0) * solids[k, ROTATION + m] + (q1 - p1) * solids[k, ROTATION + 3 + m]
             + (q2 - p2) * solids[k, ROTATION + 6 + m])
        if abs(start) > grown:
            outside = True
        if d == 0.0:
            near = -np.inf if abs(start) <= grown else np.inf
            far = np.inf if abs(start) <= grown else -np.inf
        else:
            low = (-grown - start) / d
            high = (grown - start) / d
            near = min(low, high)
            far = max(low, high)
        if near > entry or m == 0:
            entry = near
            axis = m
            direction = d
        leave = min(leave, far)
    if not (outside and entry <= leave and 0.0 <= entry <= 1.0):
        return np.inf, 0.0, 0.0, 0.0
    sign = -1.0 if direction > 0.0 else (1.0 if direction < 0.0 else 0.0)
    return (entry, sign * solids[k, ROTATION + axis], sign * solids[k, ROTATION + 3 + axis],
            sign * solids[k, ROTATION + 6 + axis])


@njit(cache=True, inline="always")
def _first_hit(solids, p0, p1, p2, q0, q1, q2, radius):
    """The earliest solid (index, fraction, outward normal) the path p → q meets from outside, solids grown by
    ``radius``; index -1 for none. Ties go to the solid listed first (solids, spheres, boxes)."""
    best = np.inf
    which = -1
    b0 = b1 = b2 = 0.0
    for k in range(solids.shape[0]):
        kind = solids[k, SOLID]
        if kind == SOLID_PLANE:
            n0, n1, n2 = solids[k, NORMAL], solids[k, NORMAL + 1], solids[k, NORMAL + 2]
            c0, c1, c2 = solids[k, CENTRE], solids[k, CENTRE + 1], solids[k, CENTRE + 2]
            d0 = (p0 - c0) * n0 + (p1 - c1) * n1 + (p2 - c2) * n2 - radius
            d1 = (q0 - c0) * n0 + (q1 - c1) * n1 + (q2 - c2) * n2 - radius
            fraction = d0 / (d0 - d1) if d0 >= 0.0 and d1 < 0.0 else np.inf
        elif kind == SOLID_SPHERE:
            fraction, n0, n1, n2 = _sphere_fraction(solids, k, p0, p1, p2, q0, q1, q2, radius)
        else:
            fraction, n0, n1, n2 = _box_fraction(solids, k, p0, p1, p2, q0, q1, q2, radius)
        if fraction < best:
            best = fraction
            which = k
            b0, b1, b2 = n0, n1, n2
    return which, best, b0, b1, b2


@njit(cache=True)
def _bounce(v0, v1, v2, n0, n1, n2, restitution, static_friction, kinetic_friction, rest_speed):
    """The velocity after bouncing off a surface of outward normal n (see collisions.bounce)."""
    normal_speed = v0 * n0 + v1 * n1 + v2 * n2
    approach = max(-normal_speed, 0.0)
    if approach <= 0.0:
        return v0, v1, v2
    e = restitution if approach > rest_speed else 0.0
    t0 = v0 - normal_speed * n0
    t1 = v1 - normal_speed * n1
    t2 = v2 - normal_speed * n2
    slide = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    impulse = (1.0 + e) * approach
    reduced = 0.0 if slide <= static_friction * impulse else max(slide - kinetic_friction * impulse, 0.0)
    scale = reduced / slide if slide > 0.0 else 0.0
    out = e * approach
    return t0 * scale + out * n0, t1 * scale + out * n1, t2 * scale + out * n2


@njit(cache=True)
def _resolve(solids, mode, max_bounces, gap, rest_speed, which, fraction, n0, n1, n2, s0, s1, s2, p0, p1, p2, u0, u1,
             u2, r, h):
    """What follows a hit on solid ``which`` (outward normal n) at ``fraction`` of the path s → p (velocity u at the
    step's end, step h): bounces for the rest of the step (up to ``max_bounces``), or a stop at the surface. Returns
    the position, velocity, hits and what happened: 0 moved on, 1 stuck, 2 died. (Rare next to the steps without a
    hit, so not inlined.)"""
    fate = 0
    hits = 0
    for bounces in range(max_bounces + 1):
        if which < 0:
            break
        hits += 1
        at0 = s0 + fraction * (p0 - s0) + gap * n0
        at1 = s1 + fraction * (p1 - s1) + gap * n1
        at2 = s2 + fraction * (p2 - s2) + gap * n2
        if mode == MODE_BOUNCE:
            u0, u1, u2 = _bounce(u0, u1, u2, n0, n1, n2, solids[which, RESTITUTION], solids[which, STATIC_FRICTION],
                                 solids[which, KINETIC_FRICTION], rest_speed)
            if bounces == max_bounces:  # out of bounces: stays at the surface for the rest of this step
                p0, p1, p2 = at0, at1, at2
                break
            rest = (1.0 - fraction) * h  # the rest of the step, bounced
            s0, s1, s2 = at0, at1, at2
            p0, p1, p2 = at0 + rest * u0, at1 + rest * u1, at2 + rest * u2
            which, fraction, n0, n1, n2 = _first_hit(solids, s0, s1, s2, p0, p1, p2, r)
            continue
        p0, p1, p2 = at0, at1, at2
        u0 = u1 = u2 = 0.0
        fate = 1 if mode == MODE_STICK else 2
        break
    return p0, p1, p2, u0, u1, u2, hits, fate


@njit(cache=True)
def _solid_distance(solids, k, p0, p1, p2):
    """Signed distance [m] of a point to sphere or box ``k`` (not grown) and its outward normal (collisions.push_out's
    to_sphere and to_box)."""
    kind = solids[k, SOLID]
    c0, c1, c2 = p0 - solids[k, CENTRE], p1 - solids[k, CENTRE + 1], p2 - solids[k, CENTRE + 2]
    if kind == SOLID_SPHERE:
        length = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        if length > 1e-12:
            return length - solids[k, RADIUS], c0 / length, c1 / length, c2 / length
        return length - solids[k, RADIUS], 0.0, 1.0, 0.0
    x0 = solids[k, ROTATION] * c0 + solids[k, ROTATION + 3] * c1 + solids[k, ROTATION + 6] * c2  # box axes: Rᵀ c
    x1 = solids[k, ROTATION + 1] * c0 + solids[k, ROTATION + 4] * c1 + solids[k, ROTATION + 7] * c2
    x2 = solids[k, ROTATION + 2] * c0 + solids[k, ROTATION + 5] * c1 + solids[k, ROTATION + 8] * c2
    h0, h1, h2 = solids[k, HALF], solids[k, HALF + 1], solids[k, HALF + 2]
    o0 = x0 - min(max(x0, -h0), h0)
    o1 = x1 - min(max(x1, -h1), h1)
    o2 = x2 - min(max(x2, -h2), h2)
    distance = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    if distance > 1e-12:
        l0, l1, l2 = o0 / distance, o1 / distance, o2 / distance
        signed = distance
    else:  # inside: out through the nearest face (the first of equals, as argmin)
        depth0, depth1, depth2 = h0 - abs(x0), h1 - abs(x1), h2 - abs(x2)
        l0 = l1 = l2 = 0.0
        if depth0 <= depth1 and depth0 <= depth2:
            signed, l0 = -depth0, (1.0 if x0 >= 0.0 else -1.0)
        elif depth1 <= depth2:
            signed, l1 = -depth1, (1.0 if x1 >= 0.0 else -1.0)
        else:
            signed, l2 = -depth2, (1.0 if x2 >= 0.0 else -1.0)
    n0 = solids[k, ROTATION] * l0 + solids[k, ROTATION + 1] * l1 + solids[k, ROTATION + 2] * l2
    n1 = solids[k, ROTATION + 3] * l0 + solids[k, ROTATION + 4] * l1 + solids[k, ROTATION + 5] * l2
    n2 = solids[k, ROTATION + 6] * l0 + solids[k, ROTATION + 7] * l1 + solids[k, ROTATION + 8] * l2
    return signed, n0, n1, n2


@njit(cache=True, inline="always")
def _push_out(solids, gap, p0, p1, p2, u0, u1, u2, r):
    """A particle left inside a solid (closer than its radius) goes back onto it, its motion into it removed; the
    solids in turn, each after the pushes out of those before it."""
    for k in range(solids.shape[0]):
        if solids[k, SOLID] == SOLID_PLANE:
            n0, n1, n2 = solids[k, NORMAL], solids[k, NORMAL + 1], solids[k, NORMAL + 2]
            distance = ((p0 - solids[k, CENTRE]) * n0 + (p1 - solids[k, CENTRE + 1]) * n1
                        + (p2 - solids[k, CENTRE + 2]) * n2)
        else:
            distance, n0, n1, n2 = _solid_distance(solids, k, p0, p1, p2)
        if distance < r:
            depth = r - distance + gap
            p0 += depth * n0
            p1 += depth * n1
            p2 += depth * n2
            into = min(u0 * n0 + u1 * n1 + u2 * n2, 0.0)
            u0 -= into * n0
            u1 -= into * n1
            u2 -= into * n2
    return p0, p1, p2, u0, u1, u2


@njit(cache=True, inline="always")
def _motion(i, h, x, v, a, mass, radius, method, fields, simple, summary):
    """One step ``h`` [s] of particle ``i``'s motion under the fields, without colliders: the start s, the end p,
    the velocity u and the acceleration c there (each three numbers)."""
    m = mass[i]
    r = radius[i]
    s0, s1, s2 = x[i, 0], x[i, 1], x[i, 2]  # the step's path starts here
    u0, u1, u2 = v[i, 0], v[i, 1], v[i, 2]
    c0, c1, c2 = a[i, 0], a[i, 1], a[i, 2]
    if method == METHOD_VERLET:
        p0 = s0 + h * u0 + (0.5 * h * h) * c0
        p1 = s1 + h * u1 + (0.5 * h * h) * c1
        p2 = s2 + h * u2 + (0.5 * h * h) * c2
        n0, n1, n2 = _field_acceleration(fields, simple, summary, p0, p1, p2, u0 + h * c0, u1 + h * c1, u2 + h * c2,
                                         m, r)
        u0 = u0 + (0.5 * h) * (c0 + n0)
        u1 = u1 + (0.5 * h) * (c1 + n1)
        u2 = u2 + (0.5 * h) * (c2 + n2)
        c0, c1, c2 = n0, n1, n2
    else:
        c0, c1, c2 = _field_acceleration(fields, simple, summary, s0, s1, s2, u0, u1, u2, m, r)
        if method == METHOD_SYMPLECTIC_EULER:
            u0 = u0 + h * c0
            u1 = u1 + h * c1
            u2 = u2 + h * c2
            p0 = s0 + h * u0
            p1 = s1 + h * u1
            p2 = s2 + h * u2
        else:  # explicit Euler: positions move with the velocity from before the step
            p0 = s0 + h * u0
            p1 = s1 + h * u1
            p2 = s2 + h * u2
            u0 = u0 + h * c0
            u1 = u1 + h * c1
            u2 = u2 + h * c2
    return s0, s1, s2, p0, p1, p2, u0, u1, u2, c0, c1, c2


@njit(cache=True, inline="always")
def _planes_clear(planes, p0, p1, p2, r):
    """Whether the end p of a step lies a radius ``r`` or more in front of every plane of ``planes`` (P, 6): each a
    point and a unit normal (the arithmetic of :func:`_clear`'s planes, so that both decide alike)."""
    for k in range(planes.shape[0]):
        ahead = ((p0 - planes[k, 0]) * planes[k, 3] + (p1 - planes[k, 1]) * planes[k, 4]
                 + (p2 - planes[k, 2]) * planes[k, 5])
        if ahead < r:
            return False
    return True


@njit(cache=True, inline="always")
def _clear(solids, s0, s1, s2, p0, p1, p2, r, gap):
    """Whether the path s → p of a particle of radius ``r`` certainly meets no solid and ends outside them all (so
    that neither a hit nor a push can follow): it ends a radius or more in front of every plane, and stays outside
    a sphere around each sphere and box grown by the radius."""
    travel = -1.0  # the path's length, found at the first solid that needs it (planes do not)
    for k in range(solids.shape[0]):
        c0, c1, c2 = solids[k, CENTRE], solids[k, CENTRE + 1], solids[k, CENTRE + 2]
        if solids[k, SOLID] == SOLID_PLANE:
            ahead = ((p0 - c0) * solids[k, NORMAL] + (p1 - c1) * solids[k, NORMAL + 1]
                     + (p2 - c2) * solids[k, NORMAL + 2])
            if ahead < r:
                return False
        else:
            if solids[k, SOLID] == SOLID_SPHERE:
                reach = solids[k, RADIUS] + r
            else:
                reach = math.sqrt((solids[k, HALF] + r) ** 2 + (solids[k, HALF + 1] + r) ** 2
                                  + (solids[k, HALF + 2] + r) ** 2)
            if travel < 0.0:
                travel = math.sqrt((p0 - s0) ** 2 + (p1 - s1) ** 2 + (p2 - s2) ** 2)
            if math.sqrt((p0 - c0) ** 2 + (p1 - c1) ** 2 + (p2 - c2) ** 2) - travel <= reach + gap:
                return False
    return True


@njit(cache=True)
def _step(i, h, t_to, x, v, a, alive, stuck, mass, radius, birth, lifetime, method, fields, simple, summary,
          solids, mode, max_bounces, gap, gravity, age, collide):
    """One step ``h`` [s] ending at ``t_to`` of particle ``i`` (in place), with everything collisions can do.
    Returns its hits on solids and whether it died. (A call, not inlined: the steps :func:`advance_pool`'s clear
    path leaves to it are few, and its code kept out of that path lets the path stay lean.)"""
    if not alive[i]:
        return 0, False
    hits = 0
    if not stuck[i]:
        r = radius[i]
        s0, s1, s2, p0, p1, p2, u0, u1, u2, c0, c1, c2 = _motion(i, h, x, v, a, mass, radius, method, fields, simple,
                                                                 summary)
        if collide:
            which, fraction, n0, n1, n2 = _first_hit(solids, s0, s1, s2, p0, p1, p2, r)
            if which >= 0:
                p0, p1, p2, u0, u1, u2, hits, fate = _resolve(
                    solids, mode, max_bounces, gap, 2.0 * h * gravity, which, fraction, n0, n1, n2, s0, s1, s2, p0,
                    p1, p2, u0, u1, u2, r, h)
                if fate == 1:
                    stuck[i] = True
                    c0 = c1 = c2 = 0.0
                elif fate == 2:
                    alive[i] = False
            p0, p1, p2, u0, u1, u2 = _push_out(solids, gap, p0, p1, p2, u0, u1, u2, r)
        x[i, 0], x[i, 1], x[i, 2] = p0, p1, p2
        v[i, 0], v[i, 1], v[i, 2] = u0, u1, u2
        a[i, 0], a[i, 1], a[i, 2] = c0, c1, c2
    if alive[i] and age and t_to - birth[i] >= lifetime[i]:
        alive[i] = False
    if not alive[i]:
        stuck[i] = False
        v[i, 0] = v[i, 1] = v[i, 2] = 0.0
        return hits, True
    return hits, False


@njit(cache=True)
def _steps_with_collisions(i, first, times, x, v, a, alive, stuck, mass, radius, birth, lifetime, method, fields,
                           simple, summary, solids, mode, max_bounces, gap, gravity, age, collide):
    """Steps ``first`` … of the call for particle ``i``, each through :func:`_step` (everything collisions can do).
    Returns (hits, 1 if it died else 0). A call, not inlined, made once per particle and call at most: its code kept
    out of :func:`advance_pool`'s loop lets that loop stay lean."""
    hits = 0
    for k in range(first, times.shape[0] - 1):
        hit, died = _step(i, times[k + 1] - times[k], times[k + 1], x, v, a, alive, stuck, mass, radius, birth,
                          lifetime, method, fields, simple, summary, solids, mode, max_bounces, gap, gravity, age,
                          collide)
        hits += hit
        if died:
            return hits, 1
    return hits, 0


@njit(cache=True, parallel=True)
def advance_pool(x, v, a, alive, stuck, mass, radius, birth, lifetime, times, method, fields, solids, planes, others,
                 mode, max_bounces, gap, gravity, age):
    """The steps between the instants ``times`` (S + 1,) [s], for every live, free particle (in place); with
    ``age``, particles die at the end of the step their age reaches their lifetime. ``solids``: every collider;
    ``planes`` (P, 6): its planes, each a point and a unit normal; ``others``: its spheres and boxes (a solid table),
    or None when there are none (a separate compilation without their code: the common emitter meets planes only).
    ``mode``: a MODE_* code; ``gravity``: |g| [m/s²] (normal speeds below 2 h |g| do not bounce). Returns (hits on
    solids, deaths, the earliest instant [s] a live particle dies at: birth + lifetime, inf unless ``age``).

    Each particle is taken through the steps of the call in turn (its state read and written once a step), as long
    as each step's path is clear of every solid (:func:`_planes_clear`, :func:`_clear`): the motion alone. From the
    first step that is not, and for stuck particles, the rest go through :func:`_step` from the same start: the same
    arithmetic, so every particle ends where :func:`_step` alone would put it."""
    hit_total = 0
    death_total = 0
    soonest = np.inf
    collide = mode != MODE_PASS and solids.shape[0] > 0
    simple, summary = field_summary(fields)
    steps = times.shape[0] - 1
    for i in prange(x.shape[0]):
        if not alive[i]:
            continue
        first = 0
        if stuck[i]:  # held: no velocity, no acceleration
            v[i, 0] = v[i, 1] = v[i, 2] = a[i, 0] = a[i, 1] = a[i, 2] = 0.0
        else:
            died = False
            while first < steps:
                h = times[first + 1] - times[first]
                t_to = times[first + 1]
                s0, s1, s2, p0, p1, p2, u0, u1, u2, c0, c1, c2 = _motion(i, h, x, v, a, mass, radius, method,
                                                                         fields, simple, summary)
                if collide:
                    r = radius[i]
                    if not _planes_clear(planes, p0, p1, p2, r) or (
                            others is not None and not _clear(others, s0, s1, s2, p0, p1, p2, r, gap)):
                        break
                x[i, 0], x[i, 1], x[i, 2] = p0, p1, p2
                v[i, 0], v[i, 1], v[i, 2] = u0, u1, u2
                a[i, 0], a[i, 1], a[i, 2] = c0, c1, c2
                first += 1
                if age and t_to - birth[i] >= lifetime[i]:
                    alive[i] = False
                    v[i, 0] = v[i, 1] = v[i, 2] = 0.0
                    died = True
                    break
            if died:  # nothing more for it in this call
                death_total += 1
                continue
        if first < steps:
            hit, died_now = _steps_with_collisions(i, first, times, x, v, a, alive, stuck, mass, radius, birth,
                                                   lifetime, method, fields, simple, summary, solids, mode,
                                                   max_bounces, gap, gravity, age, collide)
            hit_total += hit
            death_total += died_now
        if age and alive[i]:
            soonest = min(soonest, birth[i] + lifetime[i])
    return hit_total, death_total, soonest


@njit(cache=True, parallel=True)
def advance_one(x, v, a, alive, stuck, mass, radius, birth, lifetime, times, method, fields, table, solids, planes,
                rest, mode, max_bounces, gap, gravity, age):
    """:func:`advance_pool` for one step (``times`` (2,) [s]), as a pool with births goes: the same arithmetic and
    results, in a loop made lean for it. ``table`` is ``fields``, or None when :func:`field_summary` covers them (the
    summary's code alone is then compiled in). The first plane of ``planes`` is read once into scalars (a floor,
    mostly); ``rest`` is every other solid as a solid table, or None when there is none. A path that is not clear
    goes to :func:`_step` from inside the loop.

    Measured at 1e6 particles, against this loop with the step loop, with the table's code, with a second pass for
    the paths that are not clear, or with a loop over the planes after the first (even one of no turns): each of
    those cost a tenth to a fifth of the speed."""
    hit_total = 0
    death_total = 0
    soonest = np.inf
    collide = mode != MODE_PASS and solids.shape[0] > 0
    simple, summary = field_summary(fields)
    h = times[1] - times[0]
    t_to = times[1]
    if planes.shape[0] > 0:
        q0, q1, q2, q3, q4, q5 = planes[0, 0], planes[0, 1], planes[0, 2], planes[0, 3], planes[0, 4], planes[0, 5]
    else:  # a plane no path reaches
        q0, q1, q2, q3, q4, q5 = 0.0, -np.inf, 0.0, 0.0, 1.0, 0.0
    for i in prange(x.shape[0]):
        if alive[i]:
            clear = False
            if not stuck[i]:
                s0, s1, s2, p0, p1, p2, u0, u1, u2, c0, c1, c2 = _motion(i, h, x, v, a, mass, radius, method, table,
                                                                         simple, summary)
                r = radius[i]
                clear = not collide or ((p0 - q0) * q3 + (p1 - q1) * q4 + (p2 - q2) * q5 >= r and (
                    rest is None or _clear(rest, s0, s1, s2, p0, p1, p2, r, gap)))
                if clear:
                    x[i, 0], x[i, 1], x[i, 2] = p0, p1, p2
                    v[i, 0], v[i, 1], v[i, 2] = u0, u1, u2
                    a[i, 0], a[i, 1], a[i, 2] = c0, c1, c2
                    if age and t_to - birth[i] >= lifetime[i]:
                        alive[i] = False
                        v[i, 0] = v[i, 1] = v[i, 2] = 0.0
                        death_total += 1
            if not clear:  # stuck, or a path that may meet a solid: everything collisions can do
                if stuck[i]:
                    v[i, 0] = v[i, 1] = v[i, 2] = a[i, 0] = a[i, 1] = a[i, 2] = 0.0
                hit, died = _step(i, h, t_to, x, v, a, alive, stuck, mass, radius, birth, lifetime, method, fields,
                                  simple, summary, solids, mode, max_bounces, gap, gravity, age, collide)
                hit_total += hit
                death_total += died
            if age and alive[i]:
                soonest = min(soonest, birth[i] + lifetime[i])
    return hit_total, death_total, soonest


@njit(cache=True)
def collide_paths(slots, starts, x, v, alive, stuck, radius, solids, mode, max_bounces, gap, gravity, h):
    """The paths ``starts`` (K, 3) → ``x[slots]`` of particles born during a step of ``h`` [s] (few: no threads)
    against the solids (in place). Returns (hits, deaths)."""
    hit_total = 0
    death_total = 0
    if mode == MODE_PASS or solids.shape[0] == 0:
        return hit_total, death_total
    for n in range(slots.shape[0]):
        i = slots[n]
        if not alive[i] or stuck[i]:
            continue
        p0, p1, p2, u0, u1, u2 = x[i, 0], x[i, 1], x[i, 2], v[i, 0], v[i, 1], v[i, 2]
        r = radius[i]
        which, fraction, n0, n1, n2 = _first_hit(solids, starts[n, 0], starts[n, 1], starts[n, 2], p0, p1, p2, r)
        if which >= 0:
            p0, p1, p2, u0, u1, u2, hits, fate = _resolve(
                solids, mode, max_bounces, gap, 2.0 * h * gravity, which, fraction, n0, n1, n2, starts[n, 0],
                starts[n, 1], starts[n, 2], p0, p1, p2, u0, u1, u2, r, h)
            hit_total += hits
            if fate == 1:
                stuck[i] = True
            elif fate == 2:
                alive[i] = False
                death_total += 1
        x[i, 0], x[i, 1], x[i, 2], v[i, 0], v[i, 1], v[i, 2] = _push_out(solids, gap, p0, p1, p2, u0, u1, u2, r)
    return hit_total, death_total


@njit(cache=True, parallel=True)
def age_pool(alive, stuck, v, birth, lifetime, now):
    """Particles whose age at ``now`` [s] reached their lifetime die (in place); returns how many, and the earliest
    instant [s] a particle still alive dies at (birth + lifetime; inf when none is alive)."""
    total = 0
    soonest = np.inf
    for i in prange(alive.shape[0]):
        if alive[i]:
            if now - birth[i] >= lifetime[i]:
                alive[i] = False
                stuck[i] = False
                v[i, 0] = v[i, 1] = v[i, 2] = 0.0
                total += 1
            else:
                soonest = min(soonest, birth[i] + lifetime[i])
    return total, soonest
