"""Surfaces to draw: a PyVista mesh for each scene shape, smooth normals of a moving cloth, and the rotations that
point arrows."""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.camera import plane_axes
from animbatch.render.geometry import mesh_key
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import (
    BoxCollider,
    BoxShape,
    CapsuleShape,
    CompoundShape,
    CylinderShape,
    MeshCollider,
    MeshShape,
    PlaneCollider,
    RodShape,
    ShellShape,
    SphereCollider,
    SphereShape,
)


def shape_mesh(shape: Any, meshes: dict[tuple[str, str], Any], resolution: int) -> Any:
    """A PyVista surface of a scene shape, in shape coordinates; ``meshes`` holds the mesh files already read
    (vertices (V, 3) [m], faces (F, 3))."""
    import pyvista as pv  # heavy (VTK): only when drawing

    if isinstance(shape, SphereShape | ShellShape):
        return pv.Sphere(radius=shape.radius, theta_resolution=resolution, phi_resolution=resolution)
    if isinstance(shape, BoxShape):
        a, b, c = (s / 2 for s in shape.size)
        return pv.Box(bounds=(-a, a, -b, b, -c, c)).triangulate()
    if isinstance(shape, CylinderShape | RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        return pv.Cylinder(center=(0, 0, 0), direction=(0, 0, 1), radius=radius, height=shape.length,
                           resolution=resolution).triangulate()
    if isinstance(shape, CapsuleShape):
        return pv.Capsule(center=(0, 0, 0), direction=(0, 0, 1), radius=shape.radius,
                          cylinder_length=shape.length - 2 * shape.radius, resolution=resolution).triangulate()
    if isinstance(shape, MeshShape | MeshCollider):
        mesh = meshes[mesh_key(shape)]
        faces = np.hstack([np.full((len(mesh.faces), 1), 3), mesh.faces]).ravel()
        return pv.PolyData(mesh.vertices, faces)
    if isinstance(shape, CompoundShape):
        merged = None
        for part in shape.parts:
            transform = np.eye(4)
            transform[:3, :3] = orientation_matrix(part.orientation)
            transform[:3, 3] = part.offset
            piece = shape_mesh(part.shape, meshes, resolution).transform(transform, inplace=False)
            merged = piece if merged is None else merged.merge(piece)
        return merged
    raise TypeError(f"cannot draw shape {shape!r}")


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


def plane_of(collider: Any) -> tuple[np.ndarray, float]:
    """A plane collider's unit normal and level (``normal · p = level``)."""
    normal = np.asarray(collider.normal, float) / np.linalg.norm(collider.normal)
    return normal, float(np.dot(collider.point, normal))


def collider_surface(collider: Any, bounds: np.ndarray, meshes: dict[tuple[str, str], Any], resolution: int) -> Any:
    """A PyVista surface of a collider where it starts, in world coordinates [m]: planes as squares around the
    motion's ``bounds``, boxes, spheres and mesh files (a moving collider's path then moves it as a whole)."""
    import pyvista as pv  # heavy (VTK): only when drawing

    if isinstance(collider, PlaneCollider):
        normal, level = plane_of(collider)
        return plane_square(bounds, level, normal, collider.size)[0]
    if isinstance(collider, SphereCollider):
        return pv.Sphere(radius=collider.radius, center=collider.position, theta_resolution=2 * resolution,
                         phi_resolution=resolution)
    transform = np.eye(4)
    transform[:3, :3] = orientation_matrix(collider.orientation)
    transform[:3, 3] = collider.position
    if isinstance(collider, BoxCollider):
        a, b, c = (x / 2 for x in collider.size)
        return pv.Box(bounds=(-a, a, -b, b, -c, c)).triangulate().transform(transform, inplace=False)
    if isinstance(collider, MeshCollider):
        return shape_mesh(collider, meshes, resolution).transform(transform, inplace=False)
    raise TypeError(f"cannot draw collider {collider!r}")


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
