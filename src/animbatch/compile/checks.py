"""Checks of a validated scene that need the simulation's knowledge: mesh files that exist, are readable and closed,
pins that select vertices of their cloth or lattice, and an integration method that can keep the scene's contacts.
The scene layer cannot build geometry nor read the method table, so the loader takes these as its
``geometry_checks`` (:func:`animbatch.stages.load_scene` passes :func:`compile_checks`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from animbatch.scene.checks import Problem
from animbatch.scene.orientation import orientation_matrix
from animbatch.scene.schema import (
    CONTACT_METHODS,
    DEFORMABLE_SPECS,
    ClothMeshSpec,
    ClothSpec,
    CompoundShape,
    MeshCollider,
    MeshShape,
    RigidBodySpec,
    SceneSpec,
)
from animbatch.scene.yaml_source import KeyPath


def compile_checks(spec: SceneSpec, base_dir: Path) -> list[Problem]:
    """Every check of this module, each problem with the key path it is about."""
    return check_method(spec) + check_files(spec, base_dir)


def check_method(spec: SceneSpec) -> list[Problem]:
    """A fixed-step method that cannot apply contacts between its kick and its drift (an explicit Runge–Kutta
    method moves positions with the velocities from before the step) is refused for a scene with contacts; the
    analytic method, for a scene with anything that has no closed form; rotation matrices, for a scene whose
    rigid bodies do more than move freely."""
    if spec.solver.method == "analytic":
        return check_analytic(spec)
    if spec.solver.orientation == "matrix":
        problem = _matrix_orientation_problem(spec)
        if problem:
            return [(("solver", "orientation"), problem)]
    adaptive = spec.solver.is_adaptive
    colliding = any(getattr(body, "collide", True) for body in spec.bodies)
    has_contacts = (bool(spec.colliders) or spec.contacts is not None) and colliding
    kinematic = [k for k, b in enumerate(spec.bodies) if getattr(b, "moves", False)]
    if kinematic and adaptive:
        body = spec.bodies[kinematic[0]]
        how = "keyframes" if getattr(body, "keyframes", None) is not None else "motion"
        return [(("bodies", kinematic[0], how), (
            f"rigid bodies on {how} need a fixed-step method; {spec.solver.method} is adaptive. Use "
            "solver.method: symplectic_euler or verlet (with a dt that resolves the body's motion)"))]
    folding = [k for k, b in enumerate(spec.bodies) if getattr(b, "self_collision", None)]
    if folding and spec.solver.method not in CONTACT_METHODS:
        return [(("bodies", folding[0], "self_collision"), (
            f"self-collision is applied between a fixed-step method's kick and its drift; {spec.solver.method} has "
            f"none. Use solver.method: {', '.join(CONTACT_METHODS)}, or leave self_collision unset"))]
    moving = [k for k, c in enumerate(spec.colliders) if c.moves]
    if moving and has_contacts and adaptive:
        how = "keyframes" if spec.colliders[moving[0]].keyframes is not None else "motion"
        return [(("colliders", moving[0], how), (
            f"colliders on {how} need a fixed-step method; {spec.solver.method} is adaptive. Use "
            "solver.method: symplectic_euler or verlet (with a dt that resolves the collider's motion)"))]
    if not has_contacts or adaptive or spec.solver.method in CONTACT_METHODS:
        return []
    return [(("solver", "method"), (
        f"{spec.solver.method} cannot keep contacts: it moves positions with the velocities from before the step, so "
        "bodies would sink into colliders. Use symplectic_euler or verlet (fixed step), or an adaptive method such "
        "as RK45"))]


def _matrix_orientation_problem(spec: SceneSpec) -> str | None:
    """Why a scene cannot integrate rotation matrices (the teaching form of the notes), or None."""
    rigid = [body for body in spec.bodies if isinstance(body, RigidBodySpec)]
    if not rigid:
        return "orientation: matrix integrates rigid bodies' rotations, and this scene has none"
    why = ("it has joints" if spec.joints else
           "rigid bodies move on keyframes or a motion" if any(body.moves for body in rigid) else
           "its rigid bodies meet colliders or each other" if spec.has_contacts and any(b.collide for b in rigid)
           else None)
    if why is None:
        return None
    return (f"orientation: matrix is for rigid bodies that move freely under forces, and {why}: their solvers keep "
            "quaternions. Use orientation: quaternion (the default), or show the drift in a scene of free bodies")


def check_files(spec: SceneSpec, base_dir: Path) -> list[Problem]:
    """Mesh files that are missing, unreadable or not closed, found from ``base_dir`` (the scene's folder)."""
    problems: list[Problem] = []
    shapes: list[tuple[KeyPath, Any]] = [(("colliders", index), collider) for index, collider in
                                         enumerate(spec.colliders) if isinstance(collider, MeshCollider)]
    for index, body in enumerate(spec.bodies):
        if isinstance(body, ClothSpec) and body.mesh is not None:
            shapes.append((("bodies", index, "mesh"), body.mesh))
        if not isinstance(body, RigidBodySpec):
            continue
        if isinstance(body.shape, CompoundShape):
            shapes += [(("bodies", index, "shape", "parts", k, "shape"), part.shape)
                       for k, part in enumerate(body.shape.parts)]
        else:
            shapes.append((("bodies", index, "shape"), body.shape))
    for path, shape in shapes:
        if isinstance(shape, MeshShape | MeshCollider | ClothMeshSpec):
            outside = _outside_scene_folder(shape.file, base_dir)
            if outside:
                problems.append(((*path, "file"), outside))
                continue
            from animbatch.sim.rigid.shapes import load_mesh, load_surface  # only scenes with mesh files pay

            try:
                surface = isinstance(shape, ClothMeshSpec | MeshCollider)  # open surfaces are fine there
                (load_surface if surface else load_mesh)(base_dir / shape.file, shape.scale)
            except ValueError as error:
                problems.append(((*path, "file"), f"{error} (looked in {base_dir.resolve()})"
                                 if "no such file" in str(error) else str(error)))
    if not problems:
        problems += (_pin_selections(spec, base_dir) + _hollow_meshes(spec, base_dir)
                     + _closed_surfaces(spec, base_dir))
    return problems + _joint_points(spec)


#: A mesh whose convex hull holds more than this fraction beyond its own volume is hollow: not a convex solid.
HOLLOW = 0.01


def _hollow_meshes(spec: SceneSpec, base_dir: Path) -> list[Problem]:
    """Mesh bodies that other bodies touch must be convex (others meet them as a convex solid) unless they say
    ``convex_hull: true``."""
    colliding = [(index, body) for index, body in enumerate(spec.bodies) if getattr(body, "collide", True)]
    if not spec.has_contacts or (spec.contacts is not None and not spec.contacts.bodies) or len(colliding) < 2:
        return []
    problems: list[Problem] = []
    for index, body in colliding:
        if not isinstance(body, RigidBodySpec):
            continue
        shapes = ([(("bodies", index, "shape", "parts", k, "shape"), part.shape)
                   for k, part in enumerate(body.shape.parts)] if isinstance(body.shape, CompoundShape)
                  else [(("bodies", index, "shape"), body.shape)])
        for path, shape in shapes:
            if not isinstance(shape, MeshShape) or shape.convex_hull:
                continue
            from animbatch.sim.rigid.polyhedra import convex_mesh, mesh_mass_properties
            from animbatch.sim.rigid.shapes import load_mesh

            mesh = load_mesh(base_dir / shape.file, shape.scale)
            own = mesh_mass_properties(mesh).volume
            hollow = mesh_mass_properties(convex_mesh(mesh.vertices)).volume / own - 1
            if hollow > HOLLOW:
                problems.append((path, (
                    f"mesh {shape.file!r} is not convex: its convex hull is {100 * hollow:.0f} % larger than it, and "
                    "other bodies touch a mesh body as a convex solid. Split it into convex meshes (a compound "
                    "shape with mesh parts), set convex_hull: true to collide as its hull, or set "
                    "contacts: {bodies: false} if bodies need not touch each other")))
    return problems


def _joint_points(spec: Any) -> list[Problem]:
    """Ball, hinge, slider and fixed joints given by a point on each body ('attach'): the points coincide at the
    start (else the joint would snap them together)."""
    problems: list[Problem] = []
    places = {anchor.name: np.asarray(anchor.start, float) for anchor in spec.anchors}
    for body in spec.bodies:
        if hasattr(body, "position"):
            places[body.name] = np.asarray(body.position, float)
    turns = {body.name: orientation_matrix(body.orientation) for body in spec.bodies
             if isinstance(body, RigidBodySpec)}
    for index, joint in enumerate(spec.joints):
        if joint.type not in ("ball", "hinge", "slider", "fixed") or joint.attach is None or len(joint.between) < 2:
            continue
        ends = []
        for name, point in zip(joint.between, joint.attach):
            offset = np.zeros(3) if point is None or name not in turns else turns[name] @ np.asarray(point, float)
            ends.append(places[name] + offset)
        gap = float(np.linalg.norm(ends[0] - ends[1]))
        if gap > 1e-9 * max(1.0, float(np.max(np.abs(ends)))):
            problems.append((("joints", index, "attach"), (
                f"the two points are {gap:.4g} m apart at the start ({_vector(ends[0])} and {_vector(ends[1])}), "
                f"and a {joint.type} joint holds them together: move a body, or give one world point with 'anchor' "
                "instead of attach")))
    return problems


def _vector(point: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:.4g}" for c in point) + ")"


