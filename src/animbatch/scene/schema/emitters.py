"""Particle systems: emitters, their sources, lifetimes and looks."""

from __future__ import annotations

from typing import Annotated, Literal, get_args

import annotated_types as at
from pydantic import AfterValidator, Field, model_validator

from animbatch.scene.schema.bodies import _increasing_times
from animbatch.scene.schema.keys import Color, Name, NonZeroVec3, PositiveVec3, SceneModel, Vec3, key, rule_error
from animbatch.scene.schema.rigid import OrientationSpec


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


SourceSpec = Annotated[PointSource | SphereSource | DiscSource | BoxSource | SurfaceSource, Field(discriminator="type")]
#: The members of SourceSpec, in order.
SOURCE_SPECS: tuple[type[SceneModel], ...] = get_args(get_args(SourceSpec)[0])


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
    source: SourceSpec = key(PointSource(type="point"), "Where particles start: point, sphere, disc, box, or the "
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
