"""Build a Model from Python, one element at a time or many at once (after Warp's ``ModelBuilder``).

    builder = ModelBuilder()
    bob = builder.add_particle("bob", mass=0.5, position=(0, -1, 0))
    top = builder.add_anchor("top", (0, 0, 0))
    builder.add_spring(bob, top, stiffness=50.0, damping=0.2, second_is_anchor=True)
    builder.add_field(partial(build_gravity, g=(0.0, -9.81, 0.0)))  # sim.forces.gravity.build_gravity
    model = builder.finalize(duration=2.0, fps=30)

``add_particle``, ``add_particles`` and ``add_rigid_body`` return *body handles*, numbered in the order bodies were
added; springs and fields refer to bodies by handle. The model numbers bodies particles-first (see
:mod:`animbatch.sim.model.model`). Only the fields added and, when springs exist, the spring term are compiled in.

This builder works on numbers only. :class:`animbatch.compile.scene_builder.ModelBuilder` (also ``animbatch.api.
ModelBuilder``) is the same builder whose ``add_field`` takes a scene field spec or dict, ``{"type": "gravity"}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from animbatch import quaternion
from animbatch.sim.deformable.topology import Topology
from animbatch.sim.deformable.vertices import ANCHOR, BODY_POINT, PARTICLE, DeformableBody, DeformableSet, VertexMap
from animbatch.sim.forces import BodyTable, ForceTerm, SpringForces, SpringSet, TermFactory
from animbatch.sim.forces.controllers import ControllerSetting, controllers_term
from animbatch.sim.forces.dihedral import DihedralSprings
from animbatch.sim.forces.pressure import PressureSetting, build_pressure
from animbatch.sim.joints import Joints
from animbatch.sim.joints.assembly import MOVING_ANCHOR, WORLD, JointSetting, MotorSetting, assemble
from animbatch.sim.joints.assembly import TYPES as JOINT_TYPES
from animbatch.sim.model.clocks import ProperClocks
from animbatch.sim.model.layout import StateLayout
from animbatch.sim.model.model import Model
from animbatch.sim.model.rigid_set import RigidBodySet
from animbatch.sim.motion import AnchorMotion, KeyframePath
from animbatch.sim.rigid.shapes import BodyGeometry
from animbatch.timeline import frame_times


def _readonly(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


@dataclass
class _Rigid:
    name: str
    geometry: BodyGeometry
    centre_position: np.ndarray  # centre of mass, world [m]
    orientation: np.ndarray  # unit quaternion
    velocity: np.ndarray
    angular_velocity: np.ndarray


@dataclass(frozen=True)
class _JointRequest:
    """A joint as :meth:`ModelBuilder.add_joint` received it (body handles, shape coordinates)."""

    type: str
    first: int
    second: int | None
    second_is_anchor: bool
    anchor: Sequence[float] | None
    attach: tuple[Sequence[float] | None, Sequence[float] | None]
    axis: Sequence[float] | None
    length: float | None
    limits: tuple[float, float] | None
    motor: MotorSetting | None
    over: tuple[int, int] | None
    name: str


#: Joint types whose two points are one point (so ``anchor`` places them).
HOLDING_TYPES = ("ball", "hinge", "slider", "fixed")


@dataclass
class _SpringChunk:
    """K springs added together. ``first`` are body handles; ``second`` body handles or anchor indices
    (``second_is_anchor``); ``rest_length`` NaN: the initial length; ``first_point``/``second_point`` (K, 3) shape
    coordinates of rigid-body ends, NaN rows for ends at a centre of mass."""

    names: list[str]
    first: np.ndarray
    second: np.ndarray
    second_is_anchor: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    rest_length: np.ndarray
    first_point: np.ndarray
    second_point: np.ndarray
    mesh: bool = False


@dataclass
class Pin:
    """Vertices of a deformable body held by a pin: fixed (no ``path``, no ``body``), moved by ``path`` (offsets from
    their start over time), or attached to the rigid body with handle ``body``."""

    vertices: np.ndarray
    path: KeyframePath | None = None
    body: int | None = None


@dataclass
class _Deformable:
    name: str
    kind: str
    topology: Topology
    world: np.ndarray  # (V, 3) initial vertex positions [m]
    vertex_kind: np.ndarray  # (V,) PARTICLE / ANCHOR / BODY_POINT
    vertex_ref: np.ndarray  # (V,) particle handle, anchor index or rigid handle
    radius: float
    dihedral: tuple[float, float] | None
    pressure: PressureSetting | None = None
    self_collision: SelfCollisionSetting | None = None


@dataclass(frozen=True)
class SelfCollisionSetting:
    """A body's self-collision: its layers kept ``thickness`` [m] apart (None: twice its vertex radius), sliding on
    each other with Coulomb's ``friction``."""

    thickness: float | None = None
    friction: float = 0.0