def _outside_scene_folder(name: str, base_dir: Path) -> str | None:
    """Why the mesh file ``name`` may not be read (an absolute path, or one that leaves the scene's folder), or None.

    A scene is data that may come from anyone: it must not make us read ``/etc/shadow`` or ``../../secrets``."""
    if Path(name).is_absolute():
        return (f"mesh files are given relative to the scene's folder, not as absolute paths ({name!r}); copy the "
                "file into the scene's folder (or a folder below it) and give its relative path")
    if not (base_dir / name).resolve().is_relative_to(base_dir.resolve()):
        return (f"{name!r} leads outside the scene's folder (through '..' or a link); mesh files are read only from "
                "the scene's folder and the folders below it. Copy the file there")
    return None


def _closed_surfaces(spec: Any, base_dir: Path) -> list[Problem]:
    """Pressure needs a closed, consistently wound surface (a lattice's always is; a cloth mesh may not be)."""
    problems: list[Problem] = []
    for index, body in enumerate(spec.bodies):
        if not isinstance(body, ClothSpec) or body.pressure is None:
            continue
        from animbatch.compile import deformables as build  # only scenes with pressure pay
        from animbatch.sim.deformable.topology import closed_surface_problem

        problem = closed_surface_problem(build.body_topology(body, base_dir).triangles)
        if problem is not None:
            problems.append((("bodies", index, "pressure"), f"{body.name!r} cannot hold a pressure: {problem}"))
    return problems


