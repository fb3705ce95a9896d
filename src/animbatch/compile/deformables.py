"""From a cloth or lattice in a scene to what the model builder needs: topology, masses, pins, spring constants,
pressure.

Which vertices a pin selects is decided here (indices, grid corners, a region at the start), and so are the checks
that need the topology: vertex indices in range, regions that select something.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from animbatch.compile.bodies import orientation_matrix
from animbatch.scene.schema import ClothSpec, LatticeSpec, PinSpec, PressureSpec
from animbatch.sim.deformable import topology as topo
from animbatch.sim.forces.pressure import PressureSetting
from animbatch.sim.motion import KeyframePath
from animbatch.sim.rigid.shapes import load_surface

CORNERS = ("bottom-left", "bottom-right", "top-left", "top-right")


def body_topology(spec: ClothSpec | LatticeSpec, base_dir: Path) -> topo.Topology:
    """The topology of a cloth (grid or mesh file) or lattice, in its local coordinates."""
    if isinstance(spec, LatticeSpec):
        (a, b, c), (i, j, k) = spec.size, spec.resolution
        return topo.lattice((a, b, c), (i, j, k))
    if spec.grid is not None:
        (width, depth), (columns, rows) = spec.grid.size, spec.grid.resolution
        return topo.grid((width, depth), (columns, rows))
    assert spec.mesh is not None
    mesh = load_surface(base_dir / spec.mesh.file, spec.mesh.scale)
    return topo.triangle_mesh(mesh.vertices, mesh.faces)


def world_vertices(spec: ClothSpec | LatticeSpec, topology: topo.Topology) -> np.ndarray:
    """Vertex positions (V, 3) [m] at the start."""
    return topology.vertices @ orientation_matrix(spec.orientation).T + np.asarray(spec.position, float)


def vertex_masses(spec: ClothSpec | LatticeSpec, topology: topo.Topology) -> np.ndarray:
    """Mass of each vertex (V,) [kg]: its lumped area (cloth) or volume (lattice) times the density, or its share
    of the total mass."""
    if spec.density is not None:
        return spec.density * topology.weights
    assert spec.mass is not None
    return spec.mass * topology.weights / topology.weights.sum()


def pin_vertices(pin: PinSpec, topology: topo.Topology, world: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The vertices a pin selects, and what is wrong with the selection (messages; empty when fine)."""
    problems = []
    count = topology.vertex_count
    chosen = [index for index in pin.vertices if index < count]
    if len(chosen) < len(pin.vertices):
        bad = [index for index in pin.vertices if index >= count]
        problems.append(f"vertex indices {bad} are out of range: the body has {count} vertices (0 … {count - 1})")
    if pin.corners:
        nx, ny = topology.shape[:2]
        corner_index = {"bottom-left": 0, "bottom-right": nx - 1, "top-left": (ny - 1) * nx, "top-right": nx * ny - 1}
        chosen += [corner_index[name] for name in pin.corners]
    if pin.region is not None:
        low, high = np.asarray(pin.region.min), np.asarray(pin.region.max)
        inside = np.flatnonzero(np.all((world >= low - 1e-12) & (world <= high + 1e-12), axis=1))
        if not len(inside):
            problems.append(f"the region {pin.region.min} … {pin.region.max} holds no vertex at the start (the body "
                            f"spans {np.round(world.min(axis=0), 4).tolist()} … "
                            f"{np.round(world.max(axis=0), 4).tolist()})")
        chosen += inside.tolist()
    return np.unique(np.asarray(chosen, np.intp)), problems


def pin_path(pin: PinSpec) -> KeyframePath | None:
    """The offsets a moving pin follows (added to each pinned vertex's start), or None."""
    if pin.keyframes is None:
        return None
    return KeyframePath(np.array([k.time for k in pin.keyframes], float),
                        np.array([k.offset for k in pin.keyframes], float), pin.interpolation)


def spring_families(spec: ClothSpec | LatticeSpec) -> dict[str, tuple[float, float]]:
    """Family -> (ks, kd) for the families the body declares."""
    return {name: (family.stiffness, family.damping) for name in topo.FAMILIES
            for family in [getattr(spec, name)] if family is not None}


def pressure_setting(spec: PressureSpec) -> PressureSetting:
    """A body's ``pressure`` as numbers: held, along keyframes, or a gas's start."""
    if isinstance(spec.gauge, list):
        return PressureSetting(times=np.array([key.time for key in spec.gauge], float),
                               values=np.array([key.value for key in spec.gauge], float), outside=spec.outside)
    return PressureSetting(gauge=float(spec.gauge), gas=spec.gas, outside=spec.outside)
