"""Generate the key reference of ``docs/scene-format.md`` from the schema, so the docs cannot drift from the code.

    python -m animbatch.scene.key_reference docs/scene-format.md    # rewrite the generated section in place
    python -m animbatch.scene.key_reference                         # print it

The section between the BEGIN/END markers is replaced; everything else in the file is hand-written.
"""

from __future__ import annotations

import sys
import types
import typing
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from animbatch.scene import schema
from animbatch.scene.annotations import field_metadata, tag_of, union_members

BEGIN = "<!-- BEGIN GENERATED REFERENCE (python -m animbatch.scene.key_reference docs/scene-format.md) -->"
END = "<!-- END GENERATED REFERENCE -->"

#: (heading, key path prefix used in the table, model), in the order they appear in the docs.
SECTIONS: list[tuple[str, str, type[BaseModel]]] = [
    ("Top level", "", schema.SceneSpec),
    ("`solver`", "solver.", schema.SolverSpec),
    ("`bodies[]` — `type: particle` (the default)", "bodies[].", schema.ParticleSpec),
    ("`bodies[]` — `type: rigid`", "bodies[].", schema.RigidBodySpec),
    *[(f"`shape` — `type: {tag_of(shape)}`", "shape.", shape)
      for shape in schema.SHAPES],
    ("`shape.parts[]` (compound)", "shape.parts[].", schema.CompoundPart),
    ("`orientation`", "orientation.", schema.OrientationSpec),
    ("`bodies[]` — `type: cloth`", "bodies[].", schema.ClothSpec),
    ("`bodies[]` — `type: lattice`", "bodies[].", schema.LatticeSpec),
    ("`grid` (cloth)", "grid.", schema.GridSpec),
    ("`mesh` (cloth)", "mesh.", schema.ClothMeshSpec),
    ("`structural`, `shear`, `bend` (cloth and lattices)", "structural.", schema.SpringFamilySpec),
    ("`dihedral` (cloth)", "dihedral.", schema.AngleSpringSpec),
    ("`pressure` (cloth and lattices)", "pressure.", schema.PressureSpec),
    ("`pressure.gauge[]` (keyframes)", "gauge[].", schema.PressureKeyframe),
    ("`pin[]` (cloth and lattices)", "pin[].", schema.PinSpec),
    ("`pin[].region`", "pin[].region.", schema.RegionSpec),
    ("`pin[].keyframes[]`", "pin[].keyframes[].", schema.OffsetKeyframeSpec),
    ("`anchors[]`", "anchors[].", schema.AnchorSpec),
    ("`anchors[].keyframes[]`, `target.keyframes[]`", "keyframes[].", schema.KeyframeSpec),
    *[(f"`joints[]` — `type: {tag_of(spec)}`", "joints[].", spec) for spec in schema.JOINT_SPECS],
    ("`joints[].motor` (hinge, slider)", "motor.", schema.MotorSpec),
    ("`joints[].motor.target[]` (keyframes)", "target[].", schema.MotorKeyframe),
    ("`springs[]`", "springs[].", schema.SpringSpec),
    ("`controllers[]`", "controllers[].", schema.ControllerSpec),
    *[(f"`controllers[].target` — `type: {tag_of(spec)}`", "target.", spec) for spec in schema.TARGET_SPECS],
    *[(f"`fields[]` — `type: {schema.field_type_names()[i]}`", "fields[].", spec)
      for i, spec in enumerate(schema.FIELD_SPECS)],
    ("`fields[].gust` (aerodynamics)", "gust.", schema.GustSpec),
    ("`fields[].keyframes[]` (electromagnetic)", "keyframes[].", schema.FieldKeyframeSpec),
    ("`clocks`", "clocks.", schema.ClocksSpec),
    ("`assignment`", "assignment.", schema.AssignmentSpec),
    ("`assignment.checks[]`", "checks[].", schema.CheckSpec),
    ("`assignment.partial_credit`", "partial_credit.", schema.PartialCreditSpec),
    ("`stopwatches[]`", "stopwatches[].", schema.StopwatchSpec),
    ("`stopwatches[].start`, `stopwatches[].stop`", "start.", schema.EventSpec),
    ("`emitters[]`", "emitters[].", schema.EmitterSpec),
    *[(f"`emitters[].source` — `type: {tag_of(spec)}`", "source.", spec) for spec in schema.SOURCE_SPECS],
    ("`emitters[].direction`", "direction.", schema.DirectionSpec),
    ("`emitters[].rate[]` (keyframes)", "rate[].", schema.RateKeyframe),
    ("`emitters[].bursts[]`", "bursts[].", schema.BurstSpec),
    ("Random attributes (`lifetime`, `speed`, `radius`, `mass`)", "lifetime.", schema.RandomValue),
    ("`emitters[].color` (random)", "color.", schema.RandomColor),
    ("`emitters[].look`", "look.", schema.ParticleLook),
    ("`materials.<name>`", "materials.<name>.", schema.MaterialSpec),
    ("`material_pairs[]`", "material_pairs[].", schema.MaterialPairSpec),
    *[(f"`colliders[]` — `type: {tag_of(spec)}`", "colliders[].", spec) for spec in schema.COLLIDER_SPECS],
    ("`colliders[].keyframes[]`, `bodies[].keyframes[]` (rigid)", "keyframes[].",
     schema.PoseKeyframeSpec),
    ("`colliders[].motion`, `bodies[].motion` (rigid)", "motion.", schema.MotionSpec),
    ("`colliders[].motion.oscillation`, `bodies[].motion.oscillation`", "motion.oscillation.",
     schema.OscillationSpec),
    ("`contacts`", "contacts.", schema.ContactSpec),
    ("`render`", "render.", schema.RenderSpec),
    ("`render.camera`", "render.camera.", schema.CameraSpec),
    ("`render.camera.keyframes[]`", "render.camera.keyframes[].", schema.CameraKeyframe),
    ("`render.camera.orbit`", "render.camera.orbit.", schema.OrbitSpec),
    ("`render.ground`", "render.ground.", schema.GroundSpec),
    ("`render.trails`", "render.trails.", schema.TrailSpec),
    ("`render.arrows`", "render.arrows.", schema.ArrowSpec),
    ("`render.energy_panel`", "render.energy_panel.", schema.EnergyPanelSpec),
    ("`render.video`", "render.video.", schema.VideoSpec),
    ("`study`", "study.", schema.StudySpec),
    ("`study.reference`", "study.reference.", schema.StudyReferenceSpec),
]


