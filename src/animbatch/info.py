"""Human-readable descriptions of a scene and its compiled model (``animbatch validate`` and ``animbatch info``)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from animbatch.compile.forces import FIELD_TERMS
from animbatch.compile.plan import RunPlan
from animbatch.scene import LoadedScene
from animbatch.scene.schema import BoxCollider, PlaneCollider, SphereCollider, random_bounds
from animbatch.sim.contact.time_stepping import DEFAULT_REST_SPEED
from animbatch.sim.deformable.vertices import ANCHOR, BODY_POINT, PARTICLE
from animbatch.sim.joints.tree import JointTree
from animbatch.sim.ledger import conservation_laws, step_note
from animbatch.sim.model import Model
from animbatch.sim.model.compiled import COMPILE_AFTER, COMPILE_AFTER_LOADED, stepper_tables
from animbatch.sim.model.dynamics import tree_of
from animbatch.summary import describe_solver, plural


def _vector(values: Iterable[float]) -> str:
    return "(" + ", ".join(f"{float(c) + 0.0:.4g}" for c in values) + ")"  # (+0.0: no "-0")


def _rigid_lines(model: Model, x0: np.ndarray, v0: np.ndarray) -> list[str]:
    """Mass properties of each rigid body: mass, centre of mass, inertia tensor and principal moments."""
    rigid = model.rigid
    assert rigid is not None
    omega = model.angular_velocities(model.y0)
    lines = []
    for b, name in enumerate(rigid.names):
        point = model.particle_count + b
        properties = rigid.geometry[b].properties
        inertia = rigid.inertia[b]
        lines += [
            f"rigid      {name}: mass {rigid.mass[b]:.6g} kg, volume {properties.volume:.6g} m³, "
            f"centre of mass {_vector(rigid.centre[b])} m from the shape origin",
            "           inertia about the centre of mass, body axes [kg·m²]: "
            + "  ".join(_vector(row) for row in inertia),
            f"           principal moments {_vector(properties.principal_moments)} kg·m²",
            f"           start: centre at {_vector(x0[point])} m, velocity {_vector(v0[point])} m/s, "
            f"ω {_vector(omega[point])} rad/s",
        ]
        if model.kinematic is not None and b in model.kinematic.rigid:
            path = model.kinematic.paths[list(model.kinematic.rigid).index(b)]
            lines.append(f"           kinematic: follows {plural(len(path.times), 'keyframe')} "
                         f"({path.interpolation}, {path.times[0]:g}…{path.times[-1]:g} s); nothing pushes it back")
    return lines


def describe_model(run: RunPlan) -> str:
    """What was compiled: timeline, solver, state layout, force terms (in evaluation order), bodies and anchors."""
    scene, model = run.scene, run.model
    spec = scene.spec
    times = model.frame_times
    lines = [f"scene      {scene.name}" + (f"  ({scene.path})" if scene.path else "")]
    if spec.description:
        lines.append(f"           {spec.description}")
    lines += [
        f"timeline   {spec.duration:g} s at {spec.fps} fps: {len(times)} frames at t = k/{spec.fps} s, "
        f"k = 0 … {len(times) - 1} (last frame at {times[-1]:.6g} s)",
        f"solver     {describe_solver(spec.solver)}",
    ]
    steps = run.steps
    if steps.step is not None and steps.interval is not None:
        note = step_note(steps.dt, steps.step, steps.interval, steps.dt_given)
        lines.append(f"step       {steps.step:.6g} s used, {steps.frame_substeps} per frame"
                     + (f": {note}" if note else ""))
    laws = conservation_laws(model)
    for number, (name, law) in enumerate(laws.items()):
        lines.append(f"{'conserves' if number == 0 else '':<10} {name.replace('_', ' ')}: "
                     f"{'yes' if law.conserved else 'no'} ({law.reason})")
    lines += [
        f"           a run warns when a conserved quantity drifts by more than {100 * spec.solver.drift_warning:.3g} % "
        "of its scale (solver.drift_warning)",
        f"state      {model.layout.size} values (float64)",
    ]
    for block in model.layout.blocks:
        span = block.span
        shape = " × ".join(map(str, block.shape))
        lines.append(f"           y[{span.start}:{span.stop}]  {block.name}  ({shape}) [{block.unit}]  {block.role}")
    if model.joints is not None:
        joints = model.joints
        shown = ", ".join(f"{name} ({text})" for name, text in zip(joints.names[:6], joints.descriptions[:6]))
        lines.append(f"joints     {joints.count} joint{'s' if joints.count != 1 else ''}: {shown}"
                     + (" …" if joints.count > 6 else "") + "; held by Baumgarte-stabilised constraint forces "
                     "(adaptive methods) or projection after every step (fixed-step)")
        tree = tree_of(model)
        lines.append("           " + (f"a tree of {plural(tree.count, 'joint')} from the world: verlet, euler and "
                                      "midpoint steps advance its joint coordinates (joints exact)"
                                      if isinstance(tree, JointTree) else f"not stepped in joint coordinates: {tree}"))
    if model.clocks is not None:
        lines.append(f"clocks     proper time dτ/dt = √(1 − v²/c²), c = {model.clocks.c:g} m/s, carried by "
                     + ", ".join(model.clocks.names))
    lines.append(f"terms      {plural(len(model.force_terms), 'force term')} compiled, evaluated in this order:")
    for number, term in enumerate(model.force_terms, 1):
        lines.append(f"           {number}. {term.label:<12} {term.describe()}")
    declared = {field.type for field in spec.fields} | {term.kind for term in model.force_terms}
    absent = [name for name in (*FIELD_TERMS, "spring", "controller", "dihedral") if name not in declared]
    if absent:
        lines.append(f"           not compiled (not declared): {', '.join(absent)}")
    if model.layout.size:
        tables = stepper_tables(model)
        lines.append("kernels    " + (f"the equations of motion have a compiled form, taken when the numpy run would "
                                      f"take {COMPILE_AFTER:g} s or more ({COMPILE_AFTER_LOADED:g} s where this "
                                      "process has loaded the kernels; ANIMBATCH_KERNELS=numba|numpy chooses)"
                                      if not isinstance(tables, str) else f"numpy equations of motion: {tables}")
                     + ("; contacts are searched and solved compiled in long runs" if model.contact_world is not None
                        else ""))
    bodies = model.bodies
    counts = [plural(model.particle_count, "particle")] if model.particle_count else []
    counts += [plural(model.rigid_count, "rigid body", "rigid bodies")] if model.rigid_count else []
    lines.append(f"bodies     {', '.join(counts)}, total mass {float(bodies.mass.sum()):.6g} kg" if counts
                 else "bodies     none (a scene of emitters only)")
    x0, v0 = model.positions(model.y0), model.velocities(model.y0)
    plain = [i for i in range(model.particle_count) if model.owners[i] == bodies.names[i]]
    if plain:
        lines.append(f"           {'particle':<16} {'mass [kg]':>10} {'radius [m]':>11}  {'position [m]':<26} "
                     "velocity [m/s]")
        for i in plain[:50]:
            lines.append(f"           {bodies.names[i]:<16} {bodies.mass[i]:>10.4g} {bodies.radius[i]:>11.4g}  "
                         f"{_vector(x0[i]):<26} {_vector(v0[i])}")
        if len(plain) > 50:
            lines.append(f"           … and {len(plain) - 50} more")
    lines += _deformable_lines(model)
    if model.rigid is not None:
        lines += _rigid_lines(model, x0, v0)
    pinned: dict[str, list[int]] = {}
    for index, (name, position) in enumerate(zip(model.anchor_names, model.anchor_position)):
        path = model.anchors.paths.get(index)
        moving = (f", then along {len(path.times)} keyframes ({path.interpolation}) to t = {path.times[-1]:g} s"
                  if path is not None else "")
        if not model.anchor_visible[index]:  # a pinned vertex: summed up per body below, unless it moves
            if path is None:
                pinned.setdefault(name.split("[", 1)[0], []).append(index)
                continue
            moving += "  (a pinned vertex)"
        lines.append(f"anchor     {name:<16} at {_vector(position)} m{moving}")
    for body, indices in pinned.items():
        lines.append(f"pinned     {len(indices)} vertices of {body!r} held where they start, from "
                     f"{_vector(model.anchor_position[indices].min(axis=0))} to "
                     f"{_vector(model.anchor_position[indices].max(axis=0))} m")
    lines += _contact_lines(scene, model)
    lines += _emitter_lines(run)
    return "\n".join(lines)


def _emitter_lines(run: RunPlan) -> list[str]:
    """Each emitter: its pool, schedule, attribute bounds, the fields its particles feel, what they collide with."""

    spec, systems = run.spec, run.particles
    if systems is None:
        return []
    lines = []
    for item, emitter in zip(spec.emitters, systems.emitters):
        schedule = emitter.schedule
        rate = (f"{item.rate:g}/s" if isinstance(item.rate, int | float)
                else f"keyframed {min(k.rate for k in item.rate):g}…{max(k.rate for k in item.rate):g}/s")
        bursts = f" + {plural(sum(b.count for b in item.bursts), 'particle')} in bursts" if item.bursts else ""
        attached = f" on rigid body {item.body!r}" if item.body else ""
        lines.append(f"emitter    {emitter.name}: {item.source.type} source{attached}, rate {rate}{bursts}; "
                     f"{schedule.born_by(spec.duration)} born by {spec.duration:g} s; pool of {emitter.capacity} "
                     f"slots{' (automatic)' if item.capacity is None else ''}")
        bounds = "; ".join(f"{name} {low:.4g}…{high:.4g} {unit}" for name, unit in
                           (("lifetime", "s"), ("speed", "m/s"), ("radius", "m"), ("mass", "kg"))
                           for low, high in [random_bounds(getattr(item, name))])
        lines.append(f"           {bounds}; cone {item.direction.cone:g}° around "
                     f"{'the source normal' if emitter.axis is None else _vector(emitter.axis)}")
        felt = ", ".join(f.describe() for f in emitter.fields) or "none (straight lines)"
        lines.append(f"           fields on its particles: {felt}")
        colliders = systems.colliders.get(emitter.name)
        bodies = sum(1 for b in colliders.bodies if b >= 0) if colliders is not None else 0  # not moving colliders
        meets = ("no colliders" if colliders is None else
                 f"{item.collision} on {plural(len(spec.colliders), 'collider')}"
                 + (f" and {plural(bodies, 'rigid body', 'rigid bodies')}" if bodies else ""))
        lines.append(f"           collisions: {meets}; never with each other")
    return lines


def _deformable_lines(model: Model) -> list[str]:
    """Each cloth or lattice: vertices (free, pinned, attached), triangles, mass, springs by family, hinges."""
    deformables = model.deformables
    if deformables is None:
        return []

    springs = model.springs
    lines = []
    for body in deformables.bodies:
        kinds = deformables.vertex_map.kind[body.vertices]
        free = deformables.vertex_map.index[body.vertices][kinds == PARTICLE]
        mass = float(model.bodies.mass[free].sum())
        counts = {}
        if springs is not None:
            for name in springs.names:
                if name.startswith(body.name + "."):
                    family = name[len(body.name) + 1:].split("[", 1)[0]
                    counts[family] = counts.get(family, 0) + 1
        families = ", ".join(f"{count} {family}" for family, count in counts.items()) or "no springs"
        lines.append(f"{body.kind:<10} {body.name}: {len(kinds)} vertices ({int((kinds == PARTICLE).sum())} free, "
                     f"{int((kinds == ANCHOR).sum())} pinned, {int((kinds == BODY_POINT).sum())} on rigid bodies), "
                     f"{len(body.triangles)} triangles, {mass:.6g} kg on the free vertices, vertex radius "
                     f"{body.radius:.4g} m")
        lines.append(f"           springs: {families}; {len(body.hinges)} interior edges (hinges)")
    return lines


def _collider_line(collider: Any) -> str:
    if isinstance(collider, PlaneCollider):
        where = f"through {_vector(collider.point)} m, normal {_vector(collider.normal)}"
    elif isinstance(collider, SphereCollider):
        where = f"centre {_vector(collider.position)} m, radius {collider.radius:g} m"
    elif isinstance(collider, BoxCollider):
        where = f"centre {_vector(collider.position)} m, size {_vector(collider.size)} m"
    else:
        where = f"{collider.file} at {_vector(collider.position)} m"
    hidden = "" if collider.visible else ", hidden"
    keys = getattr(collider, "keyframes", None)
    moving = (f", moving along {len(keys)} keyframe{'s' if len(keys) != 1 else ''} ({collider.interpolation}) "
              f"from {keys[0].time:g} to {keys[-1].time:g} s" if keys else "")
    if getattr(collider, "motion", None) is not None:
        moving = ", moving in closed form (motion)"
    return f"{collider.type:<6} {where}, {collider.material}{hidden}{moving}"


def _contact_lines(scene: LoadedScene, model: Model) -> list[str]:
    """Colliders, contact settings, collision geometry and the coefficients of every material pair that can meet."""
    spec, world = scene.spec, model.contact_world
    if world is None:
        if not spec.bodies:
            reason = "no bodies; emitted particles have their own collision pass, below"
        elif spec.colliders or spec.contacts:
            reason = "every body has collide: false; the colliders are only drawn"
        else:
            reason = "no colliders and no 'contacts' section"
        return [f"contacts   none compiled ({reason})"]
    settings = model.contact_settings
    rest = (f"{settings.rest_speed:g} m/s" if settings.rest_speed is not None
            else f"automatic ({DEFAULT_REST_SPEED * 100:g} cm/s, or 3 g dt for fixed-step methods if more)")
    collide = "with each other and with colliders" if world.bodies_collide else "with colliders only"
    lines = [f"contacts   bodies collide {collide}; rest speed {rest}; slop {settings.slop * 1000:g} mm; "
             f"at most {settings.iterations} solver iterations per step",
             f"           geometry: {plural(world.probes.count, 'probe')} (spheres and points) on the bodies, "
             f"{plural(world.boxes.count, 'box', 'boxes')} as solids"]
    lines += [f"collider   {number}. {_collider_line(collider)}" for number, collider in enumerate(spec.colliders, 1)]
    body_materials = {body.material for body in spec.bodies if body.collide}
    others = body_materials | {collider.material for collider in spec.colliders}
    pairs = sorted({tuple(sorted((a, b))) for a in body_materials for b in others})
    custom = {frozenset(pair.materials) for pair in spec.material_pairs}
    table = world.materials
    lines.append(f"materials  {'pair':<26} {'e':>5} {'μs':>6} {'μk':>6}")
    for a, b in pairs:
        coefficients = table.pair(a, b)
        note = "  (material_pairs)" if frozenset((a, b)) in custom else ""
        lines.append(f"           {a + ' – ' + b:<26} {coefficients.restitution:>5.3g} "
                     f"{coefficients.static_friction:>6.3g} {coefficients.kinetic_friction:>6.3g}{note}")
    return lines
