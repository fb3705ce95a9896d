"""Compiled side contacts of round solids (cylinders, rods, capsules): :func:`animbatch.sim.contact.sides.side_contacts`
in one call per step, the grid searches along each segment (:func:`~animbatch.sim.contact.sides.nearest_stretch`)
done pair by pair instead of as a few dozen numpy calls over all pairs.

Every value is computed as the numpy code computes it, point by point (``round_distance``, ``to_round``,
``segment_distance``), and the searches take the same grid (``spacing``), so the contacts are the numpy ones to
round-off; they come in another order (pair by pair, not all first ends then all second ends), which the contact
solver does not depend on.

Arrays: rounds (C,) ``centre``, ``axis`` (C, 3) [m], ``half_length``, ``radius`` [m], ``rounded`` (capsule), ``owner``;
per body (P,) ``collides``, ``material``, ``travel`` [m]; ``excluded`` sorted int64 keys of body pairs that never
touch; edges (E,) ``edge_start``, ``edge_end`` (E, 3) [m], ``edge_body`` (−1: fixed), ``edge_material``,
``edge_number``. Found: integer rows (K, 6) ``probe body, solid body, solid material, kind, solid index, probe`` and
float rows (K, 7) ``point`` (3) [m], ``normal`` (3) (from the solid towards the round), ``gap`` [m].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels.probe_search import _allowed, _to_round, grown

#: The constants of animbatch.sim.contact (a kernel may not import it; the tests check they agree).
SIDE_ROUND, SIDE_EDGE = 13, 14
NEAREST_PASSES, END_PASSES = 5, 4
SHORT_STRETCH = 1e-3


@njit(cache=True, error_model="numpy", inline="always")
def _round_distance(p0: float, p1: float, p2: float, centre: np.ndarray, axis: np.ndarray, half_length: float,
                    radius: float, rounded: bool) -> float:
    """The signed distance of a point to a cylinder or capsule, as ``geometry.round_distance``."""
    o0, o1, o2 = p0 - centre[0], p1 - centre[1], p2 - centre[2]
    along = o0 * axis[0] + o1 * axis[1] + o2 * axis[2]
    rho = math.sqrt(max(o0 * o0 + o1 * o1 + o2 * o2 - along * along, 0.0))
    d_rho, d_along = rho - radius, abs(along) - half_length
    if rounded:
        return math.hypot(rho, max(d_along, 0.0)) - radius
    if d_rho > 0 and d_along > 0:
        return math.hypot(d_rho, d_along)
    return max(d_rho, d_along)


@njit(cache=True, error_model="numpy", inline="always")
def _segment_gap(a0: float, a1: float, a2: float, u0: float, u1: float, u2: float, c0: float, c1: float, c2: float,
                 w0: float, w1: float, w2: float) -> float:
    """The distance between the segments ``a + s u`` and ``c + t w`` (s, t in [0, 1]), as
    ``geometry.segment_distance``, on numbers (inlined: the loops test every round against every edge with it)."""
    b0, b1, b2 = a0 - c0, a1 - c1, a2 - c2
    aa = u0 * u0 + u1 * u1 + u2 * u2
    ee = w0 * w0 + w1 * w1 + w2 * w2
    bb = u0 * w0 + u1 * w1 + u2 * w2
    cc = u0 * b0 + u1 * b1 + u2 * b2
    ff = w0 * b0 + w1 * b1 + w2 * b2
    denominator = aa * ee - bb * bb
    s = min(max((bb * ff - cc * ee) / denominator, 0.0), 1.0) if denominator > 1e-12 * aa * ee else 0.0
    t = (bb * s + ff) / ee
    if t < 0:
        s = min(max(-cc / aa, 0.0), 1.0)
    elif t > 1:
        s = min(max((bb - cc) / aa, 0.0), 1.0)
    t = min(max(t, 0.0), 1.0)
    d0 = a0 + s * u0 - c0 - t * w0
    d1 = a1 + s * u1 - c1 - t * w1
    d2 = a2 + s * u2 - c2 - t * w2
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(cache=True, error_model="numpy", inline="always")
def _round_segment_gap(k: int, centre: np.ndarray, axis: np.ndarray, half_length: np.ndarray, c0: float, c1: float,
                       c2: float, w0: float, w1: float, w2: float) -> float:
    """The distance between round k's segment (its axis between its ends) and the segment ``c + t w``."""
    length = 2 * half_length[k]
    return _segment_gap(centre[k, 0] - half_length[k] * axis[k, 0], centre[k, 1] - half_length[k] * axis[k, 1],
                        centre[k, 2] - half_length[k] * axis[k, 2], length * axis[k, 0], length * axis[k, 1],
                        length * axis[k, 2], c0, c1, c2, w0, w1, w2)


