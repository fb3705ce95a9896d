"""Compile a validated scene into a Model: names become body handles, shapes become mass properties, declared fields
become force terms."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.compile import deformables as build
from animbatch.compile.bodies import body_geometry, orientation_matrix, orientation_quaternion
from animbatch.compile.forces import field_term
from animbatch.curves import ParametricCurve, Polyline
from animbatch.scene.schema import (
    CHARGED_FIELD_TYPES,
    CONTACT_METHODS,
    DEFORMABLE_SPECS,
    AnchorSpec,
    ClothSpec,
    LatticeSpec,
    RigidBodySpec,
    SceneSpec,
)
from animbatch.sim.forces.controllers import ControllerSetting, CurveTarget, FixedTarget, PathTarget, Target
from animbatch.sim.joints import MotorTarget
from animbatch.sim.joints.assembly import MotorSetting
from animbatch.sim.model.builder import ModelBuilder, Pin, SelfCollisionSetting
from animbatch.sim.model.model import Model
from animbatch.sim.motion import KeyframePath, KinematicBodies


def compile_scene(spec: SceneSpec, base_dir: str | Path = ".") -> Model:
    """The Model for a validated scene (cross-references were checked by the loader); ``base_dir`` resolves the
    scene's relative file names (mesh files), normally the scene file's folder."""
    builder = ModelBuilder()
    handles: dict[str, list[int]] = {}
    for body in spec.bodies:
        if isinstance(body, RigidBodySpec):
            handles[body.name] = [builder.add_rigid_body(
                body.name, body_geometry(body, Path(base_dir)), position=body.position,
                orientation=tuple(orientation_quaternion(body.orientation)), velocity=body.velocity,
                angular_velocity=body.angular_velocity)]
        elif not isinstance(body, DEFORMABLE_SPECS):
            handles[body.name] = [builder.add_particle(body.name, mass=body.mass, radius=body.radius,
                                                       position=body.position, velocity=body.velocity)]
    for body in spec.bodies:  # after the rigid bodies, which pins may attach to
        if isinstance(body, DEFORMABLE_SPECS):
            handles[body.name] = list(_add_deformable(builder, body, handles, Path(base_dir), spec))
    anchor = {a.name: builder.add_anchor(a.name, a.start, path=_anchor_path(a)) for a in spec.anchors}
    for spring in spec.springs:
        first, second = spring.between
        first_point, second_point = spring.attach or (None, None)
        if first in anchor:  # the first end is always a body
            first, second = second, first
            first_point, second_point = second_point, first_point
        builder.add_spring(handles[first][0], anchor[second] if second in anchor else handles[second][0],
                           stiffness=spring.stiffness, damping=spring.damping, rest_length=spring.rest_length,
                           second_is_anchor=second in anchor, name=spring.name or "--".join(spring.between),
                           first_point=first_point, second_point=second_point)
    for joint in spec.joints:
        _add_joint(builder, joint, handles, anchor)
    for controller in spec.controllers:
        builder.add_controller(handles[controller.body][0], ControllerSetting(
            controller.stiffness, controller.damping, controller_target(controller.target),
            None if controller.point is None else np.asarray(controller.point, float), controller.name))
    charges = {body.name: float(getattr(body, "charge", 0.0)) for body in spec.bodies
               if getattr(body, "charge", 0.0)}  # particles and rigid bodies carry charges
    for field in spec.fields if handles else ():  # a scene of emitters only has no body to act on
        if field.type in CHARGED_FIELD_TYPES:  # only the charged bodies feel it
            chosen = [name for name in (field.bodies or handles) if name in charges]
            builder.add_field(field_term(field, charges), [handle for name in chosen for handle in handles[name]])
            continue
        if field.bodies is None:
            builder.add_field(field_term(field))
            continue
        chosen = [name for name in field.bodies if name in handles]  # the others are emitters
        if chosen:
            builder.add_field(field_term(field), [handle for name in chosen for handle in handles[name]])
    if spec.clocks is not None:  # only then does the state carry proper times
        carriers = spec.clocks.bodies if spec.clocks.bodies is not None else [
            body.name for body in spec.bodies if body.type in ("particle", "rigid")]
        builder.add_clocks([handles[name][0] for name in carriers], c=spec.clocks.c)
    model = builder.finalize(duration=spec.duration, fps=spec.fps, matrices=spec.solver.orientation == "matrix",
                             renormalise_every=spec.solver.renormalise_every)
    kinematic = kinematic_bodies(spec, model)
    if kinematic is not None:  # bodies on keyframes start where their paths do
        model = replace(model, kinematic=kinematic, y0=model.y0.copy())
        model.prescribe(model.y0, float(model.frame_times[0]))
        model.y0.setflags(write=False)
    if not spec.has_contacts:
        return model
    from animbatch.compile.contacts import build_contact_world  # only scenes with contacts load contact code

    rigid = model.rigid
    centres = dict(zip(rigid.names, rigid.centre)) if rigid is not None else {}
    world, settings = build_contact_world(spec, model, centres, Path(base_dir))
    return replace(model, contact_world=world, contact_settings=settings)


def kinematic_bodies(spec: SceneSpec, model: Model) -> KinematicBodies | None:
    """The rigid bodies on keyframes: each one's path about its position, its rest orientation and its centre of
    mass from its position (world axes, at rest); None when there are none."""
    from animbatch.compile.contacts import pose_path

    moving = [body for body in spec.bodies if isinstance(body, RigidBodySpec) and body.moves]
    if not moving:
        return None
    rigid = model.rigid
    assert rigid is not None
    index = [rigid.names.index(body.name) for body in moving]
    rest = np.array([orientation_matrix(body.orientation) for body in moving])
    lever = np.einsum("kij,kj->ki", rest, rigid.centre[index])
    return KinematicBodies(np.array(index, np.intp), tuple(pose_path(body) for body in moving), rest, lever)


def controller_target(spec: Any) -> Target:
    """The target of a controller's ``target`` spec: a point, keyframes, a polyline or a parametric curve."""
    if spec.type == "point":
        return FixedTarget(np.asarray(spec.position, float))
    if spec.type == "keyframes":
        return PathTarget(KeyframePath(np.array([k.time for k in spec.keyframes], float),
                                       np.array([k.position for k in spec.keyframes], float), spec.interpolation))
    if spec.type == "polyline":
        return CurveTarget(Polyline.through(np.asarray(spec.points, float), spec.closed),
                           "closed polyline" if spec.closed else "polyline")
    curve = ParametricCurve((spec.x, spec.y, spec.z), spec.range[0], spec.range[1], spec.closed, spec.samples)
    return CurveTarget(curve, f"curve ({spec.x}, {spec.y}, {spec.z}), s in [{spec.range[0]:g}, {spec.range[1]:g}]")


