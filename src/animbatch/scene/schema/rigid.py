"""Rigid bodies: their shapes (spheres, shells, boxes, cylinders, rods, capsules,
compounds, meshes) and orientations."""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

import annotated_types as at
from pydantic import Field, field_validator, model_validator

from animbatch.scene.schema.bodies import Interpolation, KeyframeList
from animbatch.scene.schema.keys import (
    Color,
    Name,
    PositiveVec3,
    SceneModel,
    Vec3,
    charge_key,
    key,
    metallic_key,
    roughness_key,
    rule_error,
)


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


class CapsuleShape(SceneModel):
    """Solid capsule along the body z axis, centred on the origin: a cylinder of length ``l = length - 2r`` capped by
    two hemispheres. With ``m_c = ρ π r² l`` and ``m_h = ⅔ ρ π r³`` per cap: ``I_zz = ½ m_c r² + ⅘ m_h r²``,
    ``I_xx = I_yy = m_c (l²/12 + r²/4) + 2 m_h (⅖ r² + l²/4 + ⅜ l r)``."""

    type: Literal["capsule"] = key(description="Shape type.")
    radius: float = key(description="Radius of the cylinder and of its two hemispherical caps.", unit="m", gt=0)
    length: float = key(description="Overall length along the body z axis, tip to tip (caps included); at least "
                                    "2 × radius (a sphere).", unit="m", gt=0)

    @model_validator(mode="after")
    def _long_enough(self) -> "CapsuleShape":
        if self.length < 2 * self.radius:
            raise rule_error(f"must be at least 2 × radius = {2 * self.radius:g} m, since it includes both caps "
                             f"(got {self.length:g}); for a capsule whose straight part is {self.length:g} m long, "
                             f"give length: {self.length + 2 * self.radius:g}", "length")
        return self


class MeshShape(SceneModel):
    """A closed triangle mesh from an STL, OBJ or PLY file; volume, centre of mass and inertia are computed exactly
    from its surface (divergence theorem)."""

    type: Literal["mesh"] = key(description="Shape type.")
    file: str = key(description="Mesh file, relative to the scene file.", example="meshes/bunny.stl")
    scale: float | PositiveVec3 = key(1.0, "Scale factor, or factors [sx, sy, sz], applied to the file's "
                                           "coordinates (e.g. 0.001 for a file in millimetres).", "1")
    convex_hull: bool = key(False, "Collide as the mesh's convex hull (its hollows filled). Other bodies touch a mesh "
                                   "body as a convex solid: a mesh within 1 % of its hull's volume is taken as its "
                                   "hull anyway; a more hollow one is refused in a scene where bodies collide unless "
                                   "this is true, or it is split into convex parts (a compound of meshes). Mass "
                                   "properties stay the mesh's own.")

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


class PoseKeyframeSpec(SceneModel):
    """Where a moving collider or a kinematic rigid body is at a time: moved by ``offset`` from where the scene
    places it (its ``position``; a plane's ``point``), and turned by ``rotation`` about that point."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    offset: Vec3 = key([0.0, 0.0, 0.0], "Displacement from its position [dx, dy, dz].", "m")
    rotation: OrientationSpec | None = key(None, "Turn about its position from its orientation, world axes "
                                                 "(default: none).")


class OscillationSpec(SceneModel):
    """A sinusoidal oscillation of a kinematic solid's pivot: ``amplitude · e^(−γ t) · sin(2π f t + phase)``."""

    amplitude: Vec3 = key(description="Amplitude of the displacement [ax, ay, az] (along this direction).", unit="m")
    frequency: float = key(description="Frequency f.", unit="Hz", gt=0)
    phase: float = key(0.0, "Phase at t = 0 (0: at its position, moving along +amplitude).", "deg")
    damping: float = key(0.0, "Decay rate γ of the amplitude (0: it never dies down).", "1/s", ge=0)


class MotionSpec(SceneModel):
    """A closed-form motion of a kinematic solid (a collider, or a rigid body), as the kinematic mode's: from t = 0
    its pivot moves at a constant ``velocity`` plus an ``oscillation``, and it turns at a constant
    ``angular_velocity`` about its pivot. The three add; its velocity is their exact derivative."""

    velocity: Vec3 = key([0.0, 0.0, 0.0], "Constant velocity of its pivot.", "m/s")
    angular_velocity: Vec3 = key([0.0, 0.0, 0.0], "Constant angular velocity about its pivot (world axes): a "
                                                   "turntable, a paddle wheel.", "rad/s")
    oscillation: OscillationSpec | None = key(None, "A (damped) sinusoidal oscillation of its pivot: a shaker "
                                                    "table, a piston.")


