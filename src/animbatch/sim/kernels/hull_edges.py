"""Compiled crossing-edge contacts of convex polyhedra (boxes and mesh hulls): the loops of
:func:`animbatch.sim.contact.hulls.edge_contacts` and :func:`~animbatch.sim.contact.hulls.hull_edge_contact` in one
call per step, instead of a dozen small numpy operations per pair of polyhedra.

Every test is the numpy code's, in the same order (the face axes of both, then every cross product of their edge
directions, then the supporting edges of the axes that overlap least), so the two find the same contacts, in the same
order, to round-off (the tests compare them).

Arrays. The polyhedra's shapes, packed (H shapes): ``vertices`` (V, 3) [m] body axes, ``edges`` (E, 2) vertex numbers
within their shape, ``axes`` (D, 3) distinct unit edge directions, ``normals`` (F, 3) unit outward face normals, each
with a start table (H + 1,) (``vertex_start`` …) saying where shape h's rows begin; ``reach`` (H,) [m]. The solids
(N: the fixed boxes first, then the moving polyhedra): ``shape``, ``body`` (−1: fixed), ``kind``, ``base`` (added to an
edge's number for the contact's solid index), ``probe_base`` (the same for its probe number), ``material`` (N,) ints;
``size`` (N,) [m] how far the solid reaches from ``centre`` (N, 3) [m]; ``rotation`` (N, 3, 3) body-to-world.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels.probe_search import _allowed, grown

#: The constants of animbatch.sim.contact.hulls (a kernel may not import the numpy side; the tests check they agree).
END = 1e-3
TIE = 1e-7
PARALLEL = 1e-6
MAX_EDGE_DIRECTIONS = 40
#: Integer columns of a found contact: probe body, probe number, solid body, solid kind, solid index, solid material.
#: Float columns: point (3) [m], normal (3), gap [m].
INT_COLUMNS, FLOAT_COLUMNS = 6, 7


@njit(cache=True, error_model="numpy")
def _world_points(points: np.ndarray, start: int, stop: int, centre: np.ndarray, rotation: np.ndarray,
                  shift: bool) -> np.ndarray:
    """Rows ``start:stop`` of ``points`` (body axes) turned by ``rotation`` (and moved to ``centre`` if ``shift``)."""
    out = np.empty((stop - start, 3))
    for k in range(stop - start):
        p0, p1, p2 = points[start + k, 0], points[start + k, 1], points[start + k, 2]
        for i in range(3):
            turned = rotation[i, 0] * p0 + rotation[i, 1] * p1 + rotation[i, 2] * p2
            out[k, i] = centre[i] + turned if shift else turned
    return out


@njit(cache=True, error_model="numpy")
def _extent(points: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """The lowest and highest of ``points · axis``."""
    low, high = np.inf, -np.inf
    for k in range(len(points)):
        height = points[k, 0] * axis[0] + points[k, 1] * axis[1] + points[k, 2] * axis[2]
        low = min(low, height)
        high = max(high, height)
    return low, high


@njit(cache=True, error_model="numpy")
def _overlaps(verts_a: np.ndarray, verts_b: np.ndarray, axis: np.ndarray) -> tuple[float, float]:
    """Along ``axis``: the overlap with A on the + side of B, and with A on the − side."""
    low_a, high_a = _extent(verts_a, axis)
    low_b, high_b = _extent(verts_b, axis)
    return high_b - low_a, high_a - low_b


@njit(cache=True, error_model="numpy")
def _supporting(verts: np.ndarray, edges: np.ndarray, first: int, count: int, along: np.ndarray,
                direction: np.ndarray, tie: float) -> np.ndarray:
    """Of the shape's edges ``first:first+count`` parallel to ``along``, those farthest in ``direction`` (to ``tie``),
    as edge numbers within the shape."""
    height = np.full(count, -np.inf)
    for e in range(count):
        v0, v1 = edges[first + e, 0], edges[first + e, 1]
        t0, t1, t2 = verts[v1, 0] - verts[v0, 0], verts[v1, 1] - verts[v0, 1], verts[v1, 2] - verts[v0, 2]
        length = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / length, t1 / length, t2 / length
        c0, c1, c2 = t1 * along[2] - t2 * along[1], t2 * along[0] - t0 * along[2], t0 * along[1] - t1 * along[0]
        if math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) < 1e-6:
            height[e] = 0.0
            for i in range(3):
                height[e] += 0.5 * (verts[v0, i] + verts[v1, i]) * direction[i]
    top = height.max()
    return np.flatnonzero(height >= top - tie)


@njit(cache=True, error_model="numpy")
def _record(ints: np.ndarray, floats: np.ndarray, count: int, row_ints: np.ndarray, row_floats: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Row ``count`` of the found contacts."""
    ints, floats = grown(ints, floats, count)
    for c in range(INT_COLUMNS):
        ints[count, c] = row_ints[c]
    for c in range(FLOAT_COLUMNS):
        floats[count, c] = row_floats[c]
    return ints, floats


