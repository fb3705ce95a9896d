"""The studio a scene is shot in: a gradient backdrop, a three-point light rig fixed in the world, and a ground that
shows scale with a grid and fades into the backdrop towards the horizon.

The lights are scene lights (fixed in the world, like the contact shadows' key light), not lights that ride on the
camera, so that an orbiting or following camera sees the bodies lit and shadowed consistently. The ground's fade is
a per-vertex colour blend into the backdrop's colour at the height where each vertex appears on screen (through the
first frame's camera): the ground stays opaque, so it costs no translucent pass, and its edge disappears.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.render.camera import CameraPlacement, nice_spacing, plane_axes
from animbatch.render.colors import hex_to_rgb
from animbatch.render.shadows import key_light_direction

#: How far the ground reaches, as a multiple of the fitted square around the motion, and where its fade starts and
#: ends (radii as fractions of that square's side).
GROUND_REACH = 4.0
FADE_RADII = (0.6, 1.9)
#: The grid fades sooner: far away its lines crowd together into a band at the horizon.
GRID_FADE_RADII = (0.45, 1.2)
#: Points along each grid line, so that its colour can fade along it; and the most lines in each direction.
GRID_LINE_POINTS = 48
MAX_GRID_LINES = 240


#: The bounce light's intensity (the key's is 0.8).
BOUNCE = 0.35


@dataclass(frozen=True)
class RigLight:
    """One light of the rig: where it shines from (unit vector from the subject towards the light) and how bright."""

    name: str
    toward_light: np.ndarray
    intensity: float


def three_point_rig(up: np.ndarray, toward_camera: np.ndarray) -> list[RigLight]:
    """A key light from above, on the camera's side and to its left (the light the contact shadows fall from), a
    softer fill from the camera's right and low, and a rim light from behind, above and to the right that outlines
    the bodies against the backdrop; and under them, a bounce from below the camera (the light a floor throws back
    up), so that a surface the camera sees but the key does not, such as the underside of a sheet swinging towards
    the camera, stays readable. ``up``, ``toward_camera``: unit vectors (from the subject towards the camera)."""
    up = up / np.linalg.norm(up)
    level = toward_camera - np.dot(toward_camera, up) * up
    level = level / np.linalg.norm(level) if np.linalg.norm(level) > 1e-9 else plane_axes(up)[0]
    right = np.cross(up, level)  # the camera's right, seen from the camera

    def unit(vector: np.ndarray) -> np.ndarray:
        return vector / np.linalg.norm(vector)

    return [RigLight("key", -key_light_direction(up, toward_camera), 0.8),
            RigLight("fill", unit(level + 0.9 * right + 0.35 * up), 0.4),
            RigLight("rim", unit(-level + 0.4 * right + 0.8 * up), 0.3),
            RigLight("bounce", unit(level - 0.5 * up), BOUNCE)]


def add_lights(pv: Any, plotter: Any, rig: list[RigLight], focal: np.ndarray, distance: float) -> None:
    """Add the rig as directional scene lights aimed at ``focal`` [m]."""
    for light in rig:
        plotter.add_light(pv.Light(position=tuple(focal + distance * light.toward_light), focal_point=tuple(focal),
                                   intensity=light.intensity, light_type="scene light", positional=False))


def backdrop_color(bottom: np.ndarray, top: np.ndarray | None, height: np.ndarray) -> np.ndarray:
    """The backdrop's colour (…, 3) in 0…1 at screen ``height`` (…,), 0 at the bottom edge and 1 at the top."""
    if top is None:
        return np.broadcast_to(bottom, (*np.shape(height), 3)).copy()
    fraction = np.clip(height, 0.0, 1.0)[..., None]
    return bottom * (1 - fraction) + top * fraction


