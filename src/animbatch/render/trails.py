"""Trails: a polyline behind each trailed body through where it was at the frames of the last ``length`` seconds.

The path comes from the trajectory (:class:`~animbatch.render.geometry.TrailPaths`), not from frames drawn before,
so a frame range drawn on its own (a farm chunk) shows the same trails as a single pass. Each trail is one line
actor of a fixed number of points, rewritten in place per frame; before the trail has its full length, the missing
points repeat the first position (segments of zero length draw nothing). Fading is a per-point alpha that rises
from the tail to the body, so it never changes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.colors import hex_to_rgb
from animbatch.render.geometry import TrailPaths


class TrailLayer:
    """The trails of a scene; :meth:`update` moves them to a frame."""

    def __init__(self, pv: Any, plotter: Any, paths: TrailPaths) -> None:
        self.paths = paths
        times = paths.times
        interval = float(times[1] - times[0]) if len(times) > 1 else 1.0
        self.window = max(1, int(round(paths.length / interval)))  # segments per trail
        count = self.window + 1
        alpha = np.linspace(0.0, 1.0, count) if paths.fade else np.ones(count)
        lines = np.hstack([[count], np.arange(count)])
        self.meshes = []
        for color in paths.colors:
            mesh = pv.PolyData(np.zeros((count, 3)), lines=lines)
            rgba = np.empty((count, 4), np.uint8)
            rgba[:, :3] = np.round(np.array(hex_to_rgb(color)) * 255)
            rgba[:, 3] = np.round(255 * alpha)
            mesh.point_data["rgba"] = rgba
            plotter.add_mesh(mesh, scalars="rgba", rgba=True, line_width=paths.width, lighting=False,
                             show_scalar_bar=False)
            self.meshes.append(mesh)

    def update(self, t: float) -> None:
        """Show the trails as they are at time ``t`` [s] (the frame nearest to it)."""
        frame = int(np.argmin(np.abs(self.paths.times - t)))
        slots = np.clip(np.arange(frame - self.window, frame + 1), 0, None)
        for body, mesh in enumerate(self.meshes):
            mesh.points[:] = self.paths.positions[slots, body]
            mesh.GetPoints().Modified()
