"""A compiled emitter: its schedule, source and attribute laws, and what a newborn particle gets.

A particle's attributes (lifetime, speed, direction, start point, radius, mass, colour) are all drawn from its own
random numbers (its serial's block, :mod:`animbatch.sim.particles.streams`), each within the bounds the scene declares:
the lecture notes' constrained randomisation. The colour is drawn again, identically, when frames are drawn, so the
trajectory need not store it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.on_particles import ParticleLaw
from animbatch.sim.particles.body_motion import BodyMotion
from animbatch.sim.particles.schedule import Births, EmissionSchedule
from animbatch.sim.particles.sources import Source, cone_directions
from animbatch.sim.particles.streams import DRAW, ParticleStreams, spread_values


@dataclass(frozen=True)
class Law:
    """A per-particle value: ``mean ± spread`` (uniform or clipped normal)."""

    mean: float
    spread: float = 0.0
    distribution: str = "uniform"

    def draw(self, uniform: np.ndarray) -> np.ndarray:
        return spread_values(uniform, self.mean, self.spread, self.distribution)

    @property
    def largest(self) -> float:
        return self.mean + self.spread

    @property
    def smallest(self) -> float:
        return self.mean - self.spread


@dataclass(frozen=True)
class Newborns:
    """Particles at their birth: where [m] (K, 3), velocity [m/s] (K, 3), lifetime [s], mass [kg], radius [m] (K,)."""

    position: np.ndarray
    velocity: np.ndarray
    lifetime: np.ndarray
    mass: np.ndarray
    radius: np.ndarray

    def part(self, first: int, stop: int) -> Newborns:
        """Particles ``first … stop - 1`` of these (views)."""
        return Newborns(self.position[first:stop], self.velocity[first:stop], self.lifetime[first:stop],
                        self.mass[first:stop], self.radius[first:stop])


@dataclass(frozen=True, eq=False)
class Emitter:
    """One emitter of a scene, compiled.

    ``body``: index of the body it moves with in the scene's trajectory (rigid bodies come after particles), or
    None; ``body_centre``: that body's centre of mass in its shape coordinates [m] (3,). ``axis``: unit direction
    (3,) of the cone of start velocities, or None to use the source's normal; ``cone``: its half-angle [rad].
    ``collision``: bounce, stick, die or pass; ``material``: index in the scene's material table.
    """

    name: str
    index: int
    schedule: EmissionSchedule
    streams: ParticleStreams
    source: Source
    lifetime: Law
    speed: Law
    radius: Law
    mass: Law
    color_mean: np.ndarray
    color_spread: float
    color_distribution: str
    axis: np.ndarray | None
    cone: float
    body: int | None
    body_name: str | None
    body_centre: np.ndarray
    inherit_velocity: float
    collision: str
    material: int
    capacity: int
    fields: tuple[ParticleLaw, ...]

    def newborns(self, births: Births, motion: BodyMotion | None) -> Newborns:
        """Start states and attributes of ``births``; ``motion`` places an emitter that moves with a body."""
        u = self.streams.uniforms(int(births.serials[0]), births.count) if births.count else \
            self.streams.uniforms(0, 0)
        points, normals = self.source.sample(u)
        axes = np.tile(self.axis, (births.count, 1)) if self.axis is not None else normals
        directions = cone_directions(axes, self.cone, u[:, DRAW["cone"]], u[:, DRAW["turn"]])
        velocity = self.speed.draw(u[:, DRAW["speed"]])[:, None] * directions
        if self.body is not None and births.count:
            assert motion is not None
            pose = motion.pose(self.body, births.times)
            lever = np.einsum("kij,kj->ki", pose.rotation, points - self.body_centre)
            points = pose.centre + lever
            velocity = (np.einsum("kij,kj->ki", pose.rotation, velocity)
                        + self.inherit_velocity * (pose.velocity + np.cross(pose.omega, lever)))
        return Newborns(points, velocity, self.lifetime.draw(u[:, DRAW["lifetime"]]),
                        self.mass.draw(u[:, DRAW["mass"]]), self.radius.draw(u[:, DRAW["radius"]]))

    def _uniforms_of(self, serials: np.ndarray) -> np.ndarray:
        """The random numbers (K, DRAWS_PER_PARTICLE) of particles by serial (live serials span about a lifetime's
        births, so one contiguous draw covers them)."""
        first, last = int(serials.min()), int(serials.max())
        return self.streams.uniforms(first, last - first + 1)[serials - first]

    def looks(self, serials: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lifetimes [s] (K,), radii [m] (K,) and colours (K, 3) in 0…1 of particles by serial (K,): the values they
        were born with, drawn again from their own random numbers."""
        serials = np.asarray(serials, np.int64)
        if not len(serials):
            return np.zeros(0), np.zeros(0), np.zeros((0, 3))
        u = self._uniforms_of(serials)
        channels = u[:, [DRAW["red"], DRAW["green"], DRAW["blue"]]]
        colors = np.stack([spread_values(channels[:, k], self.color_mean[k], self.color_spread,
                                         self.color_distribution) for k in range(3)], axis=1)
        return (self.lifetime.draw(u[:, DRAW["lifetime"]]), self.radius.draw(u[:, DRAW["radius"]]),
                np.clip(colors, 0.0, 1.0))