@njit(cache=True, error_model="numpy", inline="always")
def _gap(u: float, start: np.ndarray, along: np.ndarray, thickness: float, centre: np.ndarray, axis: np.ndarray,
         half_length: float, radius: float, rounded: bool) -> float:
    """The gap between the round and the segment's point at ``u``, thickened by ``thickness``."""
    return _round_distance(start[0] + u * along[0], start[1] + u * along[1], start[2] + u * along[2], centre, axis,
                           half_length, radius, rounded) - thickness


@njit(cache=True, error_model="numpy")
def _stretch(start: np.ndarray, along: np.ndarray, thickness: float, centre: np.ndarray, axis: np.ndarray,
             half_length: float, radius: float, rounded: bool, reach: float, spacing: np.ndarray
             ) -> tuple[float, float]:
    """``nearest_stretch`` for one segment against one round: the ends (u) of the stretch within reach, or its
    nearest point and NaN for a short one, or NaN and NaN."""
    grid = len(spacing)
    u = np.empty(grid)
    f = np.empty(grid)
    low, high = 0.0, 1.0
    best = 0
    for _ in range(NEAREST_PASSES):
        for i in range(grid):
            u[i] = low + (high - low) * spacing[i]
            f[i] = _gap(u[i], start, along, thickness, centre, axis, half_length, radius, rounded)
        best = 0
        for i in range(1, grid):
            if f[i] < f[best]:
                best = i
        low, high = u[max(best - 1, 0)], u[min(best + 1, grid - 1)]
    nearest, least = u[best], f[best]
    if not least < reach:
        return np.nan, np.nan
    level = least + 0.1 * reach
    ends = np.empty(2)
    for side in range(2):  # from the segment's start up to the nearest point, and from its end back down to it
        outer, inner = float(side), nearest
        ends_below = _gap(outer, start, along, thickness, centre, axis, half_length, radius, rounded) <= level
        for _ in range(END_PASSES):
            inside = 0
            found = False
            for i in range(grid):
                u[i] = outer + (inner - outer) * spacing[i]
                f[i] = _gap(u[i], start, along, thickness, centre, axis, half_length, radius, rounded)
                if not found and f[i] <= level:
                    inside, found = i, True
            outer, inner = u[max(inside - 1, 0)], u[inside]
        ends[side] = float(side) if ends_below else inner
    if ends[1] - ends[0] < SHORT_STRETCH:
        return nearest, np.nan
    return ends[0], ends[1]


@njit(cache=True, error_model="numpy")
def _touching(ints: np.ndarray, floats: np.ndarray, count: int, k: int, centre: np.ndarray, axis: np.ndarray,
              half_length: np.ndarray, radius: np.ndarray, rounded: np.ndarray, owner: np.ndarray,
              other_start: np.ndarray, other_along: np.ndarray, other_radius: float, other_body: int,
              other_material: int, kind: int, index: int, probe: int, reach: float, spacing: np.ndarray,
              ends: bool) -> tuple[np.ndarray, np.ndarray, int]:
    """The contacts of round k's solid with one thickened segment (see ``sides._touching``), which the caller found
    within ``reach`` of it (:func:`_round_segment_gap`: the test made first, inline, since most segments are far)."""
    first, second = _stretch(other_start, other_along, other_radius, centre[k], axis[k], half_length[k], radius[k],
                             rounded[k], reach, spacing)
    for end in range(2):
        u = first if end == 0 else second
        if not np.isfinite(u) or (not ends and not (1e-6 < u < 1 - 1e-6)):
            continue
        p = np.empty(3)
        for i in range(3):
            p[i] = other_start[i] + u * other_along[i]
        distance, n0, n1, n2 = _to_round(p, centre[k], axis[k], half_length[k], radius[k], rounded[k])
        gap = distance - other_radius
        lift = other_radius + 0.5 * gap  # the segment's surface point nearest the round, then midway to it
        ints, floats = grown(ints, floats, count)
        ints[count, 0], ints[count, 1], ints[count, 2] = owner[k], other_body, other_material
        ints[count, 3], ints[count, 4], ints[count, 5] = kind, 2 * index + end, probe
        floats[count, 0], floats[count, 1], floats[count, 2] = p[0] - n0 * lift, p[1] - n1 * lift, p[2] - n2 * lift
        floats[count, 3], floats[count, 4], floats[count, 5], floats[count, 6] = -n0, -n1, -n2, gap
        count += 1
    return ints, floats, count


