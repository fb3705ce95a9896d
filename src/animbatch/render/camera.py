"""Camera placement: as given in the scene, or fitted to the bounding box of the whole motion; and its path over
time (:class:`CameraPath`: keyframes, following a body, orbiting).

A fitted camera keeps what it frames out of the frame's reserved strips (:class:`Reserved`) along the top and
bottom edges, where the overlay's text and the arrows' legend are written. The box is fitted into the rest of the
frame, and the camera aims above or below the box's centre so that the centre sits in the middle of that rest.

Pure geometry (no VTK), so it is cheap to test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.render.frame_geometry import BodyPath
from animbatch.render.settings import CameraSettings


@dataclass(frozen=True)
class CameraPlacement:
    """Position, focal point [m], up vector and vertical view angle [deg]. (The renderer fits the near and far
    clipping planes to everything it draws, ground included, at each frame.)"""

    position: np.ndarray
    focal_point: np.ndarray
    up: np.ndarray
    view_angle: float


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


@dataclass(frozen=True)
class Reserved:
    """The strips of the frame a fitted camera keeps clear, as fractions of the frame's height: ``top`` along the
    top edge, ``bottom`` along the bottom edge (full width: the overlay and the legend sit in corners, and a strip
    is what keeps every body, arrow and trail out of them whatever the shape of the motion)."""

    top: float = 0.0
    bottom: float = 0.0

    def __post_init__(self) -> None:
        if not (0 <= self.top and 0 <= self.bottom and self.top + self.bottom <= MOST_RESERVED):
            raise ValueError(f"reserved strips of {self.top:.3g} and {self.bottom:.3g} of the frame leave too little "
                             "to draw in")

    @property
    def limits(self) -> tuple[float, float]:
        """The lowest and highest normalised screen height (−1 at the bottom edge, 1 at the top) left to draw in."""
        return -1 + 2 * self.bottom, 1 - 2 * self.top


#: The most of a frame's height the strips may take together.
MOST_RESERVED = 0.6
NOTHING_RESERVED = Reserved()


def place_camera(spec: CameraSettings, bounds: np.ndarray, aspect: float = 16 / 9,
                 any_azimuth: bool = False, reserved: Reserved = NOTHING_RESERVED) -> CameraPlacement:
    """Where the camera goes for ``bounds`` (2, 3) and frame ``aspect`` (width / height).

    Fitted unless the scene gives position and focal point: the camera looks at the centre of the box from
    ``spec.direction`` and backs off until all eight corners of the box fit the frame, in both the vertical field of
    view and the horizontal one (wider by ``aspect``), with ``fit_margin`` to spare; with ``any_azimuth`` (an orbiting
    camera) far enough for every direction turned about ``up``. With ``reserved`` strips the corners fit between
    them, and the camera aims up or down along the screen so that the box's centre is midway between them.
    """
    centre = bounds.mean(axis=0)
    up = _unit(np.asarray(spec.up, float))
    tan_vertical = math.tan(math.radians(spec.view_angle) / 2)
    if spec.position is not None and spec.focal_point is not None:
        position = np.asarray(spec.position, float)
        focal = np.asarray(spec.focal_point, float)
    else:
        direction = _unit(np.asarray(spec.direction, float))
        if abs(float(np.dot(direction, up))) > 0.999:  # looking straight along 'up': tilt slightly
            direction = _unit(direction + 0.05 * _any_perpendicular(up))
        corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1)
                            for k in (0, 1)]) - centre
        corners *= spec.fit_margin
        low, high = reserved.limits
        if any_azimuth:  # one aim for every side: the box stays centred, inside the narrower of the two halves
            half = min(-low, high)
            turns = np.linspace(0, 2 * np.pi, 24, endpoint=False)
            distance = max(_fit(corners, _turn(direction, up, angle), up, tan_vertical, aspect, -half, half)[0]
                           for angle in turns)
            shift = 0.0
        else:
            distance, shift = _fit(corners, direction, up, tan_vertical, aspect, low, high)
        right = _unit(np.cross(up, direction))
        focal = centre + shift * np.cross(direction, right)
        position = focal + direction * distance
    return CameraPlacement(position, focal, up, float(spec.view_angle))


def _fit(corners: np.ndarray, direction: np.ndarray, up: np.ndarray, tan_vertical: float, aspect: float,
         low: float = -1.0, high: float = 1.0) -> tuple[float, float]:
    """How far along ``direction`` the camera must stand to see every corner (8, 3) [m] (relative to the box's
    centre) between the normalised screen heights ``low`` and ``high``, with the box's centre at the middle of
    them, and how far [m] along the screen's up its aim moves from the centre for that: (distance, shift).

    Seen from distance D with the aim shifted by s, a point at height h along the screen's up and w toward the camera
    is at screen height (h − s) / ((D − w) tan θ). The centre (h = w = 0) at the middle m = (low + high) / 2 takes
    s = −m D tan θ; then a corner fits when D ≥ h / (r tan θ) + high w / r and D ≥ −h / (r tan θ) − low w / r,
    r = (high − low) / 2 (with the whole frame: D ≥ w + |h| / tan θ, the symmetric fit)."""
    right = _unit(np.cross(up, direction))
    screen_up = np.cross(direction, right)
    toward_camera = corners @ direction  # a corner nearer the camera needs more distance
    height = corners @ screen_up
    middle, half = (low + high) / 2, (high - low) / 2
    distance = max(float(np.max(toward_camera + np.abs(corners @ right) / (tan_vertical * aspect))),
                   float(np.max(height / (half * tan_vertical) + high * toward_camera / half)),
                   float(np.max(-height / (half * tan_vertical) - low * toward_camera / half)), 1e-3)
    return distance, -middle * distance * tan_vertical


def _turn(vector: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``vector`` turned by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    cos, sin = math.cos(angle), math.sin(angle)
    return vector * cos + np.cross(axis, vector) * sin + axis * np.dot(axis, vector) * (1 - cos)


def follower(path: BodyPath, lag: float) -> np.ndarray:
    """Where a critically damped follower of the body is at each frame (F, 3) [m], starting on the body at rest.

    Two first-order lags of time constant τ = ``lag`` / 2 in series (a critically damped second-order system),
    solved exactly for a body path that is straight between frames; so at constant velocity the follower trails the
    body by exactly ``lag`` seconds once settled, and it never overshoots.
    """
    body = np.asarray(path.positions, float)
    if lag <= 0 or len(body) < 2:
        return body.copy()
    tau = lag / 2
    first, second = body[0].copy(), body[0].copy()  # the two stages' outputs
    result = np.empty_like(body)
    result[0] = second
    for k in range(1, len(body)):
        step = float(path.times[k] - path.times[k - 1])
        slope = (body[k] - body[k - 1]) / step if step > 0 else np.zeros(3)
        # particular solutions for a ramp input u: u − τ s and u − 2 τ s; the rest decays as e^(−t/τ) (and t e^(−t/τ))
        c1 = first - (body[k - 1] - tau * slope)
        c2 = second - (body[k - 1] - 2 * tau * slope)
        decay = math.exp(-step / tau)
        first = body[k] - tau * slope + c1 * decay
        second = body[k] - 2 * tau * slope + (c2 + c1 * step / tau) * decay
        result[k] = second
    return result


class CameraPath:
    """Where the camera is at any time: its own placement (fitted or given), moved by keyframes, then by a followed
    body (focal point on the smoothed body, same offset), then turned about the orbit's axis."""

    def __init__(self, spec: CameraSettings, bounds: np.ndarray, aspect: float = 16 / 9,
                 followed: BodyPath | None = None, reserved: Reserved = NOTHING_RESERVED) -> None:
        self.spec = spec
        self.up = _unit(np.asarray(spec.up, float))
        fit = bounds
        if followed is not None and spec.position is None:
            # frame the neighbourhood of the body, not the whole motion: a quarter of the motion, at least 8 sizes
            half = max(4 * followed.extent, float(np.max(bounds[1] - bounds[0])) / 8)
            start = np.asarray(followed.positions[0], float)
            fit = np.stack([start - half, start + half])
        self.base = place_camera(spec, fit, aspect, any_azimuth=spec.orbit is not None, reserved=reserved)
        # a followed body stays where the fit put the box's centre (between the reserved strips), not on the aim
        self.aim_offset = self.base.focal_point - fit.mean(axis=0)
        self.splines = self._keyframe_splines(spec)
        self.followed = followed
        self.track = follower(followed, spec.follow_lag) if followed is not None else None
        self.moves = spec.moves

    def _keyframe_splines(self, spec: CameraSettings) -> dict[str, Any]:
        """One clamped cubic spline (at rest at both ends) per keyframed quantity, over the keyframes giving it."""
        from scipy.interpolate import CubicSpline  # only for keyframed cameras

        splines: dict[str, Any] = {}
        for name in ("position", "focal_point", "view_angle"):
            given = [(frame.t, getattr(frame, name)) for frame in spec.keyframes or [] if getattr(frame, name)
                     is not None]
            if len(given) == 1:
                value = np.asarray(given[0][1], float)
                splines[name] = lambda t, value=value: value
            elif given:
                times, values = zip(*given)
                splines[name] = _held(CubicSpline(times, np.asarray(values, float), bc_type="clamped"),
                                      times[0], times[-1])
        return splines

    def at(self, t: float) -> CameraPlacement:
        """The camera at time ``t`` [s]."""
        base, splines = self.base, self.splines
        position = np.asarray(splines["position"](t) if "position" in splines else base.position, float)
        focal = np.asarray(splines["focal_point"](t) if "focal_point" in splines else base.focal_point, float)
        view_angle = float(splines["view_angle"](t)) if "view_angle" in splines else base.view_angle
        if self.track is not None and self.followed is not None:
            body = np.array([np.interp(t, self.followed.times, self.track[:, k]) for k in range(3)])
            aim = body + self.aim_offset
            position, focal = position + aim - focal, aim
        orbit = self.spec.orbit
        if orbit is not None:
            centre = np.asarray(orbit.center, float) if orbit.center is not None else focal
            angle = 2 * math.pi * t / orbit.period
            position = centre + _turn(position - centre, self.up, angle)
            focal = centre + _turn(focal - centre, self.up, angle)
        return CameraPlacement(position, focal, self.up, view_angle)


def _held(spline: Any, first: float, last: float) -> Any:
    """``spline`` inside [first, last], its end values outside."""
    return lambda t: spline(min(max(t, first), last))


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
