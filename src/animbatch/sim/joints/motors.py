"""Joint motors: a servo torque about a hinge's axis, or a servo force along a slider's.

A motor drives the joint coordinate q (the hinge angle θ [rad] or the slider travel s [m]) like a position
actuator in MuJoCo or a PD-controlled servo::

    effort = clip(stiffness · (q* − q) + damping · (q̇* − q̇), −max_effort, max_effort)

with the target q*(t) a constant, keyframes (whose derivative gives q̇*), or none (a speed servo: stiffness 0 and
q̇* the target speed). The effort acts on the first body and its reaction on the second (about or along the axis,
at the joint), so motors move momentum between the bodies and never add any of their own. Motors are few; they are
evaluated together, vectorised over motors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.quaternion import cross
from animbatch.sim.joints.kinds import AngleRows, SlideRows, hinge_angle
from animbatch.sim.joints.rows import JoinedMotion
from animbatch.sim.motion import KeyframePath


@dataclass(frozen=True)
class MotorTarget:
    """Where a motor drives its joint coordinate: ``path`` keyframes (their x component; None: no position target)
    and a constant ``speed`` [rad/s or m/s] added to the path's rate."""

    path: KeyframePath | None
    speed: float = 0.0

    def at(self, t: float) -> tuple[float, float]:
        """q* and q̇* at time t [s] (q* = 0 without a path: the stiffness is then 0)."""
        if self.path is None:
            return 0.0, self.speed
        return float(self.path.position(t)[0]), float(self.path.velocity(t)[0]) + self.speed


@dataclass(frozen=True, eq=False)
class Motors:
    """M motors; ``hinge`` (M,) says which drive hinges (the rest sliders). Each motor's joint geometry is one row
    of ``angles`` (for hinges) or ``travels`` (for sliders): only the coordinate and its rate are taken from them."""

    joint: np.ndarray  # (M,) the joint each motor drives
    hinge: np.ndarray  # (M,) bool
    angles: AngleRows | None  # the hinge motors' geometry, in motor order among hinge motors
    travels: SlideRows | None
    targets: tuple[MotorTarget, ...]
    stiffness: np.ndarray  # (M,) N·m/rad or N/m
    damping: np.ndarray  # (M,) N·m·s/rad or N·s/m
    max_effort: np.ndarray  # (M,) N·m or N (inf: unlimited)

    def coordinates(self, motion: JoinedMotion) -> tuple[np.ndarray, np.ndarray]:
        """q (M,) and q̇ (M,): hinge angles [rad] and slider travels [m] with their rates."""
        q, rate = np.zeros(len(self.joint)), np.zeros(len(self.joint))
        if self.angles is not None:
            a = self.angles
            q[self.hinge], rate[self.hinge], _ = hinge_angle(motion, a.bodies[:, 0], a.bodies[:, 1], a.axis,
                                                             a.first_reference, a.second_reference)
        if self.travels is not None:
            q[~self.hinge], rate[~self.hinge] = self.travels.travel(motion)[:2]
        return q, rate

    def efforts(self, t: float, motion: JoinedMotion) -> np.ndarray:
        """The motors' torques [N·m] and forces [N] (M,) at time t."""
        q, rate = self.coordinates(motion)
        goal = np.array([target.at(t) for target in self.targets]).reshape(-1, 2)
        error = goal[:, 0] - q
        error[self.hinge] = np.angle(np.exp(1j * error[self.hinge]))  # the short way round
        effort = self.stiffness * error + self.damping * (goal[:, 1] - rate)
        return np.clip(effort, -self.max_effort, self.max_effort)

    def loads(self, t: float, motion: JoinedMotion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Forces and torques (J+1, 3) on the joined bodies (the world's slot last) and the efforts (M,)."""
        count = len(motion.x)
        force, torque = np.zeros((count, 3)), np.zeros((count, 3))
        effort = self.efforts(t, motion)
        if self.angles is not None:
            a = self.angles
            n = motion.directions(a.bodies[:, 1], a.axis)
            turn = effort[self.hinge][:, None] * n
            np.add.at(torque, a.bodies[:, 0], turn)
            np.add.at(torque, a.bodies[:, 1], -turn)
        if self.travels is not None:
            s = self.travels
            _, _, n, d, _, _, lever_a, lever_b, _ = s.travel(motion)
            push = effort[~self.hinge][:, None] * n
            np.add.at(force, s.bodies[:, 0], push)
            np.add.at(torque, s.bodies[:, 0], cross(lever_a, push))
            np.add.at(force, s.bodies[:, 1], -push)  # at the same point, so that no angular momentum is made
            np.add.at(torque, s.bodies[:, 1], -cross(lever_b + d, push))
        return force, torque, effort
