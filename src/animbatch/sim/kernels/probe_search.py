"""Compiled probe search: probes (spheres and box corners fixed to bodies) against planes, fixed spheres and boxes,
other bodies' probe spheres and other bodies' boxes, in one call per step. It replaces the per-solid loops of
:func:`animbatch.sim.contact.detection.detect` (a k-d tree query, then a dozen small numpy operations per solid) for
scenes with few probes (:data:`animbatch.sim.contact.detection.COMPILED_PROBES`): the pairs are tested all against
all, with the k-d tree's own reach, so the candidates are the numpy search's.

Each candidate is measured as the numpy code measures it (:func:`~animbatch.sim.contact.geometry.to_sphere`,
``to_box``, ``separating_direction``, ``to_box_face``), in the same order of operations, so the distances and
normals agree to round-off; a candidate is kept as the numpy side keeps it
(:func:`~animbatch.sim.contact.detection.closing_margin`: its gap below the margin plus how far both bodies can
travel, ``travel`` (P,) [m]), with the same arithmetic, so only contacts come back.

Arrays: probes ``centres`` (Q, 3) [m], ``owner``, ``box`` (Q,) (the body box whose corner a probe is, or −1),
``radius`` (Q,) [m], ``active`` (Q,) bool; per body ``group`` (P,) (−1: none), ``material`` (P,), ``collides`` (P,)
bool; ``excluded`` sorted int64 keys ``low · P + high`` of body pairs that never touch. Solids: planes (point,
normal, material), fixed spheres (centre, radius, material), fixed boxes and body boxes (centre (X, 3), rotation
(X, 3, 3) box-to-world, half sides (X, 3), material or owner).
Found (the contacts): integer rows (K, 5) ``probe, solid body, solid material, kind, solid index`` and float rows (K, 4)
``distance`` [m] of the probe's centre to the solid, outward ``normal`` (3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: The contact kinds of animbatch.sim.contact.contacts (a kernel may not import it; the tests check they agree).
PLANE, STATIC_SPHERE, STATIC_BOX, BODY_SPHERE, BODY_BOX, STATIC_BOX_FACE, BODY_BOX_FACE = 0, 1, 2, 4, 5, 6, 7
BODY_ROUND, BODY_HULL = 11, 12
STATIC = -1


@njit(cache=True, error_model="numpy")
def grown(ints: np.ndarray, floats: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The tables of found rows (integer and float columns) with room for row ``count``: doubled when full."""
    if count < len(ints):
        return ints, floats
    more_ints = np.empty((2 * len(ints), ints.shape[1]), np.int64)
    more_floats = np.empty((2 * len(ints), floats.shape[1]))
    for k in range(count):
        for c in range(ints.shape[1]):
            more_ints[k, c] = ints[k, c]
        for c in range(floats.shape[1]):
            more_floats[k, c] = floats[k, c]
    return more_ints, more_floats


@njit(cache=True, error_model="numpy", inline="always")
def _add(ints: np.ndarray, floats: np.ndarray, count: int, probe: int, body: int, material: int, kind: int,
         index: int, distance: float, n0: float, n1: float, n2: float) -> tuple[np.ndarray, np.ndarray]:
    """Row ``count`` of the contacts."""
    if count >= len(ints):
        ints, floats = grown(ints, floats, count)
    ints[count, 0], ints[count, 1], ints[count, 2], ints[count, 3], ints[count, 4] = probe, body, material, kind, index
    floats[count, 0], floats[count, 1], floats[count, 2], floats[count, 3] = distance, n0, n1, n2
    return ints, floats


@njit(cache=True, error_model="numpy")
def _near(point: np.ndarray, centre: np.ndarray, reach: float) -> bool:
    """Whether ``point`` lies within ``reach`` of ``centre`` (the k-d tree's ball query)."""
    d0, d1, d2 = point[0] - centre[0], point[1] - centre[1], point[2] - centre[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) <= reach


@njit(cache=True, error_model="numpy", inline="always")
def _far(q: int, centres: np.ndarray, c0: float, c1: float, c2: float, reach: float) -> bool:
    """Whether probe q lies beyond ``reach`` of the point (c0, c1, c2): :func:`_near`'s test on numbers, inlined into
    the loops over probes, which it lets skip most probes without a call (a call that passes arrays costs more than
    the test: numba counts references to each array it passes)."""
    d0, d1, d2 = centres[q, 0] - c0, centres[q, 1] - c1, centres[q, 2] - c2
    return not math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) <= reach


