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

import numpy as np

from animbatch.curves import ParametricCurve, Polyline
from animbatch.quaternion import cross
from animbatch.sim.forces.term import ForceJacobian, ForceTerm, Kinematics
from animbatch.sim.motion import KeyframePath


@dataclass(frozen=True, eq=False)
class Goal:
    """Where a controller pulls a body point ``p`` at one instant.

    ``position`` (3,) [m] and ``velocity`` (3,) [m/s] of the target; on a curve, its unit ``tangent`` (3,), and
    ``position_gradient`` = ∂target/∂p and ``tangent_gradient`` = ∂tangent/∂p, (3, 3) each (None off curves,
    where the target does not depend on p).
    """

    position: np.ndarray
    velocity: np.ndarray
    tangent: np.ndarray | None = None
    position_gradient: np.ndarray | None = None
    tangent_gradient: np.ndarray | None = None


class Target:
    """Where a controller pulls, at a time, for a body point at ``position`` (3,)."""

    @property
    def text(self) -> str:
        """A human-readable description for ``animbatch info``."""
        return ""

    def locate(self, t: float, position: np.ndarray) -> Goal:
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class FixedTarget(Target):
    position: np.ndarray

    def locate(self, t: float, position: np.ndarray) -> Goal:
        return Goal(self.position, np.zeros(3))

    @property
    def text(self) -> str:
        return f"point ({', '.join(f'{c:g}' for c in self.position)})"


@dataclass(frozen=True, eq=False)
class PathTarget(Target):
    path: KeyframePath

    def locate(self, t: float, position: np.ndarray) -> Goal:
        return Goal(self.path.position(t), self.path.velocity(t))

    @property
    def text(self) -> str:
        return f"{len(self.path.times)} keyframes ({self.path.interpolation})"


@dataclass(frozen=True, eq=False)
class CurveTarget(Target):
    """The closest point on a curve (a :class:`Polyline` or a :class:`ParametricCurve`); it does not move."""

    curve: Polyline | ParametricCurve
    label: str

    def locate(self, t: float, position: np.ndarray) -> Goal:
        found = self.curve.closest(position[None])
        return Goal(found.position[0], np.zeros(3), found.tangent[0], found.position_gradient[0],
                    found.tangent_gradient[0])

    @property
    def text(self) -> str:
        return f"{self.label} ({self.curve.length:.4g} m long)"


@dataclass(frozen=True)
class ControllerSetting:
    """One PD controller as a model builder receives it: spring ``stiffness`` ks [N/m], ``damping`` kd [N·s/m],
    the ``target``, the body ``point`` it pulls (shape coordinates [m], rigid bodies; None: the centre of mass) and
    its ``name`` (None: '<body>-controller')."""

    stiffness: float
    damping: float
    target: Target
    point: np.ndarray | None = None
    name: str | None = None


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
        assert state.omega is not None  # a state with rigid bodies has their ω
        return state.x[point] + lever, state.v[point] + np.cross(state.omega[rigid[0]], lever), lever

    def pulls(self, t: float, state: Kinematics) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """Per controller: the force [N] and its lever (or None)."""
        result = []
        for k, target in enumerate(self.targets):
            position, velocity, lever = self._state_of(k, state)
            goal = target.locate(t, position)
            relative = velocity - goal.velocity
            if goal.tangent is not None:
                relative = relative - np.dot(relative, goal.tangent) * goal.tangent
            result.append((self.stiffness[k] * (goal.position - position) - self.damping[k] * relative, lever))
        return result

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        for k, (pull, lever) in enumerate(self.pulls(t, state)):
            force[self.point[k]] += pull
            if lever is not None:
                assert torque is not None
                torque[self.point[k] - self.first_rigid] += cross(lever[None], pull[None])[0]

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """On particles, with ``G = ∂target/∂x``: ``∂F/∂x = ks (G - I)``, plus on a curve the turn of the damped
        direction, ``kd ((v·t) I + t vᵀ) ∂t/∂x``; ``∂F/∂v = -kd Q`` with ``Q = I - t tᵀ`` on a curve, else I.
        Definite form (``out.definite``): ``∂F/∂x = -ks Q`` (G's curvature part can be indefinite)."""
        rows, stiffness_blocks, damping_blocks = [], [], []
        identity = np.eye(3)
        for k, target in enumerate(self.targets):
            point = self.point[k]
            if point >= self.first_rigid:
                continue
            goal = target.locate(t, state.x[point])
            ks, kd = self.stiffness[k], self.damping[k]
            if goal.tangent is None:
                stiffness_blocks.append(-ks * identity)
                damping_blocks.append(-kd * identity)
            elif out.definite:
                across = identity - np.outer(goal.tangent, goal.tangent)
                stiffness_blocks.append(-ks * across)
                damping_blocks.append(-kd * across)
            else:
                tangent, velocity = goal.tangent, state.v[point]
                assert goal.position_gradient is not None and goal.tangent_gradient is not None  # set on curves
                turn = (np.dot(velocity, tangent) * identity + np.outer(tangent, velocity)) @ goal.tangent_gradient
                stiffness_blocks.append(ks * (goal.position_gradient - identity) + kd * turn)
                damping_blocks.append(-kd * (identity - np.outer(tangent, tangent)))
            rows.append(point)
        if rows:
            out.add(np.array(rows), np.array(rows), np.array(stiffness_blocks), np.array(damping_blocks))
        return True

    def distances(self, t: float, state: Kinematics) -> np.ndarray:
        """Distance [m] of each controlled point from its target, (K,)."""
        positions = [self._state_of(k, state)[0] for k in range(len(self.targets))]
        return np.array([np.linalg.norm(target.locate(t, position).position - position)
                         for target, position in zip(self.targets, positions)])

    def potential_energy(self, state: Kinematics) -> float:
        return float(0.5 * np.sum(self.stiffness * self.distances(state.t, state) ** 2))

    @property
    def dissipative(self) -> bool:  # moving targets put energy in; dampers take it out
        return True

    @property
    def adds_energy(self) -> bool:
        return any(isinstance(target, PathTarget) for target in self.targets)

    @property
    def steps_lose_energy(self) -> bool:  # the definite derivative on a curve leaves out the curve's turn
        return not any(isinstance(target, CurveTarget) for target in self.targets)

    def describe(self) -> str:
        return "; ".join(f"{name}: ks {ks:g} N/m, kd {kd:g} N·s/m → {target.text}"
                         for name, ks, kd, target in zip(self.names, self.stiffness, self.damping, self.targets))


def controllers_term(records: list[tuple[int, ControllerSetting, np.ndarray, str]], first_rigid: int) -> Controllers:
    """The term for controllers given as (model point, setting, offset from the centre of mass [m], body name)."""
    return Controllers(tuple(setting.name or f"{body}-controller" for _, setting, _, body in records),
                       np.array([point for point, _, _, _ in records], np.intp),
                       np.array([offset for _, _, offset, _ in records], float).reshape(-1, 3),
                       np.array([setting.stiffness for _, setting, _, _ in records], float),
                       np.array([setting.damping for _, setting, _, _ in records], float),
                       tuple(setting.target for _, setting, _, _ in records), first_rigid)
