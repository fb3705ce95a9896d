"""Trails: a polyline behind each trailed body through where it was at the frames of the last ``length`` seconds.

The path comes from the trajectory (:class:`~animbatch.render.frame_geometry.TrailPaths`), not from frames drawn before,
so a frame range drawn on its own (a farm chunk) shows the same trails as a single pass. Each trail is one line
actor of a fixed number of points, rewritten in place per frame; before the trail has its full length, the missing
points repeat the first position (segments of zero length draw nothing). Fading is a per-point alpha that rises
from the tail to the body, so it never changes. All trails are one actor.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.colors import hex_to_rgb
from animbatch.render.frame_geometry import TrailPaths, nearest_frame


class TrailLayer:
    """The trails of a scene, as one line actor of T polylines; :meth:`update` moves them all to a frame in one
    gather (a trail per particle of a thousand-particle scene is still one actor)."""

    def __init__(self, pv: Any, plotter: Any, paths: TrailPaths) -> None:
        self.paths = paths
        times = paths.times
        interval = float(times[1] - times[0]) if len(times) > 1 else 1.0
        self.window = max(1, int(round(paths.length / interval)))  # segments per trail
        count, trails = self.window + 1, len(paths.colors)
        alpha = np.linspace(0.0, 1.0, count) if paths.fade else np.ones(count)
        first = np.arange(trails) * count
        lines = np.column_stack([np.full(trails, count), first[:, None] + np.arange(count)]).ravel()
        self.mesh = pv.PolyData(np.zeros((trails * count, 3)), lines=lines)
        rgba = np.empty((trails, count, 4), np.uint8)
        rgba[..., :3] = np.round(np.array([hex_to_rgb(color) for color in paths.colors]) * 255)[:, None, :]
        rgba[..., 3] = np.round(255 * alpha)
        self.mesh.point_data["rgba"] = rgba.reshape(-1, 4)
        plotter.add_mesh(self.mesh, scalars="rgba", rgba=True, line_width=paths.width, lighting=False,
                         show_scalar_bar=False)

    def update(self, t: float) -> None:
        """Show the trails as they are at time ``t`` [s] (the frame nearest to it)."""
        frame = nearest_frame(self.paths.times, t)
        slots = np.clip(np.arange(frame - self.window, frame + 1), 0, None)
        # (count, T, 3) -> (T, count, 3): each trail's points together, tail first
        self.mesh.points[:] = self.paths.positions[slots].transpose(1, 0, 2).reshape(-1, 3)
        self.mesh.GetPoints().Modified()