@njit(cache=True, error_model="numpy", inline="always")
def _may_touch(body: int, other: int, collides: np.ndarray, excluded: np.ndarray) -> bool:
    """A round's body and a segment's (−1: fixed) may touch: not one body, both collide, no joint joins them."""
    if body == other or not collides[body]:
        return False
    return other < 0 or (collides[other] and _allowed(body, other, excluded, len(collides)))


@njit(cache=True, error_model="numpy")
def side_contacts(centre: np.ndarray, axis: np.ndarray, half_length: np.ndarray, radius: np.ndarray,
                  rounded: np.ndarray, owner: np.ndarray, collides: np.ndarray, material: np.ndarray,
                  travel: np.ndarray, excluded: np.ndarray, edge_start: np.ndarray, edge_end: np.ndarray,
                  edge_body: np.ndarray, edge_material: np.ndarray, edge_number: np.ndarray, bodies_collide: bool,
                  margin: float, first: int, spacing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every side contact of the rounds with the edges and (``bodies_collide``) with each other's sides, within
    ``margin`` [m] plus how far both bodies can travel; ``first``: the probe number of round 0's side."""
    ints = np.empty((16, 6), np.int64)
    floats = np.empty((16, 7))
    count = 0
    largest = 0.0
    for b in range(len(travel)):
        largest = max(largest, travel[b])
    widest_edge = 0.0
    for e in range(len(edge_start)):
        d0, d1 = edge_end[e, 0] - edge_start[e, 0], edge_end[e, 1] - edge_start[e, 1]
        d2 = edge_end[e, 2] - edge_start[e, 2]
        widest_edge = max(widest_edge, 0.5 * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
    along = np.empty(3)
    middle = np.empty(3)
    for k in range(len(owner)):
        size = half_length[k] + radius[k]
        for e in range(len(edge_start)):
            for i in range(3):
                middle[i] = 0.5 * (edge_start[e, i] + edge_end[e, i])
                along[i] = edge_end[e, i] - edge_start[e, i]
            d0, d1, d2 = middle[0] - centre[k, 0], middle[1] - centre[k, 1], middle[2] - centre[k, 2]
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > size + widest_edge + margin + 2 * largest:
                continue
            other = edge_body[e]
            if not _may_touch(owner[k], other, collides, excluded):
                continue
            reach = margin + travel[owner[k]] + (travel[other] if other >= 0 else 0.0)
            if _round_segment_gap(k, centre, axis, half_length, edge_start[e, 0], edge_start[e, 1],
                                  edge_start[e, 2], along[0], along[1], along[2]) - radius[k] >= reach:
                continue
            ints, floats, count = _touching(ints, floats, count, k, centre, axis, half_length, radius, rounded, owner,
                                            edge_start[e], along, 0.0, other, edge_material[e], SIDE_EDGE,
                                            edge_number[e], first + k, reach, spacing, True)
    if not bodies_collide:
        return ints[:count], floats[:count]
    widest = 0.0
    for k in range(len(owner)):
        widest = max(widest, half_length[k] + radius[k])
    start = np.empty((len(owner), 3))
    segment = np.empty((len(owner), 3))
    for k in range(len(owner)):
        for i in range(3):
            start[k, i] = centre[k, i] - half_length[k] * axis[k, i]
            segment[k, i] = 2 * half_length[k] * axis[k, i]
    for k in range(len(owner)):
        for j in range(k + 1, len(owner)):
            d0, d1, d2 = centre[j, 0] - centre[k, 0], centre[j, 1] - centre[k, 1], centre[j, 2] - centre[k, 2]
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > 2 * widest + margin + 2 * largest:
                continue
            # each pair both ways (the side of one against the other as a whole), but where both ways find it
            # touching they found one contact twice: the first way's is kept
            before = count
            for a, b in ((k, j), (j, k)):
                if a == j and count > before:
                    break
                if not _may_touch(owner[a], owner[b], collides, excluded):
                    continue
                reach = margin + travel[owner[a]] + travel[owner[b]]
                if _round_segment_gap(a, centre, axis, half_length, start[b, 0], start[b, 1], start[b, 2],
                                      segment[b, 0], segment[b, 1], segment[b, 2]) - radius[a] - radius[b] >= reach:
                    continue
                ints, floats, count = _touching(ints, floats, count, a, centre, axis, half_length, radius, rounded,
                                                owner, start[b], segment[b], radius[b], owner[b], material[owner[b]],
                                                SIDE_ROUND, b, first + a, reach, spacing, False)
    return ints[:count], floats[:count]
