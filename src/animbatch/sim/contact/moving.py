"""Colliders that move along keyframes: kinematic solids (a paddle, a moving platform).

A moving collider's pose is prescribed, not simulated: keyframes give its centre's displacement and its turn about
the centre, interpolated linearly (constant velocity; slerp for the turn) or smoothly (a clamped cubic spline for
the displacement, SciPy's RotationSpline, continuous in angular rate and acceleration, for the turn). Its velocity
is the path's own derivative, so bodies it touches meet it with the right relative velocity.

For the contact solver a moving collider is one more "body" with no inverse mass (nothing pushes it back) and the
path's velocity and angular velocity: restitution and friction then act on the velocity relative to its surface,
``u = (v + ω × r) − (v_c + ω_c × r_c)``, so a paddle bounces a ball off at ``(1 + e)`` times its own speed and a
platform carries a box by friction.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

from animbatch.sim.contact.geometry import StaticColliders
from animbatch.sim.motion import KeyframePath

#: Half the time step [s] of the central difference that gives a turn's angular velocity.
TURN_RATE_STEP = 1e-6


@dataclass(frozen=True, eq=False)
class ColliderPath:
    """How one collider moves: its rest centre ``centre`` (3,) [m], displaced by ``offsets`` (a path of (3,)
    offsets [m]) and turned about the centre by ``turns`` (Rotations at ``times`` (K,) [s]), ``interpolation``
    'linear' or 'cubic'."""

    centre: np.ndarray
    times: np.ndarray
    offsets: KeyframePath
    turns: Rotation
    interpolation: str

    def __post_init__(self) -> None:
        if len(self.times) > 1:
            spline = (RotationSpline(self.times, self.turns) if self.interpolation == "cubic"
                      else Slerp(self.times, self.turns))
            object.__setattr__(self, "_turn", spline)

    def turn(self, t: float) -> np.ndarray:
        """The turn (3, 3) at time t [s], held before the first key and after the last."""
        if len(self.times) == 1:
            return self.turns[0].as_matrix()
        return self._turn(float(np.clip(t, self.times[0], self.times[-1]))).as_matrix()  # type: ignore[attr-defined]

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Centre (3,) [m] and turn (3, 3) at time t: a rest point p goes to ``turn (p − c₀) + c₀ + offset``."""
        return self.centre + self.offsets.position(t), self.turn(t)

    def velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocity of the centre (3,) [m/s] and angular velocity (3,) [rad/s], world axes, at time t."""
        velocity = self.offsets.velocity(t)
        if len(self.times) == 1 or t < self.times[0] or t > self.times[-1]:
            return velocity, np.zeros(3)
        early = max(t - TURN_RATE_STEP, float(self.times[0]))
        late = min(t + TURN_RATE_STEP, float(self.times[-1]))
        change = Rotation.from_matrix(self.turn(late) @ self.turn(early).T).as_rotvec()
        return velocity, change / (late - early)

    def matrix(self, t: float) -> np.ndarray:
        """The 4 × 4 transform from the rest pose to the pose at time t (for drawing)."""
        centre, turn = self.pose(t)
        transform = np.eye(4)
        transform[:3, :3] = turn
        transform[:3, 3] = centre - turn @ self.centre
        return transform


@dataclass(frozen=True, eq=False)
class MovingColliders:
    """The moving colliders of a contact world: their paths (M,), and which of the static solids each moves:
    ``sphere`` (S,) and ``box`` (X,) path indices, −1 for the solids that stay put."""

    paths: tuple[ColliderPath, ...]
    sphere: np.ndarray
    box: np.ndarray

    @property
    def count(self) -> int:
        return len(self.paths)

    def place(self, rest: StaticColliders, t: float) -> StaticColliders:
        """The solids at time t [s]: ``rest`` with the moving spheres and boxes where their paths put them."""
        sphere_centre, box_centre = rest.sphere_centre.copy(), rest.box_centre.copy()
        box_rotation = rest.box_rotation.copy()
        for m, path in enumerate(self.paths):
            centre, turn = path.pose(t)
            for k in np.flatnonzero(self.sphere == m):
                sphere_centre[k] = turn @ (rest.sphere_centre[k] - path.centre) + centre
            for k in np.flatnonzero(self.box == m):
                box_centre[k] = turn @ (rest.box_centre[k] - path.centre) + centre
                box_rotation[k] = turn @ rest.box_rotation[k]
        return replace(rest, sphere_centre=sphere_centre, box_centre=box_centre, box_rotation=box_rotation)

    def motion(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centres (M, 3) [m], velocities (M, 3) [m/s] and angular velocities (M, 3) [rad/s] at time t."""
        centres = np.array([path.pose(t)[0] for path in self.paths]).reshape(-1, 3)
        moves = [path.velocity(t) for path in self.paths]
        return (centres, np.array([v for v, _ in moves]).reshape(-1, 3),
                np.array([w for _, w in moves]).reshape(-1, 3))

    def largest_speed(self, t: float, reach: float) -> float:
        """The fastest any moving surface goes at time t [m/s], for points up to ``reach`` [m] from its centre."""
        if not self.paths:
            return 0.0
        _, velocity, omega = self.motion(t)
        return float(np.max(np.linalg.norm(velocity, axis=1) + reach * np.linalg.norm(omega, axis=1)))

    def slots(self, kind: np.ndarray, index: np.ndarray, sphere_kind: int, box_kinds: tuple[int, ...]) -> np.ndarray:
        """For contacts with solids of ``kind`` and ``index`` (K,): the moving collider (path) each touches, or −1.
        ``box_kinds``: whole box, box face (``index // 6`` is the box) and box edge (``index // 12``)."""
        slot = np.full(len(kind), -1, np.intp)
        on_sphere = kind == sphere_kind
        slot[on_sphere] = self.sphere[index[on_sphere]]
        whole, face, edge = box_kinds
        on_box = kind == whole
        slot[on_box] = self.box[index[on_box]]
        on_face = kind == face
        slot[on_face] = self.box[index[on_face] // 6]
        on_edge = kind == edge
        slot[on_edge] = self.box[index[on_edge] // 12]
        return slot
