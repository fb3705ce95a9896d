"""Colliders that move: kinematic solids (a paddle, a moving platform, a tilting floor, a scoop, a turntable).

A moving collider's pose is prescribed, not simulated (:mod:`animbatch.sim.motion`): keyframes give its pivot's
displacement and its turn about the pivot, interpolated linearly (constant velocity; slerp for the turn) or
smoothly (a clamped cubic spline for the displacement, SciPy's RotationSpline read at an eased time for the turn),
or a closed-form motion gives them (constant velocity and spin, an oscillation). Its velocity is the path's own
derivative, so bodies it touches meet it with the right relative velocity. Planes, spheres, boxes and meshes all
move: :meth:`MovingColliders.place` puts their solids where the paths say at each step.

For the contact solver a moving collider is one more "body" with no inverse mass (nothing pushes it back) and the
path's velocity and angular velocity: restitution and friction then act on the velocity relative to its surface,
``u = (v + ω × r) − (v_c + ω_c × r_c)``, so a paddle bounces a ball off at ``(1 + e)`` times its own speed and a
platform carries a box by friction.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from animbatch.sim.contact.geometry import StaticColliders
from animbatch.sim.memo import remembered
from animbatch.sim.motion import SolidPath


@dataclass(frozen=True, eq=False)
class MovingColliders:
    """The moving colliders of a contact world: their paths (M,), how far each one's surface reaches from its path's
    centre (``reach`` (M,) [m]; inf for a plane), and which of the static solids each moves: ``plane`` (L,),
    ``sphere`` (S,), ``box`` (X,) and ``triangle`` (T,) path indices, −1 for the solids that stay put."""

    paths: tuple[SolidPath, ...]
    reach: np.ndarray
    plane: np.ndarray
    sphere: np.ndarray
    box: np.ndarray
    triangle: np.ndarray

    @property
    def count(self) -> int:
        return len(self.paths)

    def place(self, rest: StaticColliders, t: float) -> StaticColliders:
        """The solids at time t [s]: ``rest`` with the moving ones where their paths put them."""
        # one instant remembered: a moving mesh's placed triangles are a copy of all of them
        return remembered(self, "place", (id(rest), t), lambda: self._place(rest, t), keep=1, hold=rest)

    def _place(self, rest: StaticColliders, t: float) -> StaticColliders:
        plane_point, plane_normal = rest.plane_point.copy(), rest.plane_normal.copy()
        sphere_centre, box_centre = rest.sphere_centre.copy(), rest.box_centre.copy()
        box_rotation, triangles = rest.box_rotation.copy(), rest.triangles
        for m, path in enumerate(self.paths):
            centre, turn = path.pose(t)
            planes = self.plane == m
            plane_point[planes] = (rest.plane_point[planes] - path.centre) @ turn.T + centre
            plane_normal[planes] = rest.plane_normal[planes] @ turn.T
            spheres = self.sphere == m
            sphere_centre[spheres] = (rest.sphere_centre[spheres] - path.centre) @ turn.T + centre
            boxes = self.box == m
            box_centre[boxes] = (rest.box_centre[boxes] - path.centre) @ turn.T + centre
            box_rotation[boxes] = turn @ rest.box_rotation[boxes]
            moved = self.triangle == m
            if moved.any():
                triangles = triangles.copy() if triangles is rest.triangles else triangles
                triangles[moved] = (rest.triangles[moved] - path.centre) @ turn.T + centre
        return replace(rest, plane_point=plane_point, plane_normal=plane_normal, sphere_centre=sphere_centre,
                       box_centre=box_centre, box_rotation=box_rotation, triangles=triangles)

    def to_rest(self, m: int, points: np.ndarray, t: float) -> np.ndarray:
        """World points (Q, 3) [m] taken back to where they would sit relative to collider ``m`` at rest."""
        path = self.paths[m]
        centre, turn = path.pose(t)
        return (points - centre) @ turn + path.centre  # Rᵀ (p − c(t)) + c₀, row-wise

    def motion(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centres (M, 3) [m], velocities (M, 3) [m/s] and angular velocities (M, 3) [rad/s] at time t."""
        return remembered(self, "motion", t, lambda: self._motion(t))

    def _motion(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        centres = np.array([path.pose(t)[0] for path in self.paths]).reshape(-1, 3)
        moves = [path.velocity(t) for path in self.paths]
        return (centres, np.array([v for v, _ in moves]).reshape(-1, 3),
                np.array([w for _, w in moves]).reshape(-1, 3))

    def largest_speed(self, t: float, points: np.ndarray, reach: np.ndarray) -> float:
        """The fastest any moving surface goes at time t [m/s] where it can touch the bodies at ``points`` (P, 3)
        [m] reaching ``reach`` (P,) [m] from them: a turning plane's lever is bounded by the bodies, not by the
        plane."""
        if not self.paths:
            return 0.0
        centre, velocity, omega = self.motion(t)
        lever = self.reach.copy()
        unbounded = ~np.isfinite(lever)
        if unbounded.any():
            apart = np.linalg.norm(points[None, :, :] - centre[unbounded, None, :], axis=2) + reach
            lever[unbounded] = apart.max(axis=1, initial=0.0)
        return float(np.max(np.linalg.norm(velocity, axis=1) + lever * np.linalg.norm(omega, axis=1)))

    def slots(self, kind: np.ndarray, index: np.ndarray, solids: dict[int, tuple[str, int]]) -> np.ndarray:
        """For contacts with solids of ``kind`` and ``index`` (K,): the moving collider (path) each touches, or −1.
        ``solids``: for each contact kind on a collider, which of this class's solid arrays its index runs over
        (``'plane'``, ``'sphere'``, ``'box'`` or ``'triangle'``) and by how much that index is multiplied (a box face
        is ``6 × box + face``, a box edge ``12 × box + edge``)."""
        slot = np.full(len(kind), -1, np.intp)
        for code, (solid, stride) in solids.items():
            chosen = kind == code
            slot[chosen] = getattr(self, solid)[index[chosen] // stride]
        return slot
