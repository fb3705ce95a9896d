"""The scene format: every key with its type, unit, default and limits (pydantic v2, unknown keys forbidden).

This module is the single source of truth for the format. ``docs/scene-format.md`` and ``animbatch schema`` are
generated from it, and error messages take their units and allowed values from it. Each key is declared with
:func:`key`, which records a description and an SI unit.

Conventions: SI units throughout (m, kg, s, N); vectors are lists of 3 numbers ``[x, y, z]``; the world is y-up by
default (gravity ``[0, -9.81, 0]``), though nothing but the default camera and ground assumes it.
"""

from __future__ import annotations

import difflib
from typing import Annotated, Any, Literal, Union

import annotated_types as at
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PlainValidator,
    Tag,
    WithJsonSchema,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError, PydanticUndefined

from animbatch.curves import ExpressionError, compile_expression
from animbatch.scene.annotations import tag_of

NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_.\-]*$"


def key(default: Any = PydanticUndefined, description: str = "", unit: str | None = None, *,
        example: Any = None, **constraints: Any) -> Any:
    """Declare a scene key: default, one-line description, SI unit (``None`` when it has none) and limits."""
    extra: dict[str, Any] = {}
    if unit is not None:
        extra["unit"] = unit
    if example is not None:
        extra["example"] = example
    return Field(default, description=description, json_schema_extra=extra or None, **constraints)


def rule_error(message: str, key: str | int | None = None) -> PydanticCustomError:
    """An error from a validator that breaks a rule between keys; ``key`` names the key it points at."""
    return PydanticCustomError("scene_rule", "{message}", {"message": message, "key": key})


class SceneModel(BaseModel):
    """Base of every scene section: unknown keys are errors, no silent type coercion, values are immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False, validate_default=True)


# ----------------------------------------------------------------------------------------------------------------
# Value types


Vec3 = Annotated[list[float], at.Len(3, 3)]
PositiveVec3 = Annotated[list[Annotated[float, Field(gt=0)]], at.Len(3, 3)]
Name = Annotated[str, Field(pattern=NAME_PATTERN, max_length=64)]


def _nonzero_vector(vector: list[float]) -> list[float]:
    if not any(vector):
        raise rule_error("must not be the zero vector")
    return vector


#: A direction: three numbers, not all zero (need not be unit length).
NonZeroVec3 = Annotated[Vec3, AfterValidator(_nonzero_vector)]


def _check_color(value: Any) -> str:
    """Accept a CSS colour name, ``#rgb``/``#rrggbb``, or ``[r, g, b]`` in 0…1; return ``#rrggbb``."""
    from PIL import ImageColor  # light import; knows the CSS colour names

    if isinstance(value, str):
        try:
            rgb = ImageColor.getrgb(value)[:3]
        except ValueError:
            close = difflib.get_close_matches(value.lower(), ImageColor.colormap.keys(), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else "."
            raise rule_error(f"unknown colour {value!r}{hint} Use a CSS name (e.g. 'tomato'), '#rrggbb' or "
                             "[r, g, b] in 0..1") from None
        return "#{:02x}{:02x}{:02x}".format(*rgb)
    if (isinstance(value, list | tuple) and len(value) == 3
            and all(isinstance(c, int | float) and not isinstance(c, bool) and 0 <= c <= 1 for c in value)):
        return "#{:02x}{:02x}{:02x}".format(*(round(255 * c) for c in value))
    raise rule_error(f"must be a colour: a CSS name, '#rrggbb' or [r, g, b] in 0..1 (got {value!r})")


Color = Annotated[
    str,
    PlainValidator(_check_color),
    WithJsonSchema({"anyOf": [{"type": "string"},
                              {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1},
                               "minItems": 3, "maxItems": 3}]}),
]

ADAPTIVE_METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
FIXED_STEP_METHODS = ("euler", "midpoint", "symplectic_euler", "verlet", "backward_euler")
METHOD_ALIASES = {
    "explicit_euler": "euler",
    "forward_euler": "euler",
    "rk2": "midpoint",
    "semi_implicit_euler": "symplectic_euler",
    "velocity_verlet": "verlet",
    "implicit_euler": "backward_euler",
}


def _canonical_method(value: Any) -> Any:
    """Method names are case-insensitive, and ``-`` may stand for ``_``; aliases map to canonical names."""
    if not isinstance(value, str):
        return value
    folded = value.strip().lower().replace("-", "_")
    for name in (*ADAPTIVE_METHODS, *FIXED_STEP_METHODS):
        if name.lower() == folded:
            return name
    return METHOD_ALIASES.get(folded, value)


Method = Annotated[Literal[*ADAPTIVE_METHODS, *FIXED_STEP_METHODS], BeforeValidator(_canonical_method)]  # type: ignore[valid-type]


# ----------------------------------------------------------------------------------------------------------------
# Solver


class SolverSpec(SceneModel):
    """How the equations of motion are integrated."""

    method: Method = key("RK45", "Integrator: an adaptive solve_ivp method (RK23, RK45, DOP853, Radau, BDF, LSODA) "
                                 "or a fixed-step one (euler, midpoint, symplectic_euler, verlet, backward_euler).",
                         example="DOP853")
    rtol: float = key(1e-6, "Relative tolerance of adaptive methods (ignored by fixed-step ones).", "1",
                      gt=0, lt=1)
    atol: float = key(1e-9, "Absolute tolerance of adaptive methods, in the units of each state component "
                            "(m for positions, m/s for velocities).", "m, m/s", gt=0)
    max_step: float | None = key(None, "Largest step an adaptive method may take (default: no limit).", "s", gt=0)
    dt: float | None = key(None, "Step of fixed-step methods (default 1e-3 s). The step used is the largest one "
                                 "<= dt that divides the frame interval 1/fps, so that frames fall on steps (to 1e-6: "
                                 "dt 0.008333333 counts as 1/120 s).",
                           "s", gt=0)
    max_cost: float = key(3600.0, "Wall-time budget of one simulation. Before it starts, a run estimated to take "
                                  "longer is refused, naming what makes it expensive; a run that reaches it anyway "
                                  "stops with exit code 3, saying how far it got. 0 = no limit. The command line's "
                                  "--max-cost takes seconds or 30min, 2h.", "s", ge=0)
    drift_warning: float = key(0.01, "Relative drift of a conserved quantity (energy, momentum, angular momentum) "
                                     "above which a run warns, naming the quantity and what to change; 0.01 is 1 % "
                                     "of the quantity's scale in the scene (see the accuracy ledger).", "1", gt=0)

    @property
    def is_adaptive(self) -> bool:
        return self.method in ADAPTIVE_METHODS


# ----------------------------------------------------------------------------------------------------------------
# Bodies, anchors, springs


class ParticleSpec(SceneModel):
    """A point mass. Its radius is used for display, Stokes drag and (later) collisions; it has no rotation."""

    type: Literal["particle"] = key("particle", "Body type.")
    name: Name = key(description="Unique name, used by springs, fields and the trajectory file.", example="ball")
    mass: float = key(1.0, "Mass.", "kg", gt=0)
    radius: float = key(0.05, "Radius for display, Stokes drag and collisions.", "m", gt=0)
    position: Vec3 = key([0.0, 0.0, 0.0], "Initial position [x, y, z].", "m")
    velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial velocity [vx, vy, vz].", "m/s")
    material: Name = key("default", "Material, for collisions: a built-in one (glass, iron, rubber, pavement, steel, "
                                    "teflon, wood, ice, oiled_steel, default) or one from 'materials'.")
    collide: bool = key(True, "Take part in collisions (when the scene has colliders or a 'contacts' section).")
    color: Color | None = key(None, "Display colour: CSS name, '#rrggbb' or [r, g, b] in 0..1 "
                                    "(default: from a palette, by body index).", example="tomato")


Interpolation = Literal["linear", "cubic"]


