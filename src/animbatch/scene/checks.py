"""Checks that need the whole scene: names that must exist or be unique.

They read the raw loaded data rather than the validated model, so that they run even when other keys are invalid
and ``animbatch validate`` reports every problem of a file at once. Anything malformed is skipped here: the schema
reports it. Rules that concern one item only (a drag law and its coefficient, say) live in the schema's validators.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from animbatch.materials import BUILT_IN
from animbatch.scene.diagnostics import did_you_mean
from animbatch.scene.schema import CHARGED_FIELD_TYPES, PARTICLE_FIELD_TYPES, label_names, label_speed_names
from animbatch.scene.yaml_source import KeyPath, format_path

Problem = tuple[KeyPath, str]


def check_references(data: dict[str, Any]) -> list[Problem]:
    """Every cross-reference problem in raw scene data, as ``(key path, message)``."""
    bodies = _names(data, "bodies")
    anchors = _names(data, "anchors")
    emitters = _names(data, "emitters")
    rigid = _of_type(data, ("rigid",))
    deformable = _of_type(data, DEFORMABLE_TYPES)
    return [*_body_list(data), *_duplicate_names(data), *_springs(data, bodies, anchors, rigid, deformable),
            *_joints(data, bodies, anchors, rigid, deformable),
            *_fields(data, bodies, anchors, rigid, deformable, emitters), *_pins(data, bodies, rigid),
            *_controllers(data, bodies, rigid, deformable), *_emitters(data, bodies, rigid), *_materials(data),
            *_trails(data, bodies, deformable), *_label(data, bodies), *_stopwatches(data, bodies, deformable),
            *_clocks(data, bodies, deformable), *_assignment(data, bodies, emitters)]


#: Body types made of many vertices (each a particle in the model).
DEFORMABLE_TYPES = ("cloth", "lattice")


def _of_type(data: dict[str, Any], types: tuple[str, ...]) -> set[str]:
    return {name for _, item in _items(data, "bodies") if item.get("type") in types
            for name in [item.get("name")] if isinstance(name, str)}


#: Field types that act on rigid bodies only.
RIGID_ONLY_FIELDS = ("torque", "angular_drag")


def _items(data: dict[str, Any], section: str) -> list[tuple[int, dict[str, Any]]]:
    items = data.get(section)
    return [(i, item) for i, item in enumerate(items) if isinstance(item, dict)] if isinstance(items, list) else []


def _names(data: dict[str, Any], section: str) -> dict[str, KeyPath]:
    """Name -> path of its first use, for the named items of a section."""
    names: dict[str, KeyPath] = {}
    for index, item in _items(data, section):
        if isinstance(item.get("name"), str):
            names.setdefault(item["name"], (section, index, "name"))
    return names


def _strings(items: list[Any]) -> list[tuple[int, str]]:
    """(position, name) of the text items of a list of names; anything else is the schema's to report."""
    return [(position, name) for position, name in enumerate(items) if isinstance(name, str)]


def _body_list(data: dict[str, Any]) -> Iterator[Problem]:
    if data.get("bodies") in (None, []) and data.get("emitters") in (None, []):
        yield ("bodies",), "a scene needs at least one body (a list under 'bodies:') or emitter ('emitters:')"


def _pairs(data: dict[str, Any], section: str) -> Iterator[tuple[int, dict[str, Any], list[str]]]:
    """The items of ``section`` (springs, joints) whose ``between`` names one or two ends, with those names."""
    for index, item in _items(data, section):
        ends = item.get("between")
        if isinstance(ends, list) and len(ends) in (1, 2) and all(isinstance(e, str) for e in ends):
            yield index, item, ends


