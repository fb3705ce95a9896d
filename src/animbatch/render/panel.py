"""The energy panel: a plot of the run's energies (and momentum) over time under the 3D view, with a cursor at the
frame's time.

The plot is drawn once, by matplotlib, when the renderer starts; each frame copies it and draws the cursor's
column, so the panel costs a copy per frame rather than a plot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.frame_geometry import PanelSeries

#: Line colours per series label (matplotlib's default cycle otherwise).
COLORS = {"kinetic [J]": "#e15759", "potential [J]": "#4e79a7", "total [J]": "#222222", "|p| [kg·m/s]": "#59a14f"}
CURSOR = np.array([230, 120, 20], np.uint8)


class EnergyPanel:
    """The panel for frames ``width`` × ``height`` [px]."""

    def __init__(self, series: PanelSeries, width: int, height: int) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # a canvas of its own: no global backend
        from matplotlib.figure import Figure

        dpi = 100
        figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        canvas = FigureCanvasAgg(figure)
        axes = figure.add_axes((0.07, 0.22, 0.86, 0.6))
        font = max(6.0, min(11.0, height / 18))
        right: Any = None  # the momentum axis, made when a series needs it
        for label, (values, side) in series.series.items():
            target: Any = axes
            if side == "right":
                right = right if right is not None else axes.twinx()
                target = right
            target.plot(series.times, values, label=label, color=COLORS.get(label), linewidth=1.4,
                        linestyle="--" if side == "right" else "-")
        axes.set_xlim(float(series.times[0]), float(series.times[-1]) if len(series.times) > 1 else 1.0)
        axes.set_xlabel("t [s]", fontsize=font, labelpad=1)
        for target in (axes, right):
            if target is not None:
                target.tick_params(labelsize=font, pad=1)
        handles = [line for target in (axes, right) if target is not None for line in target.get_lines()]
        # above the plot, not over the curves
        axes.legend(handles=handles, fontsize=font, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=len(handles),
                    frameon=False, borderaxespad=0.2)
        axes.grid(alpha=0.3)
        canvas.draw()
        self.image = np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
        # where time runs on the image: columns of t = start and end, and the rows of the axes
        (left, bottom), (end, top) = axes.transData.transform([(axes.get_xlim()[0], axes.get_ylim()[0]),
                                                                (axes.get_xlim()[1], axes.get_ylim()[1])])
        self._left, self._right = float(left), float(end)
        self._rows = slice(int(height - top), int(height - bottom))
        self._span = (float(series.times[0]), float(series.times[-1]) if len(series.times) > 1 else 1.0)

    def column(self, t: float) -> int:
        """The image column of time ``t`` [s]."""
        start, end = self._span
        fraction = (t - start) / (end - start) if end > start else 0.0
        return int(round(self._left + np.clip(fraction, 0.0, 1.0) * (self._right - self._left)))

    def draw(self, t: float) -> np.ndarray:
        """The panel (height, width, 3) uint8 with the cursor at ``t`` [s]."""
        image = self.image.copy()
        column = self.column(t)
        image[self._rows, max(column - 1, 0):column + 1] = CURSOR
        return image