def pose_interpolation_key() -> Any:
    """The ``interpolation`` key of colliders and rigid bodies on keyframes."""
    return key("cubic", "Between keyframes: linear (constant velocity, slerp) or cubic (smooth: it starts and ends at "
                        "rest, with a continuous velocity and angular velocity through the keys).")


def motion_key() -> Any:
    """The ``motion`` key of colliders and rigid bodies."""
    return key(None, "Move it in closed form instead of along keyframes: constant velocity, constant spin about "
                     "its pivot and a (damped) oscillation, from t = 0. Not with keyframes. Fixed-step methods only.",
               example={"angular_velocity": [0, 1.5, 0]})


class KinematicSolid(SceneModel):
    """What colliders and rigid bodies share as kinematic solids: they move along ``keyframes`` or by a closed-form
    ``motion`` (their own keys, each class describing them), or not at all."""

    @property
    def moves(self) -> bool:
        """Whether it is kinematic: on keyframes or a closed-form motion."""
        return getattr(self, "keyframes", None) is not None or getattr(self, "motion", None) is not None

    @model_validator(mode="after")
    def _one_way_to_move(self) -> "KinematicSolid":
        if getattr(self, "keyframes", None) is not None and getattr(self, "motion", None) is not None:
            raise rule_error("give keyframes or motion, not both", "motion")
        return self


PrimitiveShape = Annotated[SphereShape | ShellShape | BoxShape | CylinderShape | RodShape | CapsuleShape | MeshShape,
                           Field(discriminator="type")]
#: The members of PrimitiveShape, in order.
PRIMITIVE_SHAPES: tuple[type[SceneModel], ...] = get_args(get_args(PrimitiveShape)[0])


class CompoundPart(SceneModel):
    """One primitive of a compound body, placed in the body's frame, with its own density or mass."""

    shape: PrimitiveShape = key(description="The part's shape (any shape except compound).")
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


ShapeSpec = Annotated[SphereShape | ShellShape | BoxShape | CylinderShape | RodShape | CapsuleShape | MeshShape
                      | CompoundShape, Field(discriminator="type")]
#: The members of ShapeSpec, in order: the primitives, then the compound.
SHAPES: tuple[type[SceneModel], ...] = get_args(get_args(ShapeSpec)[0])


class RigidBodySpec(KinematicSolid):
    """A rigid body: a shape with mass properties from its density (or a given mass), state ``[x, q, P, L]``.

    ``position`` places the shape's origin (the centre of primitives); the body moves about its centre of mass.
    """

    type: Literal["rigid"] = key(description="Body type.")
    name: Name = key(description="Unique name.", example="crate")
    shape: ShapeSpec = key(description="Shape; gives volume, centre of mass and inertia.")
    density: float | None = key(None, "Density: mass = density × volume.", "kg/m³", gt=0)
    mass: float | None = key(None, "Mass, instead of a density (for a compound: the total, distributed as the "
                                    "parts' densities say, or uniformly where they give none).", "kg", gt=0)
    position: Vec3 = key([0.0, 0.0, 0.0], "Initial position of the shape's origin.", "m")
    orientation: OrientationSpec | None = key(None, "Initial orientation (default: body axes = world axes).")
    velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial velocity of the centre of mass.", "m/s")
    charge: float = charge_key()
    angular_velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial angular velocity ω, world axes.", "rad/s")
    material: Name = key("default", "Material, for collisions (see the particle's 'material').")
    collide: bool = key(True, "Take part in collisions (when the scene has colliders or a 'contacts' section).")
    keyframes: KeyframeList[PoseKeyframeSpec] | None = key(
        None, "Move it along keyframes instead of simulating it: a kinematic body (a paddle, a moving platform, a "
              "hand). Nothing pushes it back; it pushes bodies and emitted particles with its own velocity at the "
              "contact, and holds its first and last poses before and after the keys. Its velocity and angular "
              "velocity are the path's (velocity and angular_velocity must stay unset). Fixed-step methods only.",
        example=[{"time": 0, "offset": [0, 0, 0]}, {"time": 1, "offset": [1, 0, 0]}])
    interpolation: Interpolation = pose_interpolation_key()
    motion: MotionSpec | None = motion_key()
    color: Color | None = key(None, "Display colour (default: its material's colour, else from a palette, by body "
                                    "index).")
    metallic: float | None = metallic_key()
    roughness: float | None = roughness_key()

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

    @model_validator(mode="after")
    def _kinematic_moves_with_its_path(self) -> "RigidBodySpec":
        if self.moves:
            for name in ("velocity", "angular_velocity"):
                if any(getattr(self, name)):
                    raise rule_error(f"a kinematic body moves as its path says: leave {name} out (its keys' offsets "
                                     "and rotations, or its motion, give it)", name)
        return self
