"""Build the contact world of a scene: probes and boxes of every colliding body, the fixed colliders, materials.

Only scenes with colliders or a ``contacts`` section, and a body that collides, get one (see
:attr:`SceneSpec.has_contacts`).

What each body contributes (all in body axes from its centre of mass):

* particle: a probe sphere of its radius;
* sphere or shell: a probe sphere;
* box: probes at its 8 corners, and the box as a solid for other bodies' probes;
* cylinder, rod: probes on both rims (16 each) and at the axis ends, and the cylinder as a round solid for other
  bodies' probes, with its side against other sides and edges (:mod:`animbatch.sim.contact.sides`);
* capsule: probe spheres at both cap centres, and the capsule as a round solid, with its side as a cylinder's;
* mesh: probes at the vertices of its convex hull (at most ``MESH_PROBES``, evenly chosen), and the hull as a solid
  for other bodies (:mod:`animbatch.sim.contact.hulls`; a hollow mesh must be declared ``convex_hull`` or split);
* compound: the union of its parts'.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from animbatch.compile.bodies import orientation_matrix
from animbatch.scene.schema import (
    DEFORMABLE_SPECS,
    BoxCollider,
    BoxShape,
    CapsuleShape,
    CompoundShape,
    ContactSpec,
    CylinderShape,
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
from animbatch.sim.contact.contacts import PLANE, STATIC_BOX, STATIC_SPHERE, TRIANGLE
from animbatch.sim.contact.detection import ContactSettings, ContactWorld
from animbatch.sim.contact.geometry import BodyBoxes, BodyCylinders, Probes, StaticColliders
from animbatch.sim.contact.hulls import BodyHull
from animbatch.sim.contact.materials import Coefficients, MaterialTable
from animbatch.sim.contact.meshes import TriangleGroup
from animbatch.sim.contact.moving import MovingColliders
from animbatch.sim.motion import ClosedFormPath, KeyframePath, PosePath, SolidPath
from animbatch.sim.rigid.polyhedra import TriangleMesh, convex_mesh
from animbatch.sim.rigid.shapes import load_mesh, load_surface

RIM_PROBES = 16
MESH_PROBES = 400


def _shape_features(shape: Any, base: Path) -> tuple[list[tuple[np.ndarray, float, int]], list[tuple]]:
    """Probes [(centre, radius, box)] and boxes [(offset, rotation, half)] of one shape, in shape coordinates;
    ``box`` numbers the shape's box whose corner the probe is (-1: not a box corner)."""
    if isinstance(shape, SphereShape | ShellShape):
        return [(np.zeros(3), shape.radius, -1)], []
    if isinstance(shape, BoxShape):
        half = np.asarray(shape.size, float) / 2
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        return [(c, 0.0, 0) for c in corners], [(np.zeros(3), np.eye(3), half)]
    if isinstance(shape, CylinderShape | RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        angles = 2 * np.pi * np.arange(RIM_PROBES) / RIM_PROBES
        ring = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(RIM_PROBES)], axis=1)
        ends = [np.array([0.0, 0.0, -shape.length / 2]), np.array([0.0, 0.0, shape.length / 2])]
        return [(p + end, 0.0, -1) for end in ends for p in ring] + [(end, 0.0, -1) for end in ends], []
    if isinstance(shape, CapsuleShape):
        reach = shape.length / 2 - shape.radius  # from the centre to each cap's centre
        return [(np.array([0.0, 0.0, z]), shape.radius, -1) for z in (-reach, reach)], []
    if isinstance(shape, MeshShape):
        vertices = mesh_hull(shape, base).vertices
        if len(vertices) > MESH_PROBES:
            vertices = vertices[np.linspace(0, len(vertices) - 1, MESH_PROBES).astype(int)]
        return [(v, 0.0, -1) for v in vertices], []
    if isinstance(shape, CompoundShape):
        probes: list[tuple[np.ndarray, float, int]] = []
        boxes: list[Any] = []
        for part in shape.parts:
            rotation = orientation_matrix(part.orientation)
            offset = np.asarray(part.offset, float)
            part_probes, part_boxes = _shape_features(part.shape, base)
            probes += [(rotation @ c + offset, r, box + len(boxes) if box >= 0 else -1) for c, r, box in part_probes]
            boxes += [(rotation @ o + offset, rotation @ rot, half) for o, rot, half in part_boxes]
        return probes, boxes
    raise TypeError(f"no collision geometry for shape {shape!r}")


