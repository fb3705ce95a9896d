"""What the simulation needs of a rigid body's shape: mass properties, the geometry buoyancy integrates, and mesh
files read into triangles (the compiler, :mod:`animbatch.compile.bodies`, builds these from scene shapes).

Everything is expressed in the *shape frame*: the frame in which the scene gives the shape (primitives centred on its
origin, compound parts at their offsets, mesh files in their own coordinates). The body itself moves about its
centre of mass, ``properties.centre`` in this frame.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from animbatch.sim.rigid import mass_properties as mp
from animbatch.sim.rigid.polyhedra import TriangleMesh, volume_integrals


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


@functools.lru_cache(maxsize=32)
def _read_mesh(path: str, modified: float) -> TriangleMesh:
    import trimesh  # heavy: imported only when a mesh file is read

    try:
        loaded = cast("trimesh.Trimesh", trimesh.load(path, force="mesh", process=True))  # force: one Trimesh
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
    import trimesh  # heavy: imported only when a mesh file is read

    try:
        # force: one Trimesh; process: merge the duplicated vertices of STL
        loaded = cast("trimesh.Trimesh", trimesh.load(path, force="mesh", process=True))
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
