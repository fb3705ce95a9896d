"""Surfaces to draw: a PyVista mesh for each scene shape, smooth normals of a moving cloth, and the rotations that
point arrows."""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.geometry import mesh_key
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import (
    BoxShape,
    CapsuleShape,
    CompoundShape,
    CylinderShape,
    MeshCollider,
    MeshShape,
    RodShape,
    ShellShape,
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
