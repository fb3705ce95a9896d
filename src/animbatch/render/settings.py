"""The render settings the renderer reads, as read-only protocols: the scene's ``render`` section has this shape
(the compiler hands it over as it is), so that drawing never imports the scene format. A setting the renderer
starts to read is added here, and mypy checks that the scene format still provides it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol


class CameraKey(Protocol):
    """A camera keyframe: at time ``t`` [s], any of position [m], focal point [m] and view angle [deg]."""

    @property
    def t(self) -> float: ...

    @property
    def position(self) -> Sequence[float] | None: ...

    @property
    def focal_point(self) -> Sequence[float] | None: ...

    @property
    def view_angle(self) -> float | None: ...


class Orbit(Protocol):
    """A camera circling a vertical axis through ``center`` [m] (None: the focal point) once per ``period`` [s]."""

    @property
    def period(self) -> float: ...

    @property
    def center(self) -> Sequence[float] | None: ...


class CameraSettings(Protocol):
    """Where the camera is: given (``position`` and ``focal_point`` [m]) or fitted along ``direction`` with
    ``fit_margin``; ``up``; ``view_angle`` [deg]; keyframes, a followed body (with ``follow_lag`` [s]) or an orbit."""

    @property
    def position(self) -> Sequence[float] | None: ...

    @property
    def focal_point(self) -> Sequence[float] | None: ...

    @property
    def up(self) -> Sequence[float]: ...

    @property
    def view_angle(self) -> float: ...

    @property
    def direction(self) -> Sequence[float]: ...

    @property
    def fit_margin(self) -> float: ...

    @property
    def keyframes(self) -> Sequence[CameraKey] | None: ...

    @property
    def follow(self) -> str | None: ...

    @property
    def follow_lag(self) -> float: ...

    @property
    def orbit(self) -> Orbit | None: ...

    @property
    def moves(self) -> bool: ...


class GroundSettings(Protocol):
    """The ground drawn under the motion: at ``level`` [m] along the camera's up, ``size`` [m] across (None:
    fitted), its ``color``, with a ``grid`` and fading into the backdrop (``fade``)."""

    @property
    def level(self) -> float: ...

    @property
    def size(self) -> float | None: ...

    @property
    def color(self) -> str: ...

    @property
    def grid(self) -> bool: ...

    @property
    def fade(self) -> bool: ...


@dataclass(frozen=True)
class Ground:
    """A ground the renderer makes itself (from a plane collider facing up): :class:`GroundSettings`' shape."""

    level: float
    size: float | None
    color: str = "#d8d8d8"
    grid: bool = True
    fade: bool = True


class RenderSettings(Protocol):
    """Everything the renderer reads of a scene's ``render`` section (see docs/scene-format.md for each key)."""

    @property
    def resolution(self) -> Sequence[int]: ...

    @property
    def background(self) -> str: ...

    @property
    def background_top(self) -> str | None: ...

    @property
    def lights(self) -> str: ...

    @property
    def anti_aliasing(self) -> str: ...

    @property
    def msaa_samples(self) -> int: ...

    @property
    def particles(self) -> str: ...

    @property
    def sphere_resolution(self) -> int: ...

    @property
    def springs(self) -> str: ...

    @property
    def spring_width(self) -> float: ...

    @property
    def surface_opacity(self) -> float: ...

    @property
    def shadows(self) -> bool: ...

    @property
    def ambient_occlusion(self) -> bool: ...

    @property
    def show_anchors(self) -> bool: ...

    @property
    def show_targets(self) -> bool: ...

    @property
    def show_axes(self) -> bool: ...

    @property
    def show_vectors(self) -> str: ...

    @property
    def fluid_color(self) -> str: ...

    @property
    def ground(self) -> GroundSettings | None: ...

    @property
    def show_time(self) -> bool: ...

    @property
    def time_label(self) -> str: ...

    @property
    def label_corner(self) -> str: ...

    @property
    def label_size(self) -> float: ...

    @property
    def active_camera(self) -> CameraSettings: ...