class KeyframeSpec(SceneModel):
    """A position at a time, for anchors and targets that follow a path."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    position: Vec3 = key(description="Position at that time [x, y, z].", unit="m")


def _increasing_times(keys: list[Any]) -> list[Any]:
    times = [k.time for k in keys]
    for index in range(1, len(times)):
        if times[index] <= times[index - 1]:
            raise rule_error(f"key times must increase (key {index} at {times[index]:g} s follows "
                             f"{times[index - 1]:g} s)", index)
    return keys


def _keyframe_list(item: type) -> Any:
    """A list of 1 … 100000 keyframes of type ``item`` whose times increase."""
    return Annotated[list[item], at.Len(1, 100000), AfterValidator(_increasing_times)]  # type: ignore[valid-type]


class AnchorSpec(SceneModel):
    """A point in space that springs can attach to. It is not simulated: it stays put, or follows keyframes.

    With ``keyframes`` it moves along them (``linear``: constant speed between keys; ``cubic``: a smooth spline that
    starts and ends at rest) and holds its first and last positions before and after them.
    """

    name: Name = key(description="Unique name (shared namespace with bodies).", example="ceiling")
    position: Vec3 | None = key(None, "Position [x, y, z] (required unless keyframes are given).", "m")
    keyframes: _keyframe_list(KeyframeSpec) | None = key(  # type: ignore[valid-type]
        None, "Positions over time, instead of a fixed position.", example=[{"time": 0, "position": [0, 1, 0]},
                                                                            {"time": 2, "position": [1, 1, 0]}])
    interpolation: Interpolation = key("linear", "Between keyframes: linear or cubic.")
    color: Color | None = key(None, "Display colour (default dark grey).")

    @model_validator(mode="after")
    def _placed_once(self) -> "AnchorSpec":
        if (self.position is None) == (self.keyframes is None):
            raise rule_error("give position (a fixed anchor) or keyframes (a moving one), not both"
                             if self.position is not None else "required key missing: give position or keyframes",
                             "position")
        return self

    @property
    def start(self) -> list[float]:
        """Where the anchor is at t = 0 [m]."""
        return self.position if self.position is not None else self.keyframes[0].position  # type: ignore[index]


# ----------------------------------------------------------------------------------------------------------------
# Rigid bodies


class SphereShape(SceneModel):
    """Solid sphere, centred on the body origin: ``I = 2/5 m r²``."""

    type: Literal["sphere"] = key(description="Shape type.")
    radius: float = key(description="Radius.", unit="m", gt=0)


class ShellShape(SceneModel):
    """Spherical shell, centred on the body origin. Thin (``I = 2/3 m r²``, give a mass) unless a thickness is given
    (hollow sphere, ``I = 2/5 m (R⁵ - r⁵)/(R³ - r³)``)."""

    type: Literal["shell"] = key(description="Shape type.")
    radius: float = key(description="Outer radius.", unit="m", gt=0)
    thickness: float | None = key(None, "Wall thickness (default: infinitely thin, so the body needs a mass, not a "
                                        "density).", "m", gt=0)


class BoxShape(SceneModel):
    """Cuboid centred on the body origin, edges along the body axes: ``I = m/12 diag(b² + c², a² + c², a² + b²)``."""

    type: Literal["box"] = key(description="Shape type.")
    size: PositiveVec3 = key(description="Side lengths [a, b, c] along the body x, y, z axes.", unit="m")


class CylinderShape(SceneModel):
    """Solid cylinder along the body z axis, centred on the origin: ``I_xx = I_yy = ¼ m r² + 1/12 m l²``,
    ``I_zz = ½ m r²``."""

    type: Literal["cylinder"] = key(description="Shape type.")
    radius: float = key(description="Radius.", unit="m", gt=0)
    length: float = key(description="Length along the body z axis.", unit="m", gt=0)


class RodShape(SceneModel):
    """Thin rod along the body z axis, centred on the origin: ``I_xx = I_yy ≈ 1/12 m l²``. It is a cylinder of small
    radius, so that the moment about its own axis (``½ m r²``) is small but not zero."""

    type: Literal["rod"] = key(description="Shape type.")
    length: float = key(description="Length along the body z axis.", unit="m", gt=0)
    radius: float | None = key(None, "Radius (default: length / 100).", "m", gt=0)


class MeshShape(SceneModel):
    """A closed triangle mesh from an STL, OBJ or PLY file; volume, centre of mass and inertia are computed exactly
    from its surface (divergence theorem)."""

    type: Literal["mesh"] = key(description="Shape type.")
    file: str = key(description="Mesh file, relative to the scene file.", example="meshes/bunny.stl")
    scale: float | PositiveVec3 = key(1.0, "Scale factor, or factors [sx, sy, sz], applied to the file's "
                                           "coordinates (e.g. 0.001 for a file in millimetres).", "1")

    @field_validator("scale")
    @classmethod
    def _positive(cls, scale: float | list[float]) -> float | list[float]:
        if isinstance(scale, float | int) and scale <= 0:
            raise rule_error(f"must be > 0 (got {scale})")
        return scale


class OrientationSpec(SceneModel):
    """A rotation from body to world axes, given one way: axis and angle, a quaternion, or Euler angles."""

    axis: Vec3 | None = key(None, "Rotation axis (with angle).", "1")
    angle: float | None = key(None, "Rotation angle about the axis (with axis).", "deg")
    quaternion: Annotated[list[float], at.Len(4, 4)] | None = key(None, "Unit quaternion [w, x, y, z] (normalised "
                                                                        "if it is not).", "1")
    euler: Vec3 | None = key(None, "Rotations about the world x, then y, then z axes (extrinsic xyz).", "deg")

    @model_validator(mode="after")
    def _one_way(self) -> "OrientationSpec":
        given = [name for name in ("axis", "angle", "quaternion", "euler") if getattr(self, name) is not None]
        ways = ["axis" in given or "angle" in given, "quaternion" in given, "euler" in given]
        if sum(ways) != 1 or (("axis" in given) != ("angle" in given)):  # an empty mapping is no orientation either
            raise rule_error("give the orientation one way: axis and angle together, or quaternion, or euler "
                             f"(got {', '.join(given) or 'none of them'})")
        if self.axis is not None and not any(self.axis):
            raise rule_error("must not be the zero vector", "axis")
        if self.quaternion is not None and not any(self.quaternion):
            raise rule_error("must not be zero", "quaternion")
        return self


PRIMITIVE_SHAPES: tuple[type[SceneModel], ...] = (SphereShape, ShellShape, BoxShape, CylinderShape, RodShape,
                                                  MeshShape)
PrimitiveShape = Annotated[Union[*PRIMITIVE_SHAPES], Field(discriminator="type")]  # type: ignore[valid-type]


class CompoundPart(SceneModel):
    """One primitive of a compound body, placed in the body's frame, with its own density or mass."""

    shape: PrimitiveShape = key(description="The part's shape (any shape except compound).")  # type: ignore[valid-type]
    offset: Vec3 = key([0.0, 0.0, 0.0], "Position of the part's origin in the body frame.", "m")
    orientation: OrientationSpec | None = key(None, "Rotation of the part in the body frame (default none).")
    density: float | None = key(None, "Density of this part (default: the body's density).", "kg/m³", gt=0)
    mass: float | None = key(None, "Mass of this part, instead of a density.", "kg", gt=0)

    @model_validator(mode="after")
    def _not_both(self) -> "CompoundPart":
        if self.density is not None and self.mass is not None:
            raise rule_error("give density or mass, not both", "mass")
        return self


class CompoundShape(SceneModel):
    """Several primitives joined rigidly: ``M = Σ mᵢ``, ``c = Σ mᵢ cᵢ / M``, inertia by parallel axes and rotations."""

    type: Literal["compound"] = key(description="Shape type.")
    parts: Annotated[list[CompoundPart], at.Len(1, 1000)] = key(description="The parts.")


