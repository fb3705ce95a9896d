"""The ``render`` section: camera, lights, overlays, output."""

from __future__ import annotations

import string
from typing import Annotated, Any, Literal

import annotated_types as at
from pydantic import Field, field_validator, model_validator

from animbatch.scene.diagnostics import did_you_mean
from animbatch.scene.schema.keys import Color, Name, SceneModel, Vec3, key, rule_error


class CameraKeyframe(SceneModel):
    """Where the camera is at one time; the keys a keyframe leaves out keep the camera's own (fitted or given)."""

    t: float = key(description="Time of the keyframe.", unit="s", ge=0)
    position: Vec3 | None = key(None, "Camera position.", "m")
    focal_point: Vec3 | None = key(None, "Point looked at.", "m")
    view_angle: float | None = key(None, "Vertical field of view.", "deg", gt=0, lt=180)


class OrbitSpec(SceneModel):
    """The camera circles a vertical axis (along ``up``) at a constant rate, keeping its height and distance."""

    period: float = key(description="Time of one full turn (negative: turn the other way).", unit="s")
    center: Vec3 | None = key(None, "A point on the axis (default: the focal point).", "m")

    @field_validator("period")
    @classmethod
    def _turns(cls, period: float) -> float:
        if period == 0:
            raise rule_error("must not be zero: the time of one full turn (negative turns the other way)")
        return period


class CameraSpec(SceneModel):
    """The camera. Without position and focal point it is fitted to the bounding box of the whole motion; it can
    move by keyframes, follow a body, or orbit (applied in that order)."""

    position: Vec3 | None = key(None, "Camera position (give together with focal_point; default: fitted).", "m")
    focal_point: Vec3 | None = key(None, "Point the camera looks at (default: centre of the motion).", "m")
    up: Vec3 = key([0.0, 1.0, 0.0], "Up direction on screen; also the ground normal.", "1")
    view_angle: float = key(30.0, "Vertical field of view.", "deg", gt=0, lt=180)
    direction: Vec3 = key([0.4, 0.35, 1.0], "When fitted: direction from the focal point towards the camera.", "1")
    fit_margin: float = key(1.15, "When fitted: how much room to leave around the motion (1 = tight).", "1",
                            ge=1, le=10)
    keyframes: list[CameraKeyframe] | None = key(
        None, "Camera keyframes {t, position, focal_point, view_angle}, in increasing t; between them the camera "
              "moves on a smooth cubic spline that starts and ends at rest, and before the first and after the last "
              "it holds still.")
    follow: Name | None = key(None, "A particle or rigid body the camera tracks: the focal point follows it "
                                    "(smoothed by follow_lag) and the camera keeps its offset from it.")
    follow_lag: float = key(0.25, "How far the followed view lags behind the body: the time constant of a "
                                  "critically damped follower (0: locked on).", "s", ge=0)
    orbit: OrbitSpec | None = key(None, "Circle around a vertical axis: {period, center}.")

    @model_validator(mode="after")
    def _consistent(self) -> "CameraSpec":
        if (self.position is None) != (self.focal_point is None):
            given = "position" if self.position is not None else "focal_point"
            raise rule_error("give both position and focal_point, or neither (then the camera is fitted to the "
                             "motion)", given)
        if self.position is not None and self.position == self.focal_point:
            raise rule_error("must differ from the camera position", "focal_point")
        for name in ("up", "direction"):
            if not any(getattr(self, name)):
                raise rule_error("must not be the zero vector", name)
        return self

    @field_validator("keyframes")
    @classmethod
    def _increasing(cls, keyframes: list[CameraKeyframe] | None) -> list[CameraKeyframe] | None:
        if keyframes is not None:
            if not keyframes:
                raise rule_error("give at least one keyframe, or leave the key out")
            for index in range(1, len(keyframes)):
                if keyframes[index].t <= keyframes[index - 1].t:
                    raise rule_error(f"keyframe times must increase (t = {keyframes[index].t:g} after "
                                     f"t = {keyframes[index - 1].t:g})", index)
        return keyframes

    @property
    def moves(self) -> bool:
        """Whether the camera moves during the animation."""
        return bool(self.keyframes and len(self.keyframes) > 1) or self.follow is not None or self.orbit is not None