def _rounds(shape: Any) -> list[tuple[np.ndarray, np.ndarray, float, float, bool]]:
    """The cylinders, rods and capsules of a shape: (centre, unit axis, half length of the straight part, radius,
    whether the ends are hemispheres) in shape coordinates."""
    z = np.array([0.0, 0.0, 1.0])
    if isinstance(shape, CylinderShape | RodShape):
        radius = shape.radius if shape.radius is not None else shape.length / 100
        return [(np.zeros(3), z, shape.length / 2, radius, False)]
    if isinstance(shape, CapsuleShape):
        return [(np.zeros(3), z, shape.length / 2 - shape.radius, shape.radius, True)]
    if isinstance(shape, CompoundShape):
        found = []
        for part in shape.parts:
            rotation = orientation_matrix(part.orientation)
            found += [(rotation @ c + np.asarray(part.offset, float), rotation @ a, h, r, rounded)
                      for c, a, h, r, rounded in _rounds(part.shape)]
        return found
    return []


def _hulls(shape: Any, base: Path) -> list[np.ndarray]:
    """The vertices (V, 3) of each convex hull of a shape (its meshes), in shape coordinates."""
    if isinstance(shape, MeshShape):
        return [mesh_hull(shape, base).vertices]
    if isinstance(shape, CompoundShape):
        found = []
        for part in shape.parts:
            rotation = orientation_matrix(part.orientation)
            found += [v @ rotation.T + np.asarray(part.offset, float) for v in _hulls(part.shape, base)]
        return found
    return []


def mesh_hull(shape: MeshShape, base: Path) -> TriangleMesh:
    """The convex hull of a mesh shape's file, scaled."""
    return convex_mesh(load_mesh(base / shape.file, shape.scale).vertices)


def _statics(spec: SceneSpec, table: MaterialTable, base: Path) -> tuple[StaticColliders, dict[int, np.ndarray]]:
    """The fixed colliders, and for each kind of solid the scene collider (its number) each one came from."""
    planes, spheres, boxes, meshes = [], [], [], []
    sources: dict[int, list[int]] = {PLANE: [], STATIC_SPHERE: [], STATIC_BOX: [], TRIANGLE: []}
    for number, collider in enumerate(spec.colliders):
        material = table.index(collider.material)
        if isinstance(collider, PlaneCollider):
            normal = np.asarray(collider.normal, float)
            planes.append((np.asarray(collider.point, float), normal / np.linalg.norm(normal), material))
            sources[PLANE].append(number)
        elif isinstance(collider, SphereCollider):
            spheres.append((np.asarray(collider.position, float), collider.radius, material))
            sources[STATIC_SPHERE].append(number)
        elif isinstance(collider, BoxCollider):
            boxes.append((np.asarray(collider.position, float), orientation_matrix(collider.orientation),
                          np.asarray(collider.size, float) / 2, material))
            sources[STATIC_BOX].append(number)
        elif isinstance(collider, MeshCollider):
            mesh = load_surface(base / collider.file, collider.scale).transformed(  # open or closed
                orientation_matrix(collider.orientation), np.asarray(collider.position, float))
            meshes.append((mesh.triangles, np.full(len(mesh.faces), material)))
            sources[TRIANGLE] += [number] * len(mesh.faces)
    empty = StaticColliders.empty()

    def stack(items: list, k: int, fallback: np.ndarray) -> np.ndarray:
        return np.array([item[k] for item in items]) if items else fallback

    statics = StaticColliders(
        stack(planes, 0, empty.plane_point), stack(planes, 1, empty.plane_normal),
        stack(planes, 2, empty.plane_material).astype(np.intp),
        stack(spheres, 0, empty.sphere_centre), stack(spheres, 1, empty.sphere_radius),
        stack(spheres, 2, empty.sphere_material).astype(np.intp),
        stack(boxes, 0, empty.box_centre), stack(boxes, 1, empty.box_rotation), stack(boxes, 2, empty.box_half),
        stack(boxes, 3, empty.box_material).astype(np.intp),
        np.concatenate([m[0] for m in meshes]) if meshes else empty.triangles,
        np.concatenate([m[1] for m in meshes]).astype(np.intp) if meshes else empty.triangle_material)
    return statics, {kind: np.array(numbers, np.intp) for kind, numbers in sources.items()}


