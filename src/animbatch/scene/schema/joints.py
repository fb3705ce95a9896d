"""Joints: constraints between bodies (particles, rigid bodies, anchors and the world).

* ``distance``: a rigid, massless rod between two points (a particle, a rigid body's point, an anchor);
* ``rope``: the same but slack when shorter than its length (it only pulls);
* ``pulley``: a rope from one particle over two fixed pulleys to another (an Atwood machine);
* ``ball``: a point of two bodies (or a body and the world) held together; the bodies turn freely about it;
* ``hinge``: a ball joint that also keeps an axis, so the bodies turn only about it (limits, a motor);
* ``slider``: the bodies keep their relative orientation and move only along an axis (limits, a motor);
* ``fixed``: the bodies are welded together.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, get_args

import annotated_types as at
from pydantic import Field, model_validator

from animbatch.scene.schema.bodies import Interpolation, KeyframeList
from animbatch.scene.schema.keys import Name, NonZeroVec3, SceneModel, Vec3, key, rule_error


class MotorKeyframe(SceneModel):
    """A motor's target at a time."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    value: float = key(description="Target hinge angle [rad] or slider travel [m] at that time.")


class MotorSpec(SceneModel):
    """A servo on a hinge (a torque about its axis) or a slider (a force along it), on the first body and, in
    reaction, on the second: ``effort = clip(stiffness (q* − q) + damping (q̇* − q̇), ±max)``, with q the hinge
    angle [rad] or slider travel [m] from the start. Drive to a target (``target`` with ``stiffness``), at a speed
    (``speed`` with ``damping``), or along keyframes (their rate is the target speed)."""

    target: float | KeyframeList[MotorKeyframe] | None = key(
        None, "Target angle [rad] or travel [m] from the start: a number, or keyframes "
              "[{time, value}, …] (needs stiffness).", example=0.5)
    interpolation: Interpolation = key("cubic", "Between target keyframes: linear or cubic.")
    speed: float = key(0.0, "Target rate (added to the keyframes' own); with damping alone, a speed servo.",
                       "rad/s or m/s")
    stiffness: float = key(0.0, "Proportional gain.", "N·m/rad or N/m", ge=0)
    damping: float = key(0.0, "Derivative gain.", "N·m·s/rad or N·s/m", ge=0)
    max_torque: float | None = key(None, "Largest torque of a hinge motor (default: unlimited).", "N·m", gt=0)
    max_force: float | None = key(None, "Largest force of a slider motor (default: unlimited).", "N", gt=0)

    @model_validator(mode="after")
    def _drives_something(self) -> "MotorSpec":
        if self.target is not None and self.stiffness == 0:
            raise rule_error("a target needs stiffness > 0 (the gain that pulls towards it)", "stiffness")
        if self.stiffness > 0 and self.target is None:
            raise rule_error("stiffness pulls towards a target: give target (angle [rad] or travel [m])", "target")
        if self.stiffness == 0 and self.damping == 0:
            raise rule_error("a motor needs stiffness (with a target) or damping (with a speed)", "damping")
        if self.max_torque is not None and self.max_force is not None:
            raise rule_error("give max_torque (hinges) or max_force (sliders), not both", "max_force")
        return self


Limits = Annotated[list[float], at.Len(2, 2)]


class _JointBase(SceneModel):
    name: Name | None = key(None, "Name used in messages and the ledger (default: 'first--second').")


class _HoldingJoint(_JointBase):
    between: Annotated[list[Name], at.Len(1, 2)] = key(
        description="The bodies joined: [body] (to the world), [body, other body] or [body, anchor]. Angles and "
                    "travels are those of the first relative to the second.", example=["door", "frame"])
    anchor: Vec3 | None = key(None, "Where the joint is: a world point at the start (default: a named anchor's "
                                    "position, else the first body's centre of mass).", "m")
    attach: Annotated[list[Vec3 | None], at.Len(2, 2)] | None = key(
        None, "Instead of anchor: the joint's point on each body in body coordinates (relative to the shape's "
              "origin), [first, second], null for a centre of mass or anchor; the two must coincide at the "
              "start.", "m", example=[[0.0, 0.5, 0.0], None])

    @model_validator(mode="after")
    def _placed_once(self) -> "_HoldingJoint":
        if self.anchor is not None and self.attach is not None:
            raise rule_error("give anchor (a world point) or attach (a point on each body), not both", "attach")
        return self


class DistanceJointSpec(_JointBase):
    """A rigid, massless rod that keeps two points at a fixed distance; it pulls and pushes along itself and does
    no work. Its ends are particles, anchors, or points of rigid bodies (``attach``)."""

    type: Literal["distance"] = key(description="Joint type.")
    between: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The two ends: particles, rigid bodies or anchors (not two anchors).", example=["pivot", "bob"])
    attach: Annotated[list[Vec3 | None], at.Len(2, 2)] | None = key(
        None, "Points of rigid-body ends in body coordinates (relative to the shape's origin), [first, second]; "
              "null for a centre of mass, particle or anchor.", "m", example=[[0.0, 0.5, 0.0], None])
    length: float | None = key(None, "The rod's length (default: the ends' distance at the start).", "m", gt=0)


