"""What the renderer draws, as data: :class:`FrameGeometry`, compiled from a scene and its model by
:mod:`animbatch.compile.frame_geometry`. Numbers only: arrays, names and small frozen records, never a scene spec or
a live simulation object, so that the renderer and the exports read neither the scene format nor the model."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from animbatch.vertex_placement import VertexPlacement

#: A physically based finish: (metallic, roughness), each in 0…1; None draws with plain (Phong) shading.
Finish = tuple[float, float]


def nearest_frame(times: np.ndarray, t: float) -> int:
    """The index of the frame time (F,) [s] nearest to ``t`` [s] (0 without frames)."""
    return int(np.argmin(np.abs(times - t))) if len(times) else 0


@dataclass(frozen=True, eq=False)
class FrameSeries:
    """Something that changes over the run, sampled at the frame times: ``values`` (F, ...) at ``times`` (F,) [s]."""

    times: np.ndarray
    values: np.ndarray

    def at(self, t: float) -> np.ndarray:
        """The sample of the frame nearest to ``t`` [s] (frames are drawn at their own times)."""
        return self.values[nearest_frame(self.times, t)]


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A triangle surface read from a mesh file: ``vertices`` (V, 3) [m] and ``faces`` (F, 3) vertex indices."""

    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True, eq=False)
class Solid:
    """A shape to draw, in its own coordinates [m]: a ``sphere`` (``radius``), a ``box`` (edge lengths ``size``), a
    ``cylinder`` or a ``capsule`` along z (``radius``, whole ``length``), a ``mesh`` (``mesh``), or a ``compound`` of
    ``parts``, each a solid and its 4×4 pose in the compound's coordinates."""

    kind: Literal["sphere", "box", "cylinder", "capsule", "mesh", "compound"]
    radius: float = 0.0
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    length: float = 0.0
    mesh: TriangleMesh | None = None
    parts: tuple[tuple[Solid, np.ndarray], ...] = ()


@dataclass(frozen=True, eq=False)
class DrawnCollider:
    """A visible collider. A plane has ``normal`` (3,) (unit) and ``level`` [m] (``normal · p = level``) and is drawn
    ``size`` metres across (None: fitted to the motion); any other collider is a ``solid`` placed by ``pose`` (4×4)
    where it starts. ``color``: its own (None: the default collider colour); ``track``: its pose (F, 4, 4) at the
    frame times, relative to where it starts, when it moves (planes included)."""

    solid: Solid | None
    pose: np.ndarray
    normal: np.ndarray | None = None
    level: float = 0.0
    size: float | None = None
    color: str | None = None
    track: FrameSeries | None = None

    @property
    def kind(self) -> str:
        """'plane', or the kind of its solid."""
        return "plane" if self.normal is not None or self.solid is None else self.solid.kind


@dataclass(frozen=True, eq=False)
class SurfacePatch:
    """One cloth or lattice: its vertices ``start`` … ``stop - 1`` of the vertex placement and its ``triangles``
    (T, 3), indexing those vertices from 0."""

    name: str
    start: int
    stop: int
    triangles: np.ndarray


@dataclass(frozen=True, eq=False)
class Surfaces:
    """The cloths and lattices: where every vertex is (``placement``, from the points, rigid bodies and anchors) and
    the ``patches`` drawn from them."""

    placement: VertexPlacement
    patches: tuple[SurfacePatch, ...]


