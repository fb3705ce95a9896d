"""Emitted particles against mesh colliders and the scene's rigid bodies: swept by sphere tracing.

Planes, spheres and boxes have closed-form swept tests (:mod:`animbatch.sim.particles.collisions`). Triangles and
the shapes of rigid bodies (spheres, boxes, cylinders, rods, capsules, convex hulls of meshes) are met the same way
for all of them: each has an exact signed distance, and a particle's path ``x0 → x1`` is *sphere traced* against it:
step along the path by the distance to the solid less the particle's radius, which can never step past the surface,
until that distance is (almost) zero (a hit, at that fraction of the path) or the path ends (a miss). Head-on, a few
steps land on the surface; a path that only grazes a solid may run out of steps and miss, and then the push out at
the step's end (:meth:`ParticleObstacles.push_out`) still keeps the particle outside.

A rigid body moves during the step: the path is traced in the body's own axes, from where the particle starts
relative to the body at the step's start to where it ends relative to the body at the step's end. So a particle at
rest is hit by a body that sweeps over it, and a bounce keeps the velocity of the body's surface at the hit
(``v = v_surface + bounce(v - v_surface)``): a paddle bats particles away. Particles are massless to bodies: nothing
pushes back. The bodies' poses between frames come from :class:`~animbatch.sim.particles.body_motion.BodyMotion`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from animbatch.sim.contact.geometry import (
    BodyBoxes,
    BodyCylinders,
    to_box,
    to_round,
    to_sphere,
    to_triangles,
)
from animbatch.sim.contact.hulls import BodyHull, to_hull
from animbatch.sim.contact.meshes import TriangleGroup
from animbatch.sim.motion import SolidPath
from animbatch.sim.particles.body_motion import BodyMotion, BodyPose

#: Most sphere-tracing steps along one path (head-on hits take a few; grazing paths may run out, and then miss).
MARCH_STEPS = 40
#: A path this close to a surface [m] has reached it.
TOUCH = 1e-7
#: How far off the surface a particle is put after a hit [m], so the next test starts outside.
SURFACE_GAP = 1e-9

Distance = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def march(distance: Distance, start: np.ndarray, step: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """The fraction (K,) of each path ``start + s step`` (K, 3), s in [0, 1], at which a sphere of ``radius`` (K,)
    first touches a solid from outside, or inf: ``distance(points, which)`` gives the signed distances (and normals)
    of points (N, 3) from the solid of paths ``which`` (N,). Paths that start touching or inside never hit (the push
    out deals with them), nor do paths leaving the surface.

    Each path's solid is convex (a triangle, a primitive, a hull), so its distance along the path is a convex
    function of s and lies above its tangent ``gap + (n · step) (s − t)``: a path whose tangent stays above the
    surface to its end cannot reach it, and stops there. So a particle sliding along a surface costs one step, not
    the many tiny ones sphere tracing takes beside a surface it never meets."""
    count = len(start)
    fraction = np.full(count, np.inf)
    length = np.linalg.norm(step, axis=1)
    t = np.zeros(count)
    active = np.flatnonzero(length > 0)
    for iteration in range(MARCH_STEPS):
        if not len(active):
            break
        gap, normal = distance(start[active] + t[active, None] * step[active], active)
        gap = gap - radius[active]
        if iteration == 0:  # starting inside: not a crossing
            outside = gap >= -TOUCH
            active, gap, normal = active[outside], gap[outside], normal[outside]
        touched = gap <= TOUCH
        closing = -np.einsum("ij,ij->i", normal, step[active])  # how fast the gap shrinks per unit of s
        arriving = closing > 0  # a touch while leaving is no hit
        fraction[active[touched & arriving]] = t[active[touched & arriving]]
        reachable = gap - TOUCH <= closing * (1.0 - t[active])
        t[active] += np.maximum(gap, 0.0) / length[active]
        active = active[~touched & reachable & (t[active] <= 1.0)]
    return fraction


@dataclass(frozen=True)
class Hits:
    """First hits of K paths on obstacles: ``fraction`` (K,) (inf: none), outward ``normal`` (K, 3), ``material``
    (K,), the velocity of the surface hit (K, 3) [m/s] and the body hit (K,) (−1: a fixed collider)."""

    fraction: np.ndarray
    normal: np.ndarray
    material: np.ndarray
    surface_velocity: np.ndarray
    body: np.ndarray

    @classmethod
    def none(cls, count: int) -> Hits:
        return cls(np.full(count, np.inf), np.zeros((count, 3)), np.zeros(count, np.intp), np.zeros((count, 3)),
                   np.full(count, -1, np.intp))

    def keep_earlier(self, fraction: np.ndarray, chosen: np.ndarray, normal: np.ndarray, material: np.ndarray | int,
                     surface_velocity: np.ndarray | None = None, body: int = -1) -> None:
        """Take the hits (fraction (N,) of paths ``chosen`` (N,)) that come before the ones found so far."""
        earlier = fraction < self.fraction[chosen]
        where = chosen[earlier]
        self.fraction[where] = fraction[earlier]
        self.normal[where] = normal[earlier]
        self.material[where] = np.broadcast_to(material, earlier.shape)[earlier]
        self.surface_velocity[where] = surface_velocity[earlier] if surface_velocity is not None else 0.0
        self.body[where] = body


Sweep = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class BodyShape:
    """One solid fixed to a rigid body, in body axes from its centre of mass: which ``body`` (trajectory index; or
    ``-2 - m`` for the m-th collider on keyframes, in axes from its pivot turned by its path), its ``material``, a
    bounding sphere (``centre`` (3,), ``reach`` [m]; inf for a plane) and its signed ``distance``. ``sweep``, where
    given, finds first touches (as :func:`march` does with the distance) faster: in closed form for a plane, pair by
    pair with the nearby triangles for a mesh."""

    body: int
    material: int
    centre: np.ndarray
    reach: float
    distance: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    sweep: Sweep | None = None


def plane_sweep(normal: np.ndarray) -> Sweep:
    """First touches of spheres moving ``start + s step`` (K, 3) with the plane ``normal · p = 0``, from its free
    side: where the height above it falls to the radius (K,)."""

    def sweep(start: np.ndarray, step: np.ndarray, radius: np.ndarray) -> np.ndarray:
        above, after = start @ normal, (start + step) @ normal
        fraction = np.full(len(start), np.inf)
        hit = (above >= radius - TOUCH) & (after < radius) & (after < above)
        fraction[hit] = np.clip((above[hit] - radius[hit]) / (above[hit] - after[hit]), 0.0, 1.0)
        return fraction

    return sweep


def earliest_triangles(group: TriangleGroup, triangles: np.ndarray, start: np.ndarray, step: np.ndarray,
                       radius: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The first touches of spheres moving ``start + s step`` (K, 3) with the ``triangles`` (T, 3, 3) of ``group``
    (same frame): each path is marched against each triangle near it on its own (one triangle's distance per
    step). Returns the paths that touch one, the triangle each touches first and the fraction of its path there."""
    middle, half = start + 0.5 * step, 0.5 * np.linalg.norm(step, axis=1)
    path, triangle = group.near(middle, half + radius, triangles)
    if not len(path):
        return path, triangle, np.zeros(0)
    fraction = march(lambda p, which: to_triangles(p, triangles[triangle[which]]), start[path], step[path],
                     radius[path])
    hit = np.flatnonzero(np.isfinite(fraction))
    order = hit[np.lexsort((fraction[hit], path[hit]))]  # each path's earliest triangle first
    first = order[np.r_[True, path[order][1:] != path[order][:-1]]] if len(order) else order
    return path[first], triangle[first], fraction[first]


