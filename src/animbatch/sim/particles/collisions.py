"""Emitted particles against the scene's colliders: swept, so that no particle passes through one.

A particle moves from ``x0`` to ``x1`` in a step. Testing only ``x1`` lets a fast particle jump over a thin box or
through a sphere in one step; instead each segment ``x0 → x1`` is tested against every plane, sphere and box (grown
by the particle's radius), and the particle stops at the first surface it meets: there it bounces, sticks or dies,
and a bouncing particle travels the rest of its step with its new velocity (tested again, up to ``MAX_BOUNCES``
times, for corners). Any particle still found inside a collider after that is moved onto its surface.

A bounce keeps the tangential velocity less Coulomb friction and reverses the normal one scaled by the restitution
``e`` of the two materials: ``v_n' = -e v_n``, ``|Δv_t| = min(|v_t|, μ_k (1 + e) |v_n|)`` (no sliding at all while
``|v_t| ≤ μ_s (1 + e) |v_n|``). Normal speeds below ``rest_speed`` do not bounce, so resting particles settle instead
of chattering. The velocity used is the one at the end of the step.

Boxes grown by the radius have sharp edges instead of rounded ones (a particle grazing an edge may bounce off up
to ``r (√3 - 1)`` early). Mesh colliders and the rigid bodies' shapes are traced in
:mod:`animbatch.sim.particles.obstacles`; a bounce off a moving body uses the velocity relative to its surface.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from animbatch.sim.contact.geometry import StaticColliders, to_box, to_plane, to_sphere
from animbatch.sim.particles.body_motion import BodyPose
from animbatch.sim.particles.obstacles import SURFACE_GAP, Hits, ParticleObstacles

Poses = tuple[dict[int, BodyPose], dict[int, BodyPose]]

#: Bounces resolved within one step (a particle in a corner meets two or three faces).
MAX_BOUNCES = 3




@dataclass(frozen=True, eq=False)
class ParticleColliders:
    """The colliders particles meet, and the coefficients of each collider material against the particles'.

    ``restitution``, ``static_friction``, ``kinetic_friction``: (M,) against the emitter's material, indexed by
    collider material."""

    statics: StaticColliders
    restitution: np.ndarray
    static_friction: np.ndarray
    kinetic_friction: np.ndarray
    obstacles: ParticleObstacles | None = None  # mesh colliders and rigid bodies

    @property
    def empty(self) -> bool:
        return (len(self.statics.plane_point) + len(self.statics.sphere_centre) + len(self.statics.box_centre) == 0
                and (self.obstacles is None or self.obstacles.empty))

    @property
    def bodies(self) -> tuple[int, ...]:
        """The bodies (trajectory indices) whose poses the collisions need."""
        return self.obstacles.bodies if self.obstacles is not None else ()

    def first_hits(self, x0: np.ndarray, x1: np.ndarray, radius: np.ndarray, poses: Poses | None = None
                   ) -> Hits:
        """The first surface each segment ``x0 → x1`` (K, 3) crosses from outside, colliders grown by ``radius``;
        ``poses``: the bodies' poses at the step's start and end."""
        hits = (self.obstacles.first_hits(x0, x1, radius, poses) if self.obstacles is not None
                else Hits.none(len(x0)))
        best, normal, material = hits.fraction, hits.normal, hits.material
        count = len(x0)
        step = x1 - x0
        s = self.statics
        with np.errstate(divide="ignore", invalid="ignore"):
            for point, n, m in zip(s.plane_point, s.plane_normal, s.plane_material):
                d0 = (x0 - point) @ n - radius
                d1 = (x1 - point) @ n - radius
                hit = (d0 >= 0) & (d1 < 0)
                fraction = np.where(hit, d0 / (d0 - d1), np.inf)
                _keep(best, normal, material, fraction, np.broadcast_to(n, (count, 3)), m, hits)
            for centre, r, m in zip(s.sphere_centre, s.sphere_radius, s.sphere_material):
                grown = r + radius
                offset = x0 - centre
                a = np.einsum("ij,ij->i", step, step)
                b = np.einsum("ij,ij->i", step, offset)
                c = np.einsum("ij,ij->i", offset, offset) - grown * grown
                disc = b * b - a * c
                fraction = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
                hit = (c >= 0) & (disc >= 0) & (a > 0) & (fraction >= 0) & (fraction <= 1)
                fraction = np.where(hit, fraction, np.inf)
                at = offset + np.where(hit, fraction, 0.0)[:, None] * step
                _keep(best, normal, material, fraction, at / np.linalg.norm(at, axis=1, keepdims=True), m, hits)
            for centre, rotation, half, m in zip(s.box_centre, s.box_rotation, s.box_half, s.box_material):
                grown = half + radius[:, None]
                p0 = (x0 - centre) @ rotation  # box axes: Rᵀ (x - c)
                d = step @ rotation
                low, high = (-grown - p0) / d, (grown - p0) / d
                near = np.where(d == 0, np.where(np.abs(p0) <= grown, -np.inf, np.inf), np.minimum(low, high))
                far = np.where(d == 0, np.where(np.abs(p0) <= grown, np.inf, -np.inf), np.maximum(low, high))
                entry_axis = np.argmax(near, axis=1)
                entry, leave = near.max(axis=1), far.min(axis=1)
                outside = np.any(np.abs(p0) > grown, axis=1)
                hit = outside & (entry <= leave) & (entry >= 0) & (entry <= 1)
                fraction = np.where(hit, entry, np.inf)
                rows = np.arange(count)
                local = np.zeros((count, 3))
                local[rows, entry_axis] = -np.sign(d[rows, entry_axis])
                _keep(best, normal, material, fraction, local @ rotation.T, m, hits)
        return hits

    def _distances(self, x: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Signed distances (K,) [m] and outward normals (K, 3) of ``x`` to each collider in turn, each computed when
        asked for (so after the pushes out of the colliders before it)."""
        s = self.statics
        for point, n in zip(s.plane_point, s.plane_normal):
            yield to_plane(x, point, n)
        for centre, r in zip(s.sphere_centre, s.sphere_radius):
            yield to_sphere(x, np.broadcast_to(centre, x.shape), np.full(len(x), r))
        for centre, rotation, half in zip(s.box_centre, s.box_rotation, s.box_half):
            yield to_box(x, np.broadcast_to(centre, x.shape), np.broadcast_to(rotation, (len(x), 3, 3)),
                         np.broadcast_to(half, x.shape))

    def push_out(self, x: np.ndarray, v: np.ndarray, radius: np.ndarray, pose: dict[int, BodyPose] | None = None
                 ) -> np.ndarray:
        """Move particles found inside a collider or body (at ``pose``) onto its surface and stop their motion into
        it; return which were moved (K,)."""
        moved = (self.obstacles.push_out(x, v, radius, pose) if self.obstacles is not None
                 else np.zeros(len(x), bool))
        for distance, normal in self._distances(x):
            inside = distance < radius
            if not inside.any():
                continue
            depth = (radius - distance)[inside]
            x[inside] += (depth + SURFACE_GAP)[:, None] * normal[inside]
            into = np.einsum("ij,ij->i", v[inside], normal[inside])
            v[inside] -= np.minimum(into, 0.0)[:, None] * normal[inside]
            moved |= inside
        return moved