def material_table(spec: SceneSpec) -> MaterialTable:
    custom = {name: Coefficients(m.restitution, m.static_friction, m.kinetic_friction)
              for name, m in spec.materials.items()}
    pairs = {frozenset(p.materials): {"restitution": p.restitution, "static_friction": p.static_friction,
                                      "kinetic_friction": p.kinetic_friction} for p in spec.material_pairs}
    return MaterialTable.build(custom, pairs)


def build_contact_world(spec: SceneSpec, model: Any, centres: dict[str, np.ndarray],
                        base: Path) -> tuple[ContactWorld, ContactSettings]:
    """The contact world for a scene and its model (bodies in model order; the vertices of cloth and lattices are
    particles of the model); ``centres`` gives each rigid body's centre of mass in shape coordinates."""
    table = material_table(spec)
    by_name = {body.name: body for body in spec.bodies}
    owner_names = model.owners
    deformable_names = [body.name for body in spec.bodies if isinstance(body, DEFORMABLE_SPECS)]
    owners, offsets, radii, corner_of = [], [], [], []
    box_owner: list[int] = []
    box_offset: list[np.ndarray] = []
    box_rotation: list[np.ndarray] = []
    box_half: list[np.ndarray] = []
    rounds: list[tuple] = []  # (owner, centre, axis, half length, radius, rounded), body axes from the centre of mass
    hulls: list[BodyHull] = []
    for point, name in enumerate(owner_names):
        body = by_name[name]
        if isinstance(body, RigidBodySpec):
            probes, boxes = _shape_features(body.shape, base)
            centre = centres[name]
            rounds += [(point, offset - centre, axis, half, radius, rounded)
                       for offset, axis, half, radius, rounded in _rounds(body.shape)]
            hulls += [BodyHull.of_points(point, vertices - centre) for vertices in _hulls(body.shape, base)]
            first_box = len(box_owner)
            for c, r, box in probes:
                owners.append(point)
                offsets.append(c - centre)
                radii.append(r)
                corner_of.append(first_box + box if box >= 0 else -1)
            for offset, rotation, half in boxes:
                box_owner.append(point)
                box_offset.append(offset - centre)
                box_rotation.append(rotation)
                box_half.append(half)
        else:  # a particle, or a vertex of a cloth or lattice (a particle with the body's vertex radius)
            owners.append(point)
            offsets.append(np.zeros(3))
            radii.append(float(model.bodies.radius[point]))
            corner_of.append(-1)
    statics, sources = _statics(spec, table, base)
    moving = moving_colliders(spec, statics, sources)
    settings = spec.contacts if spec.contacts is not None else ContactSpec()
    world = ContactWorld(
        Probes(np.array(owners, np.intp), np.array(offsets, float).reshape(-1, 3), np.array(radii, float),
               np.array(corner_of, np.intp)),
        BodyBoxes(np.array(box_owner, np.intp), np.array(box_offset, float).reshape(-1, 3),
                  np.array(box_rotation, float).reshape(-1, 3, 3), np.array(box_half, float).reshape(-1, 3)),
        statics, table, np.array([table.index(by_name[n].material) for n in owner_names], np.intp),
        np.array([by_name[n].collide for n in owner_names], bool),
        settings.bodies, triangle_groups(statics, moving),
        _vertex_groups(model, owner_names, deformable_names),
        sources, tuple(model.body_names), np.asarray(model.bodies.mass, float), _jointed_pairs(model),
        moving,
        BodyCylinders(*(np.array([c[k] for c in rounds], (np.intp, float, float, float, float, bool)[k])
                        for k in range(6))) if rounds else None,
        tuple(hulls))
    return world, ContactSettings(settings.iterations, settings.rest_speed, settings.slop)