def _pin_selections(spec: Any, base_dir: Path) -> list[Problem]:
    """Pins of cloth and lattices select existing vertices, and not all of them (needs the bodies' topology)."""
    problems: list[Problem] = []
    for index, body in enumerate(spec.bodies):
        if not isinstance(body, DEFORMABLE_SPECS) or not body.pin:
            continue
        from animbatch.compile import deformables as build  # only scenes with pinned cloth or lattices pay

        topology = build.body_topology(body, base_dir)
        world = build.world_vertices(body, topology)
        pinned = set()
        for number, pin in enumerate(body.pin):
            vertices, messages = build.pin_vertices(pin, topology, world)
            pinned.update(vertices.tolist())
            for message in messages:
                key = "region" if message.startswith("the region") else "vertices"
                problems.append((("bodies", index, "pin", number, key), message))
        if len(pinned) == topology.vertex_count:
            problems.append((("bodies", index, "pin"), f"the pins hold all {topology.vertex_count} vertices of "
                                                       f"{body.name!r}, so nothing is left to simulate"))
    return problems


def check_analytic(spec: SceneSpec) -> list[Problem]:
    """``solver.method: analytic`` moves bodies by closed forms only: a scene with anything else is refused, naming
    it (compiling the model is cheap next to the run the scene would need)."""
    if spec.emitters:
        return [(("emitters", 0), "emitted particles are integrated step by step; solver.method analytic moves "
                                  "only the scene's bodies by closed forms: remove the emitters or choose a method "
                                  "that integrates (RK45, verlet, …)")]
    from animbatch.compile.model import compile_scene  # the model, to match each body to its closed form
    from animbatch.sim.closed_forms import NoClosedForm, check_closed_form

    try:
        check_closed_form(compile_scene(spec))
    except NoClosedForm as error:
        return [(("solver", "method"), f"analytic: {error}. Closed forms cover uniform gravity (a projectile), "
                                       "linear drag with gravity, one spring to a fixed anchor (a damped "
                                       "oscillator) and two bodies under mutual gravitation (Kepler); choose a "
                                       "method that integrates (RK45, DOP853, verlet, …) for anything else")]
    except Exception:  # noqa: BLE001 - a scene the model cannot be built from: its own checks report why
        return []
    return []
