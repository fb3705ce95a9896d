"""From a scene's shape to what the simulation needs: mass properties, and the geometry buoyancy integrates.

Everything is expressed in the *shape frame*: the frame in which the scene gives the shape (primitives centred on its
origin, compound parts at their offsets, mesh files in their own coordinates). The body itself moves about its
centre of mass, ``properties.centre`` in this frame.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from animbatch.rigid import mass_properties as mp
from animbatch.rigid import quaternion
from animbatch.rigid.polyhedra import (TriangleMesh, box_mesh, cylinder_mesh, mesh_mass_properties,
                                       volume_integrals)
from animbatch.scene.schema import (BoxShape, CompoundShape, CylinderShape, MeshShape, OrientationSpec, RigidBodySpec,
                                    RodShape, ShellShape, SphereShape)

#: Sides of the prism standing in for cylinders and rods when computing submerged volumes (error < 0.1 %).
BUOYANCY_SEGMENTS = 96


@dataclass(frozen=True, eq=False)
class BodyGeometry:
    """Mass properties and buoyancy geometry of one rigid body, in its shape frame.

    ``spheres``: (K, 4) rows [x, y, z, r] whose submerged volume is computed exactly; ``triangles``: (T, 3, 3) closed
    surfaces of everything else. Parts should not overlap: overlapping volume counts twice (for mass as for buoyancy).
    """

    properties: mp.MassProperties
    spheres: np.ndarray
    triangles: np.ndarray

    @property
    def displaced_volume(self) -> float:
        """Volume the body displaces when fully submerged [m³] (a sealed shell displaces its whole sphere)."""
        spheres = float(np.sum(4 / 3 * np.pi * self.spheres[:, 3] ** 3))
        if len(self.triangles) == 0:
            return spheres
        mesh = TriangleMesh(self.triangles.reshape(-1, 3), np.arange(3 * len(self.triangles)).reshape(-1, 3))
        return spheres + float(volume_integrals(mesh)[0])


def orientation_matrix(spec: OrientationSpec | None) -> np.ndarray:
    """Rotation matrix (3, 3) of an orientation spec (identity when None)."""
    return quaternion.to_matrix(orientation_quaternion(spec))


def orientation_quaternion(spec: OrientationSpec | None) -> np.ndarray:
    """Unit quaternion [w, x, y, z] of an orientation spec (identity when None)."""
    if spec is None:
        return quaternion.IDENTITY.copy()
    if spec.quaternion is not None:
        return quaternion.normalized(np.asarray(spec.quaternion, float))
    if spec.euler is not None:
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_euler("xyz", spec.euler, degrees=True).as_quat()  # scipy: scalar last
        return np.array([w, x, y, z])
    axis = np.asarray(spec.axis, float)
    return quaternion.from_rotation_vector(axis / np.linalg.norm(axis) * np.radians(spec.angle))


@functools.lru_cache(maxsize=32)
def _read_mesh(path: str, modified: float) -> TriangleMesh:
    import trimesh

    try:
        loaded = trimesh.load(path, force="mesh", process=True)
    except Exception as error:  # trimesh raises many kinds for unreadable files
        raise ValueError(f"cannot read the mesh: {error}") from None
    if len(loaded.faces) == 0:
        raise ValueError("the file holds no triangles")
    if not loaded.is_watertight:
        raise ValueError("the mesh is not closed (it has holes or open edges), so it has no inside to fill: "
                         "close it in a mesh editor first")
    if not loaded.is_winding_consistent:
        raise ValueError("the mesh's triangles are not consistently wound")
    mesh = TriangleMesh(np.asarray(loaded.vertices, float), np.asarray(loaded.faces, np.intp))
    if volume_integrals(mesh)[0] < 0:  # wound inside-out: flip so that normals face outwards
        mesh = TriangleMesh(mesh.vertices, mesh.faces[:, ::-1])
    return mesh


def load_mesh(path: Path, scale: float | list[float] = 1.0) -> TriangleMesh:
    """A closed, outward-wound mesh from an STL/OBJ/PLY file, scaled; ValueError explains what is wrong."""
    if not path.is_file():
        raise ValueError(f"no such file: {path}")
    return _read_mesh(str(path.resolve()), path.stat().st_mtime).scaled(np.asarray(scale, float))


@functools.lru_cache(maxsize=32)
def _read_surface(path: str, modified: float) -> TriangleMesh:
    import trimesh

    try:
        loaded = trimesh.load(path, force="mesh", process=True)  # process: merge the duplicated vertices of STL
    except Exception as error:  # trimesh raises many kinds for unreadable files
        raise ValueError(f"cannot read the mesh: {error}") from None
    if len(loaded.faces) == 0:
        raise ValueError("the file holds no triangles")
    return TriangleMesh(np.asarray(loaded.vertices, float), np.asarray(loaded.faces, np.intp))


def load_surface(path: Path, scale: float | list[float] = 1.0) -> TriangleMesh:
    """A triangle surface (open or closed, as wound in the file) from an STL/OBJ/PLY file, scaled; for cloth."""
    if not path.is_file():
        raise ValueError(f"no such file: {path}")
    return _read_surface(str(path.resolve()), path.stat().st_mtime).scaled(np.asarray(scale, float))


def _primitive(shape: object, mass: float | None, density: float | None, base: Path
               ) -> tuple[mp.MassProperties, list[np.ndarray], list[np.ndarray]]:
    """Properties of one primitive with a given mass or density, and its buoyancy spheres and triangles."""

    def massed(unit: mp.MassProperties) -> mp.MassProperties:  # from unit mass to the given mass or density
        total = mass if mass is not None else density * unit.volume  # type: ignore[operator]
        return unit.with_mass(total)

    if isinstance(shape, SphereShape):
        return massed(mp.solid_sphere(1.0, shape.radius)), [np.array([0, 0, 0, shape.radius])], []
    if isinstance(shape, ShellShape):
        if shape.thickness is None:
            if mass is None:
                raise ValueError("a thin shell has no volume: give it a mass")
            return mp.spherical_shell(mass, shape.radius), [np.array([0, 0, 0, shape.radius])], []
        return (massed(mp.spherical_shell(1.0, shape.radius, shape.thickness)), [np.array([0, 0, 0, shape.radius])],
                [])
    if isinstance(shape, BoxShape):
        return massed(mp.cuboid(1.0, np.asarray(shape.size))), [], [box_mesh(shape.size).triangles]
    if isinstance(shape, CylinderShape):
        return (massed(mp.cylinder(1.0, shape.radius, shape.length)), [],
                [cylinder_mesh(shape.radius, shape.length, BUOYANCY_SEGMENTS).triangles])
    if isinstance(shape, RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        return (massed(mp.cylinder(1.0, radius, shape.length)), [],
                [cylinder_mesh(radius, shape.length, BUOYANCY_SEGMENTS).triangles])
    if isinstance(shape, MeshShape):
        mesh = load_mesh(base / shape.file, shape.scale)
        return massed(mesh_mass_properties(mesh)), [], [mesh.triangles]
    raise TypeError(f"not a primitive shape: {shape!r}")


def body_geometry(spec: RigidBodySpec, base: Path = Path(".")) -> BodyGeometry:
    """Mass properties (shape frame) and buoyancy geometry of a rigid body; ``base`` resolves mesh files."""
    if isinstance(spec.shape, CompoundShape):
        parts, spheres, triangles = [], [], []
        for part in spec.shape.parts:
            # a part without density uses the body's; with only a body mass, all such parts share one density
            density = next(d for d in (part.density, spec.density, 1.0) if d is not None)
            properties, part_spheres, part_triangles = _primitive(part.shape, part.mass, density, base)
            rotation = orientation_matrix(part.orientation)
            offset = np.asarray(part.offset, float)
            parts.append(properties.transformed(rotation, offset))
            spheres += [np.concatenate([rotation @ s[:3] + offset, s[3:]]) for s in part_spheres]
            triangles += [t @ rotation.T + offset for t in part_triangles]
        properties = mp.combine(parts)
        if spec.mass is not None:
            properties = properties.with_mass(spec.mass)
    else:
        properties, spheres, triangles = _primitive(spec.shape, spec.mass, spec.density, base)
    return BodyGeometry(properties, np.array(spheres, float).reshape(-1, 4),
                        np.concatenate(triangles) if triangles else np.zeros((0, 3, 3)))
