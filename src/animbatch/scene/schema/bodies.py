"""Particles, anchors, springs and keyframes."""

from __future__ import annotations

from typing import Annotated, Any, Literal, TypeVar

import annotated_types as at
from pydantic import AfterValidator, model_validator

from animbatch.scene.schema.keys import (
    Color,
    Name,
    SceneModel,
    Vec3,
    charge_key,
    key,
    metallic_key,
    roughness_key,
    rule_error,
)


class ParticleSpec(SceneModel):
    """A point mass. Its radius is used for display, Stokes drag and (later) collisions; it has no rotation."""

    type: Literal["particle"] = key("particle", "Body type.")
    name: Name = key(description="Unique name, used by springs, fields and the trajectory file.", example="ball")
    mass: float = key(1.0, "Mass.", "kg", gt=0)
    radius: float = key(0.05, "Radius for display, Stokes drag and collisions.", "m", gt=0)
    position: Vec3 = key([0.0, 0.0, 0.0], "Initial position [x, y, z].", "m")
    velocity: Vec3 = key([0.0, 0.0, 0.0], "Initial velocity [vx, vy, vz].", "m/s")
    charge: float = charge_key()
    material: Name = key("default", "Material, for collisions: a built-in one (glass, iron, rubber, pavement, steel, "
                                    "teflon, wood, ice, oiled_steel, default) or one from 'materials'.")
    collide: bool = key(True, "Take part in collisions (when the scene has colliders or a 'contacts' section).")
    color: Color | None = key(None, "Display colour: CSS name, '#rrggbb' or [r, g, b] in 0..1 "
                                    "(default: its material's colour, else from a palette, by body index).",
                              example="tomato")
    metallic: float | None = metallic_key()
    roughness: float | None = roughness_key()


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


Key = TypeVar("Key")
#: A list of 1 … 100000 keyframes of type ``Key`` whose times increase: ``KeyframeList[KeyframeSpec]``.
KeyframeList = Annotated[list[Key], at.Len(1, 100000), AfterValidator(_increasing_times)]


class AnchorSpec(SceneModel):
    """A point in space that springs can attach to. It is not simulated: it stays put, or follows keyframes.

    With ``keyframes`` it moves along them (``linear``: constant speed between keys; ``cubic``: a smooth spline that
    starts and ends at rest) and holds its first and last positions before and after them.
    """

    name: Name = key(description="Unique name (shared namespace with bodies).", example="ceiling")
    position: Vec3 | None = key(None, "Position [x, y, z] (required unless keyframes are given).", "m")
    keyframes: KeyframeList[KeyframeSpec] | None = key(
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
        if self.position is not None:
            return self.position
        assert self.keyframes  # the schema asks for a position or keyframes
        return self.keyframes[0].position