@njit(cache=True, error_model="numpy")
def _allowed(first: int, second: int, excluded: np.ndarray, body_count: int) -> bool:
    """Whether two bodies may touch: their key is not among the sorted ``excluded``."""
    key = min(first, second) * body_count + max(first, second)
    at = np.searchsorted(excluded, key)
    return not (at < len(excluded) and excluded[at] == key)


@njit(cache=True, error_model="numpy")
def _touchable(q: int, body: int, owner: np.ndarray, active: np.ndarray, centres: np.ndarray, centre: np.ndarray,
               reach: float, excluded: np.ndarray, body_count: int) -> bool:
    """Whether probe q may touch a solid of ``body`` around ``centre``: another body's, active, within ``reach`` [m]
    (the k-d tree's ball query), and no joint holds the two."""
    return (owner[q] != body and active[q] and _near(centres[q], centre, reach)
            and _allowed(body, owner[q], excluded, body_count))


@njit(cache=True, error_model="numpy")
def _local(point: np.ndarray, centre: np.ndarray, rotation: np.ndarray) -> tuple[float, float, float]:
    """``Rᵀ (p − c)``."""
    d0, d1, d2 = point[0] - centre[0], point[1] - centre[1], point[2] - centre[2]
    return (rotation[0, 0] * d0 + rotation[1, 0] * d1 + rotation[2, 0] * d2,
            rotation[0, 1] * d0 + rotation[1, 1] * d1 + rotation[2, 1] * d2,
            rotation[0, 2] * d0 + rotation[1, 2] * d1 + rotation[2, 2] * d2)


@njit(cache=True, error_model="numpy")
def _to_box(point: np.ndarray, centre: np.ndarray, rotation: np.ndarray, half: np.ndarray
            ) -> tuple[float, float, float, float]:
    """Signed distance of a point to a box and the outward normal (world axes); inside, the nearest face's. (On
    numbers, not small arrays: a box test is made for every probe near every box, and an array each costs more.)"""
    x0, x1, x2 = _local(point, centre, rotation)
    o0 = x0 - min(max(x0, -half[0]), half[0])
    o1 = x1 - min(max(x1, -half[1]), half[1])
    o2 = x2 - min(max(x2, -half[2]), half[2])
    distance = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    if distance > 1e-12:
        l0, l1, l2 = o0 / distance, o1 / distance, o2 / distance
        signed = distance
    else:  # inside: leave through the nearest face (the first of equals)
        l0 = l1 = l2 = 0.0
        least = half[0] - abs(x0)
        axis = 0
        if half[1] - abs(x1) < least:
            axis, least = 1, half[1] - abs(x1)
        if half[2] - abs(x2) < least:
            axis, least = 2, half[2] - abs(x2)
        if axis == 0:
            l0 = 1.0 if x0 >= 0 else -1.0
        elif axis == 1:
            l1 = 1.0 if x1 >= 0 else -1.0
        else:
            l2 = 1.0 if x2 >= 0 else -1.0
        signed = -least
    return (signed, rotation[0, 0] * l0 + rotation[0, 1] * l1 + rotation[0, 2] * l2,
            rotation[1, 0] * l0 + rotation[1, 1] * l1 + rotation[1, 2] * l2,
            rotation[2, 0] * l0 + rotation[2, 1] * l1 + rotation[2, 2] * l2)


@njit(cache=True, error_model="numpy")
def _extent(a0: float, a1: float, a2: float, rotation: np.ndarray, half: np.ndarray) -> float:
    """How far a box (rotation box-to-world, half sides) reaches from its centre along a unit axis (a0, a1, a2)."""
    reach = 0.0
    for j in range(3):
        reach += abs(a0 * rotation[0, j] + a1 * rotation[1, j] + a2 * rotation[2, j]) * half[j]
    return reach


