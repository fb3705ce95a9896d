"""The compiled, immutable model: particle properties, anchors, springs, the force terms, the initial state.

A Model is built once (by :class:`~animbatch.model.builder.ModelBuilder`, usually via
:func:`~animbatch.model.compile.compile_scene`) and never changes; its arrays are read-only. Everything that changes
during a run lives in the flat state vector described by ``layout``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.forces import ForceTerm, ParticleProperties, SpringSet
from animbatch.model.layout import StateLayout


@dataclass(frozen=True, eq=False)
class Model:
    """A compiled scene.

    Attributes:
        particles: names, masses [kg] and radii [m] of the N particles.
        anchor_names: names of the A fixed anchors.
        anchor_position: anchor positions [m], shape (A, 3).
        springs: spring topology and constants, or None when the scene has none.
        force_terms: the terms the right-hand side evaluates, in order; only declared effects appear here.
        layout: the layout of the flat state vector.
        y0: initial state, shape (layout.size,).
        frame_times: times at which frames are sampled [s], ``k / fps``, shape (F,).
    """

    particles: ParticleProperties
    anchor_names: tuple[str, ...]
    anchor_position: np.ndarray
    springs: SpringSet | None
    force_terms: tuple[ForceTerm, ...]
    layout: StateLayout
    y0: np.ndarray
    frame_times: np.ndarray

    @property
    def particle_count(self) -> int:
        return len(self.particles.names)

    @property
    def spring_count(self) -> int:
        return 0 if self.springs is None else self.springs.count

    @property
    def fps(self) -> float:
        return 1.0 / (self.frame_times[1] - self.frame_times[0]) if len(self.frame_times) > 1 else 0.0

    def positions(self, y: np.ndarray) -> np.ndarray:
        """Particle positions [m] from a state (n,) or states (F, n): shape (N, 3) or (F, N, 3)."""
        return self.layout.view(y, "particle_position")

    def velocities(self, y: np.ndarray) -> np.ndarray:
        """Particle velocities [m/s] from a state (n,) or states (F, n): shape (N, 3) or (F, N, 3)."""
        return self.layout.view(y, "particle_velocity")