def _keep(best: np.ndarray, normal: np.ndarray, material: np.ndarray, fraction: np.ndarray, normals: np.ndarray,
          material_index: int, hits: Hits) -> None:
    """Where ``fraction`` is earlier than the best so far, take it (in place): a fixed collider's hit."""
    earlier = fraction < best
    best[earlier] = fraction[earlier]
    normal[earlier] = normals[earlier]
    material[earlier] = material_index
    hits.surface_velocity[earlier] = 0.0
    hits.body[earlier] = -1


def bounce(v: np.ndarray, normal: np.ndarray, restitution: np.ndarray, static_friction: np.ndarray,
           kinetic_friction: np.ndarray, rest_speed: float) -> np.ndarray:
    """Velocities (K, 3) after bouncing off surfaces with outward ``normal`` (K, 3) (see the module notes)."""
    normal_speed = np.einsum("ij,ij->i", v, normal)
    approach = np.maximum(-normal_speed, 0.0)
    e = np.where(approach > rest_speed, restitution, 0.0)
    tangential = v - normal_speed[:, None] * normal
    slide = np.linalg.norm(tangential, axis=1)
    impulse = (1.0 + e) * approach  # normal speed change
    sticks = slide <= static_friction * impulse
    reduced = np.where(sticks, 0.0, np.maximum(slide - kinetic_friction * impulse, 0.0))
    scale = np.divide(reduced, slide, out=np.zeros_like(slide), where=slide > 0)
    bounced = tangential * scale[:, None] + (e * approach)[:, None] * normal
    return np.where((approach > 0)[:, None], bounced, v)  # already leaving: unchanged