@njit(cache=True, error_model="numpy")
def _separating_direction(centre_a: np.ndarray, rotation_a: np.ndarray, half_a: np.ndarray, centre_b: np.ndarray,
                          rotation_b: np.ndarray, half_b: np.ndarray) -> tuple[float, float, float]:
    """The unit direction from box b towards box a along the face axis (of either) on which they overlap least."""
    best, best_value, best_along = 0, np.inf, 0.0
    for m in range(6):
        if m < 3:
            a0, a1, a2 = rotation_a[0, m], rotation_a[1, m], rotation_a[2, m]
        else:
            a0, a1, a2 = rotation_b[0, m - 3], rotation_b[1, m - 3], rotation_b[2, m - 3]
        reach = _extent(a0, a1, a2, rotation_a, half_a) + _extent(a0, a1, a2, rotation_b, half_b)
        along = a0 * (centre_a[0] - centre_b[0]) + a1 * (centre_a[1] - centre_b[1]) + a2 * (centre_a[2] - centre_b[2])
        if reach - abs(along) < best_value:
            best, best_value, best_along = m, reach - abs(along), along
    sign = 1.0 if best_along >= 0 else -1.0
    rotation = rotation_a if best < 3 else rotation_b
    column = best if best < 3 else best - 3
    return sign * rotation[0, column], sign * rotation[1, column], sign * rotation[2, column]


@njit(cache=True, error_model="numpy", inline="always")
def _box_measure(probe: int, centres: np.ndarray, box: np.ndarray, centre: np.ndarray, rotation: np.ndarray,
                 half: np.ndarray, kinds: tuple[int, int], index: int, box_centre: np.ndarray,
                 box_rotation: np.ndarray, box_half: np.ndarray, tolerance: float
                 ) -> tuple[float, float, float, float, int, int]:
    """Probe against one box: a corner of another box against the face the two boxes' separating axis picks (when
    it lies within that face's extent, to ``tolerance``), anything else against the box as a whole. The distance,
    the outward normal, the contact kind and the solid index."""
    point = centres[probe]
    distance, n0, n1, n2 = _to_box(point, centre, rotation, half)
    kind, solid = kinds[0], index
    own = box[probe]
    if own >= 0:
        d0, d1, d2 = _separating_direction(box_centre[own], box_rotation[own], box_half[own], centre, rotation, half)
        local_direction = (rotation[0, 0] * d0 + rotation[1, 0] * d1 + rotation[2, 0] * d2,  # Rᵀ d
                           rotation[0, 1] * d0 + rotation[1, 1] * d1 + rotation[2, 1] * d2,
                           rotation[0, 2] * d0 + rotation[1, 2] * d1 + rotation[2, 2] * d2)
        axis = 0
        for i in range(1, 3):
            if abs(local_direction[i]) > abs(local_direction[axis]):
                axis = i
        positive = local_direction[axis] >= 0
        local = _local(point, centre, rotation)
        on_face = True
        for i in range(3):
            if i != axis and abs(local[i]) - half[i] > tolerance:
                on_face = False
        if on_face:
            sign = 1.0 if positive else -1.0
            distance = sign * local[axis] - half[axis]
            n0, n1, n2 = rotation[0, axis] * sign, rotation[1, axis] * sign, rotation[2, axis] * sign
            kind, solid = kinds[1], 6 * index + 2 * axis + (1 if positive else 0)
    return distance, n0, n1, n2, kind, solid