SHAPES: tuple[type[SceneModel], ...] = (*PRIMITIVE_SHAPES, CompoundShape)
ShapeSpec = Annotated[Union[*SHAPES], Field(discriminator="type")]  # type: ignore[valid-type]


class RigidBodySpec(SceneModel):
    """A rigid body: a shape with mass properties from its density (or a given mass), state ``[x, q, P, L]``.

    ``position`` places the shape's origin (the centre of primitives); the body moves about its centre of mass.
    """

    type: Literal["rigid"] = key(description="Body type.")
    name: Name = key(description="Unique name.", example="crate")
    shape: ShapeSpec = key(description="Shape; gives volume, centre of mass and inertia.")  # type: ignore[valid-type]
    density: float | None = key(None, "Density: mass = density × volume.", "kg/m³", gt=0)
    mass: float | None = key(None, "Mass, instead of a density (for a compound: the total, distributed as the "
                                    "parts' densities say, or uniformly where they give none).", "kg", gt=0)
    position: Vec3 = key([0.0, 0.0, 0.0], "Initial position of the shape's origin.", "m")
    orientation: OrientationSpec | None = key(None, "Initial orientation (default: body axes = world axes).")
    velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial velocity of the centre of mass.", "m/s")
    angular_velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial angular velocity ω, world axes.", "rad/s")
    material: Name = key("default", "Material, for collisions (see the particle's 'material').")
    collide: bool = key(True, "Take part in collisions (when the scene has colliders or a 'contacts' section).")
    color: Color | None = key(None, "Display colour (default: from a palette, by body index).")

    @model_validator(mode="after")
    def _mass_given_once(self) -> "RigidBodySpec":
        if self.density is not None and self.mass is not None:
            raise rule_error("give density or mass, not both", "mass")
        if isinstance(self.shape, CompoundShape):
            unspecified = any(p.density is None and p.mass is None for p in self.shape.parts)
            if self.density is None and self.mass is None and unspecified:
                raise rule_error("every part needs a density or mass, or the body a density or mass", "density")
        elif self.density is None and self.mass is None:
            raise rule_error("required key missing: give density (kg/m³, mass = density × volume) or mass (kg)",
                             "density")
        thin = isinstance(self.shape, ShellShape) and self.shape.thickness is None
        if thin and self.density is not None:
            raise rule_error("a thin shell has no volume, so a density gives no mass: give mass, or shape.thickness",
                             "density")
        return self


# ----------------------------------------------------------------------------------------------------------------
# Deformable bodies: cloth and spring lattices


class SpringFamilySpec(SceneModel):
    """Stiffness and damping of one family of a mesh's springs (each spring: ``f1 = -(ks (|L| - r) + kd L̇·u) u``,
    at rest at its initial length)."""

    stiffness: float = key(description="Spring constant ks of each spring.", unit="N/m", ge=0)
    damping: float = key(0.0, "Damping constant kd of each spring, along its axis.", "N·s/m", ge=0)


class AngleSpringSpec(SceneModel):
    """Dihedral angle springs: each interior edge resists bending by ``τ = -k (θ - θ₀) - c θ̇``, θ the angle between
    its two triangles (θ₀ at the start)."""

    stiffness: float = key(description="Angular stiffness k per edge.", unit="N·m/rad", ge=0)
    damping: float = key(0.0, "Angular damping c per edge.", "N·m·s/rad", ge=0)


class OffsetKeyframeSpec(SceneModel):
    """How far pinned vertices have moved from where they started, at a time."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    offset: Vec3 = key(description="Displacement from the start [dx, dy, dz].", unit="m")


class RegionSpec(SceneModel):
    """An axis-aligned box in world coordinates; it selects the vertices inside it at the start."""

    min: Vec3 = key(description="Lower corner [x, y, z].", unit="m")
    max: Vec3 = key(description="Upper corner [x, y, z].", unit="m")

    @model_validator(mode="after")
    def _ordered(self) -> "RegionSpec":
        if any(low > high for low, high in zip(self.min, self.max)):
            raise rule_error(f"min must not exceed max in any coordinate (got min {self.min}, max {self.max})",
                             "max")
        return self


GridCorner = Literal["bottom-left", "bottom-right", "top-left", "top-right"]


class PinSpec(SceneModel):
    """Vertices held in place: fixed where they start, moved along keyframes, or attached to a rigid body.

    Select vertices by ``vertices`` (indices), ``corners`` (of a grid cloth) or ``region`` (a box, at the start); a
    pin may combine them. Pinned vertices are not simulated: they are constraints, so they never drift.
    """

    vertices: list[Annotated[int, Field(ge=0)]] = key([], "Vertex indices (grid: j·nx + i, vertex 0 at the "
                                                          "bottom-left corner).", example=[0, 31])
    corners: list[GridCorner] = key([], "Corners of a grid cloth (its local x to the right, y up).",
                                    example=["top-left", "top-right"])
    region: RegionSpec | None = key(None, "Every vertex inside this box at the start.")
    to: Name | None = key(None, "A rigid body the vertices are attached to (they move with it and pull on it).")
    keyframes: _keyframe_list(OffsetKeyframeSpec) | None = key(  # type: ignore[valid-type]
        None, "Move the pinned vertices by these offsets over time.")
    interpolation: Interpolation = key("linear", "Between keyframes: linear or cubic.")

    @model_validator(mode="after")
    def _selects_something(self) -> "PinSpec":
        if not self.vertices and not self.corners and self.region is None:
            raise rule_error("a pin selects vertices: give vertices, corners or region", "vertices")
        if self.to is not None and self.keyframes is not None:
            raise rule_error("a pin either moves with a rigid body ('to') or along keyframes, not both", "keyframes")
        return self


class GridSpec(SceneModel):
    """A rectangular sheet of vertices in the cloth's local x–y plane, centred on its position."""

    size: Annotated[list[Annotated[float, Field(gt=0)]], at.Len(2, 2)] = key(
        description="Width (local x) and height (local y).", unit="m", example=[1.5, 1.0])
    resolution: Annotated[list[Annotated[int, Field(ge=2, le=1024)]], at.Len(2, 2)] = key(
        description="Vertices along x and along y.", example=[32, 24])


class ClothMeshSpec(SceneModel):
    """A cloth from a triangle mesh file (open or closed); its vertices are the point masses."""

    file: str = key(description="Mesh file (STL, OBJ, PLY), relative to the scene file.")
    scale: float | PositiveVec3 = key(1.0, "Scale factor(s) applied to the file's coordinates.", "1")


class _DeformableBase(SceneModel):
    """Keys shared by cloth and lattices."""

    name: Name = key(description="Unique name; vertex k is the particle '<name>[k]' in trajectories.")
    position: Vec3 = key([0.0, 0.0, 0.0], "Where the body's local origin goes (a grid's or lattice's centre).", "m")
    orientation: OrientationSpec | None = key(None, "Rotation of the body from its local axes.")
    velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial velocity of every vertex.", "m/s")
    mass: float | None = key(None, "Total mass, spread over the vertices by the area (or volume) each stands "
                                   "for.", "kg", gt=0)
    structural: SpringFamilySpec | None = key(None, "Springs along the edges (none if not given).")
    shear: SpringFamilySpec | None = key(None, "Diagonal springs (none if not given).")
    bend: SpringFamilySpec | None = key(None, "Springs to the vertex after next (none if not given).")
    pin: list[PinSpec] = key([], "Vertices held fixed, moved by keyframes, or attached to rigid bodies.")
    radius: float | None = key(None, "Radius of each vertex for collisions (default: a quarter of the mean edge "
                                     "length).", "m", gt=0)
    material: Name = key("default", "Material, for collisions and friction.")
    collide: bool = key(True, "Take part in collisions (its vertices never collide with each other).")
    color: Color | None = key(None, "Display colour (default: from a palette, by body index).")