@dataclass(frozen=True, eq=False)
class ParticleLook:
    """How an emitter's particles are drawn: a pool of ``capacity`` slots, as ``sprite`` or ``sphere`` points with
    ``trail`` frames of trail; ramps over life (age / lifetime) of ``size`` (× radius), ``opacity`` and ``color``
    (R, 3) RGB in 0…1 (None: each particle keeps its own colour), around the emitter's ``color_mean`` (3,). Each
    particle's lifetime [s], radius [m] and colour (3,), by serial: ``serials`` (K,) sorted, with the values in the
    same order (every particle the trajectory shows)."""

    name: str
    capacity: int
    style: str
    trail: int
    size_ramp: np.ndarray
    opacity_ramp: np.ndarray
    color_ramp: np.ndarray | None
    color_mean: np.ndarray
    serials: np.ndarray
    lifetime: np.ndarray
    radius: np.ndarray
    color: np.ndarray

    def looks(self, serials: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lifetimes (K,), radii (K,) and colours (K, 3) of the particles ``serials`` (K,) (each one the trajectory
        shows)."""
        at = np.searchsorted(self.serials, serials)
        return self.lifetime[at], self.radius[at], self.color[at]


@dataclass(frozen=True)
class TrailPaths:
    """Where the trailed bodies were at every frame: ``positions`` (F, T, 3) [m] at ``times`` (F,) [s], one colour
    per body (T,); a trail reaches ``length`` [s] back, ``width`` [px] wide, fading towards its tail if ``fade``."""

    positions: np.ndarray
    times: np.ndarray
    colors: tuple[str, ...]
    length: float
    width: float
    fade: bool


@dataclass(frozen=True)
class BodyPath:
    """Where one body was at every frame: ``positions`` (F, 3) [m] at ``times`` (F,) [s]; ``extent`` [m]: its size
    (radius of its bounding sphere)."""

    positions: np.ndarray
    times: np.ndarray
    extent: float


@dataclass(frozen=True)
class ArrowSeries:
    """Arrows from bodies' centres of mass at every frame: for each quantity ``names[k]`` (drawn in ``colors[k]``,
    measured in ``units[k]``), ``vectors[k]`` (F, A, 3) at ``times`` (F,) [s] for the bodies ``bodies`` (A,) (indices
    into the positions drawn), drawn ``scales[k]`` metres long per unit, so that a quantity's typical longest arrow
    is ``length`` [m] long; with a legend if ``legend``."""

    times: np.ndarray
    bodies: np.ndarray
    names: tuple[str, ...]
    colors: tuple[str, ...]
    units: tuple[str, ...]
    vectors: tuple[np.ndarray, ...]
    scales: tuple[float, ...]
    length: float
    legend: bool = True


@dataclass(frozen=True)
class StopwatchReading:
    """A stopwatch over one run: ``start`` and ``stop`` [s] (None: never started, or still running at the end),
    and the closed form's ``expected`` time [s], if any."""

    name: str
    start: float | None
    stop: float | None
    expected: float | None = None

    @property
    def elapsed(self) -> float | None:
        """Seconds between start and stop (None when either never happened)."""
        return None if self.start is None or self.stop is None else self.stop - self.start

    def at(self, t: float) -> float:
        """What the stopwatch shows at time ``t`` [s]: 0 before it starts, running, then held once stopped."""
        if self.start is None or t <= self.start:
            return 0.0
        return min(t, self.stop if self.stop is not None else math.inf) - self.start

    def as_dict(self) -> dict[str, float | None]:
        error = None if self.elapsed is None or self.expected is None else self.elapsed - self.expected
        return {"start": self.start, "stop": self.stop, "elapsed": self.elapsed, "expected": self.expected,
                "error": error}

    def describe(self) -> str:
        return stopwatch_line(self.name, self.as_dict())


def stopwatch_line(name: str, reading: dict[str, float | None]) -> str:
    """"stopwatch 'fall' 0.6386 s (expected 0.6386 s, error 2e-09 s)", or why there is no reading, from
    :meth:`StopwatchReading.as_dict`."""
    start, stop, elapsed, expected = (reading.get(key) for key in ("start", "stop", "elapsed", "expected"))
    if start is None:
        return f"stopwatch {name!r} never started"
    if stop is None or elapsed is None:
        return f"stopwatch {name!r} started at {start:.6g} s and never stopped"
    text = f"stopwatch {name!r} {elapsed:.6g} s"
    if expected is not None:
        text += f" (expected {expected:.6g} s, error {elapsed - expected:.2g} s)"
    return text