def _unknown_ends(section: str, index: int, ends: list[str], bodies: dict[str, KeyPath],
                  anchors: dict[str, KeyPath]) -> Iterator[Problem]:
    """Ends that name no body or anchor (with 'did you mean'), and two anchors joined to each other."""
    known = sorted(bodies.keys() | anchors.keys())
    for end, name in enumerate(ends):
        if name not in bodies and name not in anchors:
            yield (section, index, "between", end), (
                f"unknown body or anchor {name!r}{did_you_mean(name, known)} Known: {', '.join(known) or '(none)'}")
    if len(ends) == 2 and ends[0] != ends[1] and ends[0] in anchors and ends[1] in anchors:
        what = "spring" if section == "springs" else "joint"
        yield (section, index, "between"), (f"both ends ({ends[0]!r}, {ends[1]!r}) are anchors; a {what} needs "
                                            "at least one body")


def _springs(data: dict[str, Any], bodies: dict[str, KeyPath], anchors: dict[str, KeyPath],
             rigid: set[str], deformable: set[str]) -> Iterator[Problem]:
    for index, spring, ends in _pairs(data, "springs"):
        yield from _unknown_ends("springs", index, ends, bodies, anchors)
        for end, name in enumerate(ends):
            if name in deformable:
                yield ("springs", index, "between", end), (
                    f"{name!r} is a cloth or lattice, made of many vertices; a spring joins one point to another. "
                    "Attach its vertices to a body or anchor with its 'pin' key instead")
        yield from _attach_points("springs", index, ends, spring.get("attach"), bodies, anchors, rigid)


def _attach_points(section: str, index: int, ends: list[str], attach: Any, bodies: dict[str, KeyPath],
                   anchors: dict[str, KeyPath], rigid: set[str]) -> Iterator[Problem]:
    """Attachment points (``attach``) are given only for the ends that are rigid bodies."""
    if not isinstance(attach, list):
        return
    for end, (name, point) in enumerate(zip(ends, attach)):
        if point is not None and name not in rigid and (name in bodies or name in anchors):
            kind = "an anchor" if name in anchors else "a particle"
            yield (section, index, "attach", end), (
                f"{name!r} is {kind}, which has no body points; use null for this end (attachment points are for "
                "rigid bodies)")


def _joints(data: dict[str, Any], bodies: dict[str, KeyPath], anchors: dict[str, KeyPath],
            rigid: set[str], deformable: set[str]) -> Iterator[Problem]:
    """Joints join bodies of the scene (rigid ones where orientations are held), fixed anchors and the world."""
    moving = {item.get("name") for _, item in _items(data, "anchors") if item.get("keyframes")}
    kinematic = {item.get("name") for _, item in _items(data, "bodies")
                 if item.get("keyframes") or item.get("motion")}
    for index, joint, ends in _pairs(data, "joints"):
        kind = joint.get("type")
        yield from _unknown_ends("joints", index, ends, bodies, anchors)
        for end, name in enumerate(ends):
            if name in kinematic:
                yield ("joints", index, "between", end), (
                    f"{name!r} is kinematic (keyframes or motion); joints to such a body are not supported yet. Join "
                    "to an anchor on keyframes (anchors: [{name, keyframes: [{time, position}]}]) that follows it "
                    "instead")
            if name in deformable:
                yield ("joints", index, "between", end), (
                    f"{name!r} is a cloth or lattice, made of many vertices; joints join bodies. Attach its "
                    "vertices to a body or anchor with its 'pin' key instead")
            elif kind in ("hinge", "slider", "fixed") and name in bodies and name not in rigid:
                yield ("joints", index, "between", end), (
                    f"{name!r} is a particle, which has no orientation for a {kind} joint to hold; join it with a "
                    "ball or distance joint, or make it a rigid body (type: rigid)")
        if kind in ("ball", "hinge", "slider", "fixed") and ends[0] in anchors:
            yield ("joints", index, "between", 0), (
                f"{ends[0]!r} is an anchor; put the body first: between: [body] joins it to the world, "
                "[body, anchor] to an anchor, [body, other body] to another body")
        if kind in ("distance", "rope", "pulley") and len(ends) != 2:
            yield ("joints", index, "between"), f"a {kind} joint has two ends; between: [first, second]"
        if len(ends) == 2 and ends[0] == ends[1]:
            yield ("joints", index, "between"), f"both ends are {ends[0]!r}; a joint joins two different bodies"
        yield from _attach_points("joints", index, ends, joint.get("attach"), bodies, anchors, rigid)
    for index, joint in _items(data, "joints"):
        if joint.get("type") != "pulley":
            continue
        for position, name in _strings(joint.get("between") or []):
            if name in anchors:
                yield ("joints", index, "between", position), (
                    f"{name!r} is an anchor; a pulley's rope ends at bodies (the anchors go under 'over')")
        for position, name in _strings(joint.get("over") or []):
            if name not in anchors:
                known = sorted(anchors)
                yield ("joints", index, "over", position), (
                    f"unknown anchor {name!r}{did_you_mean(name, known)} The rope runs over fixed anchors: "
                    f"{', '.join(known) or '(none: declare them under anchors:)'}")
            elif name in moving:
                yield ("joints", index, "over", position), (f"anchor {name!r} follows keyframes; pulleys are "
                                                            "fixed so far")