class ClothSpec(_DeformableBase):
    """A cloth: a sheet of point masses joined by structural, shear and bend springs, optionally with dihedral angle
    springs; drawn as a smooth two-sided surface. Give ``grid`` or ``mesh``."""

    type: Literal["cloth"] = key(description="Body type.")
    grid: GridSpec | None = key(None, "A rectangular sheet.")
    mesh: ClothMeshSpec | None = key(None, "A sheet from a triangle mesh file.")
    density: float | None = key(None, "Mass per area (cotton about 0.15, canvas 0.4), instead of mass.", "kg/m²",
                                gt=0)
    dihedral: AngleSpringSpec | None = key(None, "Dihedral angle springs on every interior edge (bending).")
    back_color: Color | None = key(None, "Colour of the back side (default: the front colour, darker).")

    @model_validator(mode="after")
    def _one_source(self) -> "ClothSpec":
        if (self.grid is None) == (self.mesh is None):
            raise rule_error("give grid (a rectangular sheet) or mesh (a file), not both" if self.grid is not None
                             else "required key missing: give grid or mesh", "grid")
        if self.mesh is not None and self.shear is not None:
            raise rule_error("shear springs are for grid cloths; a triangle mesh's edges already resist shear",
                             "shear")
        if self.mesh is not None and any(pin.corners for pin in self.pin):
            raise rule_error("corners name the corners of a grid cloth; pin mesh vertices by index or region", "pin")
        _mass_or_density(self)
        return self


class LatticeSpec(_DeformableBase):
    """A soft block ("jelly"): a 3D grid of point masses joined by springs along its edges (structural), across its
    faces and cells (shear) and to the vertex after next (bend); drawn as its outer surface."""

    type: Literal["lattice"] = key(description="Body type.")
    size: PositiveVec3 = key(description="Side lengths along local x, y, z.", unit="m")
    resolution: Annotated[list[Annotated[int, Field(ge=2, le=64)]], at.Len(3, 3)] = key(
        description="Vertices along x, y and z.", example=[6, 6, 6])
    density: float | None = key(None, "Mass per volume, instead of mass.", "kg/m³", gt=0)

    @model_validator(mode="after")
    def _mass_given(self) -> "LatticeSpec":
        if any(pin.corners for pin in self.pin):
            raise rule_error("corners name the corners of a grid cloth; pin lattice vertices by index or region",
                             "pin")
        _mass_or_density(self)
        return self


def _mass_or_density(body: Any) -> None:
    if body.mass is not None and body.density is not None:
        raise rule_error("give density or mass, not both", "mass")
    if body.mass is None and body.density is None:
        raise rule_error("required key missing: give density or mass (kg)", "density")


DEFORMABLE_SPECS = (ClothSpec, LatticeSpec)


def _body_kind(value: Any) -> str | None:
    """Bodies are particles unless they say otherwise."""
    if isinstance(value, dict):
        return value.get("type", "particle")
    return getattr(value, "type", None)


BodySpec = Annotated[Union[Annotated[ParticleSpec, Tag("particle")], Annotated[RigidBodySpec, Tag("rigid")],
                           Annotated[ClothSpec, Tag("cloth")], Annotated[LatticeSpec, Tag("lattice")]],
                     Discriminator(_body_kind)]


class SpringSpec(SceneModel):
    """A Hooke spring with a damper along its axis, between two bodies or a body and an anchor.

    Force on the first end: ``f1 = -(ks (|L| - r) + kd (v1 - v2)·L/|L|) L/|L|`` with ``L = x1 - x2``; ``f2 = -f1``.
    A spring with ``stiffness: 0`` is a pure damper.
    """

    name: Name | None = key(None, "Name used in messages (default: '<first>--<second>').")
    between: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The two ends: names of bodies or anchors (at most one anchor).", example=["ceiling", "bob"])
    stiffness: float = key(description="Spring constant ks.", unit="N/m", ge=0)
    damping: float = key(0.0, "Damping constant kd along the spring axis.", "N·s/m", ge=0)
    rest_length: float | None = key(None, "Rest length r (default: the initial distance between the ends).",
                                    "m", ge=0)
    attach: Annotated[list[Vec3 | None], at.Len(2, 2)] | None = key(
        None, "Attachment points [first, second] in body coordinates (relative to the shape's origin) for rigid "
              "bodies; null for an end at a centre of mass, particle or anchor.", "m",
        example=[[0.5, 0.25, 0.5], None])
    color: Color | None = key(None, "Display colour (default grey).")

    @field_validator("between")
    @classmethod
    def _two_different_ends(cls, ends: list[str]) -> list[str]:
        if ends[0] == ends[1]:
            raise rule_error(f"both ends are {ends[0]!r}; a spring joins two different points")
        return ends


# ----------------------------------------------------------------------------------------------------------------
# Force fields. Each is compiled into a force term only when declared.

BodySelection = list[Name] | None
_BODIES_DESCRIPTION = "Names of the bodies this field acts on (default: all bodies)."


class GravitySpec(SceneModel):
    """Uniform gravity: ``f = m g`` on each selected body."""

    type: Literal["gravity"] = key(description="Field type.")
    g: Vec3 = key([0.0, -9.81, 0.0], "Gravitational acceleration vector.", "m/s²")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class GravitationSpec(SceneModel):
    """Newtonian gravitation between every pair of selected bodies, with Plummer softening.

    ``f_i = Σ_j G m_i m_j (x_j - x_i) / (|x_j - x_i|² + ε²)^(3/2)``.
    """

    type: Literal["gravitation"] = key(description="Field type.")
    G: float = key(6.674e-11, "Gravitational constant (scenes often use G = 1 with scaled masses).",
                   "m³/(kg·s²)", gt=0)
    softening: float = key(0.0, "Plummer softening length ε; keeps close encounters finite.", "m", ge=0)
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


DragModel = Literal["linear", "quadratic", "stokes"]


class _DragLaw(SceneModel):
    """The keys shared by drag and wind, and the rule tying the drag law to its parameters."""

    at: Vec3 | None = key(None, "For rigid bodies: the point (body coordinates, relative to the shape's origin) "
                                "whose velocity the drag opposes and where it acts, giving a torque (default: the "
                                "centre of mass). Particles ignore it.", "m")

    coefficient: float | None = key(None, "C for the linear (N·s/m) or quadratic (kg/m) law; not used by stokes.",
                                    "N·s/m or kg/m", ge=0)
    viscosity: float | None = key(None, "Dynamic viscosity η of the fluid for the stokes law "
                                        "(default 1.81e-5, air at 15 °C).", "Pa·s", gt=0)

    @model_validator(mode="after")
    def _parameters_match_law(self) -> "_DragLaw":
        model = self.model  # type: ignore[attr-defined]
        if model in ("linear", "quadratic") and self.coefficient is None:
            unit = "N·s/m" if model == "linear" else "kg/m"
            raise rule_error(f"required key missing: the {model} drag law needs 'coefficient' (C in {unit})",
                             "coefficient")
        if model == "stokes" and self.coefficient is not None:
            raise rule_error("not used by the stokes law (its coefficient is 6 π η r); remove it, or set 'viscosity'",
                             "coefficient")
        if model != "stokes" and self.viscosity is not None:
            raise rule_error(f"only the stokes law uses 'viscosity'; the {model} law uses 'coefficient'",
                             "viscosity")
        return self


class DragSpec(_DragLaw):
    """Fluid drag against the body's velocity, at its centre of mass or at a point ``at`` of rigid bodies.

    ``linear``: ``f = -C v``; ``quadratic``: ``f = -C |v| v``; ``stokes``: ``f = -6 π η r v`` (r: the particle's
    radius, or for a rigid body the radius of the sphere of equal volume).
    """

    type: Literal["drag"] = key(description="Field type.")
    model: DragModel = key(description="Drag law: linear, quadratic or stokes.", example="quadratic")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class WindSpec(_DragLaw):
    """Drag relative to moving air: the drag law applied to ``v - wind velocity``."""

    type: Literal["wind"] = key(description="Field type.")
    velocity: Vec3 = key(description="Wind velocity.", unit="m/s")
    model: DragModel = key("quadratic", "Drag law: linear, quadratic or stokes.")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


