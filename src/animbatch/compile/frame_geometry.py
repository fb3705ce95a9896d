"""What the renderer draws, compiled from the scene and its model: a
:class:`~animbatch.render.frame_geometry.FrameGeometry`.

Rendering never reads the Model or recompiles anything: everything it needs about bodies, springs, fluids,
controllers and mesh files is gathered here, once per render.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from animbatch.curves import ParametricCurve, Polyline
from animbatch.materials import BUILT_IN_LOOKS
from animbatch.render.colors import (
    COLLIDER_COLOR,
    MESH_SPRING_COLOR,
    PALETTE,
    ROD_COLOR,
    SPRING_COLOR,
    darker,
    hex_to_rgb,
)
from animbatch.render.frame_geometry import (
    BodyPath,
    DrawnCollider,
    Finish,
    FrameGeometry,
    FrameSeries,
    ParticleLook,
    Solid,
    SurfacePatch,
    Surfaces,
    TrailPaths,
    TriangleMesh,
)
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import (
    BoxCollider,
    BoxShape,
    CapsuleShape,
    CompoundShape,
    CylinderShape,
    EmitterSpec,
    MeshCollider,
    MeshShape,
    PlaneCollider,
    RigidBodySpec,
    RodShape,
    SceneSpec,
    ShellShape,
    SphereCollider,
    SphereShape,
)
from animbatch.sim.forces.buoyancy import Buoyancy
from animbatch.sim.forces.controllers import Controllers, CurveTarget
from animbatch.sim.model.model import Model
from animbatch.sim.particles.emitter import Emitter
from animbatch.sim.rigid.shapes import load_mesh, load_surface
from animbatch.trajectory import ParticleFrames
from animbatch.vertex_placement import VertexPlacement


def body_extents(model: Model) -> np.ndarray:
    """How far each body reaches from its centre of mass [m], shape (P,): radius for particles, the farthest
    surface point for rigid bodies (used to fit the camera)."""
    extents = np.array(model.bodies.radius, float)
    rigid = model.rigid
    if rigid is not None:
        for b, geometry in enumerate(rigid.geometry):
            reach = 0.0
            if len(geometry.triangles):
                reach = float(np.max(np.linalg.norm(geometry.triangles - rigid.centre[b], axis=-1)))
            for x, y, z, r in geometry.spheres:
                reach = max(reach, float(np.linalg.norm(np.array([x, y, z]) - rigid.centre[b]) + r))
            extents[model.particle_count + b] = reach
    return extents


def collider_points(spec: SceneSpec, scene_dir: Path = Path(".")) -> np.ndarray:
    """Corner points (K, 3) of the finite colliders (boxes, spheres, meshes), for fitting the camera; planes are
    infinite and left out."""
    points = []
    for collider in spec.colliders:
        if not collider.visible:
            continue
        # a collider on keyframes counts at every key's offset, one in closed-form motion along its path (turns are
        # covered by its diagonal)
        keys = getattr(collider, "keyframes", None) or ()
        shifts = [np.asarray(key.offset, float) for key in keys] or [np.zeros(3)]
        if getattr(collider, "motion", None) is not None:
            from animbatch.compile.contacts import pose_path  # contact code only for scenes that need it

            path = pose_path(collider)
            shifts = [path.pose(t)[0] - path.centre for t in np.linspace(0.0, spec.duration, 25)]
        if isinstance(collider, SphereCollider):
            points += [np.asarray(collider.position) + shift + s * collider.radius for s in (-1, 1) for shift in shifts]
        elif isinstance(collider, BoxCollider):
            half = np.asarray(collider.size) / 2
            corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
            for shift in shifts:
                points += list(corners @ orientation_matrix(collider.orientation).T + collider.position + shift)
        elif isinstance(collider, MeshCollider):
            vertices = load_surface(scene_dir / collider.file, collider.scale).vertices
            vertices = vertices @ orientation_matrix(collider.orientation).T + collider.position
            points += [corner + shift for corner in (vertices.min(axis=0), vertices.max(axis=0)) for shift in shifts]
    return np.array(points, float).reshape(-1, 3)


def frame_geometry(spec: SceneSpec, model: Model, bounds: np.ndarray, largest_vector: float = 0.0,
                   scene_dir: Path = Path("."), emitters: tuple[Emitter, ...] = (),
                   motion: tuple[np.ndarray, np.ndarray] | None = None,
                   particles: tuple[ParticleFrames, ...] = ()) -> FrameGeometry:
    """What the renderer draws for a scene and its model: colours, shapes, springs, fluids, colliders, targets and
    the mesh files read, within ``bounds`` (2, 3) [m]; ``largest_vector`` scales the ω/L arrows; ``motion``: the
    bodies' positions (F, P, 3) [m] at the frame times (F,) [s] (default: the model's), which trails follow;
    ``emitters`` and their ``particles``: the compiled emitters and the particles the trajectory holds of each."""
    times = np.asarray(motion[1]) if motion is not None else np.asarray(model.frame_times)
    # palette colours follow the scene's order of bodies; the model orders them particles first
    by_name = {body.name: (index, body) for index, body in enumerate(spec.bodies)}
    looks = {body.name: surface_look(spec, body) for body in spec.bodies}
    colors = [looks[name][0] or PALETTE[by_name[name][0] % len(PALETTE)] for name in model.owners]
    n, rigid, springs = model.particle_count, model.rigid, model.springs
    extents = body_extents(model)
    none = np.zeros(0, np.intp)
    spring_parts: tuple[np.ndarray, ...] = (none, none, np.zeros(0, bool), np.zeros((0, 3)), np.zeros((0, 3)))
    spring_colors: list[str] = []
    if springs is not None:
        mesh = springs.mesh if springs.mesh is not None else np.zeros(springs.count, bool)
        drawn = ~mesh | (spec.render.mesh_springs == "line")
        spring_parts = tuple(np.asarray(a)[drawn] for a in (springs.first, springs.second, springs.second_is_anchor,
                                                            springs.first_offset, springs.second_offset))
        scene_colors = iter([s.color or SPRING_COLOR for s in spec.springs])
        spring_colors = [MESH_SPRING_COLOR if is_mesh else next(scene_colors) for is_mesh in mesh[drawn]]
    if model.joints is not None:  # rods and ropes are drawn as the springs are, in a dark steel
        near, far, near_offset, far_offset = model.joints.segments()
        fixed = far < 0
        anchors = np.asarray(model.anchor_position).reshape(-1, 3)
        if fixed.any():  # a fixed end is at one of the scene's anchors
            nearest = np.linalg.norm(far_offset[fixed][:, None] - anchors[None], axis=2).argmin(axis=1)
            far = far.copy()
            far[fixed] = nearest
        spring_parts = tuple(np.concatenate([a, b]) for a, b in zip(
            spring_parts, (near, far, fixed, near_offset, np.where(fixed[:, None], 0.0, far_offset))))
        spring_colors = spring_colors + [ROD_COLOR] * len(near)
    fluids = [(term.level, term.up) for term in model.force_terms if isinstance(term, Buoyancy)]
    rigid_extent = extents[n:]
    scale = 2 * float(np.max(rigid_extent)) / largest_vector if largest_vector > 0 and len(rigid_extent) else 0.0
    deformables = model.deformables
    owners = np.array(model.owners[:n], dtype=object)
    drawn_particles = np.ones(n, bool)
    surface_colors = []
    if deformables is not None:
        names = {body.name for body in deformables.bodies}
        drawn_particles = np.array([owner not in names for owner in owners], bool)
        for body in deformables.bodies:
            index, body_spec = by_name[body.name]
            front = looks[body.name][0] or PALETTE[index % len(PALETTE)]
            back = getattr(body_spec, "back_color", None) or darker(front)
            surface_colors.append((front, back))
    segments, targets = controller_targets(model, times)
    rigid_specs = {body.name: body for body in spec.bodies if isinstance(body, RigidBodySpec)}
    shapes = tuple(solid(rigid_specs[name].shape, scene_dir) for name in rigid.names) if rigid is not None else ()
    anchor_motion = model.anchors
    anchor_track = (FrameSeries(times, np.stack([anchor_motion.positions(float(t)) for t in times]))
                    if anchor_motion.moving else None)
    first, second, to_anchor, first_offset, second_offset = spring_parts
    return FrameGeometry(
        particle_radius=np.asarray(model.bodies.radius[:n]), colors=colors, rigid_shapes=shapes,
        rigid_centre=rigid.centre if rigid is not None else np.zeros((0, 3)),
        rigid_inertia=rigid.inertia if rigid is not None else np.zeros((0, 3, 3)), rigid_extent=rigid_extent,
        anchor_positions=np.asarray(model.anchor_position), spring_first=first, spring_second=second,
        spring_to_anchor=to_anchor, spring_first_offset=first_offset, spring_second_offset=second_offset,
        spring_colors=spring_colors, fluids=fluids, bounds=bounds, vector_scale=scale,
        colliders=drawn_colliders(spec, scene_dir, times), anchor_track=anchor_track,
        anchor_visible=np.asarray(model.anchor_visible), drawn_particles=drawn_particles, surfaces=surfaces(model),
        surface_colors=tuple(surface_colors), target_segments=segments, target_track=targets,
        emitters=particle_looks(spec.emitters, emitters, particles),
        trails=trail_paths(spec, model, colors, motion) if motion is not None else None,
        followed=followed_path(spec, model, motion) if motion is not None else None,
        finishes=tuple(looks[name][1] for name in model.owners),
        surface_finishes=tuple(looks[body.name][1] for body in deformables.bodies) if deformables is not None else (),
        collider_looks=tuple((look[0] or COLLIDER_COLOR, look[1]) for look in
                             (surface_look(spec, c) for c in spec.colliders if c.visible)),
        rigid_volume_radius=np.asarray(model.bodies.radius[n:]))


def surface_look(spec: SceneSpec, item: Any) -> tuple[str | None, Finish | None]:
    """The colour and physically based finish of a body or collider: its own keys first, then its material's (from
    the scene's materials, or the built-in table); a finish only when either gives metallic or roughness."""
    material: Any = spec.materials.get(item.material) or BUILT_IN_LOOKS.get(item.material)
    def own_or_material(name: str) -> Any:
        value = getattr(item, name, None)
        return value if value is not None else getattr(material, name, None)

    metallic, roughness = own_or_material("metallic"), own_or_material("roughness")
    finish = None if metallic is None and roughness is None else (
        float(metallic if metallic is not None else 0.0), float(roughness if roughness is not None else 0.5))
    return own_or_material("color"), finish


