"""Surfaces to draw: a PyVista mesh for each scene shape, smooth normals of a moving cloth, and the rotations that
point arrows."""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.camera import plane_axes
from animbatch.render.frame_geometry import DrawnCollider, Solid


def shape_mesh(solid: Solid, resolution: int) -> Any:
    """A PyVista surface of a solid, in its own coordinates [m]."""
    import pyvista as pv  # heavy (VTK): only when drawing

    if solid.kind == "sphere":
        return pv.Sphere(radius=solid.radius, theta_resolution=resolution, phi_resolution=resolution)
    if solid.kind == "box":
        a, b, c = (s / 2 for s in solid.size)
        return pv.Box(bounds=(-a, a, -b, b, -c, c)).triangulate()
    if solid.kind == "cylinder":
        return pv.Cylinder(center=(0, 0, 0), direction=(0, 0, 1), radius=solid.radius, height=solid.length,
                           resolution=resolution).triangulate()
    if solid.kind == "capsule":
        return pv.Capsule(center=(0, 0, 0), direction=(0, 0, 1), radius=solid.radius,
                          cylinder_length=solid.length - 2 * solid.radius, resolution=resolution).triangulate()
    if solid.kind == "mesh":
        assert solid.mesh is not None
        mesh = solid.mesh
        faces = np.hstack([np.full((len(mesh.faces), 1), 3), mesh.faces]).ravel()
        return pv.PolyData(mesh.vertices, faces)
    if solid.kind == "compound":
        merged = None
        for part, pose in solid.parts:
            piece = shape_mesh(part, resolution).transform(pose, inplace=False)
            merged = piece if merged is None else merged.merge(piece)
        return merged
    raise TypeError(f"cannot draw a solid of kind {solid.kind!r}")


def plane_square(bounds: np.ndarray, level: float, up: np.ndarray, size: float | None) -> tuple[Any, np.ndarray, float]:
    """A square of the plane ``up · p = level`` under the motion's ``bounds`` (2, 3) [m]: the PyVista mesh, its
    centre [m] and its side [m] (``size``, else 1.4 × the motion's extent across the plane, at least 1 m)."""
    import pyvista as pv  # heavy (VTK): only when drawing

    centre = bounds.mean(axis=0)
    first, second = plane_axes(up)
    corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    extent = max(np.ptp(corners @ first), np.ptp(corners @ second))
    side = size or max(1.4 * extent, 1.0)
    origin = centre - np.dot(centre, up) * up + level * up  # the motion's centre projected onto the plane
    return pv.Plane(center=origin, direction=up, i_size=side, j_size=side), origin, side


def collider_surface(collider: DrawnCollider, bounds: np.ndarray, resolution: int) -> Any:
    """A PyVista surface of a collider where it starts, in world coordinates [m]: planes as squares around the
    motion's ``bounds``, other solids placed by their pose (a moving collider's track then moves it as a whole)."""
    if collider.normal is not None:
        return plane_square(bounds, collider.level, collider.normal, collider.size)[0]
    assert collider.solid is not None
    if collider.solid.kind == "sphere":  # twice the segments around: a collider sphere is usually large on screen
        import pyvista as pv  # heavy (VTK): only when drawing

        return pv.Sphere(radius=collider.solid.radius, center=collider.pose[:3, 3], theta_resolution=2 * resolution,
                         phi_resolution=resolution)
    return shape_mesh(collider.solid, resolution).transform(collider.pose, inplace=False)


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit normals (V, 3) of a triangle surface, for smooth shading of a moving cloth."""
    a, b, c = points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]
    face = np.cross(b - a, c - a)  # length = twice the area: weights larger faces more
    normals = np.zeros_like(points)
    for k in range(3):
        np.add.at(normals, triangles[:, k], face)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


def arrow_basis(vectors: np.ndarray) -> np.ndarray:
    """Rotation matrices (K, 3, 3) taking the x axis to each vector's direction (identity for zero vectors)."""
    length = np.linalg.norm(vectors, axis=1, keepdims=True)
    x = np.divide(vectors, length, out=np.tile([1.0, 0.0, 0.0], (len(vectors), 1)), where=length > 0)
    helper = np.where(np.abs(x[:, [2]]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=2)