def screen_height(camera: CameraPlacement, points: np.ndarray) -> np.ndarray:
    """Where ``points`` (…, 3) [m] appear on screen through ``camera``: 0 at the bottom edge, 1 at the top (points
    behind the camera count as the top, the sky)."""
    forward = camera.focal_point - camera.position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, camera.up)
    right /= np.linalg.norm(right)
    screen_up = np.cross(right, forward)
    relative = points - camera.position
    depth = relative @ forward
    tangent = math.tan(math.radians(camera.view_angle) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        height = 0.5 + 0.5 * (relative @ screen_up) / (np.maximum(depth, 1e-12) * tangent)
    return np.where(depth > 0, height, 1.0)


def smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


class StudioGround:
    """The ground: an opaque square around the motion, with an optional grid, both fading into the backdrop."""

    def __init__(self, pv: Any, plotter: Any, *, origin: np.ndarray, up: np.ndarray, side: float, reach: float,
                 color: str, grid: bool, fade: bool, camera: CameraPlacement, backdrop: tuple[np.ndarray, Any]
                 ) -> None:
        """``side`` [m]: the square around the motion that the grid's spacing is chosen for; ``reach`` [m]: the
        side of the drawn ground (fading out from 0.6 to 1.9 ``side`` from the centre when ``fade``, beyond the
        motion and to its sides, never between it and the camera)."""
        first, second = plane_axes(up)
        self.origin, self.side, self.reach, self.up = origin, side, reach, up / np.linalg.norm(up)
        # fine enough for the fade to stay smooth however far the ground reaches (it runs under the camera)
        resolution = int(np.clip(8 * reach / side, 32, 192)) if fade else 1
        plane = pv.Plane(center=origin, direction=up, i_size=reach, j_size=reach, i_resolution=resolution,
                         j_resolution=resolution)
        base = np.asarray(hex_to_rgb(color))
        plane.point_data["rgb"] = self._faded(np.asarray(plane.points), base, fade, camera, backdrop, FADE_RADII)
        # unlit: directional lights shade a flat plane evenly anyway, and its faded rim must match the backdrop
        plotter.add_mesh(plane, scalars="rgb", rgb=True, show_scalar_bar=False, lighting=False)
        if grid:
            spacing = nice_spacing(side, 12)
            half = min(reach / 2, MAX_GRID_LINES / 2 * spacing)
            ticks = np.arange(-math.floor(half / spacing), math.floor(half / spacing) + 1) * spacing
            lift = up * 1e-3 * side  # just above the plane, so the lines win the depth test
            along = np.linspace(-half, half, GRID_LINE_POINTS)
            lines = []
            for offset in ticks:
                for axis, across in ((first, second), (second, first)):
                    lines.append(origin + lift + axis * offset + along[:, None] * across)
            points = np.concatenate(lines)
            count = len(lines)
            index = np.arange(count * GRID_LINE_POINTS).reshape(count, GRID_LINE_POINTS)
            cells = np.concatenate([np.full((count, 1), GRID_LINE_POINTS), index], axis=1).ravel()
            mesh = pv.PolyData(points, lines=cells)
            line_color = base * 0.72  # a darker shade of the ground: subtle, in any ground colour
            mesh.point_data["rgb"] = self._faded(points, line_color, fade, camera, backdrop, GRID_FADE_RADII)
            plotter.add_mesh(mesh, scalars="rgb", rgb=True, show_scalar_bar=False, line_width=1, lighting=False)

    def _faded(self, points: np.ndarray, color: np.ndarray, fade: bool, camera: CameraPlacement,
               backdrop: tuple[np.ndarray, Any], radii: tuple[float, float]) -> np.ndarray:
        """Per-point colours (K, 3) uint8: ``color`` near the centre, the backdrop behind each point towards the
        edge."""
        colors = np.broadcast_to(color, (len(points), 3)).astype(float)
        if fade:
            # towards the horizon and the sides only: the ground between the motion and the camera never fades
            offset = points - self.origin
            view = camera.focal_point - camera.position
            away = view - np.dot(view, self.up) * self.up
            away = away / np.linalg.norm(away) if np.linalg.norm(away) > 1e-12 else np.zeros(3)
            depth = offset @ away
            lateral = offset - np.outer(depth, away) - np.outer(offset @ self.up, self.up)
            radius = np.hypot(np.maximum(depth, 0.0), np.linalg.norm(lateral, axis=1))
            weight = smoothstep(radii[0] * self.side, radii[1] * self.side, radius)[:, None]
            behind = backdrop_color(*backdrop, screen_height(camera, points))
            colors = colors * (1 - weight) + behind * weight
        return np.round(255 * np.clip(colors, 0, 1)).astype(np.uint8)


#: Side of each face of the environment cube map [px], and how bright it is relative to the backdrop: image-based
#: lighting adds to the three lights, so the environment is dimmed to keep bodies from washing out.
ENVIRONMENT_SIZE = 32
ENVIRONMENT_GAIN = 0.35


def environment_faces(up: np.ndarray, sky: tuple[np.ndarray, np.ndarray | None], ground: np.ndarray,
                      size: int = ENVIRONMENT_SIZE) -> list[np.ndarray]:
    """The six faces (+X, −X, +Y, −Y, +Z, −Z; each (size, size, 3) uint8, rows from the top) of a cube map that
    surrounds the scene with its studio: the backdrop's gradient above the horizon (``sky``: its bottom and top
    colours in 0…1) and the ground's colour below, so that metals reflect the room they are in."""
    up = up / np.linalg.norm(up)
    u, v = np.meshgrid(np.linspace(-1, 1, size), np.linspace(-1, 1, size))  # v grows downwards on the face
    one = np.ones_like(u)
    directions = [np.stack(d, axis=-1) for d in (
        (one, -v, -u), (-one, -v, u), (u, one, v), (u, -one, -v), (u, -v, one), (-u, -v, -one))]
    bottom, top = sky
    faces = []
    for direction in directions:
        elevation = (direction / np.linalg.norm(direction, axis=-1, keepdims=True)) @ up
        above = backdrop_color(bottom, top, np.sqrt(np.clip(elevation, 0, 1)))
        color = np.where((elevation >= 0)[..., None], above, ground)
        faces.append(np.round(255 * np.clip(ENVIRONMENT_GAIN * color, 0, 1)).astype(np.uint8))
    return faces


def use_environment(pv: Any, plotter: Any, faces: list[np.ndarray]) -> None:
    """Light physically based materials by the cube map ``faces``. VTK's default prefiltering of the environment takes
    ~40 s under Mesa's software rasteriser; a 32-pixel cube, 4 roughness levels and few samples take well under a
    second and look the same on a studio gradient. Every new render window pays it at its first frame (a render, a
    farm chunk, a test), so the two smooth tables are coarse: the diffuse irradiance sampled every 0.4 rad and the
    BRDF table 32 × 32 (0.47 s → 0.30 s for a first frame of scenes/dominoes.yaml; at 640×360 the frames of
    scenes/mixed_pile.yaml differ by more than 8 levels in 10 pixels of 230 400)."""
    images = []
    for face in faces:
        image = pv.ImageData(dimensions=(face.shape[1], face.shape[0], 1))
        image.point_data["rgb"] = face[::-1].reshape(-1, 3)  # image rows run bottom-up
        images.append(image)
    plotter.set_environment_texture(pv.Texture(images))
    renderer = plotter.renderer
    prefilter = renderer.GetEnvMapPrefiltered()
    prefilter.SetPrefilterMaxSamples(32)
    prefilter.SetPrefilterLevels(4)
    irradiance = renderer.GetEnvMapIrradiance()
    irradiance.SetIrradianceSize(16)
    irradiance.SetIrradianceStep(0.4)
    lookup = renderer.GetEnvMapLookupTable()
    lookup.SetLUTSize(32)
    lookup.SetLUTSamples(32)
