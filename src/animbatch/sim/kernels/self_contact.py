"""Compiled self-collision of cloth and lattices: a velocity filter between a fixed-step scheme's kick and its drift
(Bridson, Fedkiw & Anderson 2002, "Robust treatment of collisions, contact and friction for cloth animation"; the
repulsion-then-collision pass of Houdini's Vellum and Blender's cloth).

Given the surfaces' vertices at the start of a step ``x`` (n, 3) [m], free of crossings, and the velocities ``v``
(n, 3) [m/s] they would drift with for ``h`` [s], :func:`filter_velocities` changes ``v`` in place so that the drift
``x + h v`` crosses no triangle pair:

1. **Repulsion.** Vertex–triangle and edge–edge pairs closer than their thickness [m] get an inelastic impulse that
   stops their approach along the line between their closest points, plus a push that restores a tenth of the
   missing thickness per step; tangential relative velocity is taken away up to Coulomb's μ times the normal change.
   This is what holds layers of a heap apart at rest, at the thickness.
2. **Collisions.** Continuous: each pair's four points moving linearly over the step are coplanar at the roots of a
   cubic in τ ∈ [0, 1]; at the first root where the points are also close (the vertex inside the triangle, or the
   edges' closest points on both edges) they would meet, and an inelastic impulse stops the approach there. Passes
   repeat (each on the velocities the last left) until one finds nothing, up to :data:`COLLISION_PASSES`.
3. **Impact zones** (Provot 1997), the failsafe: vertices of pairs still colliding are merged into zones that move
   rigidly (their linear and angular momentum kept), growing until nothing collides. A zone that holds a vertex of
   infinite mass (pinned, or a rigid body's point) moves with the mean velocity of those vertices.

A pair's impulse is spread over its four vertices by their weights ``c`` (1, −α, −β, −γ for a vertex and a triangle's
barycentric point; 1 − s, s, −(1 − t), −t for two edges' closest points) and inverse masses ``w`` [1/kg] (0: the
vertex is not moved), as ``Δv_i = c_i w_i J n`` with ``J = Δv_n / Σ c_j² w_j``, which changes the pair's relative
velocity by exactly ``Δv_n`` along n and keeps the linear momentum.

The broad phase is a spatial hash: each triangle's and edge's box, swept over the step and grown by the thickness,
is entered in the cells (of size ``cell`` [m]) it covers; vertices and edges look up the cells of their own swept
boxes. Pairs that share a vertex are never tested (they meet by construction).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Collision passes before the remaining collisions are resolved by impact zones.
COLLISION_PASSES = 8
#: Impact-zone rounds before the step gives up (each merges the zones of every pair still colliding).
ZONE_ROUNDS = 64
#: Fraction of the missing thickness a repulsion restores per step (more would bounce layers apart).
RESTORE = 0.1
#: A collision's pair leaves with this fraction of the thickness per step as separating speed.
SEPARATE = 0.05
#: Points closer than this fraction of the thickness at their coplanar instant meet.
MEET = 0.05
#: Room left in the broad phase's boxes, as a fraction of the thickness, for the repulsion's changes: within it,
#: the first collision pass reuses the repulsion's candidate pairs.
SLACK = 0.1
#: A pair's generalised inverse mass Σ c_i² w_i is at least this times its largest w_i (see _apply).
INERTIA_FLOOR = 0.25
#: Counters returned by filter_velocities.
STATS = ("repelled", "collisions", "passes", "zones", "largest_zone", "unresolved")


Vec = tuple[float, float, float]


@njit(cache=True, error_model="numpy", inline="always")
def _at(x: np.ndarray, i: int) -> Vec:
    return x[i, 0], x[i, 1], x[i, 2]


@njit(cache=True, error_model="numpy", inline="always")
def _sub(a: Vec, b: Vec) -> Vec:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@njit(cache=True, error_model="numpy", inline="always")
def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy", inline="always")
def _cross(a: Vec, b: Vec) -> Vec:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy", inline="always")
def _moved(a: Vec, d: Vec, tau: float) -> Vec:
    return a[0] + tau * d[0], a[1] + tau * d[1], a[2] + tau * d[2]


@njit(cache=True, error_model="numpy", inline="always")
def _combine(w0: float, a: Vec, w1: float, b: Vec, w2: float, c: Vec, w3: float, e: Vec) -> Vec:
    """w0 a + w1 b + w2 c + w3 e: a pair's separation (weights c_i) or relative velocity."""
    return (w0 * a[0] + w1 * b[0] + w2 * c[0] + w3 * e[0], w0 * a[1] + w1 * b[1] + w2 * c[1] + w3 * e[1],
            w0 * a[2] + w1 * b[2] + w2 * c[2] + w3 * e[2])