@njit(cache=True, error_model="numpy")
def _pair(vertices: np.ndarray, vertex_start: np.ndarray, edges: np.ndarray, edge_start: np.ndarray,
          axes: np.ndarray, axis_start: np.ndarray, normals: np.ndarray, face_start: np.ndarray, reach: np.ndarray,
          a: int, shape_a: int, b: int, shape_b: int, centre: np.ndarray, rotation: np.ndarray, within: float,
          ) -> tuple[np.ndarray, np.ndarray]:
    """The edge–edge contacts of solid ``a`` on solid ``b`` within ``within`` [m], as in ``hull_edge_contact``:
    edge pairs (K, 2) (numbers within each shape), and per contact the point (3) [m], the normal from B towards A (3)
    and the gap [m], packed as (K, 7)."""
    none = (np.zeros((0, 2), np.int64), np.zeros((0, 7)))
    verts_a = _world_points(vertices, vertex_start[shape_a], vertex_start[shape_a + 1], centre[a], rotation[a], True)
    verts_b = _world_points(vertices, vertex_start[shape_b], vertex_start[shape_b + 1], centre[b], rotation[b], True)
    best_face = np.inf
    for shape, solid in ((shape_a, a), (shape_b, b)):
        faces = _world_points(normals, face_start[shape], face_start[shape + 1], centre[solid], rotation[solid],
                              False)
        for f in range(len(faces)):
            plus, minus = _overlaps(verts_a, verts_b, faces[f])
            best_face = min(best_face, min(plus, minus))
    world_a = _world_points(axes, axis_start[shape_a], axis_start[shape_a + 1], centre[a], rotation[a], False)
    world_b = _world_points(axes, axis_start[shape_b], axis_start[shape_b + 1], centre[b], rotation[b], False)
    count_b = len(world_b)
    crosses = np.zeros((len(world_a) * count_b, 3))
    valid = np.zeros(len(crosses), np.bool_)
    plus_of = np.zeros(len(crosses))
    minus_of = np.zeros(len(crosses))
    for i in range(len(world_a)):
        for j in range(count_b):
            k = i * count_b + j
            u, w = world_a[i], world_b[j]
            c0, c1, c2 = u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]
            size = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            if size > PARALLEL:
                valid[k] = True
                crosses[k, 0], crosses[k, 1], crosses[k, 2] = c0 / size, c1 / size, c2 / size
    if best_face < -within or not valid.any():
        return none
    least = np.inf
    for k in range(len(crosses)):
        if valid[k]:
            plus_of[k], minus_of[k] = _overlaps(verts_a, verts_b, crosses[k])
            least = min(least, min(plus_of[k], minus_of[k]))
    if least < -within:
        return none  # an edge axis separates them
    tie = TIE * (1.0 + reach[shape_a] + reach[shape_b])
    if least > best_face + tie:
        return none  # a face overlaps least: a vertex on a face, which the vertex probes hold
    found_edges = np.zeros((0, 2), np.int64)
    found = np.zeros((0, 7))
    first_a, first_b = edge_start[shape_a], edge_start[shape_b]
    count_edges_a, count_edges_b = edge_start[shape_a + 1] - first_a, edge_start[shape_b + 1] - first_b
    for k in range(len(crosses)):
        if not valid[k] or min(plus_of[k], minus_of[k]) > least + tie:
            continue
        sign = 1.0 if plus_of[k] <= minus_of[k] else -1.0
        normal = sign * crosses[k]
        i, j = k // count_b, k % count_b
        for edge_a in _supporting(verts_a, edges, first_a, count_edges_a, world_a[i], -normal, tie):
            for edge_b in _supporting(verts_b, edges, first_b, count_edges_b, world_b[j], normal, tie):
                start_a, end_a = verts_a[edges[first_a + edge_a, 0]], verts_a[edges[first_a + edge_a, 1]]
                start_b, end_b = verts_b[edges[first_b + edge_b, 0]], verts_b[edges[first_b + edge_b, 1]]
                along_a, along_b, between = end_a - start_a, end_b - start_b, start_a - start_b
                aa = along_a[0] * along_a[0] + along_a[1] * along_a[1] + along_a[2] * along_a[2]
                bb = along_b[0] * along_b[0] + along_b[1] * along_b[1] + along_b[2] * along_b[2]
                ab = along_a[0] * along_b[0] + along_a[1] * along_b[1] + along_a[2] * along_b[2]
                da = along_a[0] * between[0] + along_a[1] * between[1] + along_a[2] * between[2]
                db = along_b[0] * between[0] + along_b[1] * between[1] + along_b[2] * between[2]
                denominator = aa * bb - ab * ab
                if denominator <= 1e-300:
                    continue
                s, u = (ab * db - bb * da) / denominator, (aa * db - ab * da) / denominator
                # near or beyond an edge's end, a vertex is the contact, and its probe holds it
                if not (END < s < 1.0 - END and END < u < 1.0 - END):
                    continue
                point_a, point_b = start_a + s * along_a, start_b + u * along_b
                row = np.empty(7)
                for c in range(3):  # element by element: slice assignment compiles numba's shape checks
                    row[c] = 0.5 * (point_a[c] + point_b[c])
                    row[3 + c] = normal[c]
                row[6] = ((point_a[0] - point_b[0]) * normal[0] + (point_a[1] - point_b[1]) * normal[1]
                          + (point_a[2] - point_b[2]) * normal[2])
                # one contact per edge pair: a later axis's overwrites an earlier one's, in its place
                at = -1
                for m in range(len(found_edges)):
                    if found_edges[m, 0] == edge_a and found_edges[m, 1] == edge_b:
                        at = m
                if at < 0:
                    at = len(found_edges)
                    grown_edges = np.empty((at + 1, 2), np.int64)
                    grown = np.empty((at + 1, 7))
                    for m in range(at):
                        grown_edges[m, 0], grown_edges[m, 1] = found_edges[m, 0], found_edges[m, 1]
                        for c in range(7):
                            grown[m, c] = found[m, c]
                    grown_edges[at, 0], grown_edges[at, 1] = edge_a, edge_b
                    found_edges, found = grown_edges, grown
                for c in range(7):
                    found[at, c] = row[c]
    return found_edges, found