def _fields(data: dict[str, Any], bodies: dict[str, KeyPath], anchors: dict[str, KeyPath],
            rigid: set[str], deformable: set[str], emitters: dict[str, KeyPath]) -> Iterator[Problem]:
    cloths = _of_type(data, ("cloth",))
    charges = _charges(data)
    for index, field in _items(data, "fields"):
        selection = field.get("bodies")
        if isinstance(selection, list):
            for position, name in _strings(selection):
                if name in emitters and name not in bodies and field.get("type") not in PARTICLE_FIELD_TYPES:
                    yield ("fields", index, "bodies", position), (
                        f"{name!r} is an emitter; {field.get('type')} does not act on emitted particles (only "
                        f"{', '.join(PARTICLE_FIELD_TYPES)} do)")
        if field.get("type") == "aerodynamics":
            if isinstance(selection, list):
                for position, name in _strings(selection):
                    if name in bodies and name not in cloths:
                        yield ("fields", index, "bodies", position), (
                            f"{name!r} is not a cloth: aerodynamics acts on the faces of cloths (use a wind or drag "
                            "field for other bodies)")
            elif not cloths:
                yield ("fields", index, "type"), "aerodynamics acts on cloths, and the scene has none"
        if field.get("type") in RIGID_ONLY_FIELDS:
            if isinstance(selection, list):
                for position, name in _strings(selection):
                    if name in bodies and name not in rigid:
                        kind = "a cloth or lattice" if name in deformable else "a particle"
                        yield ("fields", index, "bodies", position), (
                            f"{name!r} is {kind}, which cannot turn: {field['type']} acts on rigid bodies only")
            elif not rigid:
                yield ("fields", index, "type"), f"{field['type']} acts on rigid bodies, and the scene has none"
        if isinstance(selection, list):
            for position, name in _strings(selection):
                if not isinstance(name, str) or name in bodies or name in emitters:
                    continue
                known = [*bodies, *emitters]
                if name in anchors:
                    reason = " (it is an anchor; fields act on bodies only)"
                else:
                    reason = did_you_mean(name, known)
                yield ("fields", index, "bodies", position), (
                    f"unknown body or emitter {name!r}{reason} Bodies and emitters: {', '.join(known) or '(none)'}")
        if field.get("type") == "gravitation":
            count = len(selection) if isinstance(selection, list) else len(bodies)
            if count < 2:
                yield ("fields", index, "bodies" if isinstance(selection, list) else "type"), (
                    f"gravitation acts between bodies and needs at least 2 (got {count})")
        if field.get("type") in CHARGED_FIELD_TYPES:
            yield from _charged(field, index, charges)


