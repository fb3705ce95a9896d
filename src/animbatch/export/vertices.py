"""What every export reads at a frame: where the cloth and lattice vertices are, and which particles are bodies.

A deformable's vertices are not all bodies of the trajectory: pinned ones follow anchors, keyframes or rigid bodies.
The vertex map places them all from the frame's body states, as the renderer does.
"""

from __future__ import annotations

import numpy as np

from animbatch import quaternion
from animbatch.render.frame_geometry import FrameGeometry
from animbatch.trajectory import Trajectory


def deformable_vertices(geometry: FrameGeometry, trajectory: Trajectory, frame: int) -> np.ndarray:
    """All cloth and lattice vertices (V, 3) [m] at ``frame``: free ones from the trajectory, pinned ones placed
    on their anchors and bodies."""
    particles = len(geometry.particle_radius)
    rotation = quaternion.to_matrix(trajectory.orientations[frame, particles:])
    assert geometry.surfaces is not None
    return geometry.surfaces.placement.place(trajectory.positions[frame], rotation,
                                             geometry.anchors_at(float(trajectory.times[frame])))


def own_particles(geometry: FrameGeometry) -> np.ndarray:
    """Indices (K,) of the trajectory's particles that are bodies of their own, not vertices of cloth or
    lattices."""
    drawn = geometry.drawn_particles
    return np.flatnonzero(drawn) if drawn is not None else np.arange(len(geometry.particle_radius))