class ModelBuilder:
    """Collects bodies, anchors, springs and fields; :meth:`finalize` turns them into an immutable Model."""

    def __init__(self) -> None:
        self._particle_names: list[str] = []
        self._particle_owners: list[str] = []  # the scene body each particle belongs to (a cloth, for its vertices)
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # mass, radius, x, v
        self._rigid: list[_Rigid] = []
        self._segments: list[tuple[int, int, bool, int]] = []  # (first handle, count, is rigid, first local index)
        self._handles = 0
        self._anchor_names: list[str] = []
        self._anchor_position: list[np.ndarray] = []
        self._anchor_paths: dict[int, KeyframePath] = {}
        self._anchor_visible: list[bool] = []
        self._springs: list[_SpringChunk] = []
        self._fields: list[tuple[TermFactory, np.ndarray | None]] = []
        self._deformables: list[_Deformable] = []
        self._controllers: list[tuple[int, ControllerSetting]] = []  # (body handle, setting)
        self._clocks: tuple[np.ndarray | None, float] | None = None  # (body handles or None for all, c)
        self._joints: list[_JointRequest] = []

    @property
    def particle_count(self) -> int:
        return len(self._particle_names)

    def _new_handles(self, count: int, rigid: bool, local_start: int) -> np.ndarray:
        self._segments.append((self._handles, count, rigid, local_start))
        self._handles += count
        return np.arange(self._handles - count, self._handles)

    def add_particle(self, name: str, *, mass: float = 1.0, radius: float = 0.05,
                     position: Sequence[float] = (0.0, 0.0, 0.0), velocity: Sequence[float] = (0.0, 0.0, 0.0)) -> int:
        """Add one particle (mass [kg], radius [m], position [m], velocity [m/s]); return its body handle."""
        return int(self.add_particles(np.asarray([position], float), velocities=np.asarray([velocity], float),
                                      mass=mass, radius=radius, names=[name])[0])

    def add_particles(self, positions: np.ndarray, *, velocities: np.ndarray | None = None,
                      mass: float | np.ndarray = 1.0, radius: float | np.ndarray = 0.05,
                      names: Sequence[str] | None = None, owner: str | None = None) -> np.ndarray:
        """Add many particles at once. ``positions``/``velocities``: (K, 3); mass, radius: scalar or (K,).

        Returns the new particles' body handles, shape (K,). Unnamed particles are called ``p<index>``. ``owner``:
        the scene body they make up (default: each is its own).
        """
        positions = np.asarray(positions, float).reshape(-1, 3)
        count = len(positions)
        velocities = np.zeros_like(positions) if velocities is None else np.asarray(velocities, float).reshape(-1, 3)
        masses = np.broadcast_to(np.asarray(mass, float), (count,)).copy()
        radii = np.broadcast_to(np.asarray(radius, float), (count,)).copy()
        if np.any(masses <= 0) or np.any(radii <= 0):
            raise ValueError("particle masses and radii must be > 0")
        start = self.particle_count
        new_names = list(names) if names is not None else [f"p{start + i}" for i in range(count)]
        self._particle_names.extend(new_names)
        self._particle_owners.extend(new_names if owner is None else [owner] * count)
        self._chunks.append((masses, radii, positions, velocities))
        return self._new_handles(count, False, start)

    def add_rigid_body(self, name: str, geometry: BodyGeometry, *, position: Sequence[float] = (0.0, 0.0, 0.0),
                       orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
                       velocity: Sequence[float] = (0.0, 0.0, 0.0),
                       angular_velocity: Sequence[float] = (0.0, 0.0, 0.0)) -> int:
        """Add a rigid body; ``position`` places its shape origin [m], ``orientation`` is a quaternion [w, x, y, z],
        ``velocity`` [m/s] is its centre of mass's, ``angular_velocity`` [rad/s] in world axes. Returns its handle."""
        q = quaternion.normalized(np.asarray(orientation, float))
        centre = np.asarray(position, float) + quaternion.rotate(q, geometry.properties.centre)
        self._rigid.append(_Rigid(name, geometry, centre, q, np.asarray(velocity, float),
                                  np.asarray(angular_velocity, float)))
        return int(self._new_handles(1, True, len(self._rigid) - 1)[0])

    def add_anchor(self, name: str, position: Sequence[float], *, path: KeyframePath | None = None,
                   visible: bool = True) -> int:
        """Add a point [m] that springs can attach to, fixed or following ``path``; return its anchor index."""
        self._anchor_names.append(name)
        self._anchor_position.append(np.asarray(position if path is None else path.position(0.0), float).reshape(3))
        self._anchor_visible.append(visible)
        if path is not None:
            self._anchor_paths[len(self._anchor_names) - 1] = path
        return len(self._anchor_names) - 1

    def add_spring(self, first: int, second: int, *, stiffness: float, damping: float = 0.0,
                   rest_length: float | None = None, second_is_anchor: bool = False, name: str | None = None,
                   first_point: Sequence[float] | None = None, second_point: Sequence[float] | None = None) -> int:
        """Spring from body ``first`` to body (or anchor) ``second``; ks [N/m], kd [N·s/m], r [m].

        ``first_point``/``second_point``: attachment points of rigid bodies in shape coordinates [m] (default: the
        centre of mass). Without ``rest_length`` the spring rests at its initial length.
        """
        label = name or f"spring{self.spring_count}"

        def point(given: Sequence[float] | None) -> np.ndarray:
            return np.full((1, 3), np.nan) if given is None else np.asarray(given, float).reshape(1, 3)

        self.add_springs(np.array([first]), np.array([second]), stiffness=stiffness, damping=damping,
                         rest_length=np.nan if rest_length is None else rest_length,
                         second_is_anchor=np.array([second_is_anchor]), names=[label],
                         first_point=point(first_point), second_point=point(second_point))
        return self.spring_count - 1

    @property
    def spring_count(self) -> int:
        return sum(len(chunk.names) for chunk in self._springs)

    def add_springs(self, first: np.ndarray, second: np.ndarray, *, stiffness: float | np.ndarray,
                    damping: float | np.ndarray = 0.0, rest_length: float | np.ndarray = np.nan,
                    second_is_anchor: np.ndarray | None = None, names: Sequence[str],
                    first_point: np.ndarray | None = None, second_point: np.ndarray | None = None,
                    mesh: bool = False) -> None:
        """Many springs at once, as in :meth:`add_spring`, with per-spring arrays (K,) (points (K, 3)); a NaN rest
        length means the initial length, NaN points the centre of mass; ``mesh``: springs of a cloth or lattice."""
        count = len(first)
        nan_points = np.full((count, 3), np.nan)

        def each(value: float | np.ndarray) -> np.ndarray:
            return np.broadcast_to(np.asarray(value, float), (count,)).copy()

        self._springs.append(_SpringChunk(
            list(names), np.asarray(first, np.intp), np.asarray(second, np.intp),
            np.zeros(count, bool) if second_is_anchor is None else np.asarray(second_is_anchor, bool),
            each(stiffness), each(damping), each(rest_length),
            nan_points if first_point is None else np.asarray(first_point, float),
            nan_points if second_point is None else np.asarray(second_point, float), mesh))

    def add_deformable(self, name: str, kind: str, topology: Topology, *, masses: np.ndarray,
                       position: Sequence[float] = (0.0, 0.0, 0.0), rotation: np.ndarray | None = None,
                       velocity: Sequence[float] = (0.0, 0.0, 0.0), radius: float | None = None,
                       springs: dict[str, tuple[float, float]] | None = None, pins: Sequence[Pin] = (),
                       dihedral: tuple[float, float] | None = None,
                       pressure: PressureSetting | None = None,
                       self_collision: SelfCollisionSetting | None = None) -> np.ndarray:
        """Add a cloth or lattice (``kind``) from its ``topology``, placed by ``rotation`` (3, 3) and ``position``
        [m]; ``masses`` (V,) [kg]; ``springs``: family -> (ks [N/m], kd [N·s/m]); ``dihedral``: (k [N·m/rad],
        c [N·m·s/rad]); ``pressure`` inside its closed surface; ``self_collision`` (None: off). Pinned vertices
        become anchors or body points; the others particles ``name[k]``.

        Returns the handles of its free vertices (the particles), for fields and selections. Rigid bodies that pins
        attach to must be added first.
        """
        rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        world = topology.vertices @ rotation.T + np.asarray(position, float)
        count = topology.vertex_count
        vertex_kind = np.full(count, PARTICLE)
        vertex_ref = np.zeros(count, np.intp)
        for pin in pins:
            chosen = np.asarray(pin.vertices, np.intp)
            if pin.body is not None:
                vertex_kind[chosen], vertex_ref[chosen] = BODY_POINT, pin.body
                continue
            vertex_kind[chosen] = ANCHOR
            for vertex in chosen:
                path = None if pin.path is None else KeyframePath(pin.path.times, pin.path.positions + world[vertex],
                                                                  pin.path.interpolation)
                vertex_ref[vertex] = self.add_anchor(f"{name}[{vertex}]", world[vertex], path=path, visible=False)
        free = np.flatnonzero(vertex_kind == PARTICLE)
        spacing = topology.spacing
        radius = radius if radius is not None else max(0.25 * spacing, 1e-6)
        if not len(free):
            raise ValueError(f"every vertex of {name!r} is pinned: nothing is left to simulate")
        handles = self.add_particles(world[free], velocities=np.tile(np.asarray(velocity, float), (len(free), 1)),
                                     mass=np.asarray(masses, float)[free], radius=radius,
                                     names=[f"{name}[{k}]" for k in free], owner=name)
        vertex_ref[free] = handles
        self._deformables.append(_Deformable(name, kind, topology, world, vertex_kind, vertex_ref, radius, dihedral,
                                             pressure, self_collision))
        for family, (stiffness, damping) in (springs or {}).items():
            self._add_mesh_springs(self._deformables[-1], family, topology.springs[family], stiffness, damping)
        return handles

    def _add_mesh_springs(self, body: _Deformable, family: str, pairs: np.ndarray, stiffness: float,
                          damping: float) -> None:
        """The springs of one family between vertices: particle, anchor or body-point ends; springs that could
        never move anything (both ends pinned, or both on one rigid body) are left out."""
        kind, ref = body.vertex_kind, body.vertex_ref
        a, b = pairs[:, 0], pairs[:, 1]
        # the first end must be a body: swap pairs whose first end is pinned to an anchor
        swap = kind[a] == ANCHOR
        a, b = np.where(swap, b, a), np.where(swap, a, b)
        same_body = (kind[a] == BODY_POINT) & (kind[b] == BODY_POINT) & (ref[a] == ref[b])
        keep = (kind[a] != ANCHOR) & ~same_body
        a, b = a[keep], b[keep]
        if not len(a):
            return
        first_point = np.full((len(a), 3), np.nan)
        second_point = np.full((len(a), 3), np.nan)
        for end, points in ((a, first_point), (b, second_point)):
            on_body = kind[end] == BODY_POINT
            if on_body.any():
                points[on_body] = self._shape_coordinates(ref[end[on_body]], body.world[end[on_body]])
        indices = np.flatnonzero(keep)
        self.add_springs(ref[a], ref[b], stiffness=stiffness, damping=damping, second_is_anchor=kind[b] == ANCHOR,
                         names=[f"{body.name}.{family}[{k}]" for k in indices],
                         first_point=first_point, second_point=second_point, mesh=True)

    def _shape_coordinates(self, handles: np.ndarray, world: np.ndarray) -> np.ndarray:
        """Shape coordinates (K, 3) of world points (K, 3) on the rigid bodies with ``handles``, at their start."""
        result = np.empty_like(world)
        for k, (handle, point) in enumerate(zip(handles, world)):
            body = self._rigid[self._points(np.array([handle]))[0] - self.particle_count]
            rotation = quaternion.to_matrix(body.orientation)
            result[k] = rotation.T @ (point - body.centre_position) + body.geometry.properties.centre
        return result

    def add_controller(self, body: int, setting: ControllerSetting) -> None:
        """Add a PD controller pulling body ``body`` (a handle) towards its setting's target."""
        self._controllers.append((body, setting))

    def add_joint(self, type: str, first: int, second: int | None = None, *, second_is_anchor: bool = False,
                  anchor: Sequence[float] | None = None,
                  attach: tuple[Sequence[float] | None, Sequence[float] | None] = (None, None),
                  axis: Sequence[float] | None = None, length: float | None = None,
                  limits: tuple[float, float] | None = None, motor: MotorSetting | None = None,
                  over: tuple[int, int] | None = None, name: str = "") -> None:
        """A joint (see :mod:`animbatch.sim.joints`) of ``type`` (one of ``animbatch.sim.joints.assembly.TYPES``)
        between body handle ``first`` and body handle ``second``, or anchor ``second`` (``second_is_anchor``), or
        the world (None).

        Where it holds: ``anchor``, a world point at the start [m] (ball, hinge, slider, fixed; default: an anchor
        end's position, else the first body's centre of mass), or ``attach``, a point of each end in shape
        coordinates [m] (None: the centre of mass, the particle or the anchor). ``axis``: hinge or slider axis,
        world axes at the start. ``length`` [m]: of a rod, rope (its longest) or pulley rope (default: at the
        start). ``limits`` (lower, upper): hinge angle [rad] or slider travel [m] from the start. ``over``: a pulley
        rope's two anchors (pulleys)."""
        if type not in JOINT_TYPES:
            raise ValueError(f"unknown joint type {type!r}; joint types: {', '.join(JOINT_TYPES)}")
        self._joints.append(_JointRequest(type, first, second, second_is_anchor, anchor, attach, axis, length,
                                          limits, motor, over, name))

    def add_clocks(self, bodies: Sequence[int] | np.ndarray | None = None, *, c: float = 299_792_458.0) -> None:
        """Give ``bodies`` (handles; default all) proper-time clocks ticking at √(1 − v²/c²), ``c`` [m/s]."""
        if c <= 0:
            raise ValueError(f"the speed of light must be positive, got {c}")
        self._clocks = (None if bodies is None else np.asarray(bodies, dtype=np.intp), float(c))

    def add_field(self, term: TermFactory, bodies: Sequence[int] | np.ndarray | None = None) -> None:
        """Add a force term, made once the bodies are known by ``term(bodies, selected points or None)``, acting on
        ``bodies`` (handles; default all). From a scene field spec or dict:
        ``add_field(animbatch.compile.forces.field_term({"type": "gravity"}))``, or use
        :class:`animbatch.compile.scene_builder.ModelBuilder`, whose ``add_field`` takes the spec itself."""
        if not callable(term):
            raise TypeError(f"add_field takes a term factory (bodies, index) -> ForceTerm, not {type(term).__name__}; "
                            "for a scene field spec or dict use animbatch.compile.scene_builder.ModelBuilder")
        self._fields.append((term, None if bodies is None else np.asarray(bodies, dtype=np.intp)))

    # ------------------------------------------------------------------------------------------ finalize

    def _points(self, handles: np.ndarray) -> np.ndarray:
        """Model point indices (particles first, then rigid bodies) of body handles."""
        starts = np.array([segment[0] for segment in self._segments])
        which = np.searchsorted(starts, handles, side="right") - 1
        points = np.empty(len(handles), np.intp)
        for k, (first, _, rigid, local) in enumerate(self._segments):
            chosen = which == k
            points[chosen] = handles[chosen] - first + local + (self.particle_count if rigid else 0)
        return points

    def finalize(self, *, duration: float, fps: float, matrices: bool = False, renormalise_every: int = 1) -> Model:
        """Freeze everything into a Model whose frames are sampled at ``k / fps`` over ``duration`` [s]; with
        ``matrices``, the rigid bodies' orientations integrated as rotation matrices, turned back into rotations
        every ``renormalise_every`` fixed steps (0: never)."""
        n = self.particle_count  # no bodies at all is allowed: a scene of emitters only
        if self._chunks:
            mass, radius, x0, v0 = (np.concatenate(parts) for parts in zip(*self._chunks))
        else:
            mass, radius, x0, v0 = np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        rigid = self._rigid_set()
        if rigid is not None:
            equivalent_radius = np.cbrt(3 * np.maximum(rigid.volume, 1e-300) / (4 * np.pi))
            mass = np.concatenate([mass, rigid.mass])
            radius = np.concatenate([radius, equivalent_radius])
        names = tuple(self._particle_names) + tuple(body.name for body in self._rigid)
        anchors = AnchorMotion(_readonly(np.array(self._anchor_position, float).reshape(-1, 3)),
                               dict(self._anchor_paths))
        deformables = self._deformable_set(anchors, len(names))
        bodies = BodyTable(names, _readonly(mass), _readonly(radius), n, rigid, deformables)

        terms: list[ForceTerm] = []
        for factory, handles in self._fields:
            index = None if handles is None else np.unique(self._points(handles))
            if index is not None and len(index) == len(names):
                index = None  # every body selected: use the faster unindexed path
            terms.append(factory(bodies, index))
        springs = self._spring_set(x0, anchors.rest)
        if springs is not None:
            used = springs.second[springs.second_is_anchor]
            terms.append(SpringForces.build(springs, anchors.only(used), len(names), n))
        if self._controllers:
            records = []
            for handle, setting in self._controllers:
                point = int(self._points(np.array([handle]))[0])
                offset = np.zeros(3)
                if point >= n and setting.point is not None:
                    offset = np.asarray(setting.point, float) - self._rigid[point - n].geometry.properties.centre
                records.append((point, setting, offset, names[point]))
            terms.append(controllers_term(records, n))
        if deformables is not None and any(d.dihedral for d in self._deformables):
            terms.append(DihedralSprings.build(deformables, [d.dihedral for d in self._deformables]))
        if deformables is not None and any(d.pressure for d in self._deformables):
            terms.append(build_pressure(deformables, {d.name: d.pressure for d in self._deformables if d.pressure}))

        clocks = None
        if self._clocks is not None:
            handles, c = self._clocks
            points = np.unique(self._points(handles)) if handles is not None else np.arange(len(names))
            clocks = ProperClocks(_readonly(points), tuple(names[p] for p in points), c) if len(points) else None
        layout = StateLayout.for_bodies(tuple(self._particle_names), tuple(body.name for body in self._rigid),
                                        clocks.names if clocks is not None else (), matrices=matrices)
        parts = [x0.ravel()]
        motion = [v0.ravel()]
        if rigid is not None:
            rotation = quaternion.to_matrix(np.array([b.orientation for b in self._rigid]))
            inertia_world = rotation @ rigid.inertia @ np.transpose(rotation, (0, 2, 1))
            angular_momentum = np.einsum("bij,bj->bi", inertia_world, [b.angular_velocity for b in self._rigid])
            parts += [np.ravel([b.centre_position for b in self._rigid]),
                      rotation.ravel() if matrices else np.ravel([b.orientation for b in self._rigid])]
            motion += [np.ravel([b.velocity * m for b, m in zip(self._rigid, rigid.mass)]), angular_momentum.ravel()]
        if clocks is not None:
            parts.append(np.zeros(clocks.count))  # every clock reads 0 at the start
        y0 = _readonly(np.concatenate(parts + motion))
        owners = tuple(self._particle_owners) + tuple(body.name for body in self._rigid)
        return Model(bodies, tuple(self._anchor_names), anchors.rest, springs, tuple(terms), layout, y0,
                     frame_times(duration, fps), anchors=anchors,
                     anchor_visible=_readonly(np.array(self._anchor_visible, bool)), owners=owners, clocks=clocks,
                     joints=self._joint_set(x0, anchors.rest), renormalise_every=renormalise_every)

    def _joint_set(self, x0: np.ndarray, anchor_rest: np.ndarray) -> Joints | None:
        """The joints, with their points turned into body offsets (see :mod:`animbatch.sim.joints.assembly`)."""
        if not self._joints:
            return None
        n = self.particle_count
        rigid = self._rigid
        positions = np.concatenate([x0, np.array([b.centre_position for b in rigid]).reshape(-1, 3)])
        rotations = np.broadcast_to(np.eye(3), (len(positions), 3, 3)).copy()
        inertia = np.zeros((len(positions), 3, 3))
        if rigid:
            rotations[n:] = quaternion.to_matrix(np.array([b.orientation for b in rigid]))
            inertia[n:] = [b.geometry.properties.inertia for b in rigid]
        masses = np.concatenate([np.concatenate([c[0] for c in self._chunks]) if self._chunks else np.zeros(0),
                                 [b.geometry.properties.mass for b in rigid]])
        anchors = np.asarray(anchor_rest, float).reshape(-1, 3)
        def offset(point: int, shape_point: Sequence[float] | None) -> np.ndarray:
            """A point of a body in body axes from its centre of mass, from shape coordinates."""
            if shape_point is None or point < n:
                return np.zeros(3)
            return np.asarray(shape_point, float) - rigid[point - n].geometry.properties.centre

        def at_start(point: int, body_offset: np.ndarray) -> np.ndarray:
            """Where a body point is at the start (on the world: the point itself)."""
            return body_offset if point == WORLD else positions[point] + rotations[point] @ body_offset

        settings = []
        moving: dict[int, int] = {}  # anchors on keyframes that joints hold on to -> their slot
        for request in self._joints:
            first = int(self._points(np.array([request.first]))[0])
            if request.second is None:
                second, second_point = WORLD, None
            elif request.second_is_anchor:
                second, second_point = WORLD, anchors[request.second]
            else:
                second, second_point = int(self._points(np.array([request.second]))[0]), None

            first_offset = offset(first, request.attach[0])
            if second != WORLD:
                second_offset = offset(second, request.attach[1])
            elif second_point is None:  # the world, at the given point or (for a rod) the first end's start
                given = request.attach[1] if request.attach[1] is not None else request.anchor
                second_offset = np.asarray(given, float) if given is not None else at_start(first, first_offset)
            else:
                second_offset = second_point
            if request.type in HOLDING_TYPES:  # both points are one world point at the start
                if request.anchor is not None:
                    where = np.asarray(request.anchor, float)
                elif request.attach[0] is not None or request.attach[1] is None:
                    where = at_start(first, first_offset)
                else:
                    where = at_start(second, second_offset)
                if request.anchor is None and request.attach != (None, None) and not (second == WORLD
                                                                                     and second_point is None):
                    gap = float(np.linalg.norm(at_start(first, first_offset) - at_start(second, second_offset)))
                    if gap > 1e-9 * max(1.0, float(np.max(np.abs(positions)))):
                        raise ValueError(f"joint {request.name!r}: its two points are {gap:.4g} m apart at the "
                                         f"start, and a {request.type} joint holds them together. Give one world "
                                         f"point with 'anchor' instead")
                if request.anchor is None and request.attach == (None, None) and second_point is not None:
                    where = second_point  # held at the anchor it names
                first_offset = rotations[first].T @ (where - positions[first])
                second_offset = where if second == WORLD else rotations[second].T @ (where - positions[second])
            if request.second_is_anchor and request.second in self._anchor_paths:  # held by an anchor that moves:
                slot = moving.setdefault(int(request.second), len(moving))  # its own slot, from its start
                second, second_offset = MOVING_ANCHOR - slot, np.asarray(second_offset, float) - second_point
            over = None if request.over is None else anchors[list(request.over)]
            settings.append(JointSetting(request.type, first, second, first_offset, np.asarray(second_offset, float),
                                         request.name, None if request.axis is None else np.asarray(request.axis,
                                                                                                     float),
                                         request.length, request.limits, request.motor, over))
        order = sorted(moving, key=moving.__getitem__)
        return assemble(settings, positions, rotations, masses, inertia, n,
                        tuple(self._anchor_paths[a] for a in order), anchors[order].reshape(-1, 3))

    def _deformable_set(self, anchors: AnchorMotion, point_count: int) -> DeformableSet | None:
        """The vertex map of all deformable bodies (model point numbers, anchors, body points)."""
        if not self._deformables:
            return None
        kinds, indices, offsets, records = [], [], [], []
        start = 0
        n = self.particle_count
        for body in self._deformables:
            count = body.topology.vertex_count
            index = body.vertex_ref.copy()
            offset = np.zeros((count, 3))
            free = body.vertex_kind == PARTICLE
            index[free] = self._points(body.vertex_ref[free])
            attached = np.flatnonzero(body.vertex_kind == BODY_POINT)
            if len(attached):
                points = self._points(body.vertex_ref[attached])
                index[attached] = points - n
                shape = self._shape_coordinates(body.vertex_ref[attached], body.world[attached])
                offset[attached] = shape - np.array([self._rigid[p - n].geometry.properties.centre for p in points])
            kinds.append(body.vertex_kind)
            indices.append(index)
            offsets.append(offset)
            setting = body.self_collision
            thickness = 0.0 if setting is None else (setting.thickness if setting.thickness is not None
                                                     else 2 * body.radius)
            records.append(DeformableBody(body.name, body.kind, slice(start, start + count),
                                          body.topology.triangles + start, body.topology.hinges + start,
                                          body.radius, setting is not None, thickness,
                                          0.0 if setting is None else setting.friction))
            start += count
        vertex_map = VertexMap(np.concatenate(kinds), np.concatenate(indices), np.concatenate(offsets),
                               first_rigid=n, point_count=point_count)
        pinned_to = vertex_map.index[vertex_map.kind == ANCHOR]
        return DeformableSet(tuple(records), vertex_map, anchors.only(pinned_to),
                             _readonly(np.concatenate([body.world for body in self._deformables])))

    def _rigid_set(self) -> RigidBodySet | None:
        if not self._rigid:
            return None
        properties = [body.geometry.properties for body in self._rigid]
        inertia = np.array([p.inertia for p in properties])
        return RigidBodySet(tuple(b.name for b in self._rigid), _readonly(np.array([p.mass for p in properties])),
                            _readonly(inertia), _readonly(np.linalg.inv(inertia)),
                            _readonly(np.array([p.centre for p in properties])),
                            tuple(b.geometry for b in self._rigid))

    def _spring_set(self, x0: np.ndarray, anchors: np.ndarray) -> SpringSet | None:
        if not self._springs:
            return None
        chunks = self._springs
        on_anchor = np.concatenate([c.second_is_anchor for c in chunks])
        first = self._points(np.concatenate([c.first for c in chunks]))
        second = np.concatenate([c.second for c in chunks])
        second[~on_anchor] = self._points(second[~on_anchor])
        first_point = np.concatenate([c.first_point for c in chunks])
        second_point = np.concatenate([c.second_point for c in chunks])
        n = self.particle_count
        centres = np.array([b.centre_position for b in self._rigid]).reshape(-1, 3)
        rotations = (quaternion.to_matrix(np.array([b.orientation for b in self._rigid])) if self._rigid
                     else np.zeros((0, 3, 3)))
        shape_centres = np.array([b.geometry.properties.centre for b in self._rigid]).reshape(-1, 3)

        def offsets(points: np.ndarray, given: np.ndarray) -> np.ndarray:
            """Attachment points in body axes from the centre of mass (zero for particles and anchors)."""
            result = np.zeros((len(points), 3))
            chosen = (points >= n) & ~np.isnan(given).any(axis=1)
            result[chosen] = given[chosen] - shape_centres[points[chosen] - n]
            return result

        def world(points: np.ndarray, offset: np.ndarray) -> np.ndarray:
            """Initial world positions of attachment points."""
            result = np.empty((len(points), 3))
            particle = points < n
            result[particle] = x0[points[particle]]
            rigid = points[~particle] - n
            result[~particle] = centres[rigid] + np.einsum("kij,kj->ki", rotations[rigid], offset[~particle])
            return result

        first_offset = offsets(first, first_point)
        second_offset = offsets(np.where(on_anchor, -1, second), second_point)
        start = world(first, first_offset)
        end = np.empty((len(first), 3))
        end[on_anchor] = anchors[second[on_anchor]]
        end[~on_anchor] = world(second[~on_anchor], second_offset[~on_anchor])
        initial = np.linalg.norm(start - end, axis=1)
        given = np.concatenate([c.rest_length for c in chunks])
        rest = np.where(np.isnan(given), initial, given)
        return SpringSet(tuple(name for c in chunks for name in c.names), _readonly(first), _readonly(second),
                         _readonly(on_anchor), _readonly(np.concatenate([c.stiffness for c in chunks])),
                         _readonly(np.concatenate([c.damping for c in chunks])), _readonly(rest),
                         _readonly(first_offset), _readonly(second_offset),
                         _readonly(np.concatenate([np.full(len(c.names), c.mesh) for c in chunks])))
