"""The compiled equations of motion of a Model: its tables, and a Dynamics that evaluates them in compiled code.

Small scenes of rigid bodies and joints (a pendulum, a chain, a ragdoll) spend their time in Python, not in
arithmetic: a step of a 20-link hinge chain is dozens of numpy calls on 3-vectors. :class:`CompiledDynamics` is
:class:`~animbatch.sim.model.dynamics.Dynamics` with its hot forms (``rhs``, ``motion_rate``, ``drift``,
``project``) each one compiled call (:mod:`animbatch.sim.kernels.stepper`), and with :meth:`~CompiledDynamics.advance`,
which steps a whole frame of a fixed-step method in one call. Everything else (energies, joint reactions, events,
contacts) is inherited and stays numpy, which remains the reference the kernels are tested against. A scene with
contacts takes the compiled forms step by step, with the contact solve between its kick and its drift in numpy
(:class:`~animbatch.sim.contact.time_stepping.ContactResolver`).

A model is compiled when every part of it has a compiled form (:func:`stepper_tables` names the first that has
none) and when its numpy run would take long enough to repay loading numba (:func:`dynamics_for`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import scipy.sparse as sp

from animbatch.sim.bodies import Kinematics
from animbatch.sim.forces.applied import AngularDrag, AppliedForce, AppliedTorque
from animbatch.sim.forces.buoyancy import Buoyancy
from animbatch.sim.forces.drag import Drag
from animbatch.sim.forces.gravitation import InverseSquarePairs
from animbatch.sim.forces.gravity import UniformGravity
from animbatch.sim.forces.springs import SpringForces
from animbatch.sim.joints import (
    AngleRows,
    AxisRows,
    Joints,
    LockRows,
    PointRows,
    Rows,
    SegmentRows,
    SlideRows,
)
from animbatch.sim.joints.pattern import coupling_pattern
from animbatch.sim.joints.tree import JointTree
from animbatch.sim.kernels import tables as T
from animbatch.sim.kernels.tables import PackedTables, pack
from animbatch.sim.model.dynamics import TREE_FORMS, Dynamics
from animbatch.sim.model.model import Model
from animbatch.sim.motion import AnchorMotion, KeyframePath

#: A numpy run estimated to take at least this long [s] is compiled: loading numba and the kernels from its disk
#: cache takes about a second, and the compiled run a small fraction of the numpy one. Half a second, not one:
#: numpy runs take two to four times their estimate (adaptive step counts come out low, and a step's projection
#: and contact solve are only partly counted), measured on jointed boxes under DOP853 (estimated 0.9 s, ran 4.6 s)
#: and on resting contacts.
COMPILE_AFTER = 0.5
#: The same, once this process has loaded the kernels a run needs (an earlier run did: in a notebook, a study, a
#: batch worker, a test session): a compiled run then costs only its setup, some milliseconds.
COMPILE_AFTER_LOADED = 0.05

Fields = dict[int, np.ndarray]


class _Paths:
    """Keyframe paths gathered into the PATH_* fields, each once."""

    def __init__(self) -> None:
        self._index: dict[int, int] = {}
        self._rows: list[np.ndarray] = []
        self._times: list[np.ndarray] = []

    def add(self, path: KeyframePath) -> int:
        """The index of ``path`` in the table."""
        if id(path) in self._index:
            return self._index[id(path)]
        times = np.asarray(path.times, float)
        positions = np.asarray(path.positions, float).reshape(len(times), -1)
        values = np.zeros((len(times), 3))
        values[:, : positions.shape[1]] = positions
        rows = np.zeros((len(times), 4, 3))
        rows[:, 3] = values
        if len(times) > 1:
            if path.interpolation == "cubic":
                coefficients = np.asarray(getattr(path, "_spline").coefficients, float)  # (4, K−1, d), powers 3 … 0
                rows[:-1, :, : positions.shape[1]] = np.transpose(coefficients, (1, 0, 2))
            else:
                rows[:-1, 2] = np.diff(values, axis=0) / np.diff(times)[:, None]
        self._index[id(path)] = len(self._rows)
        self._rows.append(rows)
        self._times.append(times)
        return self._index[id(path)]

    def fields(self) -> Fields:
        counts = np.array([len(t) for t in self._times], np.int64)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if len(counts) else counts
        return {T.PATH_KEYS: np.stack([starts, counts], axis=1) if len(counts) else np.zeros((0, 2)),
                T.PATH_TIMES: np.concatenate(self._times) if self._times else np.zeros(0),
                T.PATH_COEFFICIENTS: np.concatenate(self._rows) if self._rows else np.zeros((0, 4, 3))}


def _anchor_paths(anchors: AnchorMotion, paths: _Paths) -> np.ndarray:
    return np.array([paths.add(anchors.paths[a]) if a in anchors.paths else -1 for a in range(anchors.count)],
                    np.int64)


def _force_fields(model: Model, paths: _Paths) -> Fields | str:
    constant_force = np.zeros((model.body_count, 3))
    springs: SpringForces | None = None
    pairs: list[InverseSquarePairs] = []
    buoyancies: list[Buoyancy] = []
    drags: list[Drag] = []
    loads: list[AppliedForce | AppliedTorque | AngularDrag] = []
    for term in model.force_terms:
        if isinstance(term, UniformGravity):
            if term.index is None:
                constant_force += term.weight
            else:
                np.add.at(constant_force, term.index, term.weight)
        elif isinstance(term, SpringForces) and springs is None:
            springs = term
        elif isinstance(term, InverseSquarePairs):
            pairs.append(term)
        elif isinstance(term, Buoyancy) and not len(term.triangles):  # bodies of spheres (a mesh's: numpy)
            buoyancies.append(term)
        elif isinstance(term, Drag):
            drags.append(term)
        elif isinstance(term, (AppliedForce, AppliedTorque, AngularDrag)):
            loads.append(term)
        else:
            return f"its {term.label} term has no compiled form"
    fields = {T.CONSTANT_FORCE: constant_force, T.CONSTANT_TORQUE: np.zeros((model.rigid_count, 3))}
    if pairs:
        points = [np.arange(model.body_count) if term.index is None else np.asarray(term.index) for term in pairs]
        fields.update({T.PAIR_TERMS: np.array([[term.coupling, term.softening] for term in pairs]),
                       T.PAIR_START: np.concatenate([[0], np.cumsum([len(p) for p in points])]),
                       T.PAIR_POINTS: np.concatenate(points),
                       T.PAIR_SOURCE: np.concatenate([term.source for term in pairs])})
    if buoyancies:
        fields.update(_buoyancy_fields(buoyancies))
    if drags:
        fields.update(_drag_fields(drags, model.body_count))
    if loads:
        fields.update(_load_fields(loads))
    if springs is not None:
        s = springs.springs
        fields.update({
            T.SPRING_ENDS: np.stack([s.first, s.second, s.second_is_anchor], axis=1),
            T.SPRING_OFFSETS: np.stack([s.first_offset, s.second_offset], axis=1),
            T.SPRING_CONSTANTS: np.stack([s.stiffness, s.damping, s.rest_length], axis=1),
            T.ANCHOR_REST: np.asarray(springs.anchors.rest, float).reshape(-1, 3),
            T.ANCHOR_PATH: _anchor_paths(springs.anchors, paths)})
    return fields


def _buoyancy_fields(terms: list[Buoyancy]) -> Fields:
    """The BUOYANCY_* fields of buoyancy terms on bodies made of spheres."""
    def each(values: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([np.full(len(v), k) for k, v in enumerate(values)])

    owners, bodies = [term.sphere_owner for term in terms], [term.bodies for term in terms]
    return {
        T.BUOYANCY_TERMS: np.array([[term.density * term.g, term.level, *term.up, term.linear_damping,
                                     term.angular_damping] for term in terms], float),
        T.BUOYANCY_SPHERES: np.stack([np.concatenate(owners), np.concatenate([t.sphere_rigid for t in terms]),
                                      each(owners)], axis=1),
        T.BUOYANCY_SHAPES: np.concatenate([np.column_stack([t.sphere_offset, t.sphere_radius]) for t in terms]),
        T.BUOYANCY_BODIES: np.stack([np.concatenate(bodies), each(bodies)], axis=1),
        T.BUOYANCY_VOLUMES: np.concatenate([term.full_volume for term in terms]),
    }


def _drag_fields(terms: list[Drag], count: int) -> Fields:
    """The DRAG_* fields: each term's points dragged at their centre of mass, then its rigid bodies dragged at a
    body point (the order the numpy term adds them in)."""
    points, shapes = [], []
    for number, term in enumerate(terms):
        centres = np.arange(count) if term.index is None else np.asarray(term.index)
        coefficient = np.broadcast_to(np.ravel(term.coefficient), (len(centres),))
        points += [[point, -1, number] for point in centres]
        shapes += [[0.0, 0.0, 0.0, c] for c in coefficient]
        if term.at_points is not None and len(term.at_points):
            assert term.at_rigid is not None and term.at_offset is not None  # set with at_points
            at_coefficient = np.broadcast_to(np.ravel(term.at_coefficient), (len(term.at_points),))
            points += [[point, rigid, number] for point, rigid in zip(term.at_points, term.at_rigid)]
            shapes += [[*offset, c] for offset, c in zip(term.at_offset, at_coefficient)]
    return {T.DRAG_TERMS: np.array([[term.law == "quadratic", *(term.wind if term.wind is not None else np.zeros(3))]
                                    for term in terms], float),
            T.DRAG_POINTS: np.array(points, np.int64).reshape(-1, 3),
            T.DRAG_SHAPES: np.array(shapes, float).reshape(-1, 4)}


def _load_fields(terms: list[AppliedForce | AppliedTorque | AngularDrag]) -> Fields:
    """The LOAD_* fields: each applied load on each of its bodies, in the order the numpy terms add them (a force's
    particles, then its rigid bodies)."""
    points, values = [], []
    for term in terms:
        first, body_axes = term.first_rigid, 0.0
        if isinstance(term, AppliedForce):
            body_axes = float(term.frame == "body")
            for point in term.particles:  # a particle has no body axes: its force is in world axes
                points.append([point, -1, T.FORCE_LOAD])
                values.append([*term.force, 0.0, 0.0, 0.0, 0.0])
            offsets = term.offset
        else:
            offsets = np.zeros((len(term.rigid), 3))
        for rigid, offset in zip(term.rigid, offsets):
            if isinstance(term, AppliedForce):
                kind, vector = T.FORCE_LOAD, term.force
            elif isinstance(term, AppliedTorque):
                kind, vector, body_axes = T.TORQUE_LOAD, term.torque, float(term.frame == "body")
            else:
                kind, vector = T.ANGULAR_DRAG_LOAD, np.array([term.coefficient, 0.0, 0.0])
            points.append([first + rigid, rigid, kind])
            values.append([*vector, body_axes, *offset])
    return {T.LOAD_POINTS: np.array(points, np.int64).reshape(-1, 3),
            T.LOAD_VALUES: np.array(values, float).reshape(-1, 7)}


def _kind_rows(joints: Joints) -> tuple[dict[type, Any], np.ndarray]:
    """The row kinds of the joints by type, and the first row of each of the six (0 where absent)."""
    by_type: dict[type, Any] = {}
    first = np.zeros(6, np.int64)
    row = 0
    order = (SegmentRows, PointRows, AxisRows, LockRows, SlideRows, AngleRows)
    for rows in joints.kinds:
        by_type[type(rows)] = rows
        first[order.index(type(rows))] = row
        row += len(rows.bodies)
    return by_type, first


def _joint_fields(model: Model, paths: _Paths) -> Fields | str:
    joints = model.joints
    if joints is None:
        return {T.SLOT_RIGID: np.array([-1]), T.SLOT_INVERSE_MASS: np.zeros(1), T.SLOT_PATH: np.array([-1]),
                T.JOINT_SCALE: np.ones(1), T.KIND_ROWS: np.zeros(6)}
    known = (SegmentRows, PointRows, AxisRows, LockRows, SlideRows, AngleRows)
    types = [type(rows) for rows in joints.kinds]
    if any(kind not in known for kind in types) or len(set(types)) != len(types):
        return "its joints have rows of a kind the compiled solve does not know"
    count = len(joints.points)
    slots = joints.world + 1
    slot_rigid = np.full(slots, -1, np.int64)
    rigid = joints.points >= joints.first_rigid
    slot_rigid[:count][rigid] = joints.points[rigid] - joints.first_rigid
    slot_inverse_mass = np.zeros(slots)
    slot_inverse_mass[:count] = joints.inverse_mass
    slot_path = np.full(slots, -1, np.int64)
    for m, path in enumerate(joints.anchor_paths):
        slot_path[count + m] = paths.add(path)
    kinds, first_rows = _kind_rows(joints)
    fields: Fields = {
        T.JOINT_POINTS: joints.points, T.SLOT_RIGID: slot_rigid, T.SLOT_INVERSE_MASS: slot_inverse_mass,
        T.SLOT_PATH: slot_path, T.ROW_BODIES: np.concatenate([rows.bodies for rows in joints.kinds]),
        T.ROW_UNILATERAL: joints.row_is_unilateral, T.JOINT_SCALE: np.array([joints.scale]),
        T.KIND_ROWS: first_rows}
    if (segments := kinds.get(SegmentRows)) is not None:
        fields[T.SEGMENT_ENDS] = np.stack([segments.segment_row, segments.near_body, segments.near_slot,
                                               segments.far_body, segments.far_slot], axis=1)
        fields[T.SEGMENT_OFFSETS] = np.stack([segments.near_offset, segments.far_offset], axis=1)
        fields[T.SEGMENT_ROWS] = np.stack([segments.length, segments.sign], axis=1)
    if (points := kinds.get(PointRows)) is not None:
        fields[T.POINT_BODIES] = points.bodies[::3]
        fields[T.POINT_OFFSETS] = np.stack([points.first_offset, points.second_offset], axis=1)
    if (axes := kinds.get(AxisRows)) is not None:
        fields[T.AXIS_BODIES] = axes.bodies[::2]
        fields[T.AXIS_AXIS], fields[T.AXIS_ACROSS] = axes.axis, axes.across
    if (locks := kinds.get(LockRows)) is not None:
        fields[T.LOCK_BODIES], fields[T.LOCK_RELATIVE] = locks.bodies[::3], locks.relative
    if (slides := kinds.get(SlideRows)) is not None:
        fields[T.SLIDE_BODIES] = slides.bodies
        fields[T.SLIDE_OFFSETS] = np.stack([slides.first_offset, slides.second_offset], axis=1)
        fields[T.SLIDE_DIRECTION] = slides.direction
        fields[T.SLIDE_BOUNDS] = np.stack([slides.bound, slides.sign], axis=1)
    if (angles := kinds.get(AngleRows)) is not None:
        fields[T.ANGLE_BODIES], fields[T.ANGLE_AXIS] = angles.bodies, angles.axis
        fields[T.ANGLE_REFERENCES] = np.stack([angles.first_reference, angles.second_reference], axis=1)
        fields[T.ANGLE_BOUNDS] = np.stack([angles.bound, angles.sign], axis=1)
    if (motors := joints.motors) is not None:
        fields.update(_motor_fields(motors, paths))
    movable = np.zeros(slots, bool)
    movable[:count] = True
    pattern = coupling_pattern(fields[T.ROW_BODIES], movable)
    fields.update({T.ORDER: pattern.order, T.COLUMN_START: pattern.column_start,
                   T.COLUMN_ROWS: pattern.column_rows,
                   T.PAIRS: np.stack([pattern.pair_first // 2, pattern.pair_first % 2, pattern.pair_second // 2,
                                      pattern.pair_second % 2, pattern.pair_target], axis=1),
                   T.UPDATE_START: pattern.update_start,
                   T.UPDATES: np.stack([pattern.update_target, pattern.update_first, pattern.update_second],
                                           axis=1)})
    return fields


def _motor_fields(motors: Any, paths: _Paths) -> Fields:
    total = len(motors.joint)
    hinge = np.asarray(motors.hinge, bool)
    bodies = np.zeros((total, 2), np.int64)
    axis, references, offsets = np.zeros((total, 3)), np.zeros((total, 2, 3)), np.zeros((total, 2, 3))
    if motors.angles is not None:
        a = motors.angles
        bodies[hinge], axis[hinge] = a.bodies, a.axis
        references[hinge] = np.stack([a.first_reference, a.second_reference], axis=1)
    if motors.travels is not None:
        s = motors.travels
        bodies[~hinge], axis[~hinge] = s.bodies, s.direction
        offsets[~hinge] = np.stack([s.first_offset, s.second_offset], axis=1)
    target_path = [paths.add(t.path) if t.path is not None else -1 for t in motors.targets]
    return {T.MOTOR_BODIES: bodies, T.MOTOR_KIND: np.stack([hinge, target_path], axis=1),
            T.MOTOR_AXIS: axis, T.MOTOR_REFERENCES: references, T.MOTOR_OFFSETS: offsets,
            T.MOTOR_GAINS: np.stack([[t.speed for t in motors.targets], motors.stiffness, motors.damping,
                                         motors.max_effort], axis=1)}


def stepper_tables(model: Model) -> PackedTables | str:
    """The packed tables of ``model`` for the compiled equations of motion, or why it has none (what it has that
    they do not cover)."""
    if model.clocks is not None:
        return "it has proper-time clocks"
    if model.layout.matrix_orientation:
        return "it integrates rotation matrices"
    if model.kinematic is not None:
        return "it has rigid bodies on keyframes"
    if not model.layout.size:
        return "it has no bodies"
    paths = _Paths()
    forces = _force_fields(model, paths)
    if isinstance(forces, str):
        return forces
    joints = _joint_fields(model, paths)
    if isinstance(joints, str):
        return joints
    rigid = model.rigid
    fields: Fields = {T.PARTICLE_INVERSE_MASS: 1.0 / model.bodies.mass[: model.particle_count]}
    if rigid is not None:
        fields.update({T.RIGID_INVERSE_MASS: 1.0 / rigid.mass, T.INERTIA: rigid.inertia,
                       T.INVERSE_INERTIA: rigid.inverse_inertia})
    return pack({**fields, **forces, **joints, **paths.fields()})


@functools.cache
def build_stepper_kernels() -> str | None:
    """Build (or load from numba's disk cache) the compiled equations of motion, every entry point once on a bob
    on a rod and a spring; None, or what numba or LLVM could not do."""
    from animbatch.sim.kernels import build_failure

    def build() -> None:
        from animbatch.sim.forces.gravity import build_gravity
        from animbatch.sim.model.builder import ModelBuilder

        builder = ModelBuilder()
        bob = builder.add_particle("bob", position=(0.5, 0.0, 0.0))
        pivot = builder.add_anchor("pivot", (0.0, 0.0, 0.0))
        builder.add_spring(bob, pivot, stiffness=10.0, second_is_anchor=True)
        builder.add_joint("distance", bob, pivot, second_is_anchor=True)
        builder.add_field(functools.partial(build_gravity, g=np.array([0.0, -9.81, 0.0])))
        system = CompiledDynamics(builder.finalize(duration=0.1, fps=10))
        y = system.model.y0.copy()
        config, motion = system.split(y)
        system.rhs(0.0, y)
        rate = system.motion_rate(0.0, config, motion)
        system.drift(config, motion, 1e-3)
        system.project(y)
        system.advance(("verlet", rate), y, 0.0, 1e-3, 1)
        system.advance(("runge_kutta", (np.zeros((1, 1)), np.ones(1), np.zeros(1))), y, 0.0, 1e-3, 1)
        state = system.kinematics(config, motion, copy=True)
        system.project_velocities(state, state.v, state.omega)
        system.velocity_rows(state, system.model.body_count)
        # and a bar on a hinge, which steps in its angle (animbatch.sim.joints.tree)
        from animbatch.sim.rigid import mass_properties
        from animbatch.sim.rigid.shapes import BodyGeometry

        builder = ModelBuilder()
        bar = builder.add_rigid_body("bar", BodyGeometry(mass_properties.cuboid(1.0, np.array([0.1, 0.02, 0.02])),
                                                         np.zeros((0, 4)), np.zeros((0, 3, 3))))
        builder.add_joint("hinge", bar, anchor=(-0.05, 0.0, 0.0), axis=(0.0, 0.0, 1.0))
        builder.add_field(functools.partial(build_gravity, g=np.array([0.0, -9.81, 0.0])))
        hinged = CompiledDynamics(builder.finalize(duration=0.1, fps=10))
        y = hinged.model.y0.copy()
        rate = hinged.motion_rate(0.0, *hinged.split(y))
        hinged.advance(("verlet", rate), y, 0.0, 1e-3, 1)
        hinged.advance(("runge_kutta", (np.zeros((1, 1)), np.ones(1), np.zeros(1))), y, 0.0, 1e-3, 1)

    return build_failure(build)


class _Entry:
    """A kernel called by its compiled entry point once it has been called through numba's dispatcher: the
    dispatcher types every argument at every call, which for the ~90 arrays of the tables costs about 20 µs, five
    times what the entry point takes to read them (an adaptive method calls the right-hand side tens of thousands of
    times). The argument types never change for one model."""

    def __init__(self, kernel: Any) -> None:
        self.kernel = kernel
        self.call: Any = None

    def __call__(self, *args: Any) -> Any:
        if self.call is not None:
            return self.call(*args)
        result = self.kernel(*args)  # compiles, or loads from the disk cache
        from numba import typeof

        compiled = self.kernel.overloads.get(tuple(typeof(argument) for argument in args))
        self.call = compiled.entry_point if compiled is not None else self.kernel
        return result


class CompiledDynamics(Dynamics):
    """:class:`Dynamics` whose right-hand side, kick, drift and projection are compiled calls on the packed
    ``tables`` (see the module notes)."""

    def __init__(self, model: Model, tables: PackedTables | None = None) -> None:
        super().__init__(model)
        from animbatch.sim.kernels import rigid_motion, stepper

        found = stepper_tables(model) if tables is None else tables
        if isinstance(found, str):
            raise ValueError(f"this model cannot be compiled: {found}")
        self.tables = found
        # the tables and this system's own factor cache (the last factorisation of the joints' coupling matrix)
        self._packed = (found.floats, found.integers, found.layout,
                        np.zeros(stepper.factor_cache_size(found.layout)))
        self._forms = {"runge_kutta": stepper.FORM_RUNGE_KUTTA, "symplectic_euler": stepper.FORM_SYMPLECTIC_EULER,
                       "verlet": stepper.FORM_VERLET}
        self._no_rows = np.zeros(0, bool)
        self._no_start = np.zeros(0)  # no step's start: a plain projection (see Dynamics.project)
        # the kernels, by their entry points once called (named apart from Dynamics' own helpers)
        self._compiled_rhs, self._compiled_rate = _Entry(stepper.rhs), _Entry(stepper.motion_rate)
        self._compiled_drift, self._compiled_project = _Entry(rigid_motion.drift), _Entry(stepper.project)
        self._compiled_advance = _Entry(stepper.advance)
        self._compiled_project_velocities = _Entry(stepper.project_velocities)
        self._compiled_held_rows = _Entry(stepper.held_rows)
        if isinstance(self.tree, JointTree):
            from animbatch.sim.kernels import joint_tree

            tree = self.tree
            self._tree_tables = (np.stack([tree.body, tree.parent, tree.slider.astype(np.int64)], axis=1),
                                 np.stack([tree.child_offset, tree.parent_offset, tree.axis], axis=1),
                                 tree.mass, tree.inertia, tree.inverse_inertia, *self._packed[:3])
            self._compiled_tree_advance = _Entry(joint_tree.advance)

    def _engaged(self) -> tuple[np.ndarray, bool]:
        if self.engaged_stops is None:
            return self._no_rows, False
        return np.asarray(self.engaged_stops, bool), True

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        dydt = np.empty(len(y))
        engaged, use = self._engaged()
        self._compiled_rhs(float(t), np.ascontiguousarray(y, dtype=float), *self._packed, self._config_size, engaged,
                           use, float(self.joint_stabilisation), dydt)
        return dydt

    def motion_rate(self, t: float, config: np.ndarray, motion: np.ndarray,
                    out: np.ndarray | None = None) -> np.ndarray:
        out = np.empty(len(motion)) if out is None else out
        engaged, use = self._engaged()
        self._compiled_rate(float(t), np.ascontiguousarray(config), np.ascontiguousarray(motion), *self._packed,
                            engaged, use, float(self.joint_stabilisation), out)
        return out

    def drift(self, config: np.ndarray, motion: np.ndarray, h: float) -> None:
        self._compiled_drift(config, np.ascontiguousarray(motion), float(h), self.tables.floats, self.tables.layout)

    def project(self, y: np.ndarray, *, joints: bool = True, reach: float = 0.0, t: float = 0.0,
                start: np.ndarray | None = None, step: float = 0.0) -> None:
        if not joints or y.ndim != 1:  # quaternions only (or many states at once): the numpy form is as quick
            super().project(y, joints=joints, reach=reach, t=t)
            return
        begun = np.ascontiguousarray(start, dtype=float) if start is not None else self._no_start
        self._compiled_project(y, *self._packed, self._config_size, float(reach), float(t), begun, float(step))

    @staticmethod
    def _placement(state: Kinematics) -> tuple[float, np.ndarray, np.ndarray]:
        """A state's time, positions (P, 3) and rotations (B, 3, 3, none for particles alone) as the kernels take
        them."""
        rotation = state.rotation if state.rotation is not None else np.zeros((0, 3, 3))
        return float(state.t), np.ascontiguousarray(state.x, dtype=float), np.ascontiguousarray(rotation, dtype=float)

    def velocity_rows(self, state: Kinematics, size: int, *, dense: bool = False) -> sp.csr_matrix | np.ndarray:
        assert self.joints is not None
        count = len(self.joints.row_is_unilateral)
        violation, jac = np.empty(count), np.empty((count, 2, 6))
        t, x, rotation = self._placement(state)
        self._compiled_held_rows(t, *self._packed[:3], x, rotation, violation, jac)
        return self.joints.held_matrix(Rows(violation, jac[:, :, :3], jac[:, :, 3:], np.full(count, np.nan)), size,
                                       dense=dense)

    def project_velocities(self, state: Kinematics, v: np.ndarray, omega: np.ndarray | None) -> None:
        turning = omega if omega is not None else np.zeros((0, 3))
        # in place on the caller's arrays: copies (for a layout numba cannot take) are written back
        moving, spinning = np.ascontiguousarray(v, dtype=float), np.ascontiguousarray(turning, dtype=float)
        t, x, rotation = self._placement(state)
        self._compiled_project_velocities(t, *self._packed, x, rotation, moving, spinning)
        if moving is not v:
            v[...] = moving
        if omega is not None and spinning is not omega:
            omega[...] = spinning

    def advances(self, form: tuple[str, object] | None) -> bool:
        """Every scheme form is stepped here, in one compiled call."""
        return form is not None

    def advance(self, form: tuple[str, Any], y: np.ndarray, t: float, h: float, steps: int) -> int:
        """``steps`` fixed steps of ``h`` [s] from ``t`` [s] of the scheme form ``form`` (see
        :meth:`~animbatch.sim.integrators.fixed_step.Scheme.compiled_form`), in place; returns the right-hand sides
        evaluated."""
        name, data = form
        if name == "runge_kutta":
            (a, weights, nodes), rate = data, np.zeros(0)
        else:
            a, weights, nodes = np.zeros((0, 0)), np.zeros(0), np.zeros(0)
            rate = data if name == "verlet" else np.zeros(0)
        if name in TREE_FORMS and isinstance(self.tree, JointTree):
            return int(self._compiled_tree_advance(y, float(t), float(h), int(steps), self._forms[name], a, weights,
                                                   nodes, rate, *self._tree_tables))
        return int(self._compiled_advance(y, float(t), float(h), int(steps), self._forms[name], a, weights, nodes,
                                          rate, *self._packed, self._config_size))


def dynamics_for(model: Model, numpy_seconds: float) -> Dynamics:
    """The Dynamics to integrate ``model`` with: compiled where every part of it has a compiled form, its numpy run
    would take ``numpy_seconds`` [s] ≥ :data:`COMPILE_AFTER` (:data:`COMPILE_AFTER_LOADED` where this process has
    loaded the kernels it needs already; or ``ANIMBATCH_KERNELS=numba`` asks for it) and the kernels build; else
    numpy, marked as a long run when it is one (its contacts then solve compiled). A model with neither a compiled
    form nor contacts has nothing to compile: numba is not even loaded for it (most of a second)."""
    from animbatch.sim.kernels import (
        CONTACT_KERNELS,
        MIN_WORK,
        STEPPER_KERNELS,
        compiled_kernels,
        kernels_loaded,
        kernels_ready,
    )

    tables = stepper_tables(model)
    needed = ([] if isinstance(tables, str) else [STEPPER_KERNELS]) + (
        [CONTACT_KERNELS] if model.contact_world is not None else [])
    threshold = COMPILE_AFTER_LOADED if needed and kernels_loaded(*needed) else COMPILE_AFTER
    long_run = compiled_kernels(MIN_WORK if numpy_seconds >= threshold and needed else 0.0)
    if isinstance(tables, str) or not (long_run and kernels_ready(MIN_WORK, build_stepper_kernels, STEPPER_KERNELS,
                                                                  "numpy integrates the bodies")):
        system = Dynamics(model)
    else:
        system = CompiledDynamics(model, tables)
    system.long_run = long_run
    return system
