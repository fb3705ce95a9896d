"""Camera placement: as given in the scene, or fitted to the bounding box of the whole motion.

Pure geometry (no VTK), so it is cheap to test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from animbatch.scene.schema import CameraSpec


@dataclass(frozen=True)
class CameraPlacement:
    """Position, focal point [m], up vector, vertical view angle [deg] and near/far clipping distances [m]."""

    position: np.ndarray
    focal_point: np.ndarray
    up: np.ndarray
    view_angle: float
    clipping_range: tuple[float, float]


def motion_bounds(positions: np.ndarray, radius: np.ndarray, extra_points: np.ndarray | None = None) -> np.ndarray:
    """Axis-aligned box [[min xyz], [max xyz]] [m] around every body at every frame, grown by each body's radius.

    ``positions``: (F, N, 3); ``radius``: (N,); ``extra_points``: (K, 3) such as anchors.
    """
    low, high = np.full(3, np.inf), np.full(3, -np.inf)
    if positions.size:
        finite = np.where(np.isfinite(positions), positions, np.nan)
        low = np.nanmin(finite - radius[None, :, None], axis=(0, 1))
        high = np.nanmax(finite + radius[None, :, None], axis=(0, 1))
    if extra_points is not None and len(extra_points):
        low = np.minimum(low, extra_points.min(axis=0))
        high = np.maximum(high, extra_points.max(axis=0))
    if not np.all(np.isfinite(low)):  # nothing to frame
        low, high = -np.ones(3), np.ones(3)
    return np.stack([low, high])


def place_camera(spec: CameraSpec, bounds: np.ndarray, aspect: float = 16 / 9) -> CameraPlacement:
    """Where the camera goes for ``bounds`` (2, 3) and frame ``aspect`` (width / height).

    Fitted unless the scene gives position and focal point: the camera looks at the centre of the box from
    ``spec.direction`` and backs off until all eight corners of the box fit the frame, in both the vertical field of
    view and the horizontal one (wider by ``aspect``), with ``fit_margin`` to spare.
    """
    centre = bounds.mean(axis=0)
    size = max(float(np.linalg.norm(bounds[1] - bounds[0])), 1e-3)  # a point-like motion still gets a size
    up = _unit(np.asarray(spec.up, float))
    tan_vertical = math.tan(math.radians(spec.view_angle) / 2)
    if spec.position is not None and spec.focal_point is not None:
        position = np.asarray(spec.position, float)
        focal = np.asarray(spec.focal_point, float)
    else:
        direction = _unit(np.asarray(spec.direction, float))
        if abs(float(np.dot(direction, up))) > 0.999:  # looking straight along 'up': tilt slightly
            direction = _unit(direction + 0.05 * _any_perpendicular(up))
        right = _unit(np.cross(up, direction))
        screen_up = np.cross(direction, right)
        corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1)
                            for k in (0, 1)]) - centre
        corners *= spec.fit_margin
        toward_camera = corners @ direction  # a corner nearer the camera needs more distance
        distance = max(float(np.max(toward_camera + np.abs(corners @ screen_up) / tan_vertical)),
                       float(np.max(toward_camera + np.abs(corners @ right) / (tan_vertical * aspect))),
                       1e-3)
        focal = centre
        position = centre + direction * distance
    to_centre = float(np.linalg.norm(centre - position))
    near = max(to_centre - 1.5 * size, to_centre * 1e-3, 1e-4)
    far = to_centre + 4.0 * size  # room for the ground plane behind the motion
    return CameraPlacement(position, focal, up, float(spec.view_angle), (near, far))


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _any_perpendicular(vector: np.ndarray) -> np.ndarray:
    trial = np.array([1.0, 0.0, 0.0]) if abs(vector[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    return _unit(np.cross(vector, trial))


def plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane perpendicular to ``normal``."""
    first = _any_perpendicular(_unit(normal))
    return first, np.cross(_unit(normal), first)


def nice_spacing(extent: float, lines: int = 10) -> float:
    """A round grid spacing (1, 2 or 5 × 10^k) giving about ``lines`` lines over ``extent``."""
    raw = max(extent, 1e-9) / lines
    power = 10 ** math.floor(math.log10(raw))
    for factor in (1, 2, 5, 10):
        if factor * power >= raw:
            return factor * power
    return 10 * power
