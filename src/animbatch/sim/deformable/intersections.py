"""Where surfaces pass through themselves or each other: triangle pairs that cross.

A cloth's vertices meet colliders, rigid bodies and the floor, but not the cloth's own triangles nor another cloth's
(self-collision is not simulated), so a cloth that folds onto itself can pass through itself. This module finds
those crossings in a frame, so that a run can say when its cloth went through itself instead of drawing it quietly.

Two triangles that share no vertex cross when an edge of one passes through the other's inside (two triangles in
general position: one of the six edges does). Pairs that share a vertex meet there by construction and are left out.
The broad phase keeps the pairs whose bounding spheres (about each triangle's centroid) overlap, found with a k-d
tree of the centroids; the narrow phase tests the six edges of each pair at once over all pairs (numpy).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: Pairs tested per batch of the narrow phase (bounds its temporary arrays: some 100 floats a pair).
BATCH = 200_000


def crossing_pairs(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The pairs (K, 2) of ``triangles`` (T, 3) (indices into ``vertices`` (V, 3) [m]) that share no vertex and
    cross each other, each pair once with the smaller triangle index first."""
    if len(triangles) < 2:
        return np.zeros((0, 2), np.intp)
    corners = vertices[triangles]  # (T, 3, 3)
    centre = corners.mean(axis=1)
    reach = np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1)  # bounding sphere radii (T,)
    if not np.all(np.isfinite(centre)):
        raise ValueError("a vertex is not finite")
    pairs = cKDTree(centre).query_pairs(2 * float(reach.max()), output_type="ndarray")
    if not len(pairs):
        return np.zeros((0, 2), np.intp)
    a, b = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(centre[a] - centre[b], axis=1) <= reach[a] + reach[b]
    shared = (triangles[a][:, :, None] == triangles[b][:, None, :]).any(axis=(1, 2))
    pairs = np.sort(pairs[near & ~shared], axis=1)
    found = [pairs[start:start + BATCH][_cross(corners, pairs[start:start + BATCH])]
             for start in range(0, len(pairs), BATCH)]
    crossing = np.concatenate(found) if found else np.zeros((0, 2), np.intp)
    return crossing[np.lexsort((crossing[:, 1], crossing[:, 0]))]


def _cross(corners: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Which pairs (K, 2) of triangles (``corners`` (T, 3, 3)) cross: an edge of either passes through the other."""
    first, second = corners[pairs[:, 0]], corners[pairs[:, 1]]
    # a triangle wholly on one side of the other's plane cannot cross it: most near pairs (neighbours in one
    # sheet, layers lying on each other) end here, before the edges' tests
    straddle = _straddles(first, second) & _straddles(second, first)
    first, second = first[straddle], second[straddle]
    crossed = np.zeros(len(first), bool)
    for edges_of, through in ((first, second), (second, first)):
        for k in range(3):
            crossed |= _segment_through(edges_of[:, k], edges_of[:, (k + 1) % 3], through)
    result = np.zeros(len(pairs), bool)
    result[straddle] = crossed
    return result


def _straddles(triangle: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Whether the corners of ``other`` (K, 3, 3) lie on both sides of the planes of ``triangle`` (K, 3, 3)."""
    normal = np.cross(triangle[:, 1] - triangle[:, 0], triangle[:, 2] - triangle[:, 0])
    side = np.einsum("kci,ki->kc", other - triangle[:, :1], normal)
    return (side.min(axis=1) < 0) & (side.max(axis=1) > 0)


def _segment_through(start: np.ndarray, end: np.ndarray, triangle: np.ndarray) -> np.ndarray:
    """Whether segments ``start`` → ``end`` (K, 3) pass through the insides of triangles (K, 3, 3) (Möller and
    Trumbore's test with the segment's parameter in (0, 1)): touching at an edge or lying in the plane does not
    count."""
    direction = end - start
    e1, e2 = triangle[:, 1] - triangle[:, 0], triangle[:, 2] - triangle[:, 0]
    p = np.cross(direction, e2)
    determinant = np.einsum("ki,ki->k", e1, p)
    scale = np.linalg.norm(direction, axis=1) * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    usable = np.abs(determinant) > 1e-12 * np.maximum(scale, 1e-300)  # a segment in the triangle's plane: no
    inverse = np.where(usable, 1.0 / np.where(usable, determinant, 1.0), 0.0)
    s = start - triangle[:, 0]
    u = np.einsum("ki,ki->k", s, p) * inverse
    q = np.cross(s, e1)
    v = np.einsum("ki,ki->k", direction, q) * inverse
    t = np.einsum("ki,ki->k", e2, q) * inverse
    return usable & (u > 0) & (v > 0) & (u + v < 1) & (t > 0) & (t < 1)