def _own_bodies(model: Model) -> dict[str, int]:
    """Particles and rigid bodies (not the vertices of cloth and lattices) by name -> index in the model."""
    return {name: k for k, (name, owner) in enumerate(zip(model.body_names, model.owners)) if name == owner}


def followed_path(spec: SceneSpec, model: Model, motion: tuple[np.ndarray, np.ndarray]) -> BodyPath | None:
    """The path of the body the render's camera follows, or None."""
    name = spec.render.active_camera.follow
    if name is None:
        return None
    index = _own_bodies(model)[name]
    positions, times = motion
    return BodyPath(np.asarray(positions)[:, index], np.asarray(times), float(body_extents(model)[index]))


def trail_paths(spec: SceneSpec, model: Model, colors: list[str],
                motion: tuple[np.ndarray, np.ndarray]) -> TrailPaths | None:
    """The paths of the bodies ``render.trails`` names (default: every particle and rigid body, not the vertices of
    cloth and lattices), or None without trails."""
    trails = spec.render.trails
    if trails is None:
        return None
    positions, times = motion
    own = _own_bodies(model)
    index = [own[name] for name in trails.bodies] if trails.bodies else list(own.values())
    return TrailPaths(np.asarray(positions)[:, index], np.asarray(times), tuple(colors[k] for k in index),
                      trails.length, trails.width, trails.fade)


