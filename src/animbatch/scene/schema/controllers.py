"""Controllers: virtual springs that pull a body towards a target."""

from __future__ import annotations

from typing import Annotated, Literal, get_args

import annotated_types as at
from pydantic import Field, field_validator

from animbatch.curves import ExpressionError, compile_expression
from animbatch.scene.schema.bodies import Interpolation, KeyframeList, KeyframeSpec
from animbatch.scene.schema.keys import Name, SceneModel, Vec3, key, rule_error


class PointTarget(SceneModel):
    """A fixed point."""

    type: Literal["point"] = key(description="Target type.")
    position: Vec3 = key(description="The point.", unit="m")


class KeyframeTarget(SceneModel):
    """A point moving along keyframes."""

    type: Literal["keyframes"] = key(description="Target type.")
    keyframes: KeyframeList[KeyframeSpec] = key(description="Positions over time.")
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


TargetSpec = Annotated[PointTarget | KeyframeTarget | PolylineTarget | ParametricTarget, Field(discriminator="type")]
#: The members of TargetSpec, in order.
TARGET_SPECS: tuple[type[SceneModel], ...] = get_args(get_args(TargetSpec)[0])


class ControllerSpec(SceneModel):
    """A proportional–derivative controller (a virtual spring, a soft constraint): ``F = ks d - kd v_rel``, with
    ``d`` from the body (or its point) to the target and ``v_rel`` its velocity relative to the target's.

    On a curve the target is the closest point, and only the velocity across the curve is damped, so the body
    slides freely along it (a bead on a wire)."""

    name: Name | None = key(None, "Name used in messages (default: '<body>-controller').")
    body: Name = key(description="The particle or rigid body it pulls.", example="bead")
    point: Vec3 | None = key(None, "For rigid bodies: the body point (shape coordinates) pulled towards the target "
                                   "(default: the centre of mass).", "m")
    target: TargetSpec = key(description="Where it pulls: a point, keyframes, a polyline or a parametric "
                                         "curve.")
    stiffness: float = key(description="Proportional gain ks.", unit="N/m", ge=0)
    damping: float = key(0.0, "Derivative gain kd.", "N·s/m", ge=0)
