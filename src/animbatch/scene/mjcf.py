"""MJCF (MuJoCo's model format) to a scene: ``animbatch import model.xml``.

What maps, element by element:

* ``<body>`` frames (``pos``, ``quat``, ``axisangle``, ``euler`` with the compiler's ``eulerseq`` and ``angle``
  unit, ``xyaxes``, ``zaxis``), nested, become rigid bodies placed in the world. Their ``<geom>`` children become
  the body's shape: one part at its place in the body frame, or a compound of several. Spheres, capsules, cylinders
  and boxes map (``size`` or ``fromto``), with each geom's ``mass`` or ``density`` (MuJoCo's default 1000 kg/m³):
  the mass properties then come from the geoms, as MuJoCo's do when a body has no ``<inertial>``.
* Geoms of ``<worldbody>`` itself become colliders: planes (the floor), boxes and spheres.
* ``<joint>``: ``hinge`` to our hinge, ``slide`` to our slider, ``ball`` to our ball joint, each between the body and
  its parent (the world at the top) at the joint's ``pos`` and ``axis``, with ``range`` as ``limits`` when the joint
  is limited (``limited="true"``, or a range under the compiler's ``autolimits``, MuJoCo's default). ``free`` means
  no joint. A body without joints is welded to its parent (a ``fixed`` joint), or to the world.
* ``<actuator>``: ``position`` servos (``kp``, optional ``kv``) become motors holding the joint at its start angle,
  ``velocity`` servos (``kv``) motors holding it still; ``motor`` actuators are torque inputs, zero without a
  controller, so nothing acts.
* ``<option gravity>`` becomes the gravity field and ``timestep`` the fixed step (``verlet``).
* ``<default>`` classes (nested, ``class`` and ``childclass``) are resolved before anything is read.

MuJoCo's world has z up, ours y up: the whole model is turned by −90° about x (MuJoCo's (x, y, z) is our
(x, z, −y)); angles between bodies are unchanged.

Everything else is listed by :func:`import_mjcf` as not mapped, with its line (an ``<inertial>``, mesh
and ellipsoid geoms, joint damping and stiffness, tendons, equality constraints, sensors, …), never dropped
silently.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.parsers import expat

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from animbatch.errors import AnimbatchError

#: MuJoCo's z-up world into ours (y up): (x, y, z) -> (x, z, -y).
TO_Y_UP = Rotation.from_euler("x", -90, degrees=True)
#: MuJoCo's default geom density [kg/m³] (water).
DEFAULT_DENSITY = 1000.0
class MjcfError(AnimbatchError):
    """A file that cannot be read as MJCF."""


@dataclass
class Imported:
    """The scene (YAML text, with a comment heading listing what was not mapped) and the list itself."""

    text: str
    scene: dict[str, Any]
    not_mapped: list[str] = field(default_factory=list)


@dataclass
class _Context:
    degrees: bool
    eulerseq: str
    autolimits: bool
    defaults: dict[str, dict[str, dict[str, str]]]  # class -> element tag -> attributes (inherited ones included)
    not_mapped: list[str]
    lines: dict[int, int] = field(default_factory=dict)  # id(element) -> its line in the file
    names: set[str] = field(default_factory=set)


def import_mjcf(path: str | Path) -> Imported:
    """Read the MJCF file at ``path`` into a scene. Raises MjcfError for a file that is not MJCF."""
    path = Path(path)
    try:
        root, lines = _parse(path.read_bytes())
    except (expat.ExpatError, OSError) as error:
        raise MjcfError(f"{path}: cannot be read as XML: {error}") from None
    if root.tag != "mujoco":
        raise MjcfError(f"{path}: the root element is <{root.tag}>, not <mujoco>: not an MJCF file")
    compiler = root.find("compiler")
    attributes = compiler.attrib if compiler is not None else {}
    context = _Context(degrees=attributes.get("angle", "degree") == "degree",
                       eulerseq=attributes.get("eulerseq", "xyz"),
                       autolimits=attributes.get("autolimits", "true") == "true",
                       defaults={}, not_mapped=[], lines=lines)
    for default in root.findall("default"):
        _read_defaults(default, "main", {}, context)
    for name in ("include", "tendon", "equality", "sensor", "contact", "keyframe", "asset"):
        for element in root.iter(name):
            if name in ("contact", "asset"):  # pairs and excludes; meshes and textures (mesh geoms are listed)
                if len(element):
                    _note(context, element, f"<{name}> ({len(element)} entries): not mapped")
                continue
            _note(context, element, f"<{name}>: not mapped")
    scene: dict[str, Any] = {"name": _scene_name(root, path), "duration": 2.0, "fps": 30}
    option = root.find("option")
    gravity = np.array([0.0, 0.0, -9.81])
    if option is not None:
        if "gravity" in option.attrib:
            gravity = _vector(option.attrib["gravity"], 3)
        if "timestep" in option.attrib:
            scene["solver"] = {"method": "verlet", "dt": float(option.attrib["timestep"])}
        for key in sorted(set(option.attrib) - {"gravity", "timestep"}):
            _note(context, option, f"<option {key}>: not mapped")
    bodies: list[dict[str, Any]] = []
    joints: list[dict[str, Any]] = []
    colliders: list[dict[str, Any]] = []
    worldbody = root.find("worldbody")
    if worldbody is None:
        raise MjcfError(f"{path}: no <worldbody>")
    joint_bodies: dict[str, str] = {}  # MJCF joint name -> our joint's index in joints (as text)
    for geom in worldbody.findall("geom"):
        collider = _collider(geom, context)
        if collider is not None:
            colliders.append(collider)
    for element in worldbody:
        if element.tag in ("light", "camera", "site"):
            _note(context, element, f"<{element.tag}>: not mapped (the renderer has its own lights and camera)")
        elif element.tag not in ("geom", "body"):
            _note(context, element, f"<{element.tag}> in <worldbody>: not mapped")
    for body in worldbody.findall("body"):
        _read_body(body, None, Rotation.identity(), np.zeros(3), None, context, bodies, joints, joint_bodies)
    _read_actuators(root, joints, joint_bodies, context)
    scene["bodies"] = bodies
    if joints:
        scene["joints"] = joints
    if colliders:
        scene["colliders"] = colliders
    g = TO_Y_UP.apply(gravity)
    scene["fields"] = [{"type": "gravity", "g": _rounded(g)}]
    context.not_mapped.sort(key=lambda line: int(line.split(":")[0].removeprefix("line ")) if line.startswith("line ")
                            else 0)
    heading = [f"Imported from {path.name} by 'animbatch import' (MuJoCo's z up is this scene's y up)."]
    if context.not_mapped:
        heading.append("Not mapped:")
        heading += [f"  - {line}" for line in context.not_mapped]
    else:
        heading.append("Everything in the file was mapped.")
    text = "".join(f"# {line}\n" for line in heading) + yaml.safe_dump(scene, sort_keys=False, width=110,
                                                                        default_flow_style=None)
    return Imported(text, scene, context.not_mapped)


def _parse(data: bytes) -> tuple[ET.Element, dict[int, int]]:
    """The element tree of an XML document (text content is not kept: MJCF has none) and the line each element
    starts on, by ``id`` (ElementTree's own parser does not tell lines)."""
    builder = ET.TreeBuilder()
    lines: dict[int, int] = {}
    parser = expat.ParserCreate()

    def start(tag: str, attributes: dict[str, str]) -> None:
        lines[id(builder.start(tag, attributes))] = parser.CurrentLineNumber

    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    parser.Parse(data, True)
    return builder.close(), lines


def _note(context: _Context, element: ET.Element, message: str) -> None:
    name = element.get("name")
    line = context.lines.get(id(element))
    context.not_mapped.append((f"line {line}: " if line else "") + message + (f" (name {name!r})" if name else ""))


def _scene_name(root: ET.Element, path: Path) -> str:
    model = root.get("model") or path.stem
    cleaned = "".join(c if c.isalnum() or c in "-_" else "-" for c in model).strip("-_") or "imported"
    return cleaned


def _read_defaults(element: ET.Element, name: str, inherited: dict[str, dict[str, str]], context: _Context) -> None:
    own = {tag: dict(attributes) for tag, attributes in inherited.items()}
    for child in element:
        if child.tag == "default":
            continue
        own.setdefault(child.tag, {}).update(child.attrib)
    context.defaults[name] = own
    for child in element.findall("default"):
        _read_defaults(child, child.get("class", name), own, context)


def _attributes(element: ET.Element, childclass: str | None, context: _Context) -> dict[str, str]:
    """The element's attributes with its class's defaults under them (its own ``class``, else the nearest
    ``childclass``, else the main defaults)."""
    chosen = element.get("class") or childclass or "main"
    merged = dict(context.defaults.get(chosen, context.defaults.get("main", {})).get(element.tag, {}))
    merged.update(element.attrib)
    return merged


def _vector(text: str, count: int) -> np.ndarray:
    values = np.array([float(part) for part in text.split()], float)
    if len(values) != count:
        raise MjcfError(f"expected {count} numbers, got {text!r}")
    return values


def _angle(value: float, context: _Context) -> float:
    return math.radians(value) if context.degrees else value


def _frame(attributes: dict[str, str], context: _Context) -> tuple[np.ndarray, Rotation]:
    """A frame's position and rotation relative to its parent."""
    position = _vector(attributes["pos"], 3) if "pos" in attributes else np.zeros(3)
    if "quat" in attributes:
        w, x, y, z = _vector(attributes["quat"], 4)
        return position, Rotation.from_quat([x, y, z, w])
    if "axisangle" in attributes:
        values = _vector(attributes["axisangle"], 4)
        axis = values[:3] / np.linalg.norm(values[:3])
        return position, Rotation.from_rotvec(axis * _angle(values[3], context))
    if "euler" in attributes:
        angles = [_angle(v, context) for v in _vector(attributes["euler"], 3)]
        return position, Rotation.from_euler(context.eulerseq.swapcase(), angles)  # MuJoCo's lower case: intrinsic
    if "xyaxes" in attributes:
        values = _vector(attributes["xyaxes"], 6)
        x = values[:3] / np.linalg.norm(values[:3])
        y = values[3:] - np.dot(values[3:], x) * x
        y /= np.linalg.norm(y)
        return position, Rotation.from_matrix(np.column_stack([x, y, np.cross(x, y)]))
    if "zaxis" in attributes:
        return position, _z_along(_vector(attributes["zaxis"], 3))
    return position, Rotation.identity()


def _z_along(direction: np.ndarray) -> Rotation:
    """The smallest rotation taking z to ``direction``."""
    direction = direction / np.linalg.norm(direction)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, direction)
    sine = np.linalg.norm(axis)
    if sine < 1e-12:
        return Rotation.identity() if direction[2] > 0 else Rotation.from_euler("x", 180, degrees=True)
    return Rotation.from_rotvec(axis / sine * math.atan2(sine, float(np.dot(z, direction))))