@njit(cache=True, error_model="numpy")
def _near_bodies(centres: np.ndarray, owner: np.ndarray, body_count: int, reach: float) -> np.ndarray:
    """Which pairs of bodies (P, P) (first index the lower) may have probes within ``reach`` [m] of each other: the
    ball around each body's first probe that holds all its probes, against the other's, with a little to spare for
    rounding. It lets the all-pairs probe loop skip the probes of bodies that are apart, without changing what it
    finds."""
    anchor = np.zeros((body_count, 3))
    extent = np.full(body_count, -1.0)  # −1: no probe
    for q in range(len(owner)):
        body = owner[q]
        if extent[body] < 0:
            anchor[body, 0], anchor[body, 1], anchor[body, 2], extent[body] = centres[q, 0], centres[q, 1], \
                centres[q, 2], 0.0
        d0, d1, d2 = centres[q, 0] - anchor[body, 0], centres[q, 1] - anchor[body, 1], centres[q, 2] - anchor[body, 2]
        extent[body] = max(extent[body], math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
    near = np.zeros((body_count, body_count), np.bool_)
    for a in range(body_count):
        if extent[a] < 0:
            continue
        for b in range(a, body_count):
            if extent[b] < 0:
                continue
            d0, d1, d2 = anchor[a, 0] - anchor[b, 0], anchor[a, 1] - anchor[b, 1], anchor[a, 2] - anchor[b, 2]
            gap = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - extent[a] - extent[b]
            near[a, b] = gap <= reach + 1e-9 * (1.0 + reach + extent[a] + extent[b])
    return near


@njit(cache=True, error_model="numpy")
def probe_candidates(centres: np.ndarray, owner: np.ndarray, box: np.ndarray, radius: np.ndarray,
                     active: np.ndarray, group: np.ndarray, material: np.ndarray, collides: np.ndarray,
                     excluded: np.ndarray, plane_point: np.ndarray, plane_normal: np.ndarray,
                     plane_material: np.ndarray, sphere_centre: np.ndarray, sphere_radius: np.ndarray,
                     sphere_material: np.ndarray, static_centre: np.ndarray, static_rotation: np.ndarray,
                     static_half: np.ndarray, static_material: np.ndarray, box_owner: np.ndarray,
                     box_centre: np.ndarray, box_rotation: np.ndarray, box_half: np.ndarray, round_owner: np.ndarray,
                     round_centre: np.ndarray, round_axis: np.ndarray, round_half_length: np.ndarray,
                     round_radius: np.ndarray, round_rounded: np.ndarray, hull_owner: np.ndarray,
                     hull_reach: np.ndarray, hull_centre: np.ndarray, hull_rotation: np.ndarray,
                     hull_vertices: np.ndarray, hull_vertex_start: np.ndarray, hull_triangles: np.ndarray,
                     hull_triangle_start: np.ndarray, hull_planes: np.ndarray, hull_plane_start: np.ndarray,
                     bodies_collide: bool, margin: float, largest_travel: float, travel: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Every probe–solid pair the numpy search measures (see the module notes) that it keeps as a contact (within
    ``margin`` [m] plus what both bodies can travel, ``travel`` (P,) [m]; ``largest_travel`` its largest), measured,
    in its order: planes, fixed spheres, fixed boxes, then (``bodies_collide``) probe spheres, body boxes and round
    solids (cylinders and capsules: ``round_*`` (C,) owner, centre and unit axis (C, 3) [m], half length of the
    straight part [m], radius [m], whether capsule) and convex hulls (``hull_*`` (H,) owner, reach [m], centre
    (H, 3) [m] and rotation (H, 3, 3) of the owner; packed vertices (V, 3) [m] and triangles (T, 3) (vertex numbers
    within the hull) in body axes, face planes (F, 4) ``n, d`` (inside: ``n · x ≤ d``), each with its start table
    (H + 1,))."""
    body_count = len(material)
    widest = 0.0
    for q in range(len(radius)):
        widest = max(widest, radius[q])
    reach = margin + largest_travel + widest  # the fixed solids' k-d tree reach
    tolerance = margin + 2 * largest_travel  # a corner within this of a face's extent is on it
    ints = np.empty((64, 5), np.int64)
    floats = np.empty((64, 4))
    count = 0
    # a pair is kept as the numpy side keeps it (closing_margin): its gap below the margin plus what both sides travel
    for k in range(len(plane_point)):
        for q in range(len(owner)):
            if active[q]:
                distance = ((centres[q, 0] - plane_point[k, 0]) * plane_normal[k, 0]
                            + (centres[q, 1] - plane_point[k, 1]) * plane_normal[k, 1]
                            + (centres[q, 2] - plane_point[k, 2]) * plane_normal[k, 2])
                if distance - radius[q] < margin + travel[owner[q]] + 0.0:
                    ints, floats = _add(ints, floats, count, q, STATIC, plane_material[k], PLANE, k, distance,
                                        plane_normal[k, 0], plane_normal[k, 1], plane_normal[k, 2])
                    count += 1
    for k in range(len(sphere_centre)):
        c0, c1, c2 = sphere_centre[k, 0], sphere_centre[k, 1], sphere_centre[k, 2]
        for q in range(len(owner)):
            if active[q] and not _far(q, centres, c0, c1, c2, sphere_radius[k] + reach):
                distance, n0, n1, n2 = _sphere_measure(q, centres, c0, c1, c2, sphere_radius[k])
                if distance - radius[q] < margin + travel[owner[q]] + 0.0:
                    ints, floats = _add(ints, floats, count, q, STATIC, sphere_material[k], STATIC_SPHERE, k,
                                        distance, n0, n1, n2)
                    count += 1
    for k in range(len(static_centre)):
        size = math.sqrt(static_half[k, 0] ** 2 + static_half[k, 1] ** 2 + static_half[k, 2] ** 2)
        c0, c1, c2 = static_centre[k, 0], static_centre[k, 1], static_centre[k, 2]
        for q in range(len(owner)):
            if active[q] and not _far(q, centres, c0, c1, c2, size + reach):
                distance, n0, n1, n2, kind, solid = _box_measure(
                    q, centres, box, static_centre[k], static_rotation[k], static_half[k],
                    (STATIC_BOX, STATIC_BOX_FACE), k, box_centre, box_rotation, box_half, tolerance)
                if distance - radius[q] < margin + travel[owner[q]] + 0.0:
                    ints, floats = _add(ints, floats, count, q, STATIC, static_material[k], kind, solid, distance,
                                        n0, n1, n2)
                    count += 1
    if not bodies_collide or not len(owner):
        return ints[:count], floats[:count]
    closing = margin + 2 * largest_travel  # both sides move
    rounded = np.flatnonzero(radius > 0)  # only a probe with a radius can be met by another (box corners have none)
    near = _near_bodies(centres, owner, body_count, 2 * widest + closing)
    for i in range(len(owner)):
        a = owner[i]
        for slot in range(np.searchsorted(rounded, i, side="right"), len(rounded)):
            j = int(rounded[slot])
            b = owner[j]
            if not near[min(a, b), max(a, b)]:
                continue
            if (a == b or not active[i] or not active[j] or radius[j] <= 0
                    or _far(i, centres, centres[j, 0], centres[j, 1], centres[j, 2], 2 * widest + closing)
                    or not _allowed(a, b, excluded, body_count)
                    or (group[a] >= 0 and group[a] == group[b])):
                continue
            distance, n0, n1, n2 = _sphere_measure(i, centres, centres[j, 0], centres[j, 1], centres[j, 2],
                                                   radius[j])
            if distance - radius[i] < margin + travel[a] + travel[b]:
                ints, floats = _add(ints, floats, count, i, b, material[b], BODY_SPHERE, j, distance, n0, n1, n2)
                count += 1
    for k in range(len(box_owner)):
        body = box_owner[k]
        if not collides[body]:
            continue
        size = math.sqrt(box_half[k, 0] ** 2 + box_half[k, 1] ** 2 + box_half[k, 2] ** 2)
        for q in range(len(owner)):
            if _far(q, centres, box_centre[k, 0], box_centre[k, 1], box_centre[k, 2], size + closing + widest):
                continue
            if _touchable(q, body, owner, active, centres, box_centre[k], size + closing + widest, excluded,
                          body_count):
                distance, n0, n1, n2, kind, solid = _box_measure(
                    q, centres, box, box_centre[k], box_rotation[k], box_half[k], (BODY_BOX, BODY_BOX_FACE), k,
                    box_centre, box_rotation, box_half, tolerance)
                if distance - radius[q] < margin + travel[owner[q]] + travel[body]:
                    ints, floats = _add(ints, floats, count, q, body, material[body], kind, solid, distance, n0, n1,
                                        n2)
                    count += 1
    for k in range(len(round_owner)):
        body = round_owner[k]
        if not collides[body]:
            continue
        for q in range(len(owner)):
            if _far(q, centres, round_centre[k, 0], round_centre[k, 1], round_centre[k, 2],
                    round_half_length[k] + round_radius[k] + closing + widest):
                continue
            if _touchable(q, body, owner, active, centres, round_centre[k],
                          round_half_length[k] + round_radius[k] + closing + widest, excluded, body_count):
                distance, n0, n1, n2 = _to_round(centres[q], round_centre[k], round_axis[k], round_half_length[k],
                                                 round_radius[k], round_rounded[k])
                if distance - radius[q] < margin + travel[owner[q]] + travel[body]:
                    ints, floats = _add(ints, floats, count, q, body, material[body], BODY_ROUND, k, distance, n0,
                                        n1, n2)
                    count += 1
    for k in range(len(hull_owner)):
        body = hull_owner[k]
        if not collides[body]:
            continue
        for q in range(len(owner)):
            if _far(q, centres, hull_centre[k, 0], hull_centre[k, 1], hull_centre[k, 2],
                    hull_reach[k] + closing + widest):
                continue
            if _touchable(q, body, owner, active, centres, hull_centre[k], hull_reach[k] + closing + widest,
                          excluded, body_count):
                distance, n0, n1, n2 = _to_hull(
                    centres[q], hull_centre[k], hull_rotation[k],
                    hull_vertices[hull_vertex_start[k]:hull_vertex_start[k + 1]],
                    hull_triangles[hull_triangle_start[k]:hull_triangle_start[k + 1]],
                    hull_planes[hull_plane_start[k]:hull_plane_start[k + 1]])
                if distance - radius[q] < margin + travel[owner[q]] + travel[body]:
                    ints, floats = _add(ints, floats, count, q, body, material[body], BODY_HULL, k, distance, n0,
                                        n1, n2)
                    count += 1
    return ints[:count], floats[:count]


@njit(cache=True, error_model="numpy")
def _to_hull(point: np.ndarray, centre: np.ndarray, rotation: np.ndarray, vertices: np.ndarray,
             triangles: np.ndarray, planes: np.ndarray) -> tuple[float, float, float, float]:
    """Signed distance of a point to a convex hull and the outward normal (world axes), as
    :func:`animbatch.sim.contact.hulls.to_hull`: inside, the nearest face's plane; outside, the nearest
    triangle."""
    l0, l1, l2 = _local(point, centre, rotation)
    face, distance = 0, -np.inf
    for f in range(len(planes)):
        height = planes[f, 0] * l0 + planes[f, 1] * l1 + planes[f, 2] * l2 - planes[f, 3]
        if height > distance:
            face, distance = f, height
    m0, m1, m2 = planes[face, 0], planes[face, 1], planes[face, 2]
    if distance > 0:  # to the nearest triangle: exact near edges and corners too
        distance = np.inf
        for t in range(len(triangles)):
            d, t0, t1, t2 = _to_triangle(l0, l1, l2, vertices, triangles[t, 0], triangles[t, 1], triangles[t, 2])
            if d < distance:
                distance, m0, m1, m2 = d, t0, t1, t2
    return (distance, rotation[0, 0] * m0 + rotation[0, 1] * m1 + rotation[0, 2] * m2,
            rotation[1, 0] * m0 + rotation[1, 1] * m1 + rotation[1, 2] * m2,
            rotation[2, 0] * m0 + rotation[2, 1] * m1 + rotation[2, 2] * m2)


@njit(cache=True, error_model="numpy", inline="always")
def _to_triangle(p0: float, p1: float, p2: float, vertices: np.ndarray, ia: int, ib: int, ic: int
                 ) -> tuple[float, float, float, float]:
    """Unsigned distance of a point (p0, p1, p2) to the triangle of ``vertices`` ia, ib, ic and the unit direction
    from its closest point to the point (the face normal, towards the point, on it), as
    :func:`animbatch.sim.contact.geometry.to_triangles` without sides (Ericson, "Real-Time Collision Detection",
    5.1.5). On numbers: it runs for every triangle of a hull near a probe, and small arrays each cost an
    allocation."""
    a0, a1, a2 = vertices[ia, 0], vertices[ia, 1], vertices[ia, 2]
    b0, b1, b2 = vertices[ib, 0], vertices[ib, 1], vertices[ib, 2]
    c0, c1, c2 = vertices[ic, 0], vertices[ic, 1], vertices[ic, 2]
    ab0, ab1, ab2 = b0 - a0, b1 - a1, b2 - a2
    ac0, ac1, ac2 = c0 - a0, c1 - a1, c2 - a2
    ap0, ap1, ap2 = p0 - a0, p1 - a1, p2 - a2
    bp0, bp1, bp2 = p0 - b0, p1 - b1, p2 - b2
    cp0, cp1, cp2 = p0 - c0, p1 - c1, p2 - c2
    d1, d2 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2, ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    d3, d4 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2, ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    d5, d6 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2, ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    if d1 <= 0 and d2 <= 0:
        q0, q1, q2 = a0, a1, a2
    elif d3 >= 0 and d4 <= d3:
        q0, q1, q2 = b0, b1, b2
    elif d6 >= 0 and d5 <= d6:
        q0, q1, q2 = c0, c1, c2
    elif vc <= 0 and d1 >= 0 and d3 <= 0:
        w = d1 / (d1 - d3)
        q0, q1, q2 = a0 + ab0 * w, a1 + ab1 * w, a2 + ab2 * w
    elif vb <= 0 and d2 >= 0 and d6 <= 0:
        w = d2 / (d2 - d6)
        q0, q1, q2 = a0 + ac0 * w, a1 + ac1 * w, a2 + ac2 * w
    elif va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        q0, q1, q2 = b0 + (c0 - b0) * w, b1 + (c1 - b1) * w, b2 + (c2 - b2) * w
    else:
        denominator = 1.0 / (va + vb + vc)
        v, w = vb * denominator, vc * denominator
        q0, q1, q2 = a0 + ab0 * v + ac0 * w, a1 + ab1 * v + ac1 * w, a2 + ab2 * v + ac2 * w
    o0, o1, o2 = p0 - q0, p1 - q1, p2 - q2
    distance = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    if distance > 1e-9:
        return distance, o0 / distance, o1 / distance, o2 / distance
    f0, f1, f2 = ab1 * ac2 - ab2 * ac1, ab2 * ac0 - ab0 * ac2, ab0 * ac1 - ab1 * ac0
    size = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    f0, f1, f2 = f0 / size, f1 / size, f2 / size
    side = 1.0 if f0 * ap0 + f1 * ap1 + f2 * ap2 >= 0 else -1.0
    return distance, side * f0, side * f1, side * f2


@njit(cache=True, error_model="numpy")
def _to_round(point: np.ndarray, centre: np.ndarray, axis: np.ndarray, half_length: float, radius: float,
              rounded: bool) -> tuple[float, float, float, float]:
    """Signed distance of a point to a cylinder (flat ends) or a capsule (``rounded``) and the outward normal, as
    :func:`animbatch.sim.contact.geometry.to_round`."""
    o0, o1, o2 = point[0] - centre[0], point[1] - centre[1], point[2] - centre[2]
    along = o0 * axis[0] + o1 * axis[1] + o2 * axis[2]
    r0, r1, r2 = o0 - along * axis[0], o1 - along * axis[1], o2 - along * axis[2]
    rho = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    # across the axis from a point on it: any direction across will do
    h0, h1, h2 = (1.0, 0.0, 0.0) if abs(axis[0]) < 0.9 else (0.0, 1.0, 0.0)
    f0, f1, f2 = axis[1] * h2 - axis[2] * h1, axis[2] * h0 - axis[0] * h2, axis[0] * h1 - axis[1] * h0
    size = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    f0, f1, f2 = f0 / size, f1 / size, f2 / size
    if rounded:
        along_clipped = min(max(along, -half_length), half_length)
        d0 = point[0] - (centre[0] + along_clipped * axis[0])
        d1 = point[1] - (centre[1] + along_clipped * axis[1])
        d2 = point[2] - (centre[2] + along_clipped * axis[2])
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if abs(along) <= half_length and rho <= 1e-12:
            return length - radius, f0, f1, f2
        if length > 1e-12:
            return length - radius, d0 / length, d1 / length, d2 / length
        return length - radius, 0.0, 1.0, 0.0
    if rho > 1e-12:
        u0, u1, u2 = r0 / rho, r1 / rho, r2 / rho
    else:
        u0, u1, u2 = f0, f1, f2
    sign = 1.0 if along > 0 else (-1.0 if along < 0 else 0.0)
    if abs(along) > 0:
        e0, e1, e2 = sign * axis[0], sign * axis[1], sign * axis[2]
    else:
        e0, e1, e2 = axis[0], axis[1], axis[2]
    d_rho, d_along = rho - radius, abs(along) - half_length
    out_rho, out_along = max(d_rho, 0.0), max(d_along, 0.0)
    rim = math.hypot(out_rho, out_along)
    if rim > 0:
        return (rim, (out_rho * u0 + out_along * e0) / rim, (out_rho * u1 + out_along * e1) / rim,
                (out_rho * u2 + out_along * e2) / rim)
    if d_rho >= d_along:
        return max(d_rho, d_along), u0, u1, u2
    return max(d_rho, d_along), e0, e1, e2


@njit(cache=True, error_model="numpy", inline="always")
def _sphere_measure(q: int, centres: np.ndarray, c0: float, c1: float, c2: float, radius: float
                    ) -> tuple[float, float, float, float]:
    """Probe q against a sphere (centre (c0, c1, c2), ``radius``): the distance of its centre to the sphere and
    the outward normal ((0, 1, 0) at the centre)."""
    d0, d1, d2 = centres[q, 0] - c0, centres[q, 1] - c1, centres[q, 2] - c2
    length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if length > 1e-12:
        return length - radius, d0 / length, d1 / length, d2 / length
    return length - radius, 0.0, 1.0, 0.0
