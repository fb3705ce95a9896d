"""Compile a validated scene into a Model: names become body handles, shapes become mass properties, declared fields
become force terms."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from animbatch.model.builder import ModelBuilder
from animbatch.model.model import Model
from animbatch.rigid.shapes import body_geometry, orientation_quaternion
from animbatch.scene.schema import RigidBodySpec, SceneSpec


def compile_scene(spec: SceneSpec, base_dir: str | Path = ".") -> Model:
    """The Model for a validated scene (cross-references were checked by the loader); ``base_dir`` resolves the
    scene's relative file names (mesh files), normally the scene file's folder."""
    builder = ModelBuilder(base_dir)
    handle: dict[str, int] = {}
    for body in spec.bodies:
        if isinstance(body, RigidBodySpec):
            handle[body.name] = builder.add_rigid_body(
                body.name, body_geometry(body, Path(base_dir)), position=body.position,
                orientation=orientation_quaternion(body.orientation), velocity=body.velocity,
                angular_velocity=body.angular_velocity, shape=body.shape)
        else:
            handle[body.name] = builder.add_particle(body.name, mass=body.mass, radius=body.radius,
                                                     position=body.position, velocity=body.velocity)
    anchor = {a.name: builder.add_anchor(a.name, a.position) for a in spec.anchors}
    for spring in spec.springs:
        first, second = spring.between
        first_point, second_point = spring.attach or (None, None)
        if first in anchor:  # the first end is always a body
            first, second = second, first
            first_point, second_point = second_point, first_point
        builder.add_spring(handle[first], anchor[second] if second in anchor else handle[second],
                           stiffness=spring.stiffness, damping=spring.damping, rest_length=spring.rest_length,
                           second_is_anchor=second in anchor, name=spring.name or "--".join(spring.between),
                           first_point=first_point, second_point=second_point)
    for field in spec.fields:
        builder.add_field(field, None if field.bodies is None else [handle[name] for name in field.bodies])
    model = builder.finalize(duration=spec.duration, fps=spec.fps)
    if not spec.has_contacts:
        return model
    from animbatch.contact.world import build_contact_world  # only scenes with contacts load contact code

    rigid = model.rigid
    centres = dict(zip(rigid.names, rigid.centre)) if rigid is not None else {}
    world, settings = build_contact_world(spec, model.body_names, centres, Path(base_dir))
    return replace(model, contact_world=world, contact_settings=settings)