class GroundSpec(SceneModel):
    """A ground plane drawn perpendicular to ``camera.up`` (display only: it does not collide)."""

    level: float = key(0.0, "Height of the ground along camera.up.", "m")
    size: float | None = key(None, "Side length of the ground square (default: fitted to the motion).", "m", gt=0)
    color: Color = key("#d8d8d8", "Ground colour.")
    grid: bool = key(True, "Draw grid lines on the ground (a darker shade of its colour, spaced 1, 2 or 5 × 10^k m).")
    fade: bool = key(True, "Reach out towards the horizon and fade into the backdrop (else a square with hard "
                           "edges).")


#: The numbers a text overlay can show (besides ``{speed[NAME]}``), see :func:`label_speed_names`.
LABEL_FIELDS = ("t", "frame", "frames", "fps", "E", "KE", "PE", "R_error", "wall_simulate", "wall_render",
                "wall_frame")
#: The fields of a text overlay that name something: ``{speed[BODY]}``, ``{stopwatch[NAME]}`` and
#: ``{proper_time[BODY]}``.
LABEL_NAMED_FIELDS = ("speed", "stopwatch", "proper_time")


class _AnyBody(dict):
    """Stands for the speeds of bodies while a label is checked: any name gives a number."""

    def __missing__(self, name: str) -> float:
        return 1.0


def label_names(label: str, kind: str = "speed") -> list[str]:
    """The names a label's ``{speed[NAME]}`` (or ``{stopwatch[NAME]}``, for ``kind`` stopwatch) fields ask for, in
    order."""
    return [field[len(kind) + 1:-1] for _, field, _, _ in string.Formatter().parse(label)
            if field is not None and field.startswith(kind + "[") and field.endswith("]")]


def label_speed_names(label: str) -> list[str]:
    """The body names a label's ``{speed[NAME]}`` fields ask for, in order."""
    return label_names(label, "speed")


class TrailSpec(SceneModel):
    """Trails: a line behind each moving body through where it was over the last ``length`` seconds."""

    bodies: list[Name] | None = key(None, "Bodies that leave a trail: particles and rigid bodies (default: all of "
                                          "them).")
    length: float = key(1.0, "How far back in time a trail reaches.", "s", gt=0)
    width: float = key(3.0, "Line width.", "px", gt=0, le=50)
    fade: bool = key(True, "Fade each trail out towards its tail (else one solid colour).")


#: The kinds of force an arrow can show: each force term's label, and 'contact' (what contacts and constraints add).
FORCE_ARROW_KINDS = ("gravity", "gravitation", "drag", "wind", "aerodynamics", "buoyancy", "spring", "dihedral",
                     "controller", "force", "electromagnetic", "coulomb", "joint", "contact")
ForceArrowKind = Literal["gravity", "gravitation", "drag", "wind", "aerodynamics", "buoyancy", "spring", "dihedral",
                         "controller", "force", "electromagnetic", "coulomb", "joint", "contact"]


class EnergyPanelSpec(SceneModel):
    """A plot under the 3D view of the run's energies (and, optionally, momentum) over time, with a cursor at the
    frame's time: the run's quantities.csv, drawn into the video."""

    height: float = key(0.3, "Share of the frame height the panel takes (the 3D view keeps the rest).", "1",
                        gt=0.1, le=0.6)
    quantities: list[Literal["energy", "momentum"]] = key(
        ["energy"], "What it plots: energy (kinetic, potential and total [J]), momentum (|p| [kg·m/s], on a second "
                    "axis).")


