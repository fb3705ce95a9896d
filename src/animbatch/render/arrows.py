"""Arrows from bodies' centres of mass (velocity, acceleration, each kind of force), and their legend.

One actor per quantity, whatever the number of bodies: a point set (a point per body, with the axes of its arrow)
feeds a VTK tensor glyph filter that stretches a unit arrow along each vector to its length while keeping every
arrow equally thick; a frame rewrites the points and axes in place. Brief peaks (an impact's mean force over a frame)
are drawn at most CAP times as long as a quantity's typical longest arrow. The vectors come precomputed per frame
(:class:`~animbatch.render.frame_geometry.ArrowSeries`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.render.colors import hex_to_rgb
from animbatch.render.frame_geometry import ArrowSeries, nearest_frame
from animbatch.render.surfaces import arrow_basis

#: The longest an arrow is drawn [in units of the typical longest arrow]: brief peaks such as impacts are capped.
CAP = 2.0


#: Gap between the legend and the frame's top and right edges, as a fraction of the frame.
LEGEND_MARGIN = 0.02
#: The least height of a legend line [px], so that a small frame's legend stays readable.
LEGEND_LINE_PIXELS = 12


class ArrowLayer:
    """The arrows of every quantity, and a legend naming each with its scale."""

    def __init__(self, pv: Any, plotter: Any, series: ArrowSeries) -> None:
        from vtkmodules.vtkFiltersCore import vtkTensorGlyph  # heavy (VTK): only when drawing

        self.series = series
        count = len(series.bodies)
        arrow = pv.Arrow(start=(0, 0, 0), direction=(1, 0, 0), scale=1.0, tip_length=0.25, tip_radius=0.07,
                         shaft_radius=0.025)
        self.clouds = []
        for color in series.colors:
            cloud = pv.PolyData(np.zeros((count, 3)))
            cloud.point_data["axes"] = np.zeros((count, 9))
            cloud.GetPointData().SetActiveTensors("axes")
            glyph = vtkTensorGlyph()
            glyph.SetSourceData(arrow)
            glyph.SetInputData(cloud)
            glyph.ExtractEigenvaluesOff()  # the tensor's columns are the glyph's axes, lengths included
            glyph.ColorGlyphsOff()
            glyph.ThreeGlyphsOff()
            # mostly ambient: an arrow is a diagram, its colour must read the same on its lit and its shaded side
            actor = plotter.add_mesh(arrow, color=color, smooth_shading=True, ambient=0.5, diffuse=0.6,
                                     specular=0.15)
            actor.mapper.SetInputConnection(glyph.GetOutputPort())  # the glyphs replace the placeholder arrow
            self.clouds.append(cloud)
        box = legend_box(series, *plotter.window_size)
        if box is not None:
            size, entries = box
            legend = plotter.add_legend(entries, bcolor=tuple(hex_to_rgb("#ffffff")), border=False, size=size,
                                        loc="upper right", face="rectangle")
            # placed here: PyVista's 'upper right' offsets the box from the right edge by its height, not its
            # width, so a legend wider than tall ran off the frame
            legend.SetPosition(1 - size[0] - LEGEND_MARGIN, 1 - size[1] - LEGEND_MARGIN)
        self.legend = legend if box is not None else None

    def update(self, t: float, positions: np.ndarray) -> None:
        """Place the arrows of the frame nearest to ``t`` [s] at the bodies' ``positions`` (P, 3) [m]."""
        series = self.series
        frame = nearest_frame(series.times, t)
        origins = positions[series.bodies]
        for cloud, vectors, scale in zip(self.clouds, series.vectors, series.scales):
            cloud.points[:] = origins
            cloud.point_data["axes"][:] = arrow_axes(np.nan_to_num(vectors[frame]), scale, series.length)
            cloud.Modified()


def arrow_tips(series: ArrowSeries, positions: np.ndarray) -> np.ndarray:
    """Where every arrow's tip is at every frame (M, 3) [m], drawn as :func:`arrow_axes` draws them (capped), from
    the bodies' ``positions`` (F, P, 3) at the series' frames: what a fitted camera must frame besides the bodies."""
    origins = positions[:, series.bodies]  # (F, A, 3)
    tips = [origins.reshape(-1, 3)]
    for vectors, scale in zip(series.vectors, series.scales):
        vectors = np.nan_to_num(vectors)
        size = np.linalg.norm(vectors, axis=-1, keepdims=True)
        length = np.minimum(size * scale, CAP * series.length)
        tips.append((origins + np.divide(vectors, size, out=np.zeros_like(vectors), where=size > 0)
                     * length).reshape(-1, 3))
    return np.vstack(tips)


def legend_box(series: ArrowSeries, width: int, height: int
               ) -> tuple[tuple[float, float], list[list[str]]] | None:
    """The legend's size (width, height) as fractions of a ``width`` × ``height`` [px] frame, and its entries
    (text, colour); None when the arrows have no legend. It sits in the upper right corner, LEGEND_MARGIN from
    both edges: the sky is the emptiest part of most frames, and the overlay's text sits upper left by default."""
    if not (series.legend and series.names):
        return None
    entries = [[f"{name} (1 m = {1 / scale:.3g} {unit})" if scale > 0 else name, color]
               for name, unit, scale, color in zip(series.names, series.units, series.scales, series.colors)]
    # wide enough for the longest entry: a letter is ~0.45 of a line's height, plus the swatch and margins
    line = min(max(0.042, LEGEND_LINE_PIXELS / height), 0.5 / len(entries))  # readable at 320×240 too
    letters = max(len(text) for text, _ in entries)
    # VTK pads the box by a few pixels, which a one-line legend's letters would lose
    size = (min(0.9, (0.45 * letters + 2.5) * line * height / width), line * len(entries) + 8 / height)
    return size, entries


def arrow_axes(vectors: np.ndarray, scale: float, width: float) -> np.ndarray:
    """Glyph axes (K, 9) turning a unit arrow along x into arrows along ``vectors`` (K, 3), ``scale`` metres long
    per unit up to CAP × ``width``, all as thick as an arrow ``width`` [m] long; columns one after the other, as
    VTK reads a tensor."""
    basis = arrow_basis(vectors)  # (K, 3, 3), columns: along, across, across
    length = np.minimum(np.linalg.norm(vectors, axis=1) * scale, CAP * width)
    columns = np.stack([basis[:, :, 0] * length[:, None], basis[:, :, 1] * width, basis[:, :, 2] * width], axis=1)
    columns[length == 0] = 0.0  # no arrow at all where the quantity is zero
    return columns.reshape(-1, 9)