def _vertex_groups(model: Any, owner_names: Sequence[str], deformable_names: list[str]) -> np.ndarray:
    """Each point's contact group (−1: none): the vertices of one cloth or lattice are one group, whose vertex
    spheres never collide with each other; so are all the bodies with self-collision, whose surfaces meet through
    it (a thickness apart) rather than through their vertex spheres."""
    folding = ({body.name for body in model.deformables.bodies if body.self_collision}
               if model.deformables is not None else set())
    return np.array([len(deformable_names) if n in folding else deformable_names.index(n)
                     if n in deformable_names else -1 for n in owner_names], np.intp)


def _jointed_pairs(model: Any) -> np.ndarray | None:
    """Keys a·P + b (a < b) of the body pairs a joint joins directly: they do not collide with each other."""
    if model.joints is None:
        return None
    pairs = model.joints.joined_pairs()
    if not len(pairs):
        return None
    low, high = pairs.min(axis=1).astype(np.int64), pairs.max(axis=1).astype(np.int64)
    return np.unique(low * model.body_count + high)


def pose_path(collider: Any) -> SolidPath:
    """The path of a kinematic collider or rigid body about its pivot, its position (a plane's point): its closed-form
    motion, or its keyframes (displaced by the keys' offsets, turned by their rotations about it)."""
    pivot = np.asarray(collider.point if isinstance(collider, PlaneCollider) else collider.position, float)
    if collider.motion is not None:
        motion, swing = collider.motion, collider.motion.oscillation
        return ClosedFormPath(pivot, np.asarray(motion.velocity, float), np.asarray(motion.angular_velocity, float),
                              np.asarray(swing.amplitude if swing else (0.0, 0.0, 0.0), float),
                              swing.frequency if swing else 0.0, np.radians(swing.phase) if swing else 0.0,
                              swing.damping if swing else 0.0)
    keys = collider.keyframes
    times = np.array([k.time for k in keys], float)
    offsets = KeyframePath(times, np.array([k.offset for k in keys], float), collider.interpolation)
    turns = Rotation.from_matrix(np.array([orientation_matrix(k.rotation) for k in keys]))
    return PosePath(pivot, times, offsets, turns, collider.interpolation)


def moving_colliders(spec: SceneSpec, statics: StaticColliders, sources: dict[int, np.ndarray]
                     ) -> MovingColliders | None:
    """The scene's colliders on keyframes, and which of the contact world's solids (``statics``, each from the
    scene collider ``sources`` names) each one moves; None when none moves."""
    moving = [number for number, collider in enumerate(spec.colliders) if collider.moves]
    if not moving:
        return None
    path_of = np.full(len(spec.colliders), -1, np.intp)
    path_of[moving] = np.arange(len(moving))
    slot = {kind: path_of[sources[kind]] if len(sources[kind]) else np.zeros(0, np.intp)
            for kind in (PLANE, STATIC_SPHERE, STATIC_BOX, TRIANGLE)}
    paths = tuple(pose_path(spec.colliders[number]) for number in moving)
    reach = np.zeros(len(paths))  # how far each one's surface reaches from its pivot
    for m, path in enumerate(paths):
        if (slot[PLANE] == m).any():
            reach[m] = np.inf
            continue
        spheres, boxes, triangles = slot[STATIC_SPHERE] == m, slot[STATIC_BOX] == m, slot[TRIANGLE] == m
        reach[m] = max(
            np.max(np.linalg.norm(statics.sphere_centre[spheres] - path.centre, axis=1)
                   + statics.sphere_radius[spheres], initial=0.0),
            np.max(np.linalg.norm(statics.box_centre[boxes] - path.centre, axis=1)
                   + np.linalg.norm(statics.box_half[boxes], axis=1), initial=0.0),
            np.max(np.linalg.norm(statics.triangles[triangles] - path.centre, axis=2), initial=0.0))
    return MovingColliders(paths, reach, slot[PLANE], slot[STATIC_SPHERE], slot[STATIC_BOX], slot[TRIANGLE])


def triangle_groups(statics: StaticColliders, moving: MovingColliders | None) -> tuple[TriangleGroup, ...]:
    """The mesh colliders' triangles as the contact search finds them: the fixed ones through one tree, each moving
    mesh through its own (built at rest)."""
    if not len(statics.triangles):
        return ()
    path = moving.triangle if moving is not None else np.full(len(statics.triangles), -1, np.intp)
    return tuple(TriangleGroup.of(statics.triangles, np.flatnonzero(path == m), int(m)) for m in np.unique(path))