Frame = Literal["world", "body"]


class ForceSpec(SceneModel):
    """A constant force, applied at a point of each selected body; off the centre of mass it gives torque r × f."""

    type: Literal["force"] = key(description="Field type.")
    force: Vec3 = key(description="The force vector.", unit="N")
    at: Vec3 | None = key(None, "Point of application in body coordinates (relative to the shape's origin; default: "
                                "the centre of mass). Particles ignore it.", "m")
    frame: Frame = key("world", "Axes of 'force': world (fixed direction) or body (turns with the body, like a "
                                "thruster).")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class TorqueSpec(SceneModel):
    """A constant torque on each selected rigid body."""

    type: Literal["torque"] = key(description="Field type.")
    torque: Vec3 = key(description="The torque vector.", unit="N·m")
    frame: Frame = key("world", "Axes of 'torque': world or body.")
    bodies: BodySelection = key(None, "Names of the rigid bodies it acts on (default: all rigid bodies).")


class AngularDragSpec(SceneModel):
    """Rotational damping ``τ = -c ω`` on each selected rigid body (air resistance to spinning, bearing friction)."""

    type: Literal["angular_drag"] = key(description="Field type.")
    coefficient: float = key(description="Rotational damping coefficient c.", unit="N·m·s", ge=0)
    bodies: BodySelection = key(None, "Names of the rigid bodies it acts on (default: all rigid bodies).")


class BuoyancySpec(SceneModel):
    """A fluid filling the half-space below a surface: each selected body is pushed up by ``ρ g V_submerged`` at the
    centre of the submerged volume (so floating bodies right themselves), and optionally damped in proportion to how
    much of it is submerged.

    Submerged volumes are exact for spheres, particles (spheres of their radius), boxes and meshes (clipped exactly
    at the surface); cylinders and rods use a 96-sided prism, within 0.1 % of their volume.
    """

    type: Literal["buoyancy"] = key(description="Field type.")
    density: float = key(1000.0, "Density ρ of the fluid (water 1000, sea water 1025, air 1.2).", "kg/m³", gt=0)
    level: float = key(0.0, "Height of the fluid surface along 'up'.", "m")
    up: NonZeroVec3 = key([0.0, 1.0, 0.0], "Upward direction (opposite to gravity).", "1")
    g: float = key(9.81, "Gravitational acceleration used for the buoyant force.", "m/s²", gt=0)
    linear_damping: float = key(0.0, "Viscous damping of the fluid, -c v, at full submersion (scaled by the "
                                     "submerged fraction).", "N·s/m", ge=0)
    angular_damping: float = key(0.0, "Rotational damping -c ω at full submersion (scaled likewise).", "N·m·s", ge=0)
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class GustSpec(SceneModel):
    """Gusts on top of the steady wind: ``w(t) = wind + amplitude · g(t)``, with g a smooth, repeatable signal in
    [-1, 1] (three sine waves at incommensurate frequencies, the slowest of period ``period``)."""

    amplitude: Vec3 = key(description="Largest change of the wind velocity.", unit="m/s")
    period: float = key(2.0, "Period of the slowest gust component.", "s", gt=0)


class AerodynamicsSpec(SceneModel):
    """Air acting on each triangle of a cloth, through its face normal n: with ``u = v_face - w`` the face's velocity
    relative to the wind, the face feels ``f = -½ ρ A |u| (C_n (u·n) n + C_t (u - (u·n) n))``, shared equally by its
    three vertices. A sheet facing the wind catches it; one edge-on barely does, so a flag billows and flutters."""

    type: Literal["aerodynamics"] = key(description="Field type.")
    wind: Vec3 = key([0.0, 0.0, 0.0], "Steady wind velocity w.", "m/s")
    gust: GustSpec | None = key(None, "Gusts added to the steady wind.")
    density: float = key(1.2, "Density ρ of the air.", "kg/m³", gt=0)
    drag: float = key(1.0, "Coefficient C_n of the force along the face normal.", "1", ge=0)
    friction: float = key(0.02, "Coefficient C_t of the force along the face (skin friction).", "1", ge=0)
    bodies: BodySelection = key(None, "Names of the cloths it acts on (default: all cloths).")


FIELD_SPECS: tuple[type[SceneModel], ...] = (GravitySpec, GravitationSpec, DragSpec, WindSpec, ForceSpec, TorqueSpec,
                                             AngularDragSpec, BuoyancySpec, AerodynamicsSpec)
#: Field types that act on emitted particles too (the others act on bodies only).
PARTICLE_FIELD_TYPES = ("gravity", "drag", "wind", "buoyancy")
FieldSpec = Annotated[Union[*FIELD_SPECS], Field(discriminator="type")]  # type: ignore[valid-type]


def field_type_names() -> tuple[str, ...]:
    """The ``type`` values of all field kinds, in declaration order."""

    return tuple(str(tag_of(spec)) for spec in FIELD_SPECS)


# ----------------------------------------------------------------------------------------------------------------
# Materials, colliders and contacts


class MaterialSpec(SceneModel):
    """A surface material: how it bounces and how it grips (see the built-in table in the docs)."""

    restitution: float = key(description="Coefficient of restitution e: separation speed / approach speed in an "
                                         "impact (0 dead, 1 perfectly elastic).", unit="1", ge=0, le=1)
    static_friction: float = key(description="Static friction coefficient μs: |f| ≤ μs N while sticking.", unit="1",
                                 ge=0)
    kinetic_friction: float = key(description="Kinetic friction coefficient μk: |f| = μk N while sliding.", unit="1",
                                  ge=0)

    @model_validator(mode="after")
    def _kinetic_not_above_static(self) -> "MaterialSpec":
        if self.kinetic_friction > self.static_friction:
            raise rule_error(f"must not exceed static_friction ({self.static_friction:g}): a sliding contact cannot "
                             "grip harder than a sticking one", "kinetic_friction")
        return self


class MaterialPairSpec(SceneModel):
    """Coefficients for one pair of materials, replacing the combination rule for that pair."""

    materials: Annotated[list[Name], at.Len(2, 2)] = key(description="The two materials (order does not matter).",
                                                         example=["rubber", "pavement"])
    restitution: float | None = key(None, "Coefficient of restitution for this pair.", "1", ge=0, le=1)
    static_friction: float | None = key(None, "Static friction coefficient for this pair.", "1", ge=0)
    kinetic_friction: float | None = key(None, "Kinetic friction coefficient for this pair.", "1", ge=0)


class _ColliderBase(SceneModel):
    material: Name = key("default", "Material of the surface (built-in or from 'materials').")
    color: Color | None = key(None, "Display colour (default light grey).")
    visible: bool = key(True, "Draw it.")


class PlaneCollider(_ColliderBase):
    """An infinite, fixed plane; bodies stay on the side its normal points to."""

    type: Literal["plane"] = key(description="Collider type.")
    point: Vec3 = key([0.0, 0.0, 0.0], "A point on the plane.", "m")
    normal: NonZeroVec3 = key([0.0, 1.0, 0.0], "Normal, pointing to the free side (need not be unit length).", "1")
    size: float | None = key(None, "Side of the square drawn to show it (default: fitted to the motion).", "m", gt=0)


class BoxCollider(_ColliderBase):
    """A fixed, solid box (a wall, a step, a table)."""

    type: Literal["box"] = key(description="Collider type.")
    position: Vec3 = key(description="Centre of the box.", unit="m")
    size: PositiveVec3 = key(description="Side lengths [a, b, c] along its axes.", unit="m")
    orientation: OrientationSpec | None = key(None, "Rotation of the box (default: axes along the world's).")


class SphereCollider(_ColliderBase):
    """A fixed, solid sphere."""

    type: Literal["sphere"] = key(description="Collider type.")
    position: Vec3 = key(description="Centre.", unit="m")
    radius: float = key(description="Radius.", unit="m", gt=0)