def _charges(data: dict[str, Any]) -> dict[str, float]:
    """Name -> charge [C] of the bodies that give a numeric charge."""
    return {item["name"]: float(item["charge"]) for _, item in _items(data, "bodies")
            if isinstance(item.get("name"), str) and isinstance(item.get("charge"), int | float)
            and not isinstance(item.get("charge"), bool)}


def _charged(field: dict[str, Any], index: int, charges: dict[str, float]) -> Iterator[Problem]:
    """An electromagnetic field acts on at least one charged body, Coulomb's law between at least two."""
    kind, selection = field["type"], field.get("bodies")
    chosen = [n for n in selection if isinstance(n, str)] if isinstance(selection, list) else list(charges)
    charged = [name for name in chosen if charges.get(name, 0.0) != 0.0]
    needed = 2 if kind == "coulomb" else 1
    if len(charged) < needed:
        where = ("fields", index, "bodies") if isinstance(selection, list) else ("fields", index, "type")
        have = f"only {charged[0]!r} has one" if charged else "none has one"
        yield where, (f"{kind} acts on charged bodies and needs at least {needed}: of the bodies it acts on, {have}. "
                      "Give bodies a charge, e.g. 'charge: 1.0e-6' (coulombs)")


def _emitters(data: dict[str, Any], bodies: dict[str, KeyPath], rigid: set[str]) -> Iterator[Problem]:
    """An emitter moves with a rigid body, if any."""
    for index, emitter in _items(data, "emitters"):
        name = emitter.get("body")
        if isinstance(name, str) and name not in rigid:
            reason = (" (it is not a rigid body: emitters move with rigid bodies, whose surface and turning they "
                      "follow)" if name in bodies else did_you_mean(name, sorted(rigid)))
            yield ("emitters", index, "body"), (
                f"unknown rigid body {name!r}{reason} Rigid bodies: {', '.join(sorted(rigid)) or '(none)'}")


def _label(data: dict[str, Any], bodies: dict[str, KeyPath]) -> Iterator[Problem]:
    """A text overlay's ``{speed[NAME]}`` names a body of the scene."""
    render = data.get("render")
    label = render.get("time_label") if isinstance(render, dict) else None
    if not isinstance(label, str):
        return
    try:
        names = label_speed_names(label)
    except ValueError:
        return  # a malformed format string: the schema reports it
    for name in names:
        if name not in bodies:
            yield ("render", "time_label"), (f"{{speed[{name}]}}: unknown body {name!r}"
                                             f"{did_you_mean(name, sorted(bodies)) or '.'} Bodies: "
                                             f"{', '.join(sorted(bodies)) or '(none)'}")
    watches = sorted(_names(data, "stopwatches"))
    for name in label_names(label, "stopwatch"):
        if name not in watches:
            yield ("render", "time_label"), (f"{{stopwatch[{name}]}}: unknown stopwatch {name!r}"
                                             f"{did_you_mean(name, watches) or '.'} Stopwatches: "
                                             f"{', '.join(watches) or '(none: declare them under stopwatches:)'}")


def _clocks(data: dict[str, Any], bodies: dict[str, KeyPath], deformable: set[str]) -> Iterator[Problem]:
    """Clocks are carried by particles and rigid bodies of the scene; the overlay's ``{proper_time[NAME]}`` names
    one that carries a clock."""
    clocks = data.get("clocks")
    carriers = [name for name in bodies if name not in deformable]
    if isinstance(clocks, dict) and isinstance(clocks.get("bodies"), list):
        for position, name in _strings(clocks["bodies"]):
            if name in deformable:
                yield ("clocks", "bodies", position), (
                    f"{name!r} is a cloth or lattice, which has no one velocity to time: name a particle or rigid body")
            elif name not in bodies:
                yield ("clocks", "bodies", position), (f"unknown body {name!r}{did_you_mean(name, carriers) or '.'} "
                                                       f"Bodies: {', '.join(carriers) or '(none)'}")
        carriers = [n for n in clocks["bodies"] if isinstance(n, str)]
    render = data.get("render")
    label = render.get("time_label") if isinstance(render, dict) else None
    if not isinstance(label, str):
        return
    try:
        names = label_names(label, "proper_time")
    except ValueError:
        return  # a malformed format string: the schema reports it
    for name in names:
        if not isinstance(clocks, dict):
            yield ("render", "time_label"), (f"{{proper_time[{name}]}}: no body carries a clock; add 'clocks: {{}}' "
                                             "(every particle and rigid body) or 'clocks: {bodies: [" + name + "]}'")
        elif name not in carriers:
            yield ("render", "time_label"), (f"{{proper_time[{name}]}}: {name!r} carries no clock"
                                             f"{did_you_mean(name, carriers) or '.'} Clocks: "
                                             f"{', '.join(carriers) or '(none)'}")


