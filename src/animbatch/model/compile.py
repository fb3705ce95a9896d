"""Compile a validated scene into a Model: names become indices, declared fields become force terms."""

from __future__ import annotations

from animbatch.model.builder import ModelBuilder
from animbatch.model.model import Model
from animbatch.scene.schema import SceneSpec


def compile_scene(spec: SceneSpec) -> Model:
    """The Model for a validated scene (cross-references were checked by the loader)."""
    builder = ModelBuilder()
    particle = {body.name: builder.add_particle(body.name, mass=body.mass, radius=body.radius,
                                                position=body.position, velocity=body.velocity)
                for body in spec.bodies}
    anchor = {a.name: builder.add_anchor(a.name, a.position) for a in spec.anchors}
    for spring in spec.springs:
        first, second = spring.between
        if first in anchor:  # the first end is always a particle
            first, second = second, first
        builder.add_spring(particle[first], anchor[second] if second in anchor else particle[second],
                           stiffness=spring.stiffness, damping=spring.damping, rest_length=spring.rest_length,
                           second_is_anchor=second in anchor, name=spring.name or "--".join(spring.between))
    for field in spec.fields:
        builder.add_field(field, None if field.bodies is None else [particle[name] for name in field.bodies])
    return builder.finalize(duration=spec.duration, fps=spec.fps)
