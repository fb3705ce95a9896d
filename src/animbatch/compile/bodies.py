"""Scene shapes and orientations -> the numbers of :mod:`animbatch.sim.rigid`: mass properties in the shape frame
and the spheres and triangles buoyancy integrates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from animbatch.scene.orientation import orientation_matrix, orientation_quaternion
from animbatch.scene.schema import (
    BoxShape,
    CapsuleShape,
    CompoundShape,
    CylinderShape,
    MeshShape,
    RigidBodySpec,
    RodShape,
    ShellShape,
    SphereShape,
)
from animbatch.sim.rigid import mass_properties as mp
from animbatch.sim.rigid.polyhedra import box_mesh, capsule_mesh, cylinder_mesh, mesh_mass_properties
from animbatch.sim.rigid.shapes import BodyGeometry, load_mesh

#: Sides of the prism standing in for cylinders and rods when computing submerged volumes (error < 0.1 %).
BUOYANCY_SEGMENTS = 96

__all__ = ["BUOYANCY_SEGMENTS", "body_geometry", "orientation_matrix", "orientation_quaternion"]


def _primitive(shape: object, mass: float | None, density: float | None, base: Path
               ) -> tuple[mp.MassProperties, list[np.ndarray], list[np.ndarray]]:
    """Properties of one primitive with a given mass or density, and its buoyancy spheres and triangles."""

    def massed(unit: mp.MassProperties) -> mp.MassProperties:  # from unit mass to the given mass or density
        if mass is not None:
            return unit.with_mass(mass)
        assert density is not None  # the schema asks for a mass or a density
        total = density * unit.volume
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
        return massed(mp.cuboid(1.0, np.asarray(shape.size))), [], [box_mesh(np.asarray(shape.size, float)).triangles]
    if isinstance(shape, CylinderShape):
        return (massed(mp.cylinder(1.0, shape.radius, shape.length)), [],
                [cylinder_mesh(shape.radius, shape.length, BUOYANCY_SEGMENTS).triangles])
    if isinstance(shape, RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        return (massed(mp.cylinder(1.0, radius, shape.length)), [],
                [cylinder_mesh(radius, shape.length, BUOYANCY_SEGMENTS).triangles])
    if isinstance(shape, CapsuleShape):
        return (massed(mp.capsule(1.0, shape.radius, shape.length)), [],
                [capsule_mesh(shape.radius, shape.length, BUOYANCY_SEGMENTS // 2).triangles])
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