def controller_targets(model: Model, times: np.ndarray) -> tuple[np.ndarray | None, FrameSeries | None]:
    """The segments (S, 2, 3) of the curves that the model's PD controllers pull towards (or None), and where their
    point and keyframe targets are (K, 3) at each of the frame ``times`` (F,) [s] (or None)."""
    term = next((term for term in model.force_terms if isinstance(term, Controllers)), None)
    if term is None:
        return None, None
    segments, points = [], []
    for target in term.targets:
        if isinstance(target, CurveTarget):
            curve = target.curve
            line: Polyline = curve.polyline if isinstance(curve, ParametricCurve) else curve  # samples of a curve
            segments.append(np.stack([line.start, line.start + line.direction], axis=1))
        else:
            points.append(target)
    track = (FrameSeries(times, np.array([[target.locate(float(t), np.zeros(3)).position for target in points]
                                          for t in times], float).reshape(len(times), len(points), 3))
             if points else None)
    return (np.concatenate(segments) if segments else None), track


def surfaces(model: Model) -> Surfaces | None:
    """The model's cloths and lattices as the renderer draws them (None without any)."""
    deformables = model.deformables
    if deformables is None:
        return None
    vertices = deformables.vertex_map
    placement = VertexPlacement(vertices.kind, vertices.index, vertices.offset, vertices.first_rigid)
    return Surfaces(placement, tuple(SurfacePatch(body.name, body.vertices.start, body.vertices.stop,
                                                  body.triangles - body.vertices.start)
                                     for body in deformables.bodies))