def mesh_sweep(group: TriangleGroup, triangles: np.ndarray) -> Sweep:
    """First touches of moving spheres with the ``triangles`` of ``group``, as a shape's sweep."""

    def sweep(start: np.ndarray, step: np.ndarray, radius: np.ndarray) -> np.ndarray:
        fraction = np.full(len(start), np.inf)
        path, _, found = earliest_triangles(group, triangles, start, step, radius)
        fraction[path] = found
        return fraction

    return sweep


def moving_collider_shapes(spheres: Sequence[tuple[int, float, int]],
                           boxes: Sequence[tuple[int, np.ndarray, np.ndarray, int]],
                           planes: Sequence[tuple[int, np.ndarray, int]] = (),
                           meshes: Sequence[tuple[int, np.ndarray, int]] = ()) -> tuple[BodyShape, ...]:
    """Colliders on keyframes as solids about their path's centre (its pivot): ``spheres`` [(path, radius,
    material)], ``boxes`` [(path, rotation at rest (3, 3), half sides (3,), material)], ``planes`` [(path, unit normal
    at rest (3,), material)], through the pivot, and ``meshes`` [(path, triangles at rest from the pivot (T, 3, 3),
    material)]."""

    def sphere(radius: float) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        return lambda p: to_sphere(p, np.zeros_like(p), np.full(len(p), radius))

    def box(rotation: np.ndarray, half: np.ndarray) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        return lambda p: to_box(p, np.zeros_like(p), np.broadcast_to(rotation, (len(p), 3, 3)),
                                np.broadcast_to(half, p.shape))

    def plane(normal: np.ndarray) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        return lambda p: (p @ normal, np.broadcast_to(normal, p.shape))

    shapes = [BodyShape(-2 - m, material, np.zeros(3), radius, sphere(radius)) for m, radius, material in spheres]
    shapes += [BodyShape(-2 - m, material, np.zeros(3), float(np.linalg.norm(half)), box(rotation, half))
               for m, rotation, half, material in boxes]
    shapes += [BodyShape(-2 - m, material, np.zeros(3), np.inf, plane(normal), plane_sweep(normal))
               for m, normal, material in planes]
    for m, triangles, material in meshes:
        middle = 0.5 * (triangles.min(axis=(0, 1)) + triangles.max(axis=(0, 1)))
        reach = float(np.max(np.linalg.norm(triangles - middle, axis=2)))
        group = TriangleGroup.of(triangles, np.arange(len(triangles)))
        shapes.append(BodyShape(-2 - m, material, middle, reach, _nearest(group, triangles),
                                mesh_sweep(group, triangles)))
    return tuple(shapes)


