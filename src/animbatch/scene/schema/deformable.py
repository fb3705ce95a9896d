"""Deformable bodies: cloth and spring lattices, and the unions of body and spring kinds."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

import annotated_types as at
from pydantic import Discriminator, Field, Tag, field_validator, model_validator

from animbatch.scene.schema.bodies import Interpolation, KeyframeList, ParticleSpec
from animbatch.scene.schema.keys import (
    Color,
    Name,
    PositiveVec3,
    SceneModel,
    Vec3,
    key,
    metallic_key,
    roughness_key,
    rule_error,
)
from animbatch.scene.schema.rigid import OrientationSpec, RigidBodySpec


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
    keyframes: KeyframeList[OffsetKeyframeSpec] | None = key(
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


class PressureKeyframe(SceneModel):
    """A gauge pressure at a time."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    value: float = key(description="Pressure inside above the outside at that time (negative: below it).",
                       unit="Pa")


class PressureSpec(SceneModel):
    """Pressure inside a closed cloth or a lattice: each surface triangle of area A and outward normal n pushes its
    three vertices with ``(P − P_outside) A n / 3`` each (F = P·A). ``gauge`` is ``P − P_outside``: held, along
    keyframes, or, with ``gas``, what it is at the start, after which the gas inside keeps ``P V`` constant
    (Boyle's law, constant temperature): squeezing the body raises it, letting it grow lowers it."""

    gauge: float | KeyframeList[PressureKeyframe] = key(
        description="Pressure inside above the outside: a number, held (or, with gas, at the start), or keyframes "
                    "{time, value}, linear between them and held before the first and after the last.",
        unit="Pa", example=2000)
    gas: bool = key(False, "An ideal gas at constant temperature fills the body: its absolute pressure outside + "
                           "gauge at the start, times the volume at the start, stays P V thereafter.")
    outside: float = key(101325.0, "Absolute pressure of the surroundings (one atmosphere by default); only the "
                                   "gas's law reads it.", "Pa", gt=0)

    @model_validator(mode="after")
    def _gas_starts_from_a_number(self) -> "PressureSpec":
        gauge = self.gauge
        if not self.gas:
            return self
        if not isinstance(gauge, float | int):
            raise rule_error("with gas, gauge is the pressure at the start (a number): the gas's law sets it after",
                             "gauge")
        if self.outside + gauge <= 0:
            raise rule_error(f"the gas's absolute pressure outside + gauge must be above 0 (got "
                             f"{self.outside + gauge:g} Pa)", "gauge")
        return self


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
    collide: bool = key(True, "Take part in collisions with colliders, bodies and particles.")
    self_collision: bool | None = key(
        None, "Its surface collides with itself and with the other self-colliding cloth and lattices, its layers "
              "kept thickness apart (default: on for a cloth that collides, under symplectic_euler, verlet or "
              "backward_euler; off for lattices and under other methods).")
    thickness: float | None = key(None, "How far apart self-collision keeps its layers (default: twice the vertex "
                                        "radius, half the mean edge length).", "m", gt=0)
    pressure: PressureSpec | None = key(None, "Pressure inside: a closed cloth (a mesh whose every edge joins two "
                                              "triangles) or a lattice, inflated or squeezed (none if not given).")
    color: Color | None = key(None, "Display colour (default: its material's colour, else from a palette, by body "
                                    "index).")
    metallic: float | None = metallic_key()
    roughness: float | None = roughness_key()


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