def type_text(field: FieldInfo) -> str:
    """A short, user-facing type: 'number', '[x, y, z]', 'colour', 'one of: a, b', 'list of names', …"""
    parts = []
    for member in union_members(field.annotation, keep_none=True):
        if member is type(None):
            continue
        parts.append(_one_type(member, field))
    nullable = " or null" if type(None) in union_members(field.annotation, keep_none=True) else ""
    return " or ".join(dict.fromkeys(parts)) + nullable


def _one_type(annotation: Any, field: FieldInfo) -> str:
    metadata = list(getattr(annotation, "__metadata__", ())) + list(field.metadata)
    base = annotation.__origin__ if typing.get_origin(annotation) is typing.Annotated else annotation
    if base is float:
        return "number"
    if base is int:
        return "integer"
    if base is bool:
        return "true/false"
    if base is str:
        nested = [inner for m in metadata for inner in getattr(m, "metadata", ())]  # Field(...) inside Annotated
        if any(getattr(m, "pattern", None) == schema.NAME_PATTERN for m in metadata + nested):
            return "name"
        if any("PlainValidator" in type(m).__name__ for m in metadata):
            return "colour"
        return "text"
    if typing.get_origin(base) is typing.Literal:
        return "one of: " + ", ".join(f"`{v}`" for v in typing.get_args(base))
    if typing.get_origin(base) is list:
        (item,) = typing.get_args(base)
        lengths = [m for m in metadata if isinstance(m, at.Len)]
        if base == list[float] and lengths and (lengths[0].min_length, lengths[0].max_length) == (3, 3):
            return "[x, y, z]"
        inner = _one_type(item, FieldInfo(annotation=item))
        count = f"{lengths[0].min_length} " if lengths and lengths[0].min_length == lengths[0].max_length else ""
        if " or " in inner:
            return f"list of {count}items (each {inner})"
        if inner.startswith("one of"):
            return f"list of {count}items, each {inner}"
        noun, _, qualifier = inner.partition(" (")
        return f"list of {count}{noun}s" + (f" ({qualifier}" if qualifier else "")
    if typing.get_origin(base) is dict:
        _, value = typing.get_args(base)
        return f"mapping of name → {value.__name__.removesuffix('Spec').lower()}"
    if isinstance(base, type) and issubclass(base, BaseModel):
        return "mapping"
    if typing.get_origin(base) in (typing.Union, types.UnionType):
        members = [m for m in typing.get_args(base) if m is not type(None)]
        models = [m.__origin__ if typing.get_origin(m) is typing.Annotated else m for m in members]
        if all(isinstance(m, type) and issubclass(m, BaseModel) for m in models):  # a discriminated union
            return "mapping (by `type`)"
        nullable = " or null" if type(None) in typing.get_args(base) else ""
        return " or ".join(dict.fromkeys(_one_type(m, FieldInfo(annotation=m)) for m in members)) + nullable
    return str(base)