def _shape(attributes: dict[str, str], element: ET.Element, context: _Context
           ) -> tuple[dict[str, Any], np.ndarray, Rotation] | None:
    """A geom's shape and its frame in the body (position, rotation); None (listed) when it does not map."""
    kind = attributes.get("type", "sphere")
    size = [float(v) for v in attributes.get("size", "0").split()]
    if "fromto" in attributes and kind in ("capsule", "cylinder", "box", "ellipsoid"):
        ends = _vector(attributes["fromto"], 6)
        start, end = ends[:3], ends[3:]
        centre, rotation = (start + end) / 2, _z_along(end - start)
        half = float(np.linalg.norm(end - start)) / 2
    else:
        centre, rotation = _frame(attributes, context)
        half = size[1] if len(size) > 1 else 0.0
    if kind == "sphere":
        return {"type": "sphere", "radius": _number(size[0])}, centre, rotation
    if kind == "capsule":
        return {"type": "capsule", "radius": _number(size[0]), "length": _number(2 * half + 2 * size[0])}, centre, \
            rotation
    if kind == "cylinder":
        return {"type": "cylinder", "radius": _number(size[0]), "length": _number(2 * half)}, centre, rotation
    if kind == "box" and len(size) == 3:
        return {"type": "box", "size": _rounded(2 * np.array(size))}, centre, rotation
    _note(context, element, f"<geom type={kind!r}>: not mapped (spheres, capsules, cylinders and boxes are)")
    return None


