"""Ambient occlusion on the ground: the soft darkening of the ground around where a body rests on it or passes close.

A sphere of radius ``r`` centred at ``c`` hides, from a point ``p`` of a plane with normal ``n``, the fraction
``(n · d / |d|) · r² / |d|²`` of its sky (``d = c − p``; exact for a sphere wholly above the plane's horizon, e.g.
Quilez, "sphere ambient occlusion"). Several bodies hide independent parts of the sky, so the light that reaches
``p`` is ``Π (1 − occlusionₖ)``. Each frame writes that, for every body near the ground, into the alpha of a black
texture laid over the ground; a rigid body counts as the sphere of its volume.

Screen-space ambient occlusion (VTK's SSAO pass) was tried first: under Mesa's software rasteriser it stippled the
far ground with patches and greyed a flat ground where nothing was near it, differently from frame to frame.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: How dark the ground gets where it is wholly occluded (directly under a resting sphere): 1 would be black.
OCCLUSION_STRENGTH = 0.55
#: Bodies whose greatest occlusion of the ground, (r / h)², is below this are skipped; and each body darkens only
#: the texels within WINDOW_RADII of its radius (where a resting sphere's occlusion has fallen to ~1/70 of its peak),
#: tapered smoothly to zero there.
NEGLIGIBLE = 0.02
WINDOW_RADII = 4.0
#: Texels across the occlusion texture (it covers the square of the ground around the motion).
TEXTURE_SIZE = 256
#: Bodies per vectorised batch (bodies are sorted by radius, so each batch's window fits its own largest body).
BATCH = 64


def sphere_occlusion(offsets: np.ndarray, heights: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """The fraction of the sky that spheres hide from points of the plane: ``offsets`` [m] (..., ) distances along
    the plane from the point under each sphere's centre, ``heights`` [m] (...) of the centres above the plane,
    ``radius`` [m] (...). Returns values in [0, 1]; a sphere touching or cutting the plane hides all of it right
    under itself."""
    distance_squared = offsets**2 + heights**2
    with np.errstate(divide="ignore", invalid="ignore"):
        occlusion = heights * radius**2 / distance_squared**1.5
    return np.clip(np.nan_to_num(occlusion, nan=1.0, posinf=1.0), 0.0, 1.0)


def ground_light(centres_uv: np.ndarray, heights: np.ndarray, radius: np.ndarray, texel: float,
                 size: int = TEXTURE_SIZE) -> np.ndarray:
    """The fraction of ambient light (size, size) that reaches each texel of a square of ``size`` texels of side
    ``texel`` [m], given bodies at ``centres_uv`` (K, 2) [texels, from the square's corner], ``heights`` (K,) [m]
    above it and of ``radius`` (K,) [m]. Row index is v, column u."""
    log_light = np.zeros(size * size)
    near = (radius > 0) & (heights < radius / math.sqrt(NEGLIGIBLE))
    order = np.argsort(radius[near])
    centres_uv, heights, radius = centres_uv[near][order], heights[near][order], radius[near][order]
    for start in range(0, len(radius), BATCH):  # a loop over batches of bodies, not over bodies
        stop = start + BATCH
        reach = int(math.ceil(WINDOW_RADII * radius[stop - 1 if stop <= len(radius) else -1] / texel))
        reach = min(reach, size)
        steps = np.arange(-reach, reach + 1)
        base = np.floor(centres_uv[start:stop]).astype(int)  # (k, 2)
        u = base[:, 0, None, None] + steps[None, None, :]  # (k, 1, w)
        v = base[:, 1, None, None] + steps[None, :, None]  # (k, w, 1)
        du = (u + 0.5 - centres_uv[start:stop, 0, None, None]) * texel
        dv = (v + 0.5 - centres_uv[start:stop, 1, None, None]) * texel
        offsets = np.hypot(du, dv)
        window = WINDOW_RADII * radius[start:stop, None, None]
        # tapered to nothing at the window's edge, so that no ring shows where a body's reach is cut off
        taper = np.clip(1 - (offsets / window) ** 2, 0.0, 1.0) ** 2
        occlusion = taper * sphere_occlusion(offsets, heights[start:stop, None, None], radius[start:stop, None, None])
        inside = (u >= 0) & (u < size) & (v >= 0) & (v < size)
        u, v = np.broadcast_arrays(u, v)
        inside = np.broadcast_to(inside, occlusion.shape)
        np.add.at(log_light, (v * size + u)[inside], np.log1p(-OCCLUSION_STRENGTH * occlusion[inside]))
    return np.exp(log_light).reshape(size, size)


class GroundOcclusion:
    """A black texture over the square of the ground around the motion, whose alpha is the ground's occlusion."""

    def __init__(self, pv: Any, plotter: Any, *, origin: np.ndarray, up: np.ndarray, side: float,
                 lift: float) -> None:
        """``origin`` [m]: the square's centre on the ground; ``side`` [m]; ``lift`` [m] above the ground, so the
        texture wins the depth test against it."""
        from vtkmodules.vtkRenderingCore import vtkTexture  # heavy (VTK): only when drawing

        self.up = up / np.linalg.norm(up)
        self.level = float(np.dot(origin, self.up))
        plane = pv.Plane(center=origin + lift * self.up, direction=self.up, i_size=side, j_size=side)
        # the square's corner and edges, in the texture's own (u, v) directions
        uv = np.asarray(plane.active_texture_coordinates)
        points = np.asarray(plane.points) - lift * self.up
        corner = points[np.argmin(uv[:, 0] + uv[:, 1])]
        self.corner = corner
        self.u_axis = points[np.argmax(uv[:, 0] - uv[:, 1])] - corner
        self.v_axis = points[np.argmax(uv[:, 1] - uv[:, 0])] - corner
        self.texel = side / TEXTURE_SIZE
        self.image = pv.ImageData(dimensions=(TEXTURE_SIZE, TEXTURE_SIZE, 1))
        self.image.point_data["rgba"] = np.zeros((TEXTURE_SIZE * TEXTURE_SIZE, 4), np.uint8)  # black
        self.alpha = self.image.point_data["rgba"]  # VTK's own array: written in place each frame
        texture = vtkTexture()
        texture.SetInputDataObject(self.image)
        texture.InterpolateOn()
        texture.SetColorModeToDirectScalars()
        actor = plotter.add_mesh(plane, texture=texture, lighting=False, show_scalar_bar=False)
        actor.prop.backface_culling = False

    def update(self, centres: np.ndarray, radius: np.ndarray) -> None:
        """Darken the ground under bodies at ``centres`` (K, 3) [m] of ``radius`` (K,) [m]."""
        offset = centres - self.corner
        uv = np.stack([offset @ self.u_axis / (self.u_axis @ self.u_axis),
                       offset @ self.v_axis / (self.v_axis @ self.v_axis)], axis=1) * TEXTURE_SIZE
        heights = centres @ self.up - self.level
        light = ground_light(uv, heights, radius, self.texel)
        self.alpha[:, 3] = np.round(255 * (1 - light)).astype(np.uint8).ravel()
        self.image.Modified()