class MeshCollider(_ColliderBase):
    """A fixed triangle mesh (a terrain, a ramp, a bowl); bodies collide with its triangles from either side."""

    type: Literal["mesh"] = key(description="Collider type.")
    file: str = key(description="Mesh file (STL, OBJ, PLY), relative to the scene file.")
    scale: float | PositiveVec3 = key(1.0, "Scale factor(s) applied to the file's coordinates.", "1")
    position: Vec3 = key([0.0, 0.0, 0.0], "Where the file's origin goes.", "m")
    orientation: OrientationSpec | None = key(None, "Rotation of the mesh.")


COLLIDER_SPECS: tuple[type[SceneModel], ...] = (PlaneCollider, BoxCollider, SphereCollider, MeshCollider)
ColliderSpec = Annotated[Union[*COLLIDER_SPECS], Field(discriminator="type")]  # type: ignore[valid-type]


class ContactSpec(SceneModel):
    """How contacts are handled. Present (even empty) or implied by colliders, it switches collisions on."""

    bodies: bool = key(True, "Moving bodies collide with each other (not only with colliders).")
    rest_speed: float | None = key(None, "Approach speed below which an impact does not bounce, so that bouncing "
                                         "ends (default: 1 cm/s, or 3 g dt for fixed-step methods if that is more).",
                                   "m/s", gt=0)
    iterations: int = key(300, "Most iterations of the contact solver per step; it stops as soon as every contact "
                               "holds (to 1e-10 m/s), usually after a few thanks to warm starting.", "1",
                          ge=1, le=10000)
    slop: float = key(1e-4, "Penetration tolerated before positions are corrected (avoids jitter).", "m", ge=0)


# ----------------------------------------------------------------------------------------------------------------
# Controllers: virtual springs that pull a body towards a target


class PointTarget(SceneModel):
    """A fixed point."""

    type: Literal["point"] = key(description="Target type.")
    position: Vec3 = key(description="The point.", unit="m")


class KeyframeTarget(SceneModel):
    """A point moving along keyframes."""

    type: Literal["keyframes"] = key(description="Target type.")
    keyframes: _keyframe_list(KeyframeSpec) = key(description="Positions over time.")  # type: ignore[valid-type]
    interpolation: Interpolation = key("linear", "Between keyframes: linear or cubic.")


class PolylineTarget(SceneModel):
    """The closest point on a polyline (a wire through the given points)."""

    type: Literal["polyline"] = key(description="Target type.")
    points: Annotated[list[Vec3], at.Len(2, 1000000)] = key(description="The polyline's points, in order.", unit="m")
    closed: bool = key(False, "Join the last point back to the first.")


class ParametricTarget(SceneModel):
    """The closest point on a curve ``(x(s), y(s), z(s))`` for s in ``range``, sampled finely into a polyline.
    Expressions use ``s``, numbers, + - * / **, pi, e, and sin, cos, tan, asin, acos, atan, atan2, sinh, cosh,
    tanh, exp, log, sqrt, abs."""

    type: Literal["parametric"] = key(description="Target type.")
    x: str = key(description="x(s).", unit="m", example="0.5 * cos(s)")
    y: str = key(description="y(s).", unit="m", example="0.5 * sin(s)")
    z: str = key("0", "z(s).", "m")
    range: Annotated[list[float], at.Len(2, 2)] = key(description="[start, end] of the parameter s.",
                                                      example=[0, 6.283185307179586])
    closed: bool = key(False, "The curve ends where it starts (join the samples into a loop).")
    samples: int = key(4096, "Points sampled along the curve (the polyline's error falls as 1/samples²).", "1",
                       ge=8, le=1000000)

    @field_validator("x", "y", "z")
    @classmethod
    def _expression(cls, text: str) -> str:

        try:
            compile_expression(text)
        except ExpressionError as error:
            raise rule_error(str(error)) from None
        return text

    @field_validator("range")
    @classmethod
    def _increasing(cls, bounds: list[float]) -> list[float]:
        if not bounds[1] > bounds[0]:
            raise rule_error(f"the end must be greater than the start (got {bounds})")
        return bounds


TARGET_SPECS: tuple[type[SceneModel], ...] = (PointTarget, KeyframeTarget, PolylineTarget, ParametricTarget)
TargetSpec = Annotated[Union[*TARGET_SPECS], Field(discriminator="type")]  # type: ignore[valid-type]


class ControllerSpec(SceneModel):
    """A proportional–derivative controller (a virtual spring, a soft constraint): ``F = ks d - kd v_rel``, with
    ``d`` from the body (or its point) to the target and ``v_rel`` its velocity relative to the target's.

    On a curve the target is the closest point, and only the velocity across the curve is damped, so the body
    slides freely along it (a bead on a wire)."""

    name: Name | None = key(None, "Name used in messages (default: '<body>-controller').")
    body: Name = key(description="The particle or rigid body it pulls.", example="bead")
    point: Vec3 | None = key(None, "For rigid bodies: the body point (shape coordinates) pulled towards the target "
                                   "(default: the centre of mass).", "m")
    target: TargetSpec = key(description="Where it pulls: a point, keyframes, a polyline or a parametric "  # type: ignore[valid-type]
                                         "curve.")
    stiffness: float = key(description="Proportional gain ks.", unit="N/m", ge=0)
    damping: float = key(0.0, "Derivative gain kd.", "N·s/m", ge=0)


# ----------------------------------------------------------------------------------------------------------------
# Particle systems: emitters


class RandomValue(SceneModel):
    """A value drawn for each particle when it is born: ``mean`` ± ``spread``, never outside those bounds.

    ``uniform``: every value in ``[mean - spread, mean + spread]`` equally likely. ``normal``: a normal distribution
    of standard deviation ``spread / 2``, clipped to the same bounds (values beyond them are moved onto them).
    A plain number instead of this block means the same value for every particle."""

    mean: float = key(description="The mean.", example=2.0)
    spread: float = key(0.0, "Largest difference from the mean.", ge=0)
    distribution: Literal["uniform", "normal"] = key("uniform", "uniform, or normal clipped to mean ± spread.")

    @property
    def bounds(self) -> tuple[float, float]:
        return self.mean - self.spread, self.mean + self.spread


class RandomColor(SceneModel):
    """A colour drawn for each particle: each of red, green and blue within ``spread`` of the mean colour's (and
    within 0…1)."""

    mean: Color = key(description="The mean colour.", example="orange")
    spread: float = key(0.0, "Largest difference of each channel from the mean's, in 0…1.", ge=0, le=1)
    distribution: Literal["uniform", "normal"] = key("uniform", "uniform, or normal clipped to mean ± spread.")


Randomised = float | RandomValue


def random_bounds(value: float | RandomValue) -> tuple[float, float]:
    """The smallest and largest value a (possibly random) attribute can take."""
    return (value, value) if isinstance(value, int | float) else value.bounds