class ArrowSpec(SceneModel):
    """Arrows from bodies' centres of mass: velocity, acceleration, and one per kind of force, with a legend."""

    show: list[Literal["velocity", "acceleration", "forces"]] = key(
        ["velocity"], "What to draw: velocity v, acceleration a, and forces (one arrow per kind of force acting).")
    forces: list[ForceArrowKind] | None = key(
        None, "Which kinds of force, with show: [forces] (default: every kind acting in the scene): "
              + ", ".join(FORCE_ARROW_KINDS[:-1]) + " (the joints' constraint forces), and contact (m·a minus the "
              "rest).")
    bodies: list[Name] | None = key(None, "Bodies with arrows: particles and rigid bodies (default: all of them).")
    length: float | None = key(None, "Length of the longest arrow of each quantity over the run (all forces share "
                                     "one scale, so they compare); default a fifth of the motion's size.", "m", gt=0)
    legend: bool = key(True, "A legend of the arrows' colours in the lower right corner.")

    @model_validator(mode="after")
    def _forces_shown(self) -> "ArrowSpec":
        if self.forces is not None and "forces" not in self.show:
            raise rule_error(f"forces picks which forces to draw, but show ({', '.join(self.show)}) does not draw "
                             "forces: add it, e.g. show: [forces] or show: [velocity, forces]", "forces")
        return self


VideoPreset = Literal["ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow"]


class VideoSpec(SceneModel):
    """H.264 MP4 encoding (yuv420p, plays in browsers)."""

    preset: VideoPreset = key("veryfast", "x264 speed preset. 'veryfast' keeps up with the renderer; slower presets "
                                          "give smaller files at equal quality.")
    crf: int = key(20, "x264 constant rate factor: 0 lossless, 18 visually lossless, 23 x264's default, 51 worst.",
                   "1", ge=0, le=51)


Quality = Literal["draft", "preview", "final"]

#: What each ``render.quality`` sets, for every key of these the scene does not set itself. ``preview`` is the
#: default look; ``draft`` drops anti-aliasing and halves the tessellation and the frame size; ``final`` draws
#: 1080p with 4× multisampling (8× costs half the frame rate under llvmpipe for a barely visible gain), finer
#: spheres, contact shadows and ambient occlusion on the ground.
QUALITY_PRESETS: dict[str, dict[str, Any]] = {
    "draft": {"resolution": [640, 360], "anti_aliasing": "none", "sphere_resolution": 16, "shadows": False},
    "preview": {"resolution": [1280, 720], "anti_aliasing": "fxaa", "sphere_resolution": 32, "shadows": False},
    "final": {"resolution": [1920, 1080], "anti_aliasing": "msaa", "msaa_samples": 4, "sphere_resolution": 64,
              "shadows": True, "ambient_occlusion": True},
}