class RopeJointSpec(DistanceJointSpec):
    """A light, inextensible rope between two points: it pulls when taut, at its ``length``, and goes slack when
    the ends come closer (a max-distance constraint). Becoming taut is an inelastic jerk."""

    type: Literal["rope"] = key(description="Joint type.")  # type: ignore[assignment]  # a rope narrows the type
    length: float | None = key(None, "The rope's length, the longest the ends can be apart (default: their "
                                     "distance at the start).", "m", gt=0)


class PulleyJointSpec(_JointBase):
    """A light, inextensible rope from one particle up over a fixed pulley, across to a second pulley and down to a
    second particle: |x₁ − p₁| + |x₂ − p₂| stays ``length`` (the rope between the pulleys is fixed and not counted).
    It is always taut."""

    type: Literal["pulley"] = key(description="Joint type.")
    between: Annotated[list[Name], at.Len(2, 2)] = key(description="The two particles at the rope's ends.",
                                                       example=["left", "right"])
    over: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The fixed anchors the rope runs over: the first particle's pulley, then the second's (the same "
                    "anchor twice for a single pulley).", example=["pulley", "pulley"])
    length: float | None = key(None, "The rope's length from each end to its pulley, summed (default: at the "
                                     "start).", "m", gt=0)


class BallJointSpec(_HoldingJoint):
    """A ball-and-socket (spherical) joint: one point of the first body stays on one point of the second (or of the
    world); the bodies turn freely about it."""

    type: Literal["ball"] = key(description="Joint type.")


class HingeJointSpec(_HoldingJoint):
    """A hinge (revolute joint): a ball joint that also keeps ``axis`` common to both bodies, so the first turns
    relative to the second only about it. Its angle is 0 at the start and grows by the right-hand rule about the
    axis; ``limits`` stop it, a ``motor`` drives it."""

    type: Literal["hinge"] = key(description="Joint type.")
    axis: NonZeroVec3 = key(description="The axis, world axes at the start.", example=[0.0, 0.0, 1.0])
    limits: Limits | None = key(None, "[lower, upper] angle, within (−π, π) and containing 0 (default: none).",
                                "rad", example=[-1.0, 1.0])
    motor: MotorSpec | None = key(None, "A servo torque about the axis (default: none).")

    @model_validator(mode="after")
    def _limits_around_start(self) -> "HingeJointSpec":
        _check_limits(self.limits, math.pi)
        if self.motor is not None and self.motor.max_force is not None:
            raise rule_error("a hinge motor's limit is max_torque (N·m); max_force is for sliders", "motor")
        return self


class SliderJointSpec(_HoldingJoint):
    """A slider (prismatic joint): the bodies keep their relative orientation, and the first moves relative to the
    second only along ``axis``. Its travel is 0 at the start; ``limits`` stop it, a ``motor`` drives it."""

    type: Literal["slider"] = key(description="Joint type.")
    axis: NonZeroVec3 = key(description="The direction of travel, world axes at the start.", example=[1.0, 0.0, 0.0])
    limits: Limits | None = key(None, "[lower, upper] travel, containing 0 (default: none).", "m",
                                example=[-0.5, 0.5])
    motor: MotorSpec | None = key(None, "A servo force along the axis (default: none).")

    @model_validator(mode="after")
    def _limits_around_start(self) -> "SliderJointSpec":
        _check_limits(self.limits, None)
        if self.motor is not None and self.motor.max_torque is not None:
            raise rule_error("a slider motor's limit is max_force (N); max_torque is for hinges", "motor")
        return self


class FixedJointSpec(_HoldingJoint):
    """A weld: the first body keeps its position and orientation relative to the second (or the world)."""

    type: Literal["fixed"] = key(description="Joint type.")


def _check_limits(limits: list[float] | None, largest: float | None) -> None:
    if limits is None:
        return
    lower, upper = limits
    if not lower <= 0 <= upper or lower == upper:
        raise rule_error(f"limits [{lower:g}, {upper:g}] must contain 0, the start, with lower < upper", "limits")
    if largest is not None and (lower <= -largest or upper >= largest):
        raise rule_error(f"hinge limits must lie within (−π, π); got [{lower:g}, {upper:g}]", "limits")


JointSpec = Annotated[DistanceJointSpec | RopeJointSpec | PulleyJointSpec | BallJointSpec | HingeJointSpec |
    SliderJointSpec | FixedJointSpec, Field(discriminator="type")]
#: The members of JointSpec, in order.
JOINT_SPECS: tuple[type[SceneModel], ...] = get_args(get_args(JointSpec)[0])