def _assignment(data: dict[str, Any], bodies: dict[str, KeyPath], emitters: dict[str, KeyPath]) -> Iterator[Problem]:
    """An assignment's checks name bodies (or, for field checks, emitters) and stopwatches of the scene."""
    assignment = data.get("assignment")
    checks = assignment.get("checks") if isinstance(assignment, dict) else None
    if not isinstance(checks, list):
        return
    watches = sorted(_names(data, "stopwatches"))
    for index, check in enumerate(checks):
        if not isinstance(check, dict):
            continue
        body, watch = check.get("body"), check.get("stopwatch")
        known = [*bodies, *emitters] if check.get("quantity") == "field" else list(bodies)
        if isinstance(body, str) and body not in known:
            yield ("assignment", "checks", index, "body"), (
                f"unknown body {body!r}{did_you_mean(body, known) or '.'} Bodies: {', '.join(known) or '(none)'}")
        if isinstance(watch, str) and watch not in watches:
            yield ("assignment", "checks", index, "stopwatch"), (
                f"unknown stopwatch {watch!r}{did_you_mean(watch, watches) or '.'} Stopwatches: "
                f"{', '.join(watches) or '(none: declare them under stopwatches:)'}")


def _stopwatches(data: dict[str, Any], bodies: dict[str, KeyPath], deformable: set[str]) -> Iterator[Problem]:
    """A stopwatch event's body is a particle or rigid body of the scene."""
    for index, watch in _items(data, "stopwatches"):
        for which in ("start", "stop"):
            event = watch.get(which)
            name = event.get("body") if isinstance(event, dict) else None
            if not isinstance(name, str):
                continue
            if name in deformable:
                yield ("stopwatches", index, which, "body"), (
                    f"{name!r} is a cloth or lattice, which has no one centre to follow: name a particle or rigid body")
            elif name not in bodies:
                yield ("stopwatches", index, which, "body"), (
                    f"unknown body {name!r}{did_you_mean(name, sorted(bodies)) or '.'} Bodies: "
                    f"{', '.join(sorted(bodies)) or '(none)'}")


def _trails(data: dict[str, Any], bodies: dict[str, KeyPath], deformable: set[str]) -> Iterator[Problem]:
    """Trails, arrows and followed cameras track particles and rigid bodies (a cloth has no one point to follow)."""
    render = data.get("render")
    if not isinstance(render, dict):
        return
    wanted: list[tuple[tuple[str | int, ...], str]] = []  # (key path, body name)
    for section in ("trails", "arrows"):
        block = render.get(section)
        names = block.get("bodies") if isinstance(block, dict) else None
        wanted += [(("render", section, "bodies", position), name)
                   for position, name in (_strings(names) if isinstance(names, list) else [])]
    cameras = render.get("cameras")
    for path, camera in [(("render", "camera"), render.get("camera")),
                         *[(("render", "cameras", name), camera)
                           for name, camera in (cameras.items() if isinstance(cameras, dict) else [])]]:
        name = camera.get("follow") if isinstance(camera, dict) else None
        if isinstance(name, str):
            wanted.append(((*path, "follow"), name))
    followable = sorted(set(bodies) - deformable)
    for path, name in wanted:
        if name not in followable:
            reason = (" (a cloth or lattice has no one point to follow; give one of its pinned bodies instead)"
                      if name in deformable else did_you_mean(name, followable) or ".")
            yield path, f"unknown body {name!r}{reason} Particles and rigid bodies: {', '.join(followable) or '(none)'}"


