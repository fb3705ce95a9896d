"""Proportional–derivative controllers: virtual springs that pull a body towards a target (lecture notes).

With ``d`` the vector from the body's point to the target and ``v_rel`` the point's velocity relative to the
target's, the controller applies ``F = ks d - kd v_rel`` (the notes write ``d = x - p`` for the spring's extension;
here d points to the target, so the same force reads with a plus sign). Targets:

* a fixed point;
* a point moving along keyframes (its velocity is the path's derivative, so a body following it is not dragged back);
* the closest point on a curve (polyline, or a parametric curve sampled into one). Only the velocity *across* the
  curve is damped, ``v_rel = v - (v·t) t`` with t the tangent there, so the body slides freely along the curve: a
  bead on a wire. The spring then holds the body within ``|F_other| / ks`` of the curve, ``F_other`` being the rest
  of the force across it (weight, centripetal force).

Controllers are few (one per controlled body), so they are evaluated in a loop over controllers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.curves import Polyline, sample_parametric
from animbatch.forces.base import ForceJacobian, ForceTerm, Kinematics
from animbatch.motion import KeyframePath
from animbatch.rigid.quaternion import cross


class Target:
    """Where a controller pulls, at a time, for a body point at ``position`` (3,)."""

    #: A human-readable description for ``animbatch info``.
    text: str = ""

    def locate(self, t: float, position: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Target position (3,) [m], its velocity (3,) [m/s], and the curve's unit tangent there (or None)."""
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class FixedTarget(Target):
    position: np.ndarray

    def locate(self, t: float, position: np.ndarray) -> tuple[np.ndarray, np.ndarray, None]:
        return self.position, np.zeros(3), None

    @property
    def text(self) -> str:  # type: ignore[override]
        return f"point ({', '.join(f'{c:g}' for c in self.position)})"


@dataclass(frozen=True, eq=False)
class PathTarget(Target):
    path: KeyframePath

    def locate(self, t: float, position: np.ndarray) -> tuple[np.ndarray, np.ndarray, None]:
        return self.path.position(t), self.path.velocity(t), None

    @property
    def text(self) -> str:  # type: ignore[override]
        return f"{len(self.path.times)} keyframes ({self.path.interpolation})"