def _collider(geom: ET.Element, context: _Context) -> dict[str, Any] | None:
    attributes = _attributes(geom, None, context)
    kind = attributes.get("type", "sphere")
    if kind == "plane":
        position, rotation = _frame(attributes, context)
        normal = TO_Y_UP.apply(rotation.apply([0.0, 0.0, 1.0]))
        return {"type": "plane", "point": _rounded(TO_Y_UP.apply(position)), "normal": _rounded(normal)}
    shape = _shape(attributes, geom, context)
    if shape is None:
        return None
    spec, centre, rotation = shape
    world = TO_Y_UP * rotation
    if spec["type"] == "sphere":
        return {"type": "sphere", "position": _rounded(TO_Y_UP.apply(centre)), "radius": spec["radius"]}
    if spec["type"] == "box":
        return {"type": "box", "position": _rounded(TO_Y_UP.apply(centre)), "size": spec["size"],
                "orientation": {"quaternion": _quaternion(world)}}
    _note(context, geom, f"<geom type={kind!r}> in <worldbody>: not mapped (planes, boxes and spheres are)")
    return None


def _read_body(element: ET.Element, parent: str | None, parent_rotation: Rotation, parent_position: np.ndarray,
               childclass: str | None, context: _Context, bodies: list[dict[str, Any]],
               joints: list[dict[str, Any]], joint_bodies: dict[str, str]) -> None:
    attributes = _attributes(element, childclass, context)
    childclass = element.get("childclass") or childclass
    local_position, local_rotation = _frame(attributes, context)
    rotation = parent_rotation * local_rotation
    position = parent_position + parent_rotation.apply(local_position)
    name = _unique(element.get("name") or f"body{len(bodies)}", context)
    parts = []
    for geom in element.findall("geom"):
        geom_attributes = _attributes(geom, childclass, context)
        shape = _shape(geom_attributes, geom, context)
        if shape is None:
            continue
        spec, centre, part_rotation = shape
        part: dict[str, Any] = {"shape": spec, "offset": _rounded(centre)}
        if not np.allclose(part_rotation.as_matrix(), np.eye(3)):
            part["orientation"] = {"quaternion": _quaternion(part_rotation)}
        if "mass" in geom_attributes:
            part["mass"] = float(geom_attributes["mass"])
        else:
            part["density"] = float(geom_attributes.get("density", DEFAULT_DENSITY))
        parts.append(part)
    inertial = element.find("inertial")
    if inertial is not None:
        _note(context, inertial, f"<inertial> of body {name!r}: its mass and inertia come from its geoms instead")
    for child in element:
        if child.tag not in ("geom", "body", "joint", "freejoint", "inertial"):
            _note(context, child, f"<{child.tag}> in body {name!r}: not mapped")
    if not parts:
        _note(context, element, f"body {name!r} has no geom that maps: not imported, nor its children")
        return
    body: dict[str, Any] = {"name": name, "type": "rigid"}
    if len(parts) == 1 and "orientation" not in parts[0] and not any(parts[0]["offset"]):
        body["shape"] = parts[0]["shape"]
        body.update({key: parts[0][key] for key in ("mass", "density") if key in parts[0]})
    else:
        body["shape"] = {"type": "compound", "parts": parts}
    body["position"] = _rounded(TO_Y_UP.apply(position))
    world = TO_Y_UP * rotation
    if not np.allclose(world.as_matrix(), np.eye(3)):
        body["orientation"] = {"quaternion": _quaternion(world)}
    bodies.append(body)
    found = element.findall("joint") + element.findall("freejoint")
    moving = [joint for joint in found if joint.tag == "joint"
              and _attributes(joint, childclass, context).get("type", "hinge") != "free"]
    free = any(joint.tag == "freejoint" or _attributes(joint, childclass, context).get("type") == "free"
               for joint in found)
    between = [name] + ([parent] if parent is not None else [])
    if not moving and not free:
        joints.append({"type": "fixed", "between": between})
    if len(moving) > 1:
        _note(context, element, f"body {name!r} has {len(moving)} joints to its parent: only the first is mapped "
                                "(one joint per pair of bodies)")
    for joint in moving[:1]:
        joints.append(_joint(joint, _attributes(joint, childclass, context), between, position, rotation, context))
        if joint.get("name"):
            joint_bodies[joint.get("name", "")] = str(len(joints) - 1)
    for child in element.findall("body"):
        _read_body(child, name, rotation, position, childclass, context, bodies, joints, joint_bodies)