_BOUNDS = ((at.Gt, ">", "gt"), (at.Ge, "≥", "ge"), (at.Lt, "<", "lt"), (at.Le, "≤", "le"))


def _bounds(items: list[Any], prefix: str = "") -> list[str]:
    return [f"{prefix}{symbol} {getattr(item, attribute):g}" for item in items for kind, symbol, attribute in _BOUNDS
            if isinstance(item, kind)]


def limits_text(field: FieldInfo) -> str:
    """Numeric limits of a key, and of each item for lists of bounded numbers."""
    found = _bounds(field_metadata(field))
    for member in union_members(field.annotation, keep_none=True):
        if typing.get_origin(member) is list:
            (item,) = typing.get_args(member)
            for constraint in getattr(item, "__metadata__", ()):
                found += _bounds(list(getattr(constraint, "metadata", ())), "each ")
    return ", ".join(found)


def default_text(field: FieldInfo) -> str:
    if field.default is PydanticUndefined:
        return "**required**"
    value = field.default
    if value is None:
        return "—"
    if isinstance(value, BaseModel):
        return "(defaults)"
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f"`{value}`" if value else '`""`'
    if isinstance(value, list):
        return "`[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value) + "]`" if value else "`[]`"
    return f"`{value:g}`" if isinstance(value, float) else f"`{value}`"


def unit_text(field: FieldInfo) -> str:
    extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
    unit = extra.get("unit")
    return "—" if unit in (None, "1") else str(unit)


def reachable_models(root: type[BaseModel] = schema.SceneSpec) -> set[type[BaseModel]]:
    """Every schema model a scene file can contain, found by walking the field annotations from ``root``."""
    found: set[type[BaseModel]] = set()
    pending = [root]
    while pending:
        model = pending.pop()
        if model in found:
            continue
        found.add(model)
        for field in model.model_fields.values():
            pending += [member for member in _nested_types(field.annotation)
                        if isinstance(member, type) and issubclass(member, BaseModel)]
    return found


def _nested_types(annotation: Any) -> Iterator[Any]:
    """The annotation and every type inside it (Annotated, unions, lists, dicts)."""
    yield annotation
    for argument in typing.get_args(annotation):
        yield from _nested_types(argument)
    for item in getattr(annotation, "__metadata__", ()):
        if isinstance(item, type):
            yield item


def key_paths() -> Iterator[str]:
    """Every documented key path, e.g. ``bodies[].mass`` or ``render.camera.up``."""
    for _, prefix, model in SECTIONS:
        for name in model.model_fields:
            yield f"{prefix}{name}"


def generate() -> str:
    lines = [BEGIN, "", "## Key reference", "",
             "Generated from the schema (`src/animbatch/scene/schema/`). Units are SI; '—' means none.", ""]
    for heading, prefix, model in SECTIONS:
        lines += [f"### {heading}", "", " ".join((model.__doc__ or "").split()), "",
                  "| key | type | unit | default | limits | meaning |", "|---|---|---|---|---|---|"]
        fields = sorted(model.model_fields.items(), key=lambda item: item[0] != "type")  # 'type' first
        for name, field in fields:
            description = (field.description or "").replace("|", "\\|")
            lines.append(f"| `{prefix}{name}` | {type_text(field)} | {unit_text(field)} | {default_text(field)} | "
                         f"{limits_text(field)} | {description} |")
        lines.append("")
    lines.append(END)
    return "\n".join(lines)


def replace_section(text: str, generated: str) -> str:
    if BEGIN not in text or END not in text:
        raise ValueError("the document has no generated-reference markers")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return head + generated + tail


def main(argv: list[str]) -> int:
    if not argv:
        print(generate())
        return 0
    path = Path(argv[0])
    path.write_text(replace_section(path.read_text(encoding="utf-8"), generate()), encoding="utf-8")
    print(f"updated the generated reference in {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
