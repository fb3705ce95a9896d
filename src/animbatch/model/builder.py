"""Build a Model from Python, one element at a time or many at once (after Warp's ``ModelBuilder``).

    builder = ModelBuilder()
    bob = builder.add_particle("bob", mass=0.5, position=(0, -1, 0))
    top = builder.add_anchor("top", (0, 0, 0))
    builder.add_spring(bob, top, stiffness=50.0, damping=0.2, second_is_anchor=True)
    builder.add_field({"type": "gravity"})
    model = builder.finalize(duration=2.0, fps=30)

``add_particle``, ``add_particles`` and ``add_rigid_body`` return *body handles*, numbered in the order bodies were
added; springs and fields refer to bodies by handle. The model numbers bodies particles-first (see
:mod:`animbatch.model.model`). Only the fields added and, when springs exist, the spring term are compiled in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from animbatch.forces import FIELD_TERMS, BodyTable, ForceTerm, SpringForces, SpringSet
from animbatch.model.layout import StateLayout
from animbatch.model.model import Model
from animbatch.model.rigid_set import RigidBodySet
from animbatch.rigid import quaternion
from animbatch.rigid.shapes import BodyGeometry
from animbatch.scene.schema import FieldSpec

_FIELD_ADAPTER: TypeAdapter[Any] = TypeAdapter(FieldSpec)


def frame_times(duration: float, fps: float) -> np.ndarray:
    """``k / fps`` for ``k = 0 … ceil(duration · fps) - 1`` [s]: the video then lasts exactly ``duration``."""
    count = max(1, math.ceil(duration * fps - 1e-9))
    return np.arange(count) / fps


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
    shape: Any


@dataclass
class _Spring:
    name: str
    first: int
    second: int
    second_is_anchor: bool
    stiffness: float
    damping: float
    rest_length: float | None
    first_point: np.ndarray | None  # shape coordinates of a rigid body
    second_point: np.ndarray | None


class ModelBuilder:
    """Collects bodies, anchors, springs and fields; :meth:`finalize` turns them into an immutable Model."""

    def __init__(self, base_dir: str | Path = ".") -> None:
        self.base_dir = Path(base_dir)
        self._particle_names: list[str] = []
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # mass, radius, x, v
        self._rigid: list[_Rigid] = []
        self._segments: list[tuple[int, int, bool, int]] = []  # (first handle, count, is rigid, first local index)
        self._handles = 0
        self._anchor_names: list[str] = []
        self._anchor_position: list[np.ndarray] = []
        self._springs: list[_Spring] = []
        self._fields: list[tuple[Any, np.ndarray | None]] = []

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
                      names: Sequence[str] | None = None) -> np.ndarray:
        """Add many particles at once. ``positions``/``velocities``: (K, 3); mass, radius: scalar or (K,).

        Returns the new particles' body handles, shape (K,). Unnamed particles are called ``p<index>``.
        """
        positions = np.asarray(positions, float).reshape(-1, 3)
        count = len(positions)
        velocities = np.zeros_like(positions) if velocities is None else np.asarray(velocities, float).reshape(-1, 3)
        masses = np.broadcast_to(np.asarray(mass, float), (count,)).copy()
        radii = np.broadcast_to(np.asarray(radius, float), (count,)).copy()
        if np.any(masses <= 0) or np.any(radii <= 0):
            raise ValueError("particle masses and radii must be > 0")
        start = self.particle_count
        self._particle_names.extend(names if names is not None else (f"p{start + i}" for i in range(count)))
        self._chunks.append((masses, radii, positions, velocities))
        return self._new_handles(count, False, start)

    def add_rigid_body(self, name: str, geometry: BodyGeometry, *, position: Sequence[float] = (0.0, 0.0, 0.0),
                       orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
                       velocity: Sequence[float] = (0.0, 0.0, 0.0),
                       angular_velocity: Sequence[float] = (0.0, 0.0, 0.0), shape: Any = None) -> int:
        """Add a rigid body; ``position`` places its shape origin [m], ``orientation`` is a quaternion [w, x, y, z],
        ``velocity`` [m/s] is its centre of mass's, ``angular_velocity`` [rad/s] in world axes. Returns its handle."""
        q = quaternion.normalized(np.asarray(orientation, float))
        centre = np.asarray(position, float) + quaternion.rotate(q, geometry.properties.centre)
        self._rigid.append(_Rigid(name, geometry, centre, q, np.asarray(velocity, float),
                                  np.asarray(angular_velocity, float), shape))
        return int(self._new_handles(1, True, len(self._rigid) - 1)[0])

    def add_anchor(self, name: str, position: Sequence[float]) -> int:
        """Add a fixed point [m] that springs can attach to; return its anchor index."""
        self._anchor_names.append(name)
        self._anchor_position.append(np.asarray(position, float).reshape(3))
        return len(self._anchor_names) - 1

    def add_spring(self, first: int, second: int, *, stiffness: float, damping: float = 0.0,
                   rest_length: float | None = None, second_is_anchor: bool = False, name: str | None = None,
                   first_point: Sequence[float] | None = None, second_point: Sequence[float] | None = None) -> int:
        """Spring from body ``first`` to body (or anchor) ``second``; ks [N/m], kd [N·s/m], r [m].

        ``first_point``/``second_point``: attachment points of rigid bodies in shape coordinates [m] (default: the
        centre of mass). Without ``rest_length`` the spring rests at its initial length.
        """
        label = name or f"spring{len(self._springs)}"
        self._springs.append(_Spring(label, first, second, second_is_anchor, stiffness, damping, rest_length,
                                     None if first_point is None else np.asarray(first_point, float),
                                     None if second_point is None else np.asarray(second_point, float)))
        return len(self._springs) - 1

    def add_field(self, spec: Any, bodies: Sequence[int] | np.ndarray | None = None) -> None:
        """Add a force field from its scene spec (a dict is validated), acting on ``bodies`` (handles; default all)."""
        if isinstance(spec, dict):
            spec = _FIELD_ADAPTER.validate_python(spec)
        if spec.type not in FIELD_TERMS:
            raise ValueError(f"no force term registered for field type {spec.type!r}")
        self._fields.append((spec, None if bodies is None else np.asarray(bodies, dtype=np.intp)))

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

    def finalize(self, *, duration: float, fps: float) -> Model:
        """Freeze everything into a Model whose frames are sampled at ``k / fps`` over ``duration`` [s]."""
        if not self._segments:
            raise ValueError("a model needs at least one body")
        n = self.particle_count
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
        bodies = BodyTable(names, _readonly(mass), _readonly(radius), n, rigid)
        anchors = _readonly(np.array(self._anchor_position, float).reshape(-1, 3))

        terms: list[ForceTerm] = []
        for spec, handles in self._fields:
            index = None if handles is None else np.unique(self._points(handles))
            if index is not None and len(index) == len(names):
                index = None  # every body selected: use the faster unindexed path
            terms.append(FIELD_TERMS[spec.type](spec, bodies, index))
        springs = self._spring_set(x0, anchors)
        if springs is not None:
            terms.append(SpringForces.build(springs, anchors, len(names), n))

        layout = StateLayout.for_bodies(tuple(self._particle_names), tuple(body.name for body in self._rigid))
        parts = [x0.ravel()]
        motion = [v0.ravel()]
        if rigid is not None:
            rotation = quaternion.to_matrix(np.array([b.orientation for b in self._rigid]))
            inertia_world = rotation @ rigid.inertia @ np.transpose(rotation, (0, 2, 1))
            angular_momentum = np.einsum("bij,bj->bi", inertia_world, [b.angular_velocity for b in self._rigid])
            parts += [np.ravel([b.centre_position for b in self._rigid]), np.ravel([b.orientation for b in self._rigid])]
            motion += [np.ravel([b.velocity * m for b, m in zip(self._rigid, rigid.mass)]), angular_momentum.ravel()]
        y0 = _readonly(np.concatenate(parts + motion))
        return Model(bodies, tuple(self._anchor_names), anchors, springs, tuple(terms), layout, y0,
                     _readonly(frame_times(duration, fps)))

    def _rigid_set(self) -> RigidBodySet | None:
        if not self._rigid:
            return None
        properties = [body.geometry.properties for body in self._rigid]
        inertia = np.array([p.inertia for p in properties])
        return RigidBodySet(tuple(b.name for b in self._rigid), _readonly(np.array([p.mass for p in properties])),
                            _readonly(inertia), _readonly(np.linalg.inv(inertia)),
                            _readonly(np.array([p.centre for p in properties])),
                            tuple(b.geometry for b in self._rigid), tuple(b.shape for b in self._rigid), self.base_dir)

    def _spring_set(self, x0: np.ndarray, anchors: np.ndarray) -> SpringSet | None:
        if not self._springs:
            return None
        springs = self._springs
        on_anchor = np.array([s.second_is_anchor for s in springs], bool)
        first = self._points(np.array([s.first for s in springs], np.intp))
        second = np.array([s.second for s in springs], np.intp)
        second[~on_anchor] = self._points(second[~on_anchor])
        n = self.particle_count

        def offsets(points: np.ndarray, attach: list[np.ndarray | None]) -> np.ndarray:
            """Attachment points in body axes from the centre of mass (zero for particles and anchors)."""
            result = np.zeros((len(points), 3))
            for k, (point, given) in enumerate(zip(points, attach)):
                if given is not None and point >= n:
                    result[k] = given - self._rigid[point - n].geometry.properties.centre
            return result

        first_offset = offsets(first, [s.first_point for s in springs])
        second_offset = offsets(np.where(on_anchor, -1, second), [s.second_point for s in springs])

        def world(points: np.ndarray, offset: np.ndarray) -> np.ndarray:
            """Initial world positions of attachment points."""
            result = np.empty((len(points), 3))
            for k, point in enumerate(points):
                if point < n:
                    result[k] = x0[point]
                else:
                    body = self._rigid[point - n]
                    result[k] = body.centre_position + quaternion.rotate(body.orientation, offset[k])
            return result

        start = world(first, first_offset)
        end = np.empty((len(springs), 3))
        end[on_anchor] = anchors[second[on_anchor]]
        end[~on_anchor] = world(second[~on_anchor], second_offset[~on_anchor])
        initial = np.linalg.norm(start - end, axis=1)
        rest = np.array([initial[k] if s.rest_length is None else s.rest_length for k, s in enumerate(springs)])
        return SpringSet(tuple(s.name for s in springs), _readonly(first), _readonly(second), _readonly(on_anchor),
                         _readonly(np.array([s.stiffness for s in springs], float)),
                         _readonly(np.array([s.damping for s in springs], float)), _readonly(rest),
                         _readonly(first_offset), _readonly(second_offset))
