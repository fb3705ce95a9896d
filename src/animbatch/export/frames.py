"""What every export reads at a frame: where the anchors are and where the cloth and lattice vertices are.

A deformable's vertices are not all bodies of the trajectory: pinned ones follow anchors, keyframes or rigid bodies.
The vertex map places them all from the frame's body states, as the renderer does.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from animbatch import quaternion
from animbatch.trajectory import Trajectory


def anchor_positions(geometry: Any, time: float) -> np.ndarray:
    """Every anchor's position (A, 3) [m] at ``time`` [s] (moving anchors follow their keyframes)."""
    return geometry.anchors.positions(time) if geometry.anchors is not None else geometry.anchor_positions


def deformable_vertices(geometry: Any, trajectory: Trajectory, frame: int) -> np.ndarray:
    """All cloth and lattice vertices (V, 3) [m] at ``frame``: free ones from the trajectory, pinned ones placed
    on their anchors and bodies."""
    particles = len(geometry.particle_radius)
    rotation = quaternion.to_matrix(trajectory.orientations[frame, particles:])
    return geometry.deformables.vertex_map.place(trajectory.positions[frame], rotation,
                                                 anchor_positions(geometry, float(trajectory.times[frame])))


def deformable_frames(geometry: Any, trajectory: Trajectory) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame, vertices (V, 3) [m])`` for every frame, when the scene has cloth or lattices."""
    if geometry.deformables is None:
        return
    for frame in range(trajectory.frame_count):
        yield frame, deformable_vertices(geometry, trajectory, frame)


def own_particles(geometry: Any) -> np.ndarray:
    """Indices (K,) of the trajectory's particles that are bodies of their own, not vertices of cloth or
    lattices."""
    drawn = geometry.drawn_particles
    return np.flatnonzero(drawn) if drawn is not None else np.arange(len(geometry.particle_radius))