def _nearest(group: TriangleGroup, triangles: np.ndarray) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    return lambda p: group.nearest(p, triangles)


def body_shapes(spheres: list[tuple[int, np.ndarray, float]], boxes: BodyBoxes, rounds: BodyCylinders | None,
                hulls: tuple[BodyHull, ...], body_material: np.ndarray) -> tuple[BodyShape, ...]:
    """The rigid bodies' solids: ``spheres`` [(body, centre (3,), radius)], boxes, rounds and hulls (as the contact
    world holds them); ``body_material`` (P,) per body."""
    shapes: list[BodyShape] = []

    def add(body: int, centre: np.ndarray, reach: float, distance: Callable) -> None:
        shapes.append(BodyShape(int(body), int(body_material[body]), np.asarray(centre, float), float(reach),
                                distance))

    for body, centre, radius in spheres:
        add(body, centre, radius, lambda p, c=centre, r=radius: to_sphere(p, np.broadcast_to(c, p.shape),
                                                                           np.full(len(p), r)))
    for k in range(boxes.count):
        offset, rotation, half = boxes.offset[k], boxes.rotation[k], boxes.half[k]
        add(boxes.owner[k], offset, float(np.linalg.norm(half)),
            lambda p, o=offset, r=rotation, h=half: to_box(p, np.broadcast_to(o, p.shape),
                                                           np.broadcast_to(r, (len(p), 3, 3)),
                                                           np.broadcast_to(h, p.shape)))
    if rounds is not None:
        for k in range(rounds.count):
            offset, axis = rounds.offset[k], rounds.axis[k]
            half, radius, rounded = rounds.half_length[k], rounds.radius[k], rounds.rounded[k]
            add(rounds.owner[k], offset, half + radius,
                lambda p, o=offset, a=axis, h=half, r=radius, c=rounded: to_round(
                    p, np.broadcast_to(o, p.shape), np.broadcast_to(a, p.shape), np.full(len(p), h),
                    np.full(len(p), r), np.full(len(p), c)))
    for hull in hulls:
        add(hull.owner, np.zeros(3), hull.reach, lambda p, h=hull: to_hull(p, h, np.zeros(3), np.eye(3)))
    return tuple(shapes)