@njit(cache=True, error_model="numpy")
def edge_contacts(vertices: np.ndarray, vertex_start: np.ndarray, edges: np.ndarray, edge_start: np.ndarray,
                  axes: np.ndarray, axis_start: np.ndarray, normals: np.ndarray, face_start: np.ndarray,
                  reach: np.ndarray, shape: np.ndarray, body: np.ndarray, kind: np.ndarray, base: np.ndarray,
                  probe_base: np.ndarray, material: np.ndarray, size: np.ndarray, centre: np.ndarray,
                  rotation: np.ndarray, fixed_count: int, bodies_collide: bool, collides: np.ndarray,
                  excluded: np.ndarray, travel: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Every crossing-edge contact of the moving solids (``fixed_count:``) with the fixed ones and, when
    ``bodies_collide``, with the moving ones after them, within ``margin`` [m] plus the distance both bodies can travel
    (``travel`` (P,) [m]): integer rows (K, 6) and float rows (K, 7) (see :data:`INT_COLUMNS`)."""
    body_count = len(collides)
    ints = np.empty((16, INT_COLUMNS), np.int64)
    floats = np.empty((16, FLOAT_COLUMNS))
    count = 0
    row_ints = np.empty(INT_COLUMNS, np.int64)
    for a in range(fixed_count, len(shape)):
        owner = body[a]
        if not collides[owner]:
            continue
        last = len(shape) if bodies_collide else fixed_count
        for b in range(last):
            if fixed_count <= b <= a:
                continue
            other = body[b]
            if other == owner or (other >= 0 and (not collides[other]
                                                  or not _allowed(owner, other, excluded, body_count))):
                continue
            within = margin + travel[owner] + (travel[other] if other >= 0 else 0.0)
            d0, d1, d2 = centre[a, 0] - centre[b, 0], centre[a, 1] - centre[b, 1], centre[a, 2] - centre[b, 2]
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > size[a] + size[b] + within:
                continue
            if (axis_start[shape[a] + 1] - axis_start[shape[a]] > MAX_EDGE_DIRECTIONS
                    or axis_start[shape[b] + 1] - axis_start[shape[b]] > MAX_EDGE_DIRECTIONS):
                continue
            pairs, rows = _pair(vertices, vertex_start, edges, edge_start, axes, axis_start, normals, face_start,
                                   reach, a, shape[a], b, shape[b], centre, rotation, within)
            for m in range(len(pairs)):
                row_ints[0], row_ints[1], row_ints[2] = owner, probe_base[a] + pairs[m, 0], other
                row_ints[3], row_ints[4], row_ints[5] = kind[b], base[b] + pairs[m, 1], material[b]
                ints, floats = _record(ints, floats, count, row_ints, rows[m])
                count += 1
    return ints[:count], floats[:count]