@dataclass(frozen=True)
class LabelValues:
    """What a text overlay can show at each frame: ``times`` (F,) [s], the frames per second, and per-frame series
    (F,) by name: energies ``E``, ``KE``, ``PE`` [J] when the label asks for them, ``speeds`` [m/s] of the
    bodies it names, the scene's stopwatches, the proper times of the clocks it names and the simulation's wall time
    [s]."""

    times: np.ndarray
    fps: float
    series: dict[str, np.ndarray] = field(default_factory=dict)
    speeds: dict[str, np.ndarray] = field(default_factory=dict)
    stopwatches: dict[str, StopwatchReading] = field(default_factory=dict)
    proper_times: dict[str, np.ndarray] = field(default_factory=dict)  # (F,) [s] per body with a clock
    wall_simulate: float = 0.0  # [s] the simulation's wall time, for {wall_simulate}

    def at(self, t: float) -> dict[str, Any]:
        """The label's fields at the frame nearest to time ``t`` [s]."""
        frame = nearest_frame(self.times, t)
        values: dict[str, Any] = {"t": t, "frame": frame, "frames": len(self.times), "fps": self.fps}
        values.update({name: float(series[frame]) for name, series in self.series.items()})
        values["speed"] = {name: float(series[frame]) for name, series in self.speeds.items()}
        values["stopwatch"] = {name: reading.at(t) for name, reading in self.stopwatches.items()}
        values["proper_time"] = {name: float(series[frame]) for name, series in self.proper_times.items()}
        values["wall_simulate"] = self.wall_simulate
        return values


@dataclass(frozen=True)
class PanelSeries:
    """What the energy panel plots: ``times`` (F,) [s] and, by label, series (F,) with their axis ('left' for
    energies [J], 'right' for momentum [kg·m/s]); ``height``: the panel's share of the frame height."""

    times: np.ndarray
    series: dict[str, tuple[np.ndarray, str]]
    height: float


@dataclass(frozen=True)
class FrameGeometry:
    """What the renderer draws, independent of the scene file: sizes, shapes, colours, springs, fluids, bounds."""

    particle_radius: np.ndarray  # (N,) [m]
    colors: list[str]  # (P,) '#rrggbb', bodies in model order
    rigid_shapes: tuple[Solid, ...]  # (B,) in shape coordinates
    rigid_centre: np.ndarray  # (B, 3) centre of mass in shape coordinates [m]
    rigid_inertia: np.ndarray  # (B, 3, 3) body axes [kg·m²]
    rigid_extent: np.ndarray  # (B,) [m]
    anchor_positions: np.ndarray  # (A, 3) [m]
    spring_first: np.ndarray  # (S,) body indices
    spring_second: np.ndarray  # (S,) body or anchor indices
    spring_to_anchor: np.ndarray  # (S,) bool
    spring_first_offset: np.ndarray  # (S, 3) body axes from the centre of mass
    spring_second_offset: np.ndarray
    spring_colors: list[str]
    fluids: list[tuple[float, np.ndarray]]  # (level, up) of each buoyancy fluid
    bounds: np.ndarray  # (2, 3) [m], whole motion
    vector_scale: float = 0.0  # arrow length per unit of |ω| or |L| [m per unit]
    colliders: tuple[DrawnCollider, ...] = ()  # the visible colliders
    anchor_track: FrameSeries | None = None  # (F, A, 3) [m]: where the anchors are at each frame, when any moves
    anchor_visible: np.ndarray | None = None  # (A,) bool
    drawn_particles: np.ndarray | None = None  # (N,) bool: particles drawn as themselves (not cloth vertices)
    surfaces: Surfaces | None = None  # cloths and lattices
    surface_colors: tuple[tuple[str, str], ...] = ()  # (front, back) per deformable body
    target_segments: np.ndarray | None = None  # (S, 2, 3) [m]: the curves PD controllers keep bodies on
    target_track: FrameSeries | None = None  # (F, K, 3) [m]: the PD controllers' point and keyframe targets
    emitters: tuple[ParticleLook, ...] = ()  # how each emitter's particles are drawn
    trails: TrailPaths | None = None
    label: LabelValues | None = None
    followed: BodyPath | None = None  # the body the camera follows
    arrows: ArrowSeries | None = None
    panel: PanelSeries | None = None
    finishes: tuple[Finish | None, ...] = ()  # (P,) per body in model order, like colors
    surface_finishes: tuple[Finish | None, ...] = ()  # per deformable body, like surface_colors
    collider_looks: tuple[tuple[str, Finish | None], ...] = ()  # (colour, finish) per drawn collider
    rigid_volume_radius: np.ndarray | None = None  # (B,) [m] the radius of the sphere of each rigid body's volume

    def anchors_at(self, t: float) -> np.ndarray:
        """Every anchor's position (A, 3) [m] at the frame of time ``t`` [s] (moving anchors follow their
        keyframes)."""
        return self.anchor_track.at(t) if self.anchor_track is not None else self.anchor_positions
