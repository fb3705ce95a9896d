"""Materials, colliders and contacts."""

from __future__ import annotations

from typing import Annotated, Literal, get_args

import annotated_types as at
from pydantic import Field, model_validator

from animbatch.scene.schema.bodies import Interpolation, KeyframeList
from animbatch.scene.schema.keys import (
    Color,
    Name,
    NonZeroVec3,
    PositiveVec3,
    SceneModel,
    Vec3,
    key,
    metallic_key,
    roughness_key,
    rule_error,
)
from animbatch.scene.schema.rigid import (
    KinematicSolid,
    MotionSpec,
    OrientationSpec,
    PoseKeyframeSpec,
    motion_key,
    pose_interpolation_key,
)


class MaterialSpec(SceneModel):
    """A surface material: how it bounces and how it grips (see the built-in table in the docs)."""

    restitution: float = key(description="Coefficient of restitution e: separation speed / approach speed in an "
                                         "impact (0 dead, 1 perfectly elastic).", unit="1", ge=0, le=1)
    static_friction: float = key(description="Static friction coefficient μs: |f| ≤ μs N while sticking.", unit="1",
                                 ge=0)
    kinetic_friction: float = key(description="Kinetic friction coefficient μk: |f| = μk N while sliding.", unit="1",
                                  ge=0)
    color: Color | None = key(None, "How bodies of this material look when they give no colour of their own "
                                    "(display only).")
    metallic: float | None = key(None, "Physically based look of bodies of this material: 0 a dielectric, 1 a metal "
                                       "(display only).", "1", ge=0, le=1)
    roughness: float | None = key(None, "Physically based look of bodies of this material: 0 mirror-smooth, 1 fully "
                                        "matte (display only).", "1", ge=0, le=1)

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
    color: Color | None = key(None, "Display colour (default: its material's colour, else light grey).")
    metallic: float | None = metallic_key()
    roughness: float | None = roughness_key()
    visible: bool = key(True, "Draw it.")


class _MovingCollider(_ColliderBase, KinematicSolid):
    """A collider that stays put, or moves along keyframes (every collider type can)."""

    keyframes: KeyframeList[PoseKeyframeSpec] | None = key(
        None, "Move it along keyframes: a kinematic collider (a paddle, a moving platform, a tilting floor, a "
              "scoop), pushing bodies, cloth and emitted particles with its own velocity at the contact; it holds its "
              "first and last poses before and after them. Fixed-step methods only.",
        example=[{"time": 0, "offset": [0, 0, 0]}, {"time": 1, "offset": [1, 0, 0]}])
    interpolation: Interpolation = pose_interpolation_key()
    motion: MotionSpec | None = motion_key()


class PlaneCollider(_MovingCollider):
    """An infinite plane, bodies staying on the side its normal points to; fixed, or moving along keyframes (turned
    about its ``point``)."""

    type: Literal["plane"] = key(description="Collider type.")
    point: Vec3 = key([0.0, 0.0, 0.0], "A point on the plane.", "m")
    normal: NonZeroVec3 = key([0.0, 1.0, 0.0], "Normal, pointing to the free side (need not be unit length).", "1")
    size: float | None = key(None, "Side of the square drawn to show it (default: fitted to the motion).", "m", gt=0)


class BoxCollider(_MovingCollider):
    """A solid box (a wall, a step, a table); fixed, or moving along keyframes (a paddle, a platform)."""

    type: Literal["box"] = key(description="Collider type.")
    position: Vec3 = key(description="Centre of the box.", unit="m")
    size: PositiveVec3 = key(description="Side lengths [a, b, c] along its axes.", unit="m")
    orientation: OrientationSpec | None = key(None, "Rotation of the box (default: axes along the world's).")


class SphereCollider(_MovingCollider):
    """A solid sphere; fixed, or moving along keyframes."""

    type: Literal["sphere"] = key(description="Collider type.")
    position: Vec3 = key(description="Centre.", unit="m")
    radius: float = key(description="Radius.", unit="m", gt=0)


class MeshCollider(_MovingCollider):
    """A triangle mesh (a terrain, a ramp, a bowl, a scoop); bodies collide with its triangles from either side.
    Fixed, or moving along keyframes (turned about its ``position``, where the file's origin goes)."""

    type: Literal["mesh"] = key(description="Collider type.")
    file: str = key(description="Mesh file (STL, OBJ, PLY), relative to the scene file.")
    scale: float | PositiveVec3 = key(1.0, "Scale factor(s) applied to the file's coordinates.", "1")
    position: Vec3 = key([0.0, 0.0, 0.0], "Where the file's origin goes.", "m")
    orientation: OrientationSpec | None = key(None, "Rotation of the mesh.")


ColliderSpec = Annotated[PlaneCollider | BoxCollider | SphereCollider | MeshCollider, Field(discriminator="type")]
#: The members of ColliderSpec, in order.
COLLIDER_SPECS: tuple[type[SceneModel], ...] = get_args(get_args(ColliderSpec)[0])


class ContactSpec(SceneModel):
    """How contacts are handled. Present (even empty) or implied by colliders, it switches collisions on."""

    bodies: bool = key(True, "Moving bodies collide with each other (not only with colliders).")
    rest_speed: float | None = key(None, "Approach speed below which an impact does not bounce, so that bouncing "
                                         "ends (default: 1 cm/s, or 3 g dt for fixed-step methods if that is more).",
                                   "m/s", gt=0)
    iterations: int = key(300, "Most iterations of the contact solver per step; it stops as soon as every contact "
                               "holds (to 1e-10 m/s), after one for a body resting on its own (warm starting), or "
                               "when its misses stop falling (3 % in 20 iterations), as in stacks and piles (the "
                               "ledger counts the steps that stop short).", "1",
                          ge=1, le=10000)
    slop: float = key(1e-4, "Penetration tolerated before positions are corrected (avoids jitter).", "m", ge=0)
