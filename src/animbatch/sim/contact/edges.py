"""Edge-to-edge contact between boxes (the case that corner probes miss).

Probes at a box's corners catch a corner on a face, which is almost every real contact. But two boxes whose edges
cross, with no corner of either inside the other (a beam laid across a ridge, boxes turned 45° to each other), touch
only along their edges. For each pair of boxes that may touch this finds, by the separating-axis test, the axis of
least overlap among the 6 face normals and the 9 cross products of their edges; when an edge–edge axis wins (with a
margin, so that faces win ties), the contact is between the two edges that support the boxes along it: at the
midpoint of their closest points, with that axis as its normal and the boxes' separation along it as its gap. Where
the closest points fall beyond an edge's end, a corner probe holds that contact instead.

Edge contacts are fixed-step contacts (:class:`~animbatch.sim.contact.stepping.ContactResolver`); the adaptive
methods' events track probes only.
"""

from __future__ import annotations

import numpy as np

#: An edge–edge axis must overlap less than this fraction of the best face axis to win (faces win ties).
EDGE_PREFERENCE = 0.95
#: Edges this close to parallel (|sin angle|) give no edge axis (their contact is a face's).
PARALLEL = 1e-6


def edge_contact(centre_a: np.ndarray, rotation_a: np.ndarray, half_a: np.ndarray, centre_b: np.ndarray,
                 rotation_b: np.ndarray, half_b: np.ndarray, reach: float
                 ) -> tuple[np.ndarray, np.ndarray, float, int, int] | None:
    """The edge–edge contact of box A on box B (centres (3,), rotations (3, 3) whose columns are the box axes,
    half sizes (3,)), if their least-overlap axis is an edge pair and the edges are within ``reach`` [m]: contact
    point (3,), unit normal from B towards A (3,), gap [m] (negative when overlapping), and the two edges (0 … 11:
    ``4 axis + corner``); else None."""
    offset = centre_a - centre_b
    axes_a, axes_b = rotation_a.T, rotation_b.T  # rows: the boxes' axes in world coordinates

    def overlap(axis: np.ndarray) -> float:
        return float(np.abs(axes_a @ axis) @ half_a + np.abs(axes_b @ axis) @ half_b - abs(offset @ axis))

    faces = [overlap(axis) for axis in (*axes_a, *axes_b)]
    best_face = min(faces)
    if best_face < -reach:
        return None  # a face separates them
    best = None
    for i in range(3):
        for j in range(3):
            axis = np.cross(axes_a[i], axes_b[j])
            size = float(np.linalg.norm(axis))
            if size < PARALLEL:
                continue
            axis /= size
            depth = overlap(axis)
            if depth < -reach:
                return None  # an edge axis separates them
            if best is None or depth < best[0]:
                best = (depth, i, j, axis)
    if best is None or not best[0] < EDGE_PREFERENCE * best_face:
        return None
    depth, i, j, normal = best
    if offset @ normal < 0:
        normal = -normal
    # the supporting edges: A's edge along its axis i nearest B, B's along its axis j nearest A
    signs_a = -np.sign(axes_a @ normal)
    signs_b = np.sign(axes_b @ normal)
    signs_a[i] = signs_b[j] = 0.0
    edge_a = centre_a + (signs_a * half_a) @ axes_a
    edge_b = centre_b + (signs_b * half_b) @ axes_b
    s, u = _closest_parameters(edge_a, axes_a[i], edge_b, axes_b[j])
    if abs(s) > half_a[i] or abs(u) > half_b[j]:
        return None  # beyond an edge's end: a corner's contact
    point_a, point_b = edge_a + s * axes_a[i], edge_b + u * axes_b[j]
    return (0.5 * (point_a + point_b), normal, float((point_a - point_b) @ normal), _edge_number(i, signs_a),
            _edge_number(j, signs_b))


def _closest_parameters(start_a: np.ndarray, direction_a: np.ndarray, start_b: np.ndarray,
                        direction_b: np.ndarray) -> tuple[float, float]:
    """Parameters s, u of the closest points ``start_a + s d_a`` and ``start_b + u d_b`` of two lines with unit,
    non-parallel directions."""
    between = start_a - start_b
    cosine = float(direction_a @ direction_b)
    along_a, along_b = float(direction_a @ between), float(direction_b @ between)
    denominator = 1.0 - cosine * cosine
    return (cosine * along_b - along_a) / denominator, (along_b - cosine * along_a) / denominator


def _edge_number(axis: int, signs: np.ndarray) -> int:
    """0 … 11: which of a box's 12 edges: 4 along each axis, told apart by the signs of the other two."""
    others = [k for k in range(3) if k != axis]
    return 4 * axis + 2 * int(signs[others[0]] > 0) + int(signs[others[1]] > 0)