def _pins(data: dict[str, Any], bodies: dict[str, KeyPath], rigid: set[str]) -> Iterator[Problem]:
    """A pin's ``to`` names a rigid body."""
    for index, body in _items(data, "bodies"):
        pins = body.get("pin")
        if body.get("type") not in DEFORMABLE_TYPES or not isinstance(pins, list):
            continue
        for number, pin in enumerate(pins):
            target = pin.get("to") if isinstance(pin, dict) else None
            if isinstance(target, str) and target not in rigid:
                reason = (" (it is not a rigid body; pin to a rigid body, or use keyframes to move the vertices)"
                          if target in bodies else did_you_mean(target, sorted(rigid)))
                yield ("bodies", index, "pin", number, "to"), (
                    f"unknown rigid body {target!r}{reason} Rigid bodies: {', '.join(sorted(rigid)) or '(none)'}")


def _controllers(data: dict[str, Any], bodies: dict[str, KeyPath], rigid: set[str],
                 deformable: set[str]) -> Iterator[Problem]:
    """A controller pulls a particle or a rigid body (a point of it only for rigid bodies)."""
    pullable = sorted(set(bodies) - deformable)
    for index, controller in _items(data, "controllers"):
        name = controller.get("body")
        if not isinstance(name, str):
            continue
        if name not in bodies:
            yield ("controllers", index, "body"), (
                f"unknown body {name!r}{did_you_mean(name, pullable)} Bodies: {', '.join(pullable) or '(none)'}")
        elif name in deformable:
            yield ("controllers", index, "body"), (
                f"{name!r} is a cloth or lattice; a controller pulls one particle or rigid body (pin cloth vertices "
                "with keyframes to move them along a path)")
        elif controller.get("point") is not None and name not in rigid:
            yield ("controllers", index, "point"), (f"{name!r} is a particle, which has no body points; remove "
                                                    "'point' (it is for rigid bodies)")


def _materials(data: dict[str, Any]) -> Iterator[Problem]:
    """Material names used by bodies, colliders and pairs must be built in or defined under 'materials'."""
    custom = data.get("materials")
    known = sorted(set(BUILT_IN) | (set(custom) if isinstance(custom, dict) else set()))

    def unknown(path: KeyPath, name: Any) -> Iterator[Problem]:
        if isinstance(name, str) and name not in known:
            yield path, (f"unknown material {name!r}{did_you_mean(name, known)} Known: {', '.join(known)} "
                         "(define it under 'materials')")

    for section in ("bodies", "colliders", "emitters"):
        for index, item in _items(data, section):
            yield from unknown((section, index, "material"), item.get("material"))
    for index, pair in _items(data, "material_pairs"):
        names = pair.get("materials")
        if isinstance(names, list):
            for position, name in enumerate(names):
                yield from unknown(("material_pairs", index, "materials", position), name)


def _duplicate_names(data: dict[str, Any]) -> Iterator[Problem]:
    """Bodies, anchors and emitters share one namespace; springs and stopwatches have their own."""
    for sections in (("bodies", "anchors", "emitters"), ("springs",), ("stopwatches",)):
        first: dict[str, KeyPath] = {}
        for section in sections:
            for index, item in _items(data, section):
                name = item.get("name")
                if not isinstance(name, str):
                    continue
                if name in first:
                    yield (section, index, "name"), (f"name {name!r} is already used by "
                                                     f"{format_path(first[name][:2])}; names must be unique")
                else:
                    first[name] = (section, index, "name")
