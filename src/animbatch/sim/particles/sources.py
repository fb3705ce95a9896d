"""Where particles start and which way they go: source shapes sampled evenly, and cones of directions.

Every sample is a function of a particle's own uniform numbers (:mod:`animbatch.sim.particles.streams`), so it does not
depend on which other particles are born in the same step. Points are in the emitter's frame: the world's, or, for
an emitter that moves with a body, the body's shape coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.particles.streams import DRAW


def unit_vectors(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions (K, 3) evenly spread over the sphere, from two uniforms each (Archimedes: z uniform in [-1, 1])."""
    z = 1.0 - 2.0 * u1
    ring = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = 2.0 * np.pi * u2
    return np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1)


def perpendicular_bases(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (K, 3) each, perpendicular to unit ``axes`` (K, 3) and to each other."""
    helper = np.where(np.abs(axes[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(axes, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return first, np.cross(axes, first)


def cone_directions(axes: np.ndarray, half_angle: float, u_cone: np.ndarray, u_turn: np.ndarray) -> np.ndarray:
    """Unit directions (K, 3) evenly spread over the cap of half-angle ``half_angle`` [rad] around unit ``axes``
    (K, 3): ``cos θ`` uniform in ``[cos half_angle, 1]``, the turn about the axis uniform."""
    cos_theta = 1.0 - u_cone * (1.0 - np.cos(half_angle))
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
    phi = 2.0 * np.pi * u_turn
    first, second = perpendicular_bases(axes)
    return (cos_theta[:, None] * axes + (sin_theta * np.cos(phi))[:, None] * first
            + (sin_theta * np.sin(phi))[:, None] * second)


@dataclass(frozen=True, eq=False)
class Source:
    """A source shape. ``sample`` gives start points (K, 3) [m] and outward unit normals (K, 3) (zero where the
    shape has none) from the particles' uniforms (K, DRAWS_PER_PARTICLE)."""

    kind: str
    centre: np.ndarray
    radius: float = 0.0
    surface_only: bool = False
    normal: np.ndarray | None = None
    rotation: np.ndarray | None = None
    half: np.ndarray | None = None
    triangles: np.ndarray | None = None  # surface: (T, 3, 3), outward wound
    spheres: np.ndarray | None = None  # surface: (S, 4) [x, y, z, r]
    area_cumulative: np.ndarray | None = None  # surface: over spheres then triangles, normalised to end at 1

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        count = len(u)
        a, b, c = u[:, DRAW["place"]], u[:, DRAW["place2"]], u[:, DRAW["place3"]]
        if self.kind == "point":
            return np.tile(self.centre, (count, 1)), np.zeros((count, 3))
        if self.kind == "sphere":
            directions = unit_vectors(a, b)
            radius = np.full(count, self.radius) if self.surface_only else self.radius * np.cbrt(c)  # even in volume
            return self.centre + directions * radius[:, None], directions
        if self.kind == "disc":
            assert self.normal is not None  # every disc has one
            first, second = perpendicular_bases(self.normal[None, :])
            r = self.radius * np.sqrt(a)  # evenly by area
            phi = 2.0 * np.pi * b
            points = self.centre + (r * np.cos(phi))[:, None] * first + (r * np.sin(phi))[:, None] * second
            return points, np.tile(self.normal, (count, 1))
        if self.kind == "box":
            assert self.half is not None and self.rotation is not None  # every box has both
            local = (2.0 * np.stack([a, b, c], axis=1) - 1.0) * self.half
            return self.centre + local @ self.rotation.T, np.zeros((count, 3))
        return self._sample_surface(u)

    def _sample_surface(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Evenly by area over a body's spheres and triangles."""
        spheres, triangles = self.spheres, self.triangles
        assert spheres is not None and triangles is not None and self.area_cumulative is not None
        piece = np.minimum(np.searchsorted(self.area_cumulative, u[:, DRAW["choice"]], side="right"),
                           len(self.area_cumulative) - 1)
        points = np.empty((len(u), 3))
        normals = np.empty((len(u), 3))
        on_sphere = piece < len(spheres)
        if on_sphere.any():
            rows = spheres[piece[on_sphere]]
            direction = unit_vectors(u[on_sphere, DRAW["place"]], u[on_sphere, DRAW["place2"]])
            points[on_sphere] = rows[:, :3] + direction * rows[:, 3:]
            normals[on_sphere] = direction
        on_triangle = ~on_sphere
        if on_triangle.any():
            corners = triangles[piece[on_triangle] - len(spheres)]
            root = np.sqrt(u[on_triangle, DRAW["place"]])  # even over the triangle (Osada et al. 2002)
            second = u[on_triangle, DRAW["place2"]]
            weights = np.stack([1.0 - root, root * (1.0 - second), root * second], axis=1)
            points[on_triangle] = np.einsum("kj,kji->ki", weights, corners)
            face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            normals[on_triangle] = face / np.linalg.norm(face, axis=1, keepdims=True)
        return points, normals


