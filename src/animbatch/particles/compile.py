"""Compile a scene's emitters: schedules, sources, attribute laws, the fields and colliders each one meets."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.particles.collisions import ParticleColliders
from animbatch.particles.emitter import Emitter, Law, color_law
from animbatch.particles.fields import particle_fields
from animbatch.particles.schedule import EmissionSchedule
from animbatch.particles.sources import build_source
from animbatch.particles.streams import ParticleStreams
from animbatch.scene.schema import SceneSpec


@dataclass(frozen=True, eq=False)
class ParticleSystems:
    """A scene's compiled emitters and the colliders their particles meet (per emitter, by name; None: none)."""

    emitters: tuple[Emitter, ...]
    colliders: dict[str, ParticleColliders | None]

    def emitter(self, name: str) -> Emitter:
        return next(e for e in self.emitters if e.name == name)


def pool_sizes(spec: SceneSpec) -> list[tuple[str, int, float]]:
    """(emitter name, pool capacity, particles born over the animation) of each emitter, without allocating the
    pools: what the cost pre-flight needs."""
    sizes = []
    for item in spec.emitters:
        schedule = EmissionSchedule.from_spec(item, spec.duration)
        sizes.append((item.name, _capacity(item, schedule, spec.duration), float(schedule.born_by(spec.duration))))
    return sizes


def _capacity(item: Any, schedule: EmissionSchedule, duration: float) -> int:
    """Slots of an emitter's pool: its declared capacity, or the most its rate, bursts and longest life keep alive."""
    return int(item.capacity or max(1, schedule.most_alive(Law.of(item.lifetime).largest, duration)))


def compile_particles(spec: SceneSpec, model: Any, base_dir: Path = Path(".")) -> ParticleSystems | None:
    """The particle systems of a scene (None when it declares no emitters). ``model`` gives the bodies that
    emitters move with (their index in the trajectory, centre of mass and surface)."""
    if not spec.emitters:
        return None
    from animbatch.contact.world import _statics, material_table

    table = material_table(spec)
    statics = _statics(spec, table, base_dir)[0] if spec.colliders else None
    emitters, colliders = [], {}
    for index, item in enumerate(spec.emitters):
        body = body_centre = geometry = None
        if item.body is not None:
            body = model.body_names.index(item.body)
            rigid = body - model.particle_count
            body_centre = model.rigid.centre[rigid]
            geometry = model.rigid.geometry[rigid]
        schedule = EmissionSchedule.from_spec(item, spec.duration)
        lifetime = Law.of(item.lifetime)
        capacity = _capacity(item, schedule, spec.duration)
        mean, spread, distribution = color_law(item.color)
        axis = None
        if item.direction.axis != "normal":
            axis = np.asarray(item.direction.axis, float)
            axis /= np.linalg.norm(axis)
        emitters.append(Emitter(
            item.name, index, schedule, ParticleStreams(spec.seed, index), build_source(item.source, geometry),
            lifetime, Law.of(item.speed), Law.of(item.radius), Law.of(item.mass), mean, spread, distribution, axis,
            float(np.radians(item.direction.cone)), body, item.body,
            body_centre if body_centre is not None else np.zeros(3), item.inherit_velocity, item.collision,
            table.index(item.material), capacity, particle_fields(spec.fields, item.name), item.look))
        if statics is not None and item.collision != "pass":
            own = table.index(item.material)
            colliders[item.name] = ParticleColliders(statics, table.restitution[own], table.static_friction[own],
                                                     table.kinetic_friction[own])
        else:
            colliders[item.name] = None
    return ParticleSystems(tuple(emitters), colliders)
