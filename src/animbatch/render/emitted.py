"""Draw emitted particles: one point cloud per emitter, never a mesh per particle, updated in place per frame.

Every slot of an emitter's pool is a point of its cloud, drawn by VTK's point-Gaussian mapper as a splat scaled by
the particle's radius (``sprite``: glowing and unlit, as particles in the lecture notes "do not reflect light,
usually emit it"; ``sphere``: shaded sphere impostors). Free slots get radius and opacity zero. Each particle's
radius, colour and lifetime come from its serial (:meth:`~animbatch.sim.particles.emitter.Emitter.looks`), computed
only when a slot takes a new particle; size, opacity and colour then follow the ramps of the emitter's ``look`` over
the particle's age / lifetime.

Trails are polylines through each particle's positions at the previous frames of the trajectory (where the slot
held the same particle), so that a frame looks the same whichever frames were drawn before it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.frame_geometry import ParticleLook
from animbatch.trajectory import ParticleFrames


def ramp(values: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """Values (R,) or (R, 3) at evenly spaced points of life, interpolated at life fractions (K,) in 0…1."""
    values = np.asarray(values, float)
    if len(values) == 1:
        return np.broadcast_to(values[0], (len(fraction), *values.shape[1:])).copy()
    knots = np.linspace(0.0, 1.0, len(values))
    if values.ndim == 1:
        return np.interp(fraction, knots, values)
    return np.stack([np.interp(fraction, knots, values[:, k]) for k in range(values.shape[1])], axis=1)


class ParticleAppearance:
    """How an emitter's particles look at a frame, slot by slot: radius [m], opacity and colour, from each particle's
    own lifetime, radius and colour (drawn again from its serial when a slot takes a new particle) and the ramps of
    the emitter's ``look`` over age / lifetime. Numbers only; the renderer and the exports share it."""

    def __init__(self, look: ParticleLook) -> None:
        self.look = look
        capacity = look.capacity
        self._serial = np.full(capacity, -1, np.int64)
        self._lifetime = np.ones(capacity)
        self._radius = np.zeros(capacity)
        self._color = np.zeros((capacity, 3))

    def _refresh_slots(self, serials: np.ndarray) -> None:
        """Look up the attributes of slots that took a new particle since the last frame asked for."""
        changed = np.flatnonzero((serials != self._serial) & (serials >= 0))
        self._serial[:] = serials
        if len(changed):
            lifetime, radius, color = self.look.looks(serials[changed])
            self._lifetime[changed], self._radius[changed], self._color[changed] = lifetime, radius, color

    def at(self, frames: ParticleFrames, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every slot at ``frame``: serials (C,) int64 (-1 where free), radius (C,) [m] and opacity (C,) (both zero
        where free), and colour (C, 3) RGB in 0…1."""
        serials = frames.serials[frame].astype(np.int64)
        self._refresh_slots(serials)
        live = serials >= 0
        life = np.clip(frames.ages[frame] / self._lifetime, 0.0, 1.0)
        look = self.look
        size = np.where(live, self._radius * ramp(look.size_ramp, life), 0.0)
        opacity = np.where(live, ramp(look.opacity_ramp, life), 0.0)
        color = self._color
        if look.color_ramp is not None:  # each particle keeps its own difference from the mean colour
            color = np.clip(ramp(look.color_ramp, life) + (self._color - look.color_mean), 0.0, 1.0)
        return serials, size, opacity, color


class EmitterLayer:
    """The actors of one emitter: its cloud and, optionally, its trails."""

    def __init__(self, pv: Any, plotter: Any, look: ParticleLook) -> None:
        self.look = look
        self.appearance = ParticleAppearance(look)
        capacity = look.capacity
        self.cloud = pv.PolyData(np.zeros((capacity, 3), np.float32))
        self.cloud.point_data["radius"] = np.zeros(capacity)
        self.cloud.point_data["rgba"] = np.zeros((capacity, 4), np.uint8)
        sprite = look.style == "sprite"
        actor = plotter.add_mesh(self.cloud, style="points_gaussian", emissive=sprite,
                                 render_points_as_spheres=not sprite, scalars="rgba", rgba=True,
                                 show_scalar_bar=False)
        actor.mapper.SetScaleArray("radius")
        actor.mapper.SetScaleFactor(1.0)
        self.trail = look.trail
        self.lines: Any = None
        if self.trail:
            points_per = self.trail + 1
            index = np.arange(capacity * points_per).reshape(capacity, points_per)
            cells = np.concatenate([np.full((capacity, self.trail, 1), 2),
                                    np.stack([index[:, :-1], index[:, 1:]], axis=2)], axis=2).ravel()
            self.lines = pv.PolyData(np.zeros((capacity * points_per, 3), np.float32), lines=cells)
            self.lines.point_data["rgba"] = np.zeros((capacity * points_per, 4), np.uint8)
            plotter.add_mesh(self.lines, scalars="rgba", rgba=True, show_scalar_bar=False, line_width=1.5)

    def update(self, frames: ParticleFrames, frame: int) -> None:
        """Show the emitter's particles at ``frame`` of ``frames``."""
        serials, size, opacity, color = self.appearance.at(frames, frame)
        rgba = np.empty((len(serials), 4), np.uint8)
        rgba[:, :3] = np.round(255 * color)
        rgba[:, 3] = np.round(255 * opacity)
        self.cloud.points[:] = frames.positions[frame]
        self.cloud.point_data["radius"][:] = size
        self.cloud.point_data["rgba"][:] = rgba
        self.cloud.Modified()
        if self.lines is not None:
            self._update_trails(frames, frame, serials, rgba)

    def _update_trails(self, frames: ParticleFrames, frame: int, serials: np.ndarray, rgba: np.ndarray) -> None:
        """Polylines back through the frames where each slot held the same particle (collapsed elsewhere)."""
        points = np.empty((len(serials), self.trail + 1, 3), np.float32)
        colors = np.zeros((len(serials), self.trail + 1, 4), np.uint8)
        current = frames.positions[frame]
        points[:, 0] = current
        same = serials >= 0
        for back in range(1, self.trail + 1):
            earlier = frame - back
            if earlier >= 0:
                same = same & (frames.serials[earlier] == serials)
            else:
                same = np.zeros_like(same)
            points[:, back] = np.where(same[:, None], frames.positions[max(earlier, 0)], points[:, back - 1])
            colors[:, back, :3] = rgba[:, :3]
            colors[:, back, 3] = np.where(same, rgba[:, 3] * (1.0 - back / (self.trail + 1)), 0).astype(np.uint8)
        colors[:, 0] = rgba
        self.lines.points[:] = points.reshape(-1, 3)
        self.lines.point_data["rgba"][:] = colors.reshape(-1, 4)
        self.lines.Modified()
