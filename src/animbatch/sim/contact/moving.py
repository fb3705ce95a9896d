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

from animbatch.sim.contact.geometry import StaticColliders
from animbatch.sim.motion import PosePath


@dataclass(frozen=True, eq=False)
class MovingColliders:
    """The moving colliders of a contact world: their paths (M,), and which of the static solids each moves:
    ``sphere`` (S,) and ``box`` (X,) path indices, −1 for the solids that stay put."""

    paths: tuple[PosePath, ...]
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
