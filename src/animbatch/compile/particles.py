"""Compile a scene's emitters: schedules, sources, attribute laws, the fields and colliders each one meets."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.compile.bodies import orientation_matrix
from animbatch.compile.contacts import _statics, build_contact_world, material_table, pose_path
from animbatch.compile.forces import particle_law
from animbatch.render.colors import hex_to_rgb
from animbatch.scene.schema import (
    BoxCollider,
    BoxSource,
    DiscSource,
    MeshCollider,
    PlaneCollider,
    PointSource,
    RandomColor,
    RandomValue,
    SceneSpec,
    SphereCollider,
    SphereSource,
)
from animbatch.sim.contact.geometry import BodyBoxes, BodyCylinders, StaticColliders
from animbatch.sim.contact.meshes import TriangleGroup
from animbatch.sim.forces.on_particles import ParticleLaw
from animbatch.sim.motion import SolidPath
from animbatch.sim.particles.collisions import ParticleColliders
from animbatch.sim.particles.compiled import kernel_work, numpy_pool_seconds, particle_step_seconds
from animbatch.sim.particles.emitter import Emitter, Law
from animbatch.sim.particles.obstacles import ParticleObstacles, body_shapes, moving_collider_shapes
from animbatch.sim.particles.schedule import EmissionSchedule
from animbatch.sim.particles.sources import Source
from animbatch.sim.particles.streams import ParticleStreams
from animbatch.sim.rigid.shapes import BodyGeometry, load_surface


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
        schedule = _schedule(item, spec.duration)
        sizes.append((item.name, _capacity(item, schedule, spec.duration), float(schedule.born_by(spec.duration))))
    return sizes


def particle_costs(spec: SceneSpec, systems: ParticleSystems | None, particle_steps: int
                   ) -> list[tuple[str, int, float, float]]:
    """:func:`pool_sizes`, each with what one particle-step of that emitter costs [s] (the compiled kernel's figure
    where it will step the pool over ``particle_steps`` steps, else the numpy code's): the cost pre-flight's input."""
    if systems is None:
        return []
    method = spec.solver.method
    sizes = pool_sizes(spec)
    run_seconds = sum(numpy_pool_seconds(capacity, particle_steps) for _, capacity, _ in sizes)
    return [(name, capacity, births,
             particle_step_seconds(systems.emitter(name), systems.colliders.get(name), method,
                                   kernel_work(capacity, particle_steps, run_seconds)))
            for name, capacity, births in sizes]


def _capacity(item: Any, schedule: EmissionSchedule, duration: float) -> int:
    """Slots of an emitter's pool: its declared capacity, or the most its rate, bursts and longest life keep alive."""
    return int(item.capacity or max(1, schedule.most_alive(_law(item.lifetime).largest, duration)))


def compile_particles(spec: SceneSpec, model: Any, base_dir: Path = Path(".")) -> ParticleSystems | None:
    """The particle systems of a scene (None when it declares no emitters). ``model`` gives the bodies that
    emitters move with (their index in the trajectory, centre of mass and surface)."""
    if not spec.emitters:
        return None

    table = material_table(spec)
    # colliders on keyframes are obstacles that move (particle_obstacles); the closed-form tests take the rest
    fixed = [c for c in spec.colliders if not c.moves]
    statics = _statics(spec.model_copy(update={"colliders": fixed}), table, base_dir)[0] if fixed else None
    obstacles = particle_obstacles(spec, statics, model, base_dir)
    emitters: list[Emitter] = []
    colliders: dict[str, ParticleColliders | None] = {}
    for index, item in enumerate(spec.emitters):
        body = body_centre = geometry = None
        if item.body is not None:
            body = model.body_names.index(item.body)
            rigid = body - model.particle_count
            body_centre = model.rigid.centre[rigid]
            geometry = model.rigid.geometry[rigid]
        schedule = _schedule(item, spec.duration)
        lifetime = _law(item.lifetime)
        capacity = _capacity(item, schedule, spec.duration)
        mean, spread, distribution = _color_law(item.color)
        axis = None
        if item.direction.axis != "normal":
            axis = np.asarray(item.direction.axis, float)
            axis /= np.linalg.norm(axis)
        emitters.append(Emitter(
            item.name, index, schedule, ParticleStreams(spec.seed, index), _source(item.source, geometry),
            lifetime, _law(item.speed), _law(item.radius), _law(item.mass), mean, spread, distribution, axis,
            float(np.radians(item.direction.cone)), body, item.body,
            body_centre if body_centre is not None else np.zeros(3), item.inherit_velocity, item.collision,
            table.index(item.material), capacity, _particle_fields(spec.fields, item.name)))
        met = obstacles.without(body) if obstacles is not None else None  # not the body it is born on
        if (statics is not None or met is not None) and item.collision != "pass":
            own = table.index(item.material)
            colliders[item.name] = ParticleColliders(statics if statics is not None else StaticColliders.empty(),
                                                     table.restitution[own], table.static_friction[own],
                                                     table.kinetic_friction[own], met)
        else:
            colliders[item.name] = None
    return ParticleSystems(tuple(emitters), colliders)


def particle_obstacles(spec: SceneSpec, statics: StaticColliders | None, model: Any, base_dir: Path
                       ) -> ParticleObstacles | None:
    """What particles meet beyond planes, spheres and boxes: the triangles of mesh colliders, and the solids of the
    rigid bodies that collide (as the contact world holds them; built here when the bodies themselves have no
    contacts to simulate); None when there are none."""
    triangles = statics.triangles if statics is not None else np.zeros((0, 3, 3))
    group = TriangleGroup.of(triangles, np.arange(len(triangles))) if len(triangles) else None
    world = getattr(model, "contact_world", None)
    if world is None and model.rigid is not None and any(getattr(b, "collide", False) for b in spec.bodies
                                                         if b.type == "rigid"):
        world, _ = build_contact_world(spec, model, dict(zip(model.rigid.names, model.rigid.centre)), base_dir)
    shapes: tuple = ()
    if world is not None:
        probes, first_rigid = world.probes, model.particle_count
        solid = (probes.radius > 0) & (probes.owner >= first_rigid) & world.collides[probes.owner]
        spheres = [(int(probes.owner[k]), probes.offset[k], float(probes.radius[k])) for k in np.flatnonzero(solid)]
        boxes = world.boxes
        keep = world.collides[boxes.owner]
        rounds = world.cylinders
        if rounds is not None:
            chosen = world.collides[rounds.owner]
            rounds = BodyCylinders(*(getattr(rounds, name)[chosen] for name in
                                     ("owner", "offset", "axis", "half_length", "radius", "rounded")))
        shapes = body_shapes(spheres, BodyBoxes(boxes.owner[keep], boxes.offset[keep], boxes.rotation[keep],
                                                boxes.half[keep]), rounds,
                             tuple(h for h in world.hulls if world.collides[h.owner]), world.body_material)
    paths: list[SolidPath] = []
    moving: dict[type, list[tuple]] = {SphereCollider: [], BoxCollider: [], PlaneCollider: [], MeshCollider: []}
    table = material_table(spec)
    for collider in spec.colliders:
        if not collider.moves:
            continue
        path, material = len(paths), table.index(collider.material)
        paths.append(pose_path(collider))
        if isinstance(collider, SphereCollider):
            moving[SphereCollider].append((path, float(collider.radius), material))
        elif isinstance(collider, BoxCollider):
            moving[BoxCollider].append((path, orientation_matrix(collider.orientation),
                                        np.asarray(collider.size, float) / 2, material))
        elif isinstance(collider, PlaneCollider):
            normal = np.asarray(collider.normal, float)
            moving[PlaneCollider].append((path, normal / np.linalg.norm(normal), material))
        else:  # a mesh, from its pivot (where the file's origin goes)
            mesh = load_surface(base_dir / collider.file, collider.scale)
            moving[MeshCollider].append((path, mesh.triangles @ orientation_matrix(collider.orientation).T, material))
    shapes = shapes + moving_collider_shapes(moving[SphereCollider], moving[BoxCollider], moving[PlaneCollider],
                                             moving[MeshCollider])
    if group is None and not shapes:
        return None
    triangle_material = statics.triangle_material if statics is not None else np.zeros(0, np.intp)
    return ParticleObstacles(triangles, triangle_material, group, shapes, tuple(paths))


def _law(value: float | RandomValue) -> Law:
    """A per-particle value: fixed, or ``mean ± spread`` as the scene's random value gives it."""
    if isinstance(value, RandomValue):
        return Law(value.mean, value.spread, value.distribution)
    return Law(float(value))


def _color_law(color: str | RandomColor) -> tuple[np.ndarray, float, str]:
    """(mean RGB (3,), spread, distribution) of an emitter's colour key."""
    if isinstance(color, RandomColor):
        return np.array(hex_to_rgb(color.mean)), color.spread, color.distribution
    return np.array(hex_to_rgb(color)), 0.0, "uniform"


def _schedule(spec: Any, end: float) -> EmissionSchedule:
    """The schedule of an emitter spec, for an animation that ends at ``end`` [s]."""
    rate = spec.rate
    start = float(spec.start)
    stop = float(spec.stop) if spec.stop is not None else max(end, start) + 1.0
    if isinstance(rate, int | float):
        times, rates = np.array([start, stop]), np.array([float(rate)] * 2)
    else:
        keys_t = np.array([k.time for k in rate], float)
        keys_r = np.array([k.rate for k in rate], float)
        inner = keys_t[(keys_t > start) & (keys_t < stop)]
        times = np.concatenate([[start], inner, [stop]])
        rates = np.interp(times, keys_t, keys_r)
    bursts = spec.bursts
    return EmissionSchedule(times, rates, np.array([b.time for b in bursts], float),
               np.array([b.count for b in bursts], np.int64))


def _source(spec: object, body_geometry: BodyGeometry | None = None) -> Source:
    """The source of an emitter spec; a ``surface`` source needs its body's geometry (shape coordinates)."""
    if isinstance(spec, PointSource):
        return Source("point", np.asarray(spec.position, float))
    if isinstance(spec, SphereSource):
        return Source("sphere", np.asarray(spec.position, float), spec.radius, spec.surface)
    if isinstance(spec, DiscSource):
        normal = np.asarray(spec.normal, float)
        return Source("disc", np.asarray(spec.position, float), spec.radius, normal=normal / np.linalg.norm(normal))
    if isinstance(spec, BoxSource):
        return Source("box", np.asarray(spec.position, float), rotation=orientation_matrix(spec.orientation),
                      half=np.asarray(spec.size, float) / 2)
    assert body_geometry is not None, "a surface source needs its body"
    spheres, triangles = body_geometry.spheres, body_geometry.triangles
    areas = np.concatenate([4.0 * np.pi * spheres[:, 3] ** 2,
                            0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                                          triangles[:, 2] - triangles[:, 0]), axis=1)])
    cumulative = np.cumsum(areas) / np.sum(areas)
    return Source("surface", np.zeros(3), triangles=triangles, spheres=spheres, area_cumulative=cumulative)


def _particle_fields(fields: list, emitter: str) -> tuple[ParticleLaw, ...]:
    """The laws of the fields (scene specs) that act on the particles of ``emitter``, in declaration order (see the
    table of laws, :data:`animbatch.compile.forces.LAWS`)."""
    built = []
    for field in fields:
        if field.bodies is not None and emitter not in field.bodies:
            continue
        law = particle_law(field)
        if law is not None:
            built.append(law)
    return tuple(built)