def _joint(element: ET.Element, attributes: dict[str, str], between: list[str], body_position: np.ndarray,
           body_rotation: Rotation, context: _Context) -> dict[str, Any]:
    kind = attributes.get("type", "hinge")
    ours = {"hinge": "hinge", "slide": "slider", "ball": "ball"}[kind]
    point = body_position + body_rotation.apply(_vector(attributes["pos"], 3) if "pos" in attributes else np.zeros(3))
    joint: dict[str, Any] = {"type": ours, "between": between, "anchor": _rounded(TO_Y_UP.apply(point))}
    if ours != "ball":
        axis = body_rotation.apply(_vector(attributes.get("axis", "0 0 1"), 3))
        joint["axis"] = _rounded(TO_Y_UP.apply(axis / np.linalg.norm(axis)))
    limited = attributes.get("limited", "auto")
    if "range" in attributes and (limited == "true" or (limited == "auto" and context.autolimits)):
        low, high = _vector(attributes["range"], 2)
        if ours == "ball":
            _note(context, element, "a ball joint's range: not mapped (ball joints have no limits here)")
        else:
            scale = (math.radians(1) if context.degrees else 1.0) if ours == "hinge" else 1.0
            joint["limits"] = _rounded([low * scale, high * scale])
    for key in ("damping", "stiffness", "armature", "frictionloss", "springref", "ref"):
        if float(attributes.get(key, "0").split()[0]) != 0:
            _note(context, element, f"joint {key}={attributes[key]}: not mapped")
    return joint