class RenderSpec(SceneModel):
    """How frames are drawn and written."""

    quality: Quality = key("preview", "Preset for the keys it lists (resolution, anti_aliasing, msaa_samples, "
                                      "sphere_resolution, shadows, ambient_occlusion) that the scene does not set "
                                      "itself: draft "
                                      "(fastest), preview or final (see Render quality).")
    resolution: Annotated[list[Annotated[int, Field(ge=16, le=7680)]], at.Len(2, 2)] = key(
        [1280, 720], "Frame size [width, height]; both even (required by H.264 yuv420p).", "px")
    background: Color = key("#eef0f3", "Backdrop colour (at the bottom of the frame when background_top is set).")
    background_top: Color | None = key("#a9b6c6", "Backdrop colour at the top of the frame, for a vertical "
                                                   "gradient; null for a plain backdrop. A scene that sets "
                                                   "background but not this gets a plain backdrop.")
    lights: Literal["three_point", "light_kit"] = key(
        "three_point", "Lighting: three_point (a key light that also casts the contact shadows, a fill, a rim "
                       "light and a weak bounce from below, fixed in the world, so a moving camera sees the bodies "
                       "lit the same way) or "
                       "light_kit (VTK's light kit, riding with the camera).")
    anti_aliasing: Literal["fxaa", "msaa", "none"] = key(
        "fxaa", "Edge smoothing: fxaa (default), msaa (smoother, slower) or none (fastest).")
    msaa_samples: int = key(4, "Samples per pixel when anti_aliasing is msaa.", "1", ge=2, le=16)
    particles: Literal["auto", "mesh", "sprite"] = key(
        "auto", "How particles are drawn: sphere meshes, point sprites (fast for many), or auto "
                "(meshes up to 200 particles, sprites beyond).")
    sphere_resolution: int = key(32, "Segments around a sphere mesh.", "1", ge=8, le=256)
    springs: Literal["tube", "line", "hidden"] = key("tube", "How springs are drawn.")
    spring_width: float = key(3.0, "Width of spring lines and tubes on screen.", "px", gt=0, le=50)
    mesh_springs: Literal["hidden", "line"] = key(
        "hidden", "The springs of cloth and lattices: hidden (their surface shows them) or line (every spring, "
                  "drawn over the surface).")
    surface_opacity: float = key(1.0, "Opacity of cloth and lattice surfaces (lower it to see springs inside).", "1",
                                 gt=0, le=1)
    trails: TrailSpec | None = key(None, "Trails behind moving bodies (omit for none; 'trails: {}' for every "
                                         "particle and rigid body).")
    shadows: bool = key(False, "Contact shadows: each body and particle sphere casts its shape along the key light "
                               "onto the ground, or onto the upward face of a fixed box collider under it (needs a "
                               "ground; on with quality: final).")
    ambient_occlusion: bool = key(False, "Ambient occlusion: the ground darkens softly around where bodies rest on "
                                         "it or pass close (needs a ground; on with quality: final).")
    show_anchors: bool = key(True, "Draw anchors as small dark cubes.")
    show_targets: bool = key(True, "Draw what PD controllers pull towards: curves as thin lines (the wire of a "
                                   "bead), point and keyframed targets as small grey spheres.")
    show_axes: bool = key(False, "Draw each rigid body's axes (x red, y green, z blue), turning with it.")
    energy_panel: EnergyPanelSpec | None = key(None, "A plot of the energies over time under the 3D view, with a "
                                                     "cursor at each frame's time (omit for none; "
                                                     "'energy_panel: {}' for the defaults).")
    arrows: ArrowSpec | None = key(None, "Velocity, acceleration and force arrows with a legend (omit for none; "
                                         "'arrows: {}' for every body's velocity).")
    show_vectors: Literal["none", "angular_velocity", "angular_momentum"] = key(
        "none", "Draw an arrow from each rigid body's centre of mass along ω or L, scaled so that the largest over "
                "the animation is twice the body's size.")
    fluid_color: Color = key("#3a7bd5", "Colour of the surfaces of buoyancy fluids (drawn translucent).")
    ground: GroundSpec | None = key(None, "Ground plane (omit for none; 'ground: {}' for the defaults).")
    show_time: bool = key(True, "Overlay the simulated time.")
    time_label: str = key("t = {t:.2f} s", "The text overlay (HUD), in Python format syntax: {t} simulated time "
                                           "[s], {frame}, {frames}, {fps}, energies {E}, {KE}, {PE} [J], "
                                           "{speed[NAME]} [m/s] of a body, {stopwatch[NAME]} [s], "
                                           "{proper_time[NAME]} [s] of a body's clock, {R_error}: the "
                                           "largest ‖RᵀR − I‖ of rotation matrices (solver.orientation: matrix; "
                                           "0 with quaternions), wall-clock "
                                           "times {wall_simulate}, {wall_render}, {wall_frame} [s] (see Render); "
                                           "'\\n' starts a line.")
    label_corner: Literal["upper_left", "upper_right", "lower_left", "lower_right"] = key(
        "upper_left", "Where the text overlay sits.")
    label_size: float = key(1 / 36, "Size of the text overlay, as a fraction of the frame height (the same look at "
                                    "320×240 and at 4K): its margin from the frame's edges; its font is twice as "
                                    "large. A line too long for the frame is drawn smaller until it fits.", "1",
                            gt=0, le=0.25)
    camera: CameraSpec = key(CameraSpec(), "Camera.")
    cameras: dict[Name, CameraSpec] = key({}, "More cameras, by name: each a camera block like render.camera. "
                                              "'render --camera NAME' renders through one, '--camera all' through "
                                              "render.camera and each of these, into separate videos.")
    use_camera: Name | None = key(None, "Render through this camera of render.cameras (default: render.camera); "
                                        "its outputs are named <scene>-<camera>.")
    formats: Annotated[list[Literal["mp4", "png", "webm", "gif"]], at.Len(1, 4)] = key(
        ["mp4"], "Outputs: mp4 (H.264), webm (VP9), gif (256 colours; GIF times are in 1/100 s, so 30 fps plays "
        "at 33.3), and png (keep the frame files; they are also the render's resumable state: a render with png "
        "that is interrupted goes on from the frames on disk. Without png, one process streams its frames straight "
        "into the encoder, and frames drawn in parallel or by range are deleted once every video is encoded).")
    video: VideoSpec = key(VideoSpec(), "MP4 encoding settings.")
    max_cost: float = key(3600.0, "Wall-time budget of drawing the frames (each render process gets it). After "
                                  "two frames the time of the rest is projected, and a render that would take "
                                  "longer stops with exit code 4, saying what it would take; frames drawn to disk "
                                  "(with png, --jobs or --frames) stay there, and a run with a larger budget goes "
                                  "on from them. 0 = no limit.",
                          "s", ge=0)

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data: Any) -> Any:
        """Fill the keys the quality preset lists and the scene leaves out (before validation, so that a preset's
        values are checked like the scene's own)."""
        if not isinstance(data, dict):
            return data
        if "background" in data and "background_top" not in data:  # a colour of one's own: plain, as asked
            data = {**data, "background_top": None}
        preset = QUALITY_PRESETS.get(data.get("quality", "preview"))
        if preset is None:
            return data  # an unknown quality: reported by the field's own validation
        return {**{name: value for name, value in preset.items() if name not in data}, **data}

    @model_validator(mode="after")
    def _known_camera(self) -> "RenderSpec":
        if self.use_camera is not None and self.use_camera not in self.cameras:
            hint = did_you_mean(self.use_camera, list(self.cameras)) or "."
            raise rule_error(f"no camera {self.use_camera!r} in render.cameras{hint} Cameras: "
                             f"{', '.join(self.cameras) or '(none: add render.cameras)'}", "use_camera")
        return self

    @property
    def active_camera(self) -> CameraSpec:
        """The camera frames are drawn through: ``cameras[use_camera]``, or ``camera``."""
        return self.cameras[self.use_camera] if self.use_camera is not None else self.camera

    @field_validator("resolution")
    @classmethod
    def _even(cls, size: list[int]) -> list[int]:
        for index, value in enumerate(size):
            if value % 2:
                raise rule_error(f"must be even (got {value}): H.264 with yuv420p halves the colour resolution; "
                                 f"try {value + 1}", index)
        return size

    @field_validator("time_label")
    @classmethod
    def _formattable(cls, label: str) -> str:
        try:
            label.format(**{name: 1.0 for name in LABEL_FIELDS}, **{name: _AnyBody() for name in LABEL_NAMED_FIELDS})
        except (KeyError, IndexError, ValueError, AttributeError) as error:
            raise rule_error(f"is not a valid format string ({error}); its fields are "
                             f"{', '.join('{' + name + '}' for name in LABEL_FIELDS)}, {{speed[BODY]}}, "
                             "{stopwatch[NAME]} and {proper_time[BODY]}, e.g. 't = {t:.2f} s'") from None
        return label