@dataclass(frozen=True, eq=False)
class CurveTarget(Target):
    curve: Polyline
    label: str

    def locate(self, t: float, position: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        closest, tangent = self.curve.closest(position[None])
        return closest[0], np.zeros(3), tangent[0]

    @property
    def text(self) -> str:  # type: ignore[override]
        return f"{self.label} ({len(self.curve.start)} segments, {self.curve.length:.4g} m)"


def make_target(spec: Any) -> Target:
    """The target of a controller's ``target`` spec."""
    if spec.type == "point":
        return FixedTarget(np.asarray(spec.position, float))
    if spec.type == "keyframes":
        return PathTarget(KeyframePath(np.array([k.time for k in spec.keyframes], float),
                                       np.array([k.position for k in spec.keyframes], float), spec.interpolation))
    if spec.type == "polyline":
        return CurveTarget(Polyline.through(np.asarray(spec.points, float), spec.closed),
                           "closed polyline" if spec.closed else "polyline")
    points = sample_parametric(spec.x, spec.y, spec.z, spec.range[0], spec.range[1], spec.samples, spec.closed)
    return CurveTarget(Polyline.through(points, spec.closed), f"curve ({spec.x}, {spec.y}, {spec.z})")


@dataclass(frozen=True, eq=False)
class Controllers(ForceTerm):
    """All PD controllers of a model: K controllers on model points ``point`` (K,), pulling the body points
    ``offset`` (K, 3) (body axes from the centre of mass; zero for particles) towards ``targets``."""

    kind = "controller"
    has_potential = True

    names: tuple[str, ...]
    point: np.ndarray
    offset: np.ndarray
    stiffness: np.ndarray  # (K,) [N/m]
    damping: np.ndarray  # (K,) [N·s/m]
    targets: tuple[Target, ...]
    first_rigid: int

    def _state_of(self, k: int, state: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Position and velocity of controller k's body point, and its lever (or None at a centre of mass)."""
        point = self.point[k]
        if point < self.first_rigid or not self.offset[k].any():
            return state.x[point], state.v[point], None
        rigid = np.array([point - self.first_rigid])
        lever = state.lever(rigid, self.offset[k][None])[0]
        return state.x[point] + lever, state.v[point] + np.cross(state.omega[rigid[0]], lever), lever  # type: ignore[index]

    def pulls(self, t: float, state: Kinematics) -> list[tuple[np.ndarray, np.ndarray | None, np.ndarray | None]]:
        """Per controller: the force [N], its lever (or None), and the curve tangent at the target (or None)."""
        result = []
        for k, target in enumerate(self.targets):
            position, velocity, lever = self._state_of(k, state)
            goal, goal_velocity, tangent = target.locate(t, position)
            relative = velocity - goal_velocity
            if tangent is not None:
                relative = relative - np.dot(relative, tangent) * tangent
            result.append((self.stiffness[k] * (goal - position) - self.damping[k] * relative, lever, tangent))
        return result

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        for k, (pull, lever, _) in enumerate(self.pulls(t, state)):
            force[self.point[k]] += pull
            if lever is not None:
                assert torque is not None
                torque[self.point[k] - self.first_rigid] += cross(lever[None], pull[None])[0]

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """On particles: ``∂F/∂x = -ks Q``, ``∂F/∂v = -kd Q``, with ``Q = I`` for point and keyframe targets and
        ``Q = I - t tᵀ`` on a curve (exact along a straight piece of it)."""
        rows, across = [], []
        for k, target in enumerate(self.targets):
            point = self.point[k]
            if point >= self.first_rigid:
                continue
            _, _, tangent = target.locate(t, state.x[point])
            rows.append(point)
            across.append(np.eye(3) if tangent is None else np.eye(3) - np.outer(tangent, tangent))
        if rows:
            particles = np.flatnonzero(self.point < self.first_rigid)
            projector = np.array(across)
            out.add(np.array(rows), np.array(rows), -self.stiffness[particles, None, None] * projector,
                    -self.damping[particles, None, None] * projector)
        return True

    def distances(self, t: float, state: Kinematics) -> np.ndarray:
        """Distance [m] of each controlled point from its target, (K,)."""
        return np.array([np.linalg.norm(target.locate(t, self._state_of(k, state)[0])[0] - self._state_of(k, state)[0])
                         for k, target in enumerate(self.targets)])

    def potential_energy(self, state: Kinematics) -> float:
        return float(0.5 * np.sum(self.stiffness * self.distances(state.t, state) ** 2))

    @property
    def dissipative(self) -> bool:  # moving targets put energy in; dampers take it out
        return True

    def describe(self) -> str:
        return "; ".join(f"{name}: ks {ks:g} N/m, kd {kd:g} N·s/m → {target.text}"
                         for name, ks, kd, target in zip(self.names, self.stiffness, self.damping, self.targets))


def controllers_term(records: list[tuple[int, Any, np.ndarray, str]], first_rigid: int) -> Controllers:
    """The term for controllers given as (model point, spec, offset from the centre of mass, body name)."""
    return Controllers(tuple(spec.name or f"{body}-controller" for _, spec, _, body in records),
                       np.array([point for point, _, _, _ in records], np.intp),
                       np.array([offset for _, _, offset, _ in records], float).reshape(-1, 3),
                       np.array([spec.stiffness for _, spec, _, _ in records], float),
                       np.array([spec.damping for _, spec, _, _ in records], float),
                       tuple(make_target(spec.target) for _, spec, _, _ in records), first_rigid)