class RateKeyframe(SceneModel):
    """An emission rate at a time; between keys the rate changes linearly."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    rate: float = key(description="Particles per second at that time.", unit="1/s", ge=0)


class BurstSpec(SceneModel):
    """Many particles born at one instant."""

    time: float = key(description="When.", unit="s", ge=0)
    count: int = key(description="How many particles.", unit="1", ge=1, le=10_000_000)


class PointSource(SceneModel):
    """Particles start at one point."""

    type: Literal["point"] = key(description="Source shape.")
    position: Vec3 = key([0.0, 0.0, 0.0], "The point.", "m")


class SphereSource(SceneModel):
    """Particles start anywhere inside a ball (or on its surface)."""

    type: Literal["sphere"] = key(description="Source shape.")
    position: Vec3 = key([0.0, 0.0, 0.0], "Centre.", "m")
    radius: float = key(description="Radius.", unit="m", gt=0)
    surface: bool = key(False, "Only on the sphere's surface.")


class DiscSource(SceneModel):
    """Particles start anywhere on a flat disc."""

    type: Literal["disc"] = key(description="Source shape.")
    position: Vec3 = key([0.0, 0.0, 0.0], "Centre.", "m")
    radius: float = key(description="Radius.", unit="m", gt=0)
    normal: NonZeroVec3 = key([0.0, 1.0, 0.0], "Normal of the disc (the direction 'normal' emits along).", "1")


class BoxSource(SceneModel):
    """Particles start anywhere inside a box."""

    type: Literal["box"] = key(description="Source shape.")
    position: Vec3 = key([0.0, 0.0, 0.0], "Centre.", "m")
    size: PositiveVec3 = key(description="Side lengths [a, b, c] along its axes.", unit="m")
    orientation: OrientationSpec | None = key(None, "Rotation of the box (default: axes along the world's).")


class SurfaceSource(SceneModel):
    """Particles start anywhere on the surface of the emitter's rigid body (``body``), evenly by area."""

    type: Literal["surface"] = key(description="Source shape.")


SOURCE_SPECS: tuple[type[SceneModel], ...] = (PointSource, SphereSource, DiscSource, BoxSource, SurfaceSource)
SourceSpec = Annotated[Union[*SOURCE_SPECS], Field(discriminator="type")]  # type: ignore[valid-type]


class DirectionSpec(SceneModel):
    """Directions of the start velocities: evenly spread over a cone of half-angle ``cone`` around ``axis``
    (0: all along the axis; 180: every direction)."""

    axis: NonZeroVec3 | Literal["normal"] = key(
        [0.0, 1.0, 0.0], "Axis of the cone, or 'normal': the outward normal of the source where the particle starts "
                         "(sphere, disc, surface).", "1")
    cone: float = key(0.0, "Half-angle of the cone.", "deg", ge=0, le=180)


class ParticleLook(SceneModel):
    """How emitted particles are drawn. Ramps (``size``, ``opacity``, ``color``) are values at evenly spaced points
    of a particle's life, from birth (first) to death (last), linearly interpolated; one value holds all life."""

    style: Literal["sprite", "sphere"] = key(
        "sprite", "sprite: glowing, unlit splats (sparks, fire, smoke); sphere: lit spheres (drops, snow). Both draw "
                  "every particle of an emitter as one point cloud, never a mesh per particle.")
    size: Annotated[list[Annotated[float, Field(ge=0)]], at.Len(1, 64)] = key(
        [1.0], "Factors on the particle's radius over its life.", "1")
    opacity: Annotated[list[Annotated[float, Field(ge=0, le=1)]], at.Len(1, 64)] = key(
        [1.0], "Opacity over its life (0 invisible, 1 opaque).", "1")
    color: Annotated[list[Color], at.Len(1, 64)] | None = key(
        None, "Colours over its life (default: the particle's own colour throughout). The particle's random "
              "difference from the mean colour is added to them.")
    trail: int = key(0, "Draw a line through the particle's positions at this many previous frames (0: none).", "1",
                     ge=0, le=60)


class EmitterSpec(SceneModel):
    """A particle emitter: where particles are born, how many, and the attributes each is given.

    Emitted particles feel the fields that act on them (gravity, drag, wind, buoyancy; see 'fields'), collide with
    the colliders, never with each other, and do not push on the scene's bodies. Each emitter keeps a pool of
    ``capacity`` slots: a particle that dies frees its slot, and a new particle takes the lowest free slot
    (the lecture notes' "if dead, reallocate and assign new attributes")."""

    name: Name = key(description="Unique name (shared namespace with bodies); fields name it in 'bodies'.",
                     example="fountain")
    source: SourceSpec = key(PointSource(type="point"), "Where particles start: point, sphere, disc, box, or the "  # type: ignore[valid-type]
                                                        "surface of 'body'.")
    body: Name | None = key(None, "A rigid body the emitter moves with: the source is then in the body's shape "
                                  "coordinates, and turns with it.")
    inherit_velocity: float = key(1.0, "Fraction of the body's velocity at the birth point that particles start "
                                       "with (with 'body').", "1")
    rate: Annotated[float, Field(ge=0)] | Annotated[list[RateKeyframe], at.Len(1, 100000),
                                                  AfterValidator(_increasing_times)] = key(
        0.0, "Particles per second: a number, or keyframes [{time, rate}] (linear between keys, held outside "
             "them). Fractions of a particle carry over exactly: rate × time particles are born by any time.",
        "1/s", example=500)
    start: float = key(0.0, "When the rate starts.", "s", ge=0)
    stop: float | None = key(None, "When the rate stops (default: the end of the animation).", "s", gt=0)
    bursts: list[BurstSpec] = key([], "Particles born all at once at given times, in addition to the rate.")
    capacity: int | None = key(None, "Slots in the pool: the most particles alive at once (default: the most the "
                                     "rate, bursts and longest lifetime can keep alive). Births beyond it are "
                                     "dropped and counted.", "1", ge=1, le=50_000_000)
    lifetime: Randomised = key(2.0, "How long a particle lives.", "s", example={"mean": 2.0, "spread": 0.5})
    speed: Randomised = key(1.0, "Start speed (before any velocity inherited from the body).", "m/s")
    direction: DirectionSpec = key(DirectionSpec(), "Directions of the start velocities.")
    radius: Randomised = key(0.01, "Particle radius: its size on screen, for Stokes drag, buoyancy and collisions.",
                             "m")
    mass: Randomised = key(1e-3, "Particle mass.", "kg")
    color: Color | RandomColor = key("orange", "Colour, or {mean, spread} for a colour drawn per particle.")
    collision: Literal["bounce", "stick", "die", "pass"] = key(
        "bounce", "On hitting a collider: bounce (with the restitution and friction of the two materials), stick "
                  "(stay where it hit, until it dies), die, or pass (no collisions).")
    material: Name = key("default", "Material of the particles, for bouncing (see the body 'material').")
    look: ParticleLook = key(ParticleLook(), "How the particles are drawn.")

    @model_validator(mode="after")
    def _positive_attributes(self) -> "EmitterSpec":
        for name, smallest, inclusive in (("lifetime", 0.0, False), ("radius", 0.0, False), ("mass", 0.0, False),
                                          ("speed", 0.0, True)):
            low, _ = random_bounds(getattr(self, name))
            if low < smallest or (low == smallest and not inclusive):
                raise rule_error(f"can reach {low:g} (mean - spread); it must stay {'≥' if inclusive else '>'} "
                                 f"{smallest:g}: lower the spread or raise the mean", name)
        if self.stop is not None and self.stop <= self.start:
            raise rule_error(f"must be after start ({self.start:g} s)", "stop")
        if isinstance(self.source, SurfaceSource) and self.body is None:
            raise rule_error("a surface source needs the rigid body whose surface it is: set 'body'", "source")
        if self.direction.axis == "normal" and isinstance(self.source, PointSource | BoxSource):
            raise rule_error(f"a {self.source.type} source has no normal; give an axis vector (with cone: 180 for "
                             "every direction)", "direction")
        return self


# ----------------------------------------------------------------------------------------------------------------
# Rendering


class CameraSpec(SceneModel):
    """The camera. Without position and focal point it is fitted to the bounding box of the whole motion."""

    position: Vec3 | None = key(None, "Camera position (give together with focal_point; default: fitted).", "m")
    focal_point: Vec3 | None = key(None, "Point the camera looks at (default: centre of the motion).", "m")
    up: Vec3 = key([0.0, 1.0, 0.0], "Up direction on screen; also the ground normal.", "1")
    view_angle: float = key(30.0, "Vertical field of view.", "deg", gt=0, lt=180)
    direction: Vec3 = key([0.4, 0.35, 1.0], "When fitted: direction from the focal point towards the camera.", "1")
    fit_margin: float = key(1.15, "When fitted: how much room to leave around the motion (1 = tight).", "1",
                            ge=1, le=10)

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