def solid(shape: Any, scene_dir: Path) -> Solid:
    """The solid the renderer draws for a rigid body's shape spec (mesh files read from ``scene_dir``)."""
    if isinstance(shape, SphereShape | ShellShape):
        return Solid("sphere", radius=float(shape.radius))
    if isinstance(shape, BoxShape):
        return Solid("box", size=(float(shape.size[0]), float(shape.size[1]), float(shape.size[2])))
    if isinstance(shape, CylinderShape | RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        return Solid("cylinder", radius=float(radius), length=float(shape.length))
    if isinstance(shape, CapsuleShape):
        return Solid("capsule", radius=float(shape.radius), length=float(shape.length))
    if isinstance(shape, MeshShape):
        return Solid("mesh", mesh=_triangles(load_mesh(scene_dir / shape.file, shape.scale)))
    if isinstance(shape, CompoundShape):
        return Solid("compound", parts=tuple((solid(part.shape, scene_dir),
                                              _pose(orientation_matrix(part.orientation), part.offset))
                                             for part in shape.parts))
    raise TypeError(f"cannot draw shape {shape!r}")


def drawn_colliders(spec: SceneSpec, scene_dir: Path, times: np.ndarray) -> tuple[DrawnCollider, ...]:
    """The visible colliders as the renderer draws them, with the pose of each moving one at the frame ``times``."""
    drawn = []
    for collider in spec.colliders:
        if not collider.visible:
            continue
        track = None
        if collider.moves:
            from animbatch.compile.contacts import pose_path  # contact code only for scenes that need it

            path = pose_path(collider)
            track = FrameSeries(times, np.stack([path.matrix(float(t)) for t in times]))
        color = collider.color or None
        if isinstance(collider, PlaneCollider):
            normal = np.asarray(collider.normal, float) / np.linalg.norm(collider.normal)
            drawn.append(DrawnCollider(None, np.eye(4), normal, float(np.dot(collider.point, normal)),
                                       collider.size, color, track))
            continue
        if isinstance(collider, SphereCollider):
            shape = Solid("sphere", radius=float(collider.radius))
        elif isinstance(collider, BoxCollider):
            shape = Solid("box", size=(float(collider.size[0]), float(collider.size[1]), float(collider.size[2])))
        elif isinstance(collider, MeshCollider):
            shape = Solid("mesh", mesh=_triangles(load_surface(scene_dir / collider.file, collider.scale)))
        else:
            raise TypeError(f"cannot draw collider {collider!r}")
        turn = np.eye(3) if isinstance(collider, SphereCollider) else orientation_matrix(collider.orientation)
        drawn.append(DrawnCollider(shape, _pose(turn, collider.position), color=color, track=track))
    return tuple(drawn)


def particle_looks(items: list[EmitterSpec], emitters: tuple[Emitter, ...], particles: tuple[ParticleFrames, ...]
                   ) -> tuple[ParticleLook, ...]:
    """How each emitter's particles are drawn: its ``look`` and each particle's own lifetime, radius and colour, for
    every particle ``particles`` (the trajectory's frames of each emitter, if any) shows."""
    looks = []
    for index, (item, emitter) in enumerate(zip(items, emitters)):
        frames = particles[index] if index < len(particles) else None
        serials = (np.unique(frames.serials[frames.serials >= 0]).astype(np.int64) if frames is not None
                   else np.zeros(0, np.int64))
        lifetime, radius, color = emitter.looks(serials)
        look = item.look
        ramp = np.array([hex_to_rgb(c) for c in look.color]) if look.color else None
        looks.append(ParticleLook(emitter.name, emitter.capacity, look.style, int(look.trail),
                                  np.asarray(look.size, float), np.asarray(look.opacity, float), ramp,
                                  np.asarray(emitter.color_mean, float), serials, lifetime, radius, color))
    return tuple(looks)


def _pose(turn: np.ndarray, position: Any) -> np.ndarray:
    """The 4×4 transform that turns by ``turn`` (3, 3) and then moves by ``position`` (3,) [m]."""
    pose = np.eye(4)
    pose[:3, :3] = turn
    pose[:3, 3] = np.asarray(position, float)
    return pose


def _triangles(mesh: Any) -> TriangleMesh:
    return TriangleMesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.intp))