@dataclass(frozen=True, eq=False)
class ParticleObstacles:
    """The obstacles particles meet beyond planes, spheres and boxes: the triangles of fixed mesh colliders
    (``triangles`` (T, 3, 3) [m], ``triangle_material`` (T,), found through ``triangle_group``, None without any),
    the rigid bodies' ``shapes`` and the moving colliders'."""

    triangles: np.ndarray
    triangle_material: np.ndarray
    triangle_group: TriangleGroup | None
    shapes: tuple[BodyShape, ...]
    paths: tuple[SolidPath, ...] = ()  # colliders on keyframes (shapes with body -2 - m)

    def poses(self, t: float, motion: BodyMotion | None) -> dict[int, BodyPose]:
        """The pose at time t [s] of every body and moving collider the obstacles need (bodies from ``motion``)."""
        found = {}
        for key in self.bodies:
            if key >= 0:
                assert motion is not None
                found[key] = motion.pose(key, np.array([t]))
            else:
                path = self.paths[-2 - key]
                centre, turn = path.pose(t)
                velocity, omega = path.velocity(t)
                found[key] = BodyPose(centre[None], turn[None], velocity[None], omega[None])
        return found

    def without(self, body: int | None) -> ParticleObstacles | None:
        """These obstacles less the solids of ``body`` (an emitter's own body: its particles are born on or in it);
        None when nothing is left."""
        shapes = tuple(s for s in self.shapes if s.body != body)
        if self.triangle_group is None and not shapes:
            return None
        return ParticleObstacles(self.triangles, self.triangle_material, self.triangle_group, shapes, self.paths)

    @property
    def bodies(self) -> tuple[int, ...]:
        """The bodies whose poses the obstacles need."""
        return tuple(sorted({shape.body for shape in self.shapes}))

    @property
    def empty(self) -> bool:
        return self.triangle_group is None and not self.shapes

    def first_hits(self, x0: np.ndarray, x1: np.ndarray, radius: np.ndarray,
                   poses: tuple[dict[int, BodyPose], dict[int, BodyPose]] | None) -> Hits:
        """The first obstacle each path ``x0 → x1`` (K, 3) meets, with the bodies at ``poses`` (at the step's start
        and end: each body's pose as a BodyPose of one instant)."""
        hits = Hits.none(len(x0))
        if not len(x0):
            return hits
        middle, half = 0.5 * (x0 + x1), 0.5 * np.linalg.norm(x1 - x0, axis=1)
        widest = float(half.max()) + float(radius.max())
        if self.triangle_group is not None:
            self._triangle_hits(hits, x0, x1, radius)
        if self.shapes and poses is not None:
            tree = cKDTree(middle)
            for shape in self.shapes:
                self._shape_hits(hits, shape, x0, x1, radius, tree, widest, poses)
        return hits

    def _near_triangles(self, points: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (particle, triangle) (N,) each whose triangle may lie within the particle's ``reach`` (K,) [m] of
        its point."""
        assert self.triangle_group is not None
        return self.triangle_group.near(points, reach)

    def _triangle_hits(self, hits: Hits, x0: np.ndarray, x1: np.ndarray, radius: np.ndarray) -> None:
        assert self.triangle_group is not None
        particle, triangle, fraction = earliest_triangles(self.triangle_group, self.triangles, x0, x1 - x0, radius)
        if not len(particle):
            return
        at = x0[particle] + fraction[:, None] * (x1[particle] - x0[particle])
        _, normal = to_triangles(at, self.triangles[triangle])
        hits.keep_earlier(fraction, particle, normal, self.triangle_material[triangle])

    def _shape_hits(self, hits: Hits, shape: BodyShape, x0: np.ndarray, x1: np.ndarray, radius: np.ndarray,
                    tree: cKDTree, widest: float, poses: tuple[dict[int, BodyPose], dict[int, BodyPose]]) -> None:
        start, end = poses[0][shape.body], poses[1][shape.body]
        r0, r1 = start.rotation[0], end.rotation[0]
        c0, c1 = start.centre[0] + r0 @ shape.centre, end.centre[0] + r1 @ shape.centre
        # the particles whose paths pass near the solid anywhere between its two places
        chosen = np.asarray(tree.query_ball_point(0.5 * (c0 + c1), shape.reach + widest
                                                  + 0.5 * float(np.linalg.norm(c1 - c0))), np.intp)
        if not len(chosen):
            return
        local0 = (x0[chosen] - start.centre[0]) @ r0  # Rᵀ (x - c), row-wise: the body's own axes
        local1 = (x1[chosen] - end.centre[0]) @ r1
        if shape.sweep is not None:
            fraction = shape.sweep(local0, local1 - local0, radius[chosen])
        else:
            fraction = march(lambda p, which: shape.distance(p), local0, local1 - local0, radius[chosen])
        hit = np.isfinite(fraction)
        if not hit.any():
            return
        at = local0[hit] + fraction[hit, None] * (local1[hit] - local0[hit])
        _, normal = shape.distance(at)
        lever = at @ r1.T  # from the centre of mass, world axes, at the step's end
        surface = end.velocity[0] + np.cross(end.omega[0], lever)
        hits.keep_earlier(fraction[hit], chosen[hit], normal @ r1.T, shape.material, surface, shape.body)

    def push_out(self, x: np.ndarray, v: np.ndarray, radius: np.ndarray, pose: dict[int, BodyPose] | None
                 ) -> np.ndarray:
        """Move particles found inside a triangle's reach or a body onto the surface, and stop their motion into it
        (relative to a body's surface); return which were moved (K,)."""
        moved = np.zeros(len(x), bool)
        if self.triangle_group is not None and len(x):
            particle, triangle = self._near_triangles(x, radius)
            if len(particle):
                distance, normal = to_triangles(x[particle], self.triangles[triangle])
                depth = radius[particle] - distance
                order = np.lexsort((-depth, particle))  # each particle's deepest triangle first
                first = order[np.r_[True, particle[order][1:] != particle[order][:-1]]]
                inside = first[depth[first] > 0]
                _push(x, v, particle[inside], depth[inside], normal[inside], np.zeros((len(inside), 3)))
                moved[particle[inside]] = True
        if self.shapes and pose is not None and len(x):
            for shape in self.shapes:
                now = pose[shape.body]
                rotation = now.rotation[0]
                local = (x - now.centre[0]) @ rotation
                near = np.flatnonzero(np.linalg.norm(local - shape.centre, axis=1) < shape.reach + radius)
                if not len(near):
                    continue
                distance, normal = shape.distance(local[near])
                inside = distance < radius[near]
                which = near[inside]
                lever = local[which] @ rotation.T
                surface = now.velocity[0] + np.cross(now.omega[0], lever)
                _push(x, v, which, (radius[which] - distance[inside]), normal[inside] @ rotation.T, surface)
                moved[which] = True
        return moved


def _push(x: np.ndarray, v: np.ndarray, which: np.ndarray, depth: np.ndarray, normal: np.ndarray,
          surface_velocity: np.ndarray) -> None:
    """Move particles ``which`` out along ``normal`` by ``depth`` (and a hair), and take away their velocity into
    the surface (relative to the surface's own velocity)."""
    x[which] += (depth + SURFACE_GAP)[:, None] * normal
    into = np.einsum("ij,ij->i", v[which] - surface_velocity, normal)
    v[which] -= np.minimum(into, 0.0)[:, None] * normal
