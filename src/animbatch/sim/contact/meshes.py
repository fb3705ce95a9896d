"""Finding the triangles of mesh colliders near points: one k-d tree over the centroids of the fixed meshes'
triangles, and one per moving mesh over its triangles at rest.

A moving mesh is searched in its own rest frame: the points are taken back along its path (``Rᵀ (p − c(t)) +
c₀``) and looked up in the tree built once, so nothing is rebuilt as it moves; the distances are then measured to
its triangles where the path has put them. A triangle lies within its circumradius ``reach`` of its centroid, so a
triangle within ``r`` of a point has its centroid within ``r + reach``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from animbatch.sim.contact.geometry import to_triangles


@dataclass(frozen=True, eq=False)
class TriangleGroup:
    """Triangles found through one tree: ``index`` (N,) into the collider triangles (T, 3, 3), the tree of their
    centroids at rest, the largest circumradius ``reach`` [m], and ``path``: the moving collider they move with
    (−1: fixed)."""

    index: np.ndarray
    tree: cKDTree
    reach: float
    path: int = -1

    @classmethod
    def of(cls, triangles: np.ndarray, index: np.ndarray, path: int = -1) -> TriangleGroup:
        """The group of ``triangles[index]`` ((T, 3, 3) at rest [m])."""
        corners = triangles[index]
        centroids = corners.mean(axis=1)
        reach = float(np.max(np.linalg.norm(corners - centroids[:, None, :], axis=2)))
        return cls(np.asarray(index, np.intp), cKDTree(centroids), reach, path)

    def near(self, points: np.ndarray, radius: float | np.ndarray, triangles: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (point, triangle) (N,) each whose triangle may lie within ``radius`` [m] (scalar or (Q,)) of the
        point (points (Q, 3) in the group's rest frame); the triangle as its number among all collider triangles.
        Given the ``triangles`` (T, 3, 3) themselves (same frame), only the pairs that do lie within reach: long
        thin triangles have centroids far from much of their surface, and their broad search finds many more."""
        if not len(points):
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        found = self.tree.query_ball_point(points, np.asarray(radius) + self.reach)
        point = np.repeat(np.arange(len(points)), [len(f) for f in found])
        if not len(point):
            return point, np.zeros(0, np.intp)
        triangle = self.index[np.concatenate([np.asarray(f, np.intp) for f in found])]
        if triangles is not None:
            distance, _ = to_triangles(points[point], triangles[triangle])
            keep = distance <= np.broadcast_to(radius, (len(points),))[point]
            point, triangle = point[keep], triangle[keep]
        return point, triangle

    def nearest(self, points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (Q,) [m] from each point (Q, 3) to the nearest of the group's triangles, and the unit normal
        (Q, 3) from that triangle to the point (points and ``triangles`` (T, 3, 3) in the same frame: the rest
        frame). Exact: the nearest centroid bounds the distance, and every triangle that can beat it has its
        centroid within that bound plus ``reach``."""
        if not len(points):
            return np.zeros(0), np.zeros((0, 3))
        bound, _ = self.tree.query(points)
        found = self.tree.query_ball_point(points, bound + self.reach)
        point = np.repeat(np.arange(len(points)), [len(f) for f in found])
        triangle = self.index[np.concatenate([np.asarray(f, np.intp) for f in found])]
        distance, normal = to_triangles(points[point], triangles[triangle])
        order = np.lexsort((distance, point))  # each point's nearest triangle first
        first = order[np.r_[True, point[order][1:] != point[order][:-1]]]
        return distance[first], normal[first]
