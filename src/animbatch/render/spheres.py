"""Particles drawn as sphere meshes: one instanced actor per look, whatever the number of particles.

A VTK glyph mapper draws one sphere mesh at every point of a point set, scaled by the particle's radius and coloured
by its colour, in one draw call; a frame rewrites the points in place. (One actor per sphere, moved by SetPosition,
cost a draw call and a matrix per sphere: 1000 spheres drew at a third of a frame per second.) The sphere is
tessellated for its size on screen, a segment every few pixels of its outline up to the quality's
``sphere_resolution``, so that a thousand small spheres do not cost a thousand 64-segment meshes. Contact shadows
are the same glyphs through the shadows' constant flattening matrix: one set on the ground, and one on each face
that catches shadows (:mod:`animbatch.render.shadows`), where a sphere's glyph has its radius only while that face
is the one under it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from animbatch.render.colors import hex_to_rgb, srgb_to_linear
from animbatch.render.frame_geometry import Finish
from animbatch.render.shadows import GroundShadows

#: Pixels of a sphere's outline per segment when it is tessellated for its size on screen.
PIXELS_PER_SEGMENT = 4.0


def sphere_segments(most: int, radius: float, distance: float, view_angle: float, height: int) -> int:
    """Segments around a sphere of ``radius`` [m] seen from ``distance`` [m] with a vertical ``view_angle`` [deg] in
    a frame ``height`` [px] high: one per PIXELS_PER_SEGMENT of its outline, between 8 and ``most``."""
    if distance <= 0:
        return most
    pixels = radius / (distance * math.tan(math.radians(view_angle) / 2)) * height / 2  # its radius on screen
    return int(np.clip(math.ceil(2 * math.pi * pixels / PIXELS_PER_SEGMENT), 8, most))


class SphereGroup:
    """Spheres that share a look (one finish): one instanced actor, and one for their shadows."""

    def __init__(self, pv: Any, plotter: Any, radius: np.ndarray, colors: list[str], segments: int,
                 shading: dict[str, Any], shadows: GroundShadows | None) -> None:
        """``radius`` (K,) [m], ``colors`` (K,) '#rrggbb', ``shading``: the add_mesh keywords of their look (its
        colour is ignored: each sphere has its own); ``shadows``: the scene's contact shadows, or None."""
        from vtkmodules.vtkRenderingCore import vtkGlyph3DMapper  # heavy (VTK): only when drawing

        count = len(radius)
        self.radius = np.asarray(radius, float)
        self.points = pv.PolyData(np.zeros((count, 3)))
        self.points.point_data["radius"] = self.radius
        rgb = np.array([hex_to_rgb(c) for c in colors]).reshape(count, 3)
        if shading.get("pbr"):  # physically based shading takes linear colours
            rgb = srgb_to_linear(rgb)
        self.points.point_data["rgb"] = np.round(255 * rgb).astype(np.uint8)
        sphere = pv.Sphere(radius=1.0, theta_resolution=segments, phi_resolution=segments)

        def mapper(points: Any, colored: bool) -> Any:
            glyphs = vtkGlyph3DMapper()
            glyphs.SetInputData(points)
            glyphs.SetSourceData(sphere)
            glyphs.SetScaleArray("radius")
            glyphs.SetScaleModeToScaleByMagnitude()
            glyphs.OrientOff()
            if colored:
                glyphs.SetScalarModeToUsePointFieldData()
                glyphs.SelectColorArray("rgb")
                glyphs.SetColorModeToDirectScalars()
                glyphs.ScalarVisibilityOn()
            else:
                glyphs.ScalarVisibilityOff()
            return glyphs

        look = {key: value for key, value in shading.items() if key != "color"}
        self.actor = plotter.add_mesh(sphere, **look)  # its properties; the glyph mapper then replaces the mesh
        self.actor.SetMapper(mapper(self.points, colored=True))
        self.shadows = shadows
        # (receiver, its points): the ground's shadows share the spheres' points while no face catches any
        self._shadow_sets: list[tuple[int, Any]] = []
        if shadows is not None:
            for receiver in range(-1, len(shadows.receivers)):
                points = self.points
                if shadows.receivers:
                    points = pv.PolyData(np.zeros((count, 3)))
                    points.point_data["radius"] = np.zeros(count)
                actor = plotter.add_mesh(sphere, **GroundShadows.LOOK)
                actor.SetMapper(mapper(points, colored=False))
                shadows.clip(actor.mapper, receiver)
                actor.prop.backface_culling = False
                # constant: the points are already in world coordinates
                actor.SetUserMatrix(_matrix(shadows.projection_onto(receiver)))
                self._shadow_sets.append((receiver, points))

    def update(self, positions: np.ndarray) -> None:
        """Move the spheres (and their shadows) to ``positions`` (K, 3) [m]."""
        self.points.points[:] = positions
        self.points.GetPoints().Modified()
        if self.shadows is None or not self.shadows.receivers:
            return
        under = self.shadows.receivers_of(np.asarray(positions, float))
        for receiver, points in self._shadow_sets:  # each sphere's shadow drawn on the face under it alone
            points.points[:] = positions
            points.point_data["radius"][:] = np.where(under == receiver, self.radius, 0.0)
            points.Modified()


def _matrix(values: np.ndarray) -> Any:
    from vtkmodules.vtkCommonMath import vtkMatrix4x4  # heavy (VTK): only when drawing

    matrix = vtkMatrix4x4()
    matrix.DeepCopy(np.asarray(values, float).ravel().tolist())
    return matrix


def group_by_finish(finishes: list[Finish | None]) -> dict[Finish | None, np.ndarray]:
    """Indices (into ``finishes``) of the particles of each look, in first-seen order."""
    groups: dict[Finish | None, list[int]] = {}
    for index, finish in enumerate(finishes):
        groups.setdefault(finish, []).append(index)
    return {finish: np.array(indices, np.intp) for finish, indices in groups.items()}