@njit(cache=True, error_model="numpy")
def _closest_on_triangle(p: Vec, a: Vec, b: Vec, c: Vec) -> tuple[float, float, float]:
    """Barycentric weights (α, β, γ) of the point of triangle abc closest to p (Ericson, Real-Time Collision
    Detection, 5.1.5)."""
    ab, ac, ap = _sub(b, a), _sub(c, a), _sub(p, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return 1.0, 0.0, 0.0
    bp = _sub(p, b)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        s = d1 / (d1 - d3)
        return 1.0 - s, s, 0.0
    cp = _sub(p, c)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        s = d2 / (d2 - d6)
        return 1.0 - s, 0.0, s
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - s, s
    denominator = 1.0 / (va + vb + vc)
    beta, gamma = vb * denominator, vc * denominator
    return 1.0 - beta - gamma, beta, gamma


@njit(cache=True, error_model="numpy")
def _closest_on_segments(p1: Vec, p2: Vec, q1: Vec, q2: Vec) -> tuple[float, float]:
    """Parameters (s, t) in [0, 1] of the closest points of segments p1p2 and q1q2 (Ericson 5.1.9)."""
    d1, d2, r = _sub(p2, p1), _sub(q2, q1), _sub(p1, q1)
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    if a <= 1e-30 and e <= 1e-30:
        return 0.0, 0.0
    if a <= 1e-30:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = _dot(d1, r)
    if e <= 1e-30:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = _dot(d1, d2)
    denominator = a * e - b * b
    s = min(max((b * f - c * e) / denominator, 0.0), 1.0) if denominator > 1e-12 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return s, t


@njit(cache=True, error_model="numpy")
def _weights(kind: int, p0: Vec, p1: Vec, p2: Vec, p3: Vec) -> tuple[float, float, float, float]:
    """The weights c of a pair's four points: (1, −α, −β, −γ) for a vertex p0 and triangle p1p2p3, or
    (1 − s, s, −(1 − t), −t) for edges p0p1 and p2p3, at their closest points."""
    if kind == 0:
        alpha, beta, gamma = _closest_on_triangle(p0, p1, p2, p3)
        return 1.0, -alpha, -beta, -gamma
    s, t = _closest_on_segments(p0, p1, p2, p3)
    return 1.0 - s, s, -(1.0 - t), -t


# ----------------------------------------------------------------------------------------------------------- broad


@njit(cache=True, error_model="numpy", inline="always")
def _bucket(i: int, j: int, k: int, mask: int) -> int:
    return ((i * 73856093) ^ (j * 19349663) ^ (k * 83492791)) & mask


@njit(cache=True, error_model="numpy")
def _hash(low: np.ndarray, high: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, int]:
    """A spatial hash of boxes ``low``–``high`` (m, 3) [m]: (start (M + 1,), items, mask), the items of bucket b being
    ``items[start[b]:start[b + 1]]`` (every box entered in each cell it covers)."""
    m = len(low)
    lo = np.floor(low / cell).astype(np.int64)
    hi = np.floor(high / cell).astype(np.int64)
    entries = 0
    for q in range(m):
        entries += (hi[q, 0] - lo[q, 0] + 1) * (hi[q, 1] - lo[q, 1] + 1) * (hi[q, 2] - lo[q, 2] + 1)
    size = 1
    while size < 2 * entries:
        size *= 2
    mask = size - 1
    start = np.zeros(size + 1, np.int64)
    for q in range(m):
        for i in range(lo[q, 0], hi[q, 0] + 1):
            for j in range(lo[q, 1], hi[q, 1] + 1):
                for k in range(lo[q, 2], hi[q, 2] + 1):
                    start[_bucket(i, j, k, mask) + 1] += 1
    for b in range(size):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    items = np.empty(entries, np.int64)
    for q in range(m):
        for i in range(lo[q, 0], hi[q, 0] + 1):
            for j in range(lo[q, 1], hi[q, 1] + 1):
                for k in range(lo[q, 2], hi[q, 2] + 1):
                    b = _bucket(i, j, k, mask)
                    items[fill[b]] = q
                    fill[b] += 1
    return start, items, mask


@njit(cache=True, error_model="numpy")
def _grow(pairs: np.ndarray, count: int) -> np.ndarray:
    if count < len(pairs):
        return pairs
    bigger = np.empty((2 * len(pairs) + 16, 2), np.int64)
    bigger[:count] = pairs[:count]
    return bigger


@njit(cache=True, error_model="numpy")
def _swept_boxes(x: np.ndarray, d: np.ndarray, corners: np.ndarray, grow: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (m, 3) around the primitives' corners (m, k) over the step (from x to x + d), grown by ``grow`` (m,)."""
    m, k = corners.shape
    low = np.empty((m, 3))
    high = np.empty((m, 3))
    for q in range(m):
        for axis in range(3):
            lo, hi = np.inf, -np.inf
            for c in range(k):
                vertex = corners[q, c]
                a, b = x[vertex, axis], x[vertex, axis] + d[vertex, axis]
                lo, hi = min(lo, a, b), max(hi, a, b)
            low[q, axis], high[q, axis] = lo - grow[q], hi + grow[q]
    return low, high


@njit(cache=True, error_model="numpy")
def _query(low: np.ndarray, high: np.ndarray, other_low: np.ndarray, other_high: np.ndarray, cell: float,
           kind: int, triangles: np.ndarray, edges: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Pairs (K, 2) of a query box (``low``–``high``, (m, 3) [m]: vertices for kind 0, edges for kind 1) and an
    entered box (``other_*``: triangles for kind 0, edges for kind 1) that overlap, found through a hash of the
    entered boxes; pairs that share a vertex or have no movable vertex are left out, and edge pairs are listed once
    (first edge lower)."""
    start, items, mask = _hash(other_low, other_high, cell)
    stamp = np.full(len(other_low), -1, np.int64)
    pairs = np.empty((4 * len(low) + 16, 2), np.int64)
    found = 0
    for p in range(len(low)):
        if kind == 0:
            a0, a1 = p, p
        else:
            a0, a1 = edges[p, 0], edges[p, 1]
        for i in range(math.floor(low[p, 0] / cell), math.floor(high[p, 0] / cell) + 1):
            for j in range(math.floor(low[p, 1] / cell), math.floor(high[p, 1] / cell) + 1):
                for k in range(math.floor(low[p, 2] / cell), math.floor(high[p, 2] / cell) + 1):
                    b = _bucket(i, j, k, mask)
                    for e in range(start[b], start[b + 1]):
                        q = items[e]
                        if stamp[q] == p or (kind == 1 and q <= p):
                            continue
                        stamp[q] = p
                        if kind == 0:
                            b0, b1, b2 = triangles[q, 0], triangles[q, 1], triangles[q, 2]
                        else:
                            b0, b1, b2 = edges[q, 0], edges[q, 1], edges[q, 1]
                        if a0 == b0 or a0 == b1 or a0 == b2 or a1 == b0 or a1 == b1 or a1 == b2:
                            continue
                        if not (movable[a0] or movable[a1] or movable[b0] or movable[b1] or movable[b2]):
                            continue
                        if (high[p, 0] < other_low[q, 0] or low[p, 0] > other_high[q, 0]
                                or high[p, 1] < other_low[q, 1] or low[p, 1] > other_high[q, 1]
                                or high[p, 2] < other_low[q, 2] or low[p, 2] > other_high[q, 2]):
                            continue
                        pairs = _grow(pairs, found)
                        pairs[found, 0], pairs[found, 1] = p, q
                        found += 1
    return pairs[:found].copy()


@njit(cache=True, error_model="numpy")
def candidate_pairs(x: np.ndarray, d: np.ndarray, thickness: np.ndarray, triangles: np.ndarray, edges: np.ndarray,
                    movable: np.ndarray, cell: float, slack: float) -> tuple[np.ndarray, np.ndarray]:
    """The vertex–triangle pairs (K, 2) and edge–edge pairs (L, 2) (first edge lower) whose boxes, swept from ``x``
    by ``d`` (n, 3) [m] and grown by the thickness and by ``slack`` [m], overlap (so the list stays complete while
    no displacement changes by more than ``slack``); pairs sharing a vertex, or with no ``movable`` vertex, are
    left out."""
    n = len(x)
    # the boxes entered in the hash are the primitives' own swept boxes; the query boxes are grown by the whole
    # thickness instead (the same overlaps, with a third as many entries in a crumpled sheet's cells)
    triangle_low, triangle_high = _swept_boxes(x, d, triangles, np.full(len(triangles), slack))
    grow = np.empty(n)
    for p in range(n):
        grow[p] = thickness[p] + slack
    vertex_low, vertex_high = _swept_boxes(x, d, np.arange(n).reshape(n, 1), grow)
    faces = _query(vertex_low, vertex_high, triangle_low, triangle_high, cell, 0, triangles, edges, movable)
    edge_low, edge_high = _swept_boxes(x, d, edges, np.full(len(edges), slack))
    grow = np.empty(len(edges))
    for q in range(len(edges)):
        grow[q] = max(thickness[edges[q, 0]], thickness[edges[q, 1]])
    query_low, query_high = _swept_boxes(x, d, edges, grow + slack)
    crossings = _query(query_low, query_high, edge_low, edge_high, cell, 1, triangles, edges, movable)
    return faces, crossings


# ---------------------------------------------------------------------------------------------------------- impulses


@njit(cache=True, error_model="numpy")
def _apply(v: np.ndarray, w: np.ndarray, i0: int, i1: int, i2: int, i3: int,
           c: tuple[float, float, float, float], normal: Vec, change: float, friction: float) -> bool:
    """Change the pair's relative velocity Σ c_i v_i by ``change`` [m/s] along ``normal``, and take its tangential
    part away up to ``friction`` times that (Coulomb); False if no vertex of the pair can move."""
    inertia = c[0] * c[0] * w[i0] + c[1] * c[1] * w[i1] + c[2] * c[2] * w[i2] + c[3] * c[3] * w[i3]
    if inertia <= 0.0:
        return False
    # a pair whose only free vertices weigh little in it (a triangle's far corner, the rest held by solids or
    # pins) would need them to fly off to change it: each moves by at most 1 / INERTIA_FLOOR times the change
    inertia = max(inertia, INERTIA_FLOOR * max(w[i0], w[i1], w[i2], w[i3]))
    relative = _combine(c[0], _at(v, i0), c[1], _at(v, i1), c[2], _at(v, i2), c[3], _at(v, i3))
    along = _dot(relative, normal)
    t0, t1, t2 = relative[0] - along * normal[0], relative[1] - along * normal[1], relative[2] - along * normal[2]
    speed = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    slip = 0.0
    if speed > 0.0 and friction > 0.0:
        slip = -min(1.0, friction * abs(change) / speed)
    k = 0
    for i in (i0, i1, i2, i3):
        scale = c[k] * w[i] / inertia
        v[i, 0] += scale * (change * normal[0] + slip * t0)
        v[i, 1] += scale * (change * normal[1] + slip * t1)
        v[i, 2] += scale * (change * normal[2] + slip * t2)
        k += 1
    return True


@njit(cache=True, error_model="numpy")
def _pair(kind: int, first: int, second: int, triangles: np.ndarray, edges: np.ndarray) -> tuple[int, int, int, int]:
    """The four vertices of a pair: (p, a, b, c) of a vertex and a triangle (kind 0), or (p1, p2, q1, q2) of two
    edges (kind 1)."""
    if kind == 0:
        return first, triangles[second, 0], triangles[second, 1], triangles[second, 2]
    return edges[first, 0], edges[first, 1], edges[second, 0], edges[second, 1]


@njit(cache=True, error_model="numpy")
def _repel(x: np.ndarray, v: np.ndarray, w: np.ndarray, thickness: np.ndarray, friction: np.ndarray,
           triangles: np.ndarray, edges: np.ndarray, faces: np.ndarray, crossings: np.ndarray, h: float) -> int:
    """Step 1: pairs closer than their thickness stop approaching and drift apart by RESTORE of what they lack."""
    repelled = 0
    for kind in range(2):
        pairs = faces if kind == 0 else crossings
        for r in range(len(pairs)):
            i0, i1, i2, i3 = _pair(kind, pairs[r, 0], pairs[r, 1], triangles, edges)
            keep = max(thickness[i0], thickness[i1], thickness[i2], thickness[i3])
            p0, p1, p2, p3 = _at(x, i0), _at(x, i1), _at(x, i2), _at(x, i3)
            c = _weights(kind, p0, p1, p2, p3)
            if kind == 1 and (c[0] == 0.0 or c[0] == 1.0) and (c[2] == 0.0 or c[2] == -1.0):
                continue  # two edges nearest at their ends: a vertex–vertex case the faces around them hold
            gap_vector = _combine(c[0], p0, c[1], p1, c[2], p2, c[3], p3)
            gap = math.sqrt(_dot(gap_vector, gap_vector))
            if gap >= keep or gap <= 1e-12 * keep:
                continue
            normal = (gap_vector[0] / gap, gap_vector[1] / gap, gap_vector[2] / gap)
            relative = _combine(c[0], _at(v, i0), c[1], _at(v, i1), c[2], _at(v, i2), c[3], _at(v, i3))
            target = RESTORE * (keep - gap) / h
            along = _dot(relative, normal)
            if along >= target:
                continue
            mu = 0.25 * (friction[i0] + friction[i1] + friction[i2] + friction[i3])
            if _apply(v, w, i0, i1, i2, i3, c, normal, target - along, mu):
                repelled += 1
    return repelled


@njit(cache=True, error_model="numpy")
def _cubic_roots(c0: float, c1: float, c2: float, c3: float) -> np.ndarray:
    """The roots in [0, 1] of c0 + c1 τ + c2 τ² + c3 τ³, ascending (found by bisection on the intervals where the
    cubic is monotone, so a double root touching zero is found too when it reaches zero within the rounding)."""
    scale = abs(c0) + abs(c1) + abs(c2) + abs(c3)
    out = np.empty(3)
    count = 0
    if scale == 0.0:
        return out[:0]
    tiny = 1e-12 * scale
    # the derivative's roots split [0, 1] into monotone pieces
    splits = np.empty(4)
    splits[0] = 0.0
    pieces = 1
    a, b, c = 3 * c3, 2 * c2, c1
    if abs(a) > tiny:
        disc = b * b - 4 * a * c
        if disc >= 0:
            root = math.sqrt(disc)
            r1, r2 = (-b - root) / (2 * a), (-b + root) / (2 * a)
            if r1 > r2:
                r1, r2 = r2, r1
            for r in (r1, r2):
                if 0.0 < r < 1.0:
                    splits[pieces] = r
                    pieces += 1
    elif abs(b) > tiny:
        r = -c / b
        if 0.0 < r < 1.0:
            splits[pieces] = r
            pieces += 1
    splits[pieces] = 1.0
    for s in range(pieces):
        lo, hi = splits[s], splits[s + 1]
        f_lo = c0 + lo * (c1 + lo * (c2 + lo * c3))
        f_hi = c0 + hi * (c1 + hi * (c2 + hi * c3))
        if abs(f_lo) <= tiny:
            root = lo
        elif f_lo * f_hi > 0:
            if abs(f_hi) <= tiny and s == pieces - 1:
                root = hi
            else:
                continue
        else:
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                f_mid = c0 + mid * (c1 + mid * (c2 + mid * c3))
                if (f_mid < 0) == (f_lo < 0):
                    lo, f_lo = mid, f_mid
                else:
                    hi = mid
            root = 0.5 * (lo + hi)
        if count == 0 or root > out[count - 1] + 1e-12:
            out[count] = root
            count += 1
    return out[:count]


@njit(cache=True, error_model="numpy", inline="always")
def _triple(a: Vec, b: Vec, c: Vec) -> float:
    return _dot(_cross(a, b), c)


@njit(cache=True, error_model="numpy")
def _meeting(x: np.ndarray, d: np.ndarray, kind: int, i0: int, i1: int, i2: int, i3: int, keep: float
             ) -> tuple[bool, tuple[float, float, float, float], Vec]:
    """Whether the pair meets within the step (its points moving from x by d): at the first coplanar instant τ
    where its closest points are within MEET of the thickness. Then also the pair's weights at that instant and the
    unit normal there, pointing to the side the pair's first point started on."""
    p0, p1, p2, p3 = _at(x, i0), _at(x, i1), _at(x, i2), _at(x, i3)
    d0, d1, d2, d3 = _at(d, i0), _at(d, i1), _at(d, i2), _at(d, i3)
    a0, a1, a2 = _sub(p1, p0), _sub(p2, p0), _sub(p3, p0)
    b0, b1, b2 = _sub(d1, d0), _sub(d2, d0), _sub(d3, d0)
    c0 = _triple(a0, a1, a2)
    c1 = _triple(b0, a1, a2) + _triple(a0, b1, a2) + _triple(a0, a1, b2)
    c2 = _triple(a0, b1, b2) + _triple(b0, a1, b2) + _triple(b0, b1, a2)
    c3 = _triple(b0, b1, b2)
    nothing = (0.0, 0.0, 0.0, 0.0)
    if c0 * c1 > 0 and c0 * (c0 + c1 + c2 + c3) > 0 and c2 * c0 >= 0 and c3 * c0 >= 0:
        return False, nothing, (0.0, 0.0, 0.0)  # every term keeps the sign of c0 on [0, 1]: never coplanar
    for tau in _cubic_roots(c0, c1, c2, c3):
        q0, q1, q2, q3 = _moved(p0, d0, tau), _moved(p1, d1, tau), _moved(p2, d2, tau), _moved(p3, d3, tau)
        c = _weights(kind, q0, q1, q2, q3)
        gap_vector = _combine(c[0], q0, c[1], q1, c[2], q2, c[3], q3)
        if _dot(gap_vector, gap_vector) > (MEET * keep) ** 2:
            continue
        plane = _cross(_sub(q2, q1), _sub(q3, q1)) if kind == 0 else _cross(_sub(q1, q0), _sub(q3, q2))
        size = math.sqrt(_dot(plane, plane))
        if size <= 1e-30:
            continue
        plane = (plane[0] / size, plane[1] / size, plane[2] / size)
        side = _dot(_combine(c[0], p0, c[1], p1, c[2], p2, c[3], p3), plane)
        if side == 0.0:  # started in the plane: take the side the relative motion leaves from
            side = -_dot(_combine(c[0], d0, c[1], d1, c[2], d2, c[3], d3), plane)
        if side < 0:
            plane = (-plane[0], -plane[1], -plane[2])
        return True, c, plane
    return False, nothing, (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy")
def _apart(x: np.ndarray, d: np.ndarray, kind: int, i0: int, i1: int, i2: int, i3: int, near: float) -> bool:
    """Whether the pair stays farther apart than ``near`` [m] over the step, for certain: its closest points start
    farther apart than that by more than the two sides can move towards each other (most pairs a flat sheet's
    neighbours make, whose coplanarity cubic is zero everywhere, end here)."""
    p0, p1, p2, p3 = _at(x, i0), _at(x, i1), _at(x, i2), _at(x, i3)
    c = _weights(kind, p0, p1, p2, p3)
    gap_vector = _combine(c[0], p0, c[1], p1, c[2], p2, c[3], p3)
    r0, r1 = math.sqrt(_dot(_at(d, i0), _at(d, i0))), math.sqrt(_dot(_at(d, i1), _at(d, i1)))
    r2, r3 = math.sqrt(_dot(_at(d, i2), _at(d, i2))), math.sqrt(_dot(_at(d, i3), _at(d, i3)))
    travel = r0 + max(r1, r2, r3) if kind == 0 else max(r0, r1) + max(r2, r3)
    return math.sqrt(_dot(gap_vector, gap_vector)) - travel > near


@njit(cache=True, error_model="numpy")
def _collide(x: np.ndarray, v: np.ndarray, w: np.ndarray, thickness: np.ndarray, friction: np.ndarray,
             triangles: np.ndarray, edges: np.ndarray, faces: np.ndarray, crossings: np.ndarray, h: float,
             respond: bool, hits: np.ndarray) -> int:
    """Step 2: one pass over the pairs; each that meets within the step gets an impulse (if ``respond``) that
    stops its approach and sends it apart at SEPARATE of its thickness per step. Pairs that meet are listed in
    ``hits`` (rows: kind, first, second) as far as it has rows; returns how many met."""
    d = h * v
    met = 0
    for kind in range(2):
        pairs = faces if kind == 0 else crossings
        for r in range(len(pairs)):
            i0, i1, i2, i3 = _pair(kind, pairs[r, 0], pairs[r, 1], triangles, edges)
            keep = max(thickness[i0], thickness[i1], thickness[i2], thickness[i3])
            if _apart(x, d, kind, i0, i1, i2, i3, MEET * keep):
                continue
            meets, c, normal = _meeting(x, d, kind, i0, i1, i2, i3, keep)
            if not meets:
                continue
            if met < len(hits):
                hits[met, 0], hits[met, 1], hits[met, 2] = kind, pairs[r, 0], pairs[r, 1]
            met += 1
            if not respond:
                continue
            relative = _combine(c[0], _at(v, i0), c[1], _at(v, i1), c[2], _at(v, i2), c[3], _at(v, i3))
            target = SEPARATE * keep / h
            along = _dot(relative, normal)
            mu = 0.25 * (friction[i0] + friction[i1] + friction[i2] + friction[i3])
            if along < target and _apply(v, w, i0, i1, i2, i3, c, normal, target - along, mu):
                for i in (i0, i1, i2, i3):  # later pairs see the new velocities
                    d[i, 0], d[i, 1], d[i, 2] = h * v[i, 0], h * v[i, 1], h * v[i, 2]
    return met


@njit(cache=True, error_model="numpy")
def _root(parent: np.ndarray, i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, error_model="numpy")
def _rigid_zones(x: np.ndarray, v: np.ndarray, w: np.ndarray, parent: np.ndarray) -> tuple[int, int]:
    """Step 3: every zone of two or more vertices (``parent``: a union–find forest) moves rigidly, keeping its linear
    and angular momentum (or with its fixed vertices' mean velocity); returns (zones, largest)."""
    n = len(x)
    root = np.empty(n, np.int64)
    size = np.zeros(n, np.int64)
    for i in range(n):
        root[i] = _root(parent, i)
        size[root[i]] += 1
    zones, largest = 0, 0
    mass = np.zeros(n)
    fixed = np.zeros(n, np.int64)
    centre = np.zeros((n, 3))
    momentum = np.zeros((n, 3))
    fixed_velocity = np.zeros((n, 3))
    for i in range(n):
        r = root[i]
        if size[r] < 2:
            continue
        if w[i] <= 0.0:
            fixed[r] += 1
            fixed_velocity[r] += v[i]
        else:
            m = 1.0 / w[i]
            mass[r] += m
            centre[r] += m * x[i]
            momentum[r] += m * v[i]
    angular = np.zeros((n, 3))
    inertia = np.zeros((n, 3, 3))
    for i in range(n):
        r = root[i]
        if size[r] < 2 or fixed[r] or w[i] <= 0.0:
            continue
        m = 1.0 / w[i]
        arm = x[i] - centre[r] / mass[r]
        angular[r] += m * np.cross(arm, v[i] - momentum[r] / mass[r])
        inertia[r] += m * (np.dot(arm, arm) * np.eye(3) - np.outer(arm, arm))
    spin = np.zeros((n, 3))
    for r in range(n):
        if size[r] < 2 or root[r] != r:
            continue
        zones += 1
        largest = max(largest, size[r])
        if fixed[r] or mass[r] <= 0:
            continue
        # a zone on one line has a singular inertia: its spin about that line is left out
        scale = np.trace(inertia[r]) + 1e-300
        spin[r] = np.linalg.solve(inertia[r] + 1e-9 * scale * np.eye(3), angular[r])
    for i in range(n):
        r = root[i]
        if size[r] < 2 or w[i] <= 0.0:
            continue
        if fixed[r]:
            v[i] = fixed_velocity[r] / fixed[r]
        else:
            v[i] = momentum[r] / mass[r] + np.cross(spin[r], x[i] - centre[r] / mass[r])
    return zones, largest


@njit(cache=True, error_model="numpy")
def filter_velocities(x: np.ndarray, v: np.ndarray, w: np.ndarray, thickness: np.ndarray, friction: np.ndarray,
                      triangles: np.ndarray, edges: np.ndarray, h: float, cell: float) -> np.ndarray:
    """Change ``v`` (n, 3) [m/s] in place so that the drift from ``x`` (n, 3) [m] by ``h`` [s] crosses nothing (see
    the module notes). ``w`` (n,) inverse masses [1/kg] (0: not moved), ``thickness`` (n,) [m] and ``friction``
    (n,) per vertex, ``triangles`` (T, 3) and ``edges`` (E, 2) index the vertices, ``cell`` [m] the hash's cell.
    Returns the counters of :data:`STATS`."""
    stats = np.zeros(len(STATS), np.int64)
    movable = w > 0
    # one search serves the repulsion and the first collision pass, unless the repulsion changed some
    # displacement by more than its slack
    slack = SLACK * thickness.max()
    faces, crossings = candidate_pairs(x, h * v, thickness, triangles, edges, movable, cell, slack)
    before = v.copy()
    stats[0] = _repel(x, v, w, thickness, friction, triangles, edges, faces, crossings, h)
    stale = h * np.sqrt(((v - before) ** 2).sum(axis=1)).max() > slack if len(v) else False
    hits = np.empty((0, 3), np.int64)
    for attempt in range(COLLISION_PASSES):
        if attempt or stale:
            faces, crossings = candidate_pairs(x, h * v, thickness, triangles, edges, movable, cell, 0.0)
        met = _collide(x, v, w, thickness, friction, triangles, edges, faces, crossings, h, True, hits)
        stats[2] = attempt + 1
        stats[1] += met
        if not met:
            return stats
    parent = np.arange(len(x))
    for _ in range(ZONE_ROUNDS):
        faces, crossings = candidate_pairs(x, h * v, thickness, triangles, edges, movable, cell, 0.0)
        hits = np.empty((len(faces) + len(crossings), 3), np.int64)
        met = _collide(x, v, w, thickness, friction, triangles, edges, faces, crossings, h, False, hits)
        if not met:
            return stats
        for r in range(min(met, len(hits))):
            i0, i1, i2, i3 = _pair(hits[r, 0], hits[r, 1], hits[r, 2], triangles, edges)
            top = _root(parent, i0)
            for other in (i1, i2, i3):
                second = _root(parent, other)
                if second != top:
                    parent[second] = top
        stats[3], stats[4] = _rigid_zones(x, v, w, parent)
    stats[5] = 1
    return stats