def _anchor_path(anchor: AnchorSpec) -> KeyframePath | None:
    keyframes = anchor.keyframes
    if keyframes is None:
        return None
    return KeyframePath(np.array([k.time for k in keyframes], float), np.array([k.position for k in keyframes], float),
                        anchor.interpolation)


def _add_deformable(builder: ModelBuilder, body: ClothSpec | LatticeSpec, handles: dict[str, list[int]],
                    base_dir: Path, spec: SceneSpec) -> np.ndarray:
    """Add a cloth or lattice: its topology, vertex masses, pins and spring families."""
    topology = build.body_topology(body, base_dir)
    world = build.world_vertices(body, topology)
    pins = []
    for pin in body.pin:
        vertices, problems = build.pin_vertices(pin, topology, world)
        if problems:  # the loader reports these with file positions; reaching here means a Python caller
            raise ValueError(f"{body.name}: {'; '.join(problems)}")
        pins.append(Pin(vertices, build.pin_path(pin), handles[pin.to][0] if pin.to is not None else None))
    dihedral = body.dihedral if isinstance(body, ClothSpec) else None
    return builder.add_deformable(
        body.name, body.type, topology, masses=build.vertex_masses(body, topology),
        position=body.position, rotation=orientation_matrix(body.orientation),
        velocity=body.velocity, radius=body.radius, springs=build.spring_families(body),
        pins=pins, dihedral=(dihedral.stiffness, dihedral.damping) if dihedral is not None else None,
        pressure=build.pressure_setting(body.pressure) if body.pressure is not None else None,
        self_collision=_self_collision(body, spec))


def _self_collision(body: ClothSpec | LatticeSpec, spec: SceneSpec) -> SelfCollisionSetting | None:
    """The body's self-collision (None: off): on by default for a cloth that collides, where the method applies
    it; its friction is its material's against itself."""
    on = body.self_collision
    if on is None:
        on = isinstance(body, ClothSpec) and body.collide and spec.solver.method in CONTACT_METHODS
    if not on:
        return None
    from animbatch.compile.contacts import material_table

    friction = material_table(spec).pair(body.material, body.material).kinetic_friction
    return SelfCollisionSetting(body.thickness, friction)


def _add_joint(builder: ModelBuilder, joint: Any, handles: dict[str, list[int]], anchor: dict[str, int]) -> None:
    """One scene joint into the builder: names become handles (anchors: the world at that point)."""
    ends = list(joint.between)
    attach = list(getattr(joint, "attach", None) or (None, None))
    if joint.type in ("distance", "rope") and ends[0] in anchor:  # the first end is always a body
        ends.reverse()
        attach.reverse()
    first = handles[ends[0]][0]
    second = ends[1] if len(ends) == 2 else None
    motor = getattr(joint, "motor", None)
    builder.add_joint(
        joint.type, first, None if second is None else anchor[second] if second in anchor else handles[second][0],
        second_is_anchor=second in anchor, anchor=getattr(joint, "anchor", None),
        attach=(attach[0], attach[1]), axis=getattr(joint, "axis", None), length=getattr(joint, "length", None),
        limits=None if getattr(joint, "limits", None) is None else tuple(joint.limits),
        motor=None if motor is None else _motor(motor),
        over=(anchor[joint.over[0]], anchor[joint.over[1]]) if joint.type == "pulley" else None,
        name=joint.name or "--".join(joint.between))


def _motor(motor: Any) -> MotorSetting:
    """A scene motor as the builder takes it: its target as keyframes in x, and its effort limit."""
    target = motor.target
    path = None
    if isinstance(target, (int, float)):
        path = KeyframePath(np.zeros(1), np.array([[float(target), 0.0, 0.0]]))
    elif target is not None:
        path = KeyframePath(np.array([key.time for key in target]),
                            np.array([[key.value, 0.0, 0.0] for key in target]), motor.interpolation)
    limit = motor.max_torque if motor.max_torque is not None else motor.max_force
    return MotorSetting(MotorTarget(path, motor.speed), motor.stiffness, motor.damping,
                        np.inf if limit is None else limit)