class GroundSpec(SceneModel):
    """A ground plane drawn perpendicular to ``camera.up`` (display only: it does not collide)."""

    level: float = key(0.0, "Height of the ground along camera.up.", "m")
    size: float | None = key(None, "Side length of the ground square (default: fitted to the motion).", "m", gt=0)
    color: Color = key("#d8d8d8", "Ground colour.")
    grid: bool = key(True, "Draw grid lines on the ground.")


VideoPreset = Literal["ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower", "veryslow"]


class VideoSpec(SceneModel):
    """H.264 MP4 encoding (yuv420p, plays in browsers)."""

    preset: VideoPreset = key("veryfast", "x264 speed preset. 'veryfast' keeps up with the renderer; slower presets "
                                          "give smaller files at equal quality.")
    crf: int = key(20, "x264 constant rate factor: 0 lossless, 18 visually lossless, 23 x264's default, 51 worst.",
                   "1", ge=0, le=51)


class RenderSpec(SceneModel):
    """How frames are drawn and written."""

    resolution: Annotated[list[Annotated[int, Field(ge=16, le=7680)]], at.Len(2, 2)] = key(
        [1280, 720], "Frame size [width, height]; both even (required by H.264 yuv420p).", "px")
    background: Color = key("white", "Background colour.")
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
    show_anchors: bool = key(True, "Draw anchors as small dark cubes.")
    show_targets: bool = key(True, "Draw what PD controllers pull towards: curves as thin lines (the wire of a "
                                   "bead), point and keyframed targets as small grey spheres.")
    show_axes: bool = key(False, "Draw each rigid body's axes (x red, y green, z blue), turning with it.")
    show_vectors: Literal["none", "angular_velocity", "angular_momentum"] = key(
        "none", "Draw an arrow from each rigid body's centre of mass along ω or L, scaled so that the largest over "
                "the animation is twice the body's size.")
    fluid_color: Color = key("#3a7bd5", "Colour of the surfaces of buoyancy fluids (drawn translucent).")
    ground: GroundSpec | None = key(None, "Ground plane (omit for none; 'ground: {}' for the defaults).")
    show_time: bool = key(True, "Overlay the simulated time.")
    time_label: str = key("t = {t:.2f} s", "Format of the time overlay; {t} is the simulated time in s.")
    camera: CameraSpec = key(CameraSpec(), "Camera.")
    formats: Annotated[list[Literal["mp4", "png", "webm", "gif"]], at.Len(1, 4)] = key(
        ["mp4"], "Outputs: mp4 (H.264), webm (VP9), gif (256 colours; GIF times are in 1/100 s, so 30 fps plays "
        "at 33.3), and png (keep the frame files; they are the render's resumable state and are otherwise deleted "
        "once every video is encoded).")
    video: VideoSpec = key(VideoSpec(), "MP4 encoding settings.")
    max_cost: float = key(3600.0, "Wall-time budget of drawing the frames (each render process gets it). After "
                                  "two frames the time of the rest is projected, and a render that would take "
                                  "longer stops with exit code 4, saying what it would take; the frames drawn stay "
                                  "on disk, and a run with a larger budget goes on from them. 0 = no limit.",
                          "s", ge=0)

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
            label.format(t=1.0)
        except (KeyError, IndexError, ValueError) as error:
            raise rule_error(f"is not a valid format string ({error}); use {{t}} for the time, e.g. "
                             "'t = {t:.2f} s'") from None
        return label


# ----------------------------------------------------------------------------------------------------------------
# The scene


class StudySpec(SceneModel):
    """Settings of ``animbatch study``: the work-precision study of this scene (no effect on a render)."""

    closed_form: bool = key(False, "Measure errors against closed-form solutions instead of a tight reference run. "
                                   "Every body must have one: a projectile (uniform gravity only), a fall with "
                                   "linear drag (and gravity, optionally wind), a mass on one spring to a fixed "
                                   "anchor moving along the spring (gravity allowed along it), or one of a pair "
                                   "attracting each other by gravitation alone (Kepler orbit).")
    methods: list[Method] | None = key(None, "Integrators to study (default: every one that applies to the scene).",
                                       example=["RK45", "DOP853", "verlet"])
    rtols: list[Annotated[float, Field(gt=0, lt=1)]] = key(
        [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
        "Relative tolerances swept for adaptive methods; atol is rtol times each component's scale (the scene's "
        "length for positions, its speed for velocities).", "1", min_length=1)
    dt_levels: int = key(6, "Steps swept for fixed-step methods: dt = frame interval / 2^k for k = 0 … dt_levels-1.",
                         "1", ge=1, le=16)
    repeats: int = key(3, "Timed repeats per run after an untimed one that measures the errors; the minimum wall "
                          "time is reported.", "1", ge=1, le=20)
    timeout: float = key(60.0, "Wall-time limit per run; a run that exceeds it is reported as a timeout.", "s", gt=0)


class SceneSpec(SceneModel):
    """A whole scene: what exists, what acts on it, how to integrate it and how to draw it."""

    name: Name | None = key(None, "Scene name; output goes to renders/<name>/ (default: the file name).")
    description: str = key("", "Free text, shown by 'animbatch info'.")
    duration: float = key(5.0, "Length of the animation; frames are at t = k/fps for k = 0 … ceil(duration·fps)-1.",
                          "s", gt=0, le=86400)
    fps: int = key(30, "Frames per second of the animation (and of the trajectory samples).", "Hz", ge=1, le=240)
    solver: SolverSpec = key(SolverSpec(), "Integrator settings.")
    bodies: list[BodySpec] = key([], "Simulated bodies: particles (the default type) and rigid bodies.")
    anchors: list[AnchorSpec] = key([], "Fixed points for springs.")
    springs: list[SpringSpec] = key([], "Springs and dampers.")
    controllers: list[ControllerSpec] = key([], "PD controllers (virtual springs) pulling bodies towards targets.")
    emitters: list[EmitterSpec] = key([], "Particle emitters (particle systems).")
    seed: int = key(0, "Seed of every random draw (the attributes of emitted particles): the same seed gives the "
                       "same particles, bit for bit.", "1", ge=0, lt=2**63)
    fields: list[FieldSpec] = key([], "Force fields; only the declared ones are compiled.")  # type: ignore[valid-type]
    materials: dict[Name, MaterialSpec] = key({}, "Materials of your own, by name (added to the built-in ones).")
    material_pairs: list[MaterialPairSpec] = key([], "Coefficients for particular pairs of materials.")
    colliders: list[ColliderSpec] = key([], "Fixed obstacles: planes, boxes, spheres, meshes.")  # type: ignore[valid-type]
    contacts: ContactSpec | None = key(None, "Contact settings; collisions are on when this or colliders exist.")
    render: RenderSpec = key(RenderSpec(), "Rendering and output settings.")
    study: StudySpec = key(StudySpec(), "Settings of 'animbatch study' (error against work per integrator).")
    sweep: dict[str, list[Any]] = key(
        {}, "Values to sweep with 'animbatch batch' (key path -> list of values): one variant per combination, as "
        "with --sweep; ignored by the other commands.", example={"springs[0].stiffness": [100, 1000, 10000]})

    @property
    def has_contacts(self) -> bool:
        """Whether collisions are simulated at all: only when the scene asks for them (colliders or a ``contacts``
        section) and some body takes part (colliders that nothing touches are scenery, and cost no contact pass)."""
        return (bool(self.colliders) or self.contacts is not None) and any(body.collide for body in self.bodies)

    @property
    def frame_count(self) -> int:
        """Number of frames: ``ceil(duration · fps)`` (at least 1), so that the video lasts ``duration``."""
        import math

        return max(1, math.ceil(self.duration * self.fps - 1e-9))


#: Top-level keys that do not change the physics (excluded from the physics hash).
PRESENTATION_KEYS = frozenset({"name", "description", "render", "solver", "study", "sweep"})