def _read_actuators(root: ET.Element, joints: list[dict[str, Any]], joint_bodies: dict[str, str],
                    context: _Context) -> None:
    for actuator in root.iter("actuator"):
        for element in actuator:
            attributes = _attributes(element, None, context)
            target = attributes.get("joint")
            if target is None or target not in joint_bodies:
                _note(context, element, f"<{element.tag}> on {target or 'no joint'}: not mapped (actuators on "
                                        "imported joints are)")
                continue
            joint = joints[int(joint_bodies[target])]
            if joint["type"] == "ball":
                _note(context, element, f"<{element.tag}> on ball joint {target!r}: not mapped")
            elif element.tag == "position":
                motor = {"target": 0.0, "stiffness": float(attributes.get("kp", "1"))}
                if "kv" in attributes:
                    motor["damping"] = float(attributes["kv"])
                joint["motor"] = motor
            elif element.tag == "velocity":
                joint["motor"] = {"speed": 0.0, "damping": float(attributes.get("kv", "1"))}
            elif element.tag == "motor":
                _note(context, element, f"<motor> on {target!r}: a torque input, zero without a controller; "
                                        "nothing acts")
            else:
                _note(context, element, f"<{element.tag}> on {target!r}: not mapped")


def _unique(name: str, context: _Context) -> str:
    candidate, number = name, 2
    while candidate in context.names:
        candidate, number = f"{name}-{number}", number + 1
    context.names.add(candidate)
    return candidate


def _quaternion(rotation: Rotation) -> list[float]:
    x, y, z, w = rotation.as_quat()
    return _rounded(np.array([w, x, y, z]))


def _rounded(values: Any) -> list[float]:
    """Plain floats with 12 significant digits (0.1 + 0.2 stays 0.3 in the file), round-off of the turn to y up
    (below 1e-12) and -0 as 0."""
    return [_number(value) for value in np.asarray(values, float)]


def _number(value: float) -> float:
    return 0.0 if abs(value) < 1e-12 else float(f"{value:.12g}") + 0.0
