"""Build a Model from Python, one element at a time or many at once (after Warp's ``ModelBuilder``).

    builder = ModelBuilder()
    bob = builder.add_particle("bob", mass=0.5, position=(0, -1, 0))
    top = builder.add_anchor("top", (0, 0, 0))
    builder.add_spring(bob, top, stiffness=50.0, damping=0.2, second_is_anchor=True)
    builder.add_field({"type": "gravity"})
    model = builder.finalize(duration=2.0, fps=30)

Only the fields added and, when springs exist, the spring term are compiled into the model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from animbatch.forces import FIELD_TERMS, ForceTerm, ParticleProperties, SpringForces, SpringSet
from animbatch.model.layout import StateLayout
from animbatch.model.model import Model
from animbatch.scene.schema import FieldSpec

_FIELD_ADAPTER: TypeAdapter[Any] = TypeAdapter(FieldSpec)


def frame_times(duration: float, fps: float) -> np.ndarray:
    """``k / fps`` for ``k = 0 … ceil(duration · fps) - 1`` [s]: the video then lasts exactly ``duration``."""
    count = max(1, math.ceil(duration * fps - 1e-9))
    return np.arange(count) / fps


def _readonly(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


class ModelBuilder:
    """Collects particles, anchors, springs and fields; :meth:`finalize` turns them into an immutable Model."""

    def __init__(self) -> None:
        self._names: list[str] = []
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # mass, radius, x, v
        self._anchor_names: list[str] = []
        self._anchor_position: list[np.ndarray] = []
        self._springs: list[tuple[str, int, int, bool, float, float, float | None]] = []
        self._fields: list[tuple[Any, np.ndarray | None]] = []

    @property
    def particle_count(self) -> int:
        return len(self._names)

    def add_particle(self, name: str, *, mass: float = 1.0, radius: float = 0.05,
                     position: Sequence[float] = (0.0, 0.0, 0.0), velocity: Sequence[float] = (0.0, 0.0, 0.0)) -> int:
        """Add one particle (mass [kg], radius [m], position [m], velocity [m/s]); return its index."""
        return int(self.add_particles(np.asarray([position], float), velocities=np.asarray([velocity], float),
                                      mass=mass, radius=radius, names=[name])[0])

    def add_particles(self, positions: np.ndarray, *, velocities: np.ndarray | None = None,
                      mass: float | np.ndarray = 1.0, radius: float | np.ndarray = 0.05,
                      names: Sequence[str] | None = None) -> np.ndarray:
        """Add many particles at once. ``positions``/``velocities``: (K, 3); mass, radius: scalar or (K,).

        Returns the new particles' indices, shape (K,). Unnamed particles are called ``p<index>``.
        """
        positions = np.asarray(positions, float).reshape(-1, 3)
        count = len(positions)
        velocities = np.zeros_like(positions) if velocities is None else np.asarray(velocities, float).reshape(-1, 3)
        masses = np.broadcast_to(np.asarray(mass, float), (count,)).copy()
        radii = np.broadcast_to(np.asarray(radius, float), (count,)).copy()
        if np.any(masses <= 0) or np.any(radii <= 0):
            raise ValueError("particle masses and radii must be > 0")
        start = self.particle_count
        self._names.extend(names if names is not None else (f"p{start + i}" for i in range(count)))
        self._chunks.append((masses, radii, positions, velocities))
        return np.arange(start, start + count)

    def add_anchor(self, name: str, position: Sequence[float]) -> int:
        """Add a fixed point [m] that springs can attach to; return its anchor index."""
        self._anchor_names.append(name)
        self._anchor_position.append(np.asarray(position, float).reshape(3))
        return len(self._anchor_names) - 1

    def add_spring(self, first: int, second: int, *, stiffness: float, damping: float = 0.0,
                   rest_length: float | None = None, second_is_anchor: bool = False, name: str | None = None) -> int:
        """Spring from particle ``first`` to particle (or anchor) ``second``; ks [N/m], kd [N·s/m], r [m].

        Without ``rest_length`` the spring rests at its initial length.
        """
        label = name or f"spring{len(self._springs)}"
        self._springs.append((label, first, second, second_is_anchor, stiffness, damping, rest_length))
        return len(self._springs) - 1

    def add_field(self, spec: Any, particles: Sequence[int] | np.ndarray | None = None) -> None:
        """Add a force field from its scene spec (a dict is validated), acting on ``particles`` (default all)."""
        if isinstance(spec, dict):
            spec = _FIELD_ADAPTER.validate_python(spec)
        if spec.type not in FIELD_TERMS:
            raise ValueError(f"no force term registered for field type {spec.type!r}")
        index = None if particles is None else np.unique(np.asarray(particles, dtype=np.intp))
        self._fields.append((spec, index))

    def finalize(self, *, duration: float, fps: float) -> Model:
        """Freeze everything into a Model whose frames are sampled at ``k / fps`` over ``duration`` [s]."""
        if not self._chunks:
            raise ValueError("a model needs at least one particle")
        mass, radius, x0, v0 = (np.concatenate(parts) for parts in zip(*self._chunks))
        names = tuple(self._names)
        particles = ParticleProperties(names, _readonly(mass), _readonly(radius))
        anchors = _readonly(np.array(self._anchor_position, float).reshape(-1, 3))

        terms: list[ForceTerm] = []
        for spec, index in self._fields:
            if index is not None and len(index) == len(names):
                index = None  # every particle selected: use the faster unindexed path
            terms.append(FIELD_TERMS[spec.type](spec, particles, index))
        springs = self._spring_set(x0, anchors)
        if springs is not None:
            terms.append(SpringForces.build(springs, anchors, len(names)))

        layout = StateLayout.for_particles(names)
        y0 = _readonly(np.concatenate([x0.ravel(), v0.ravel()]))
        return Model(particles, tuple(self._anchor_names), anchors, springs, tuple(terms), layout, y0,
                     _readonly(frame_times(duration, fps)))

    def _spring_set(self, x0: np.ndarray, anchors: np.ndarray) -> SpringSet | None:
        if not self._springs:
            return None
        names, first, second, on_anchor, stiffness, damping, rest = zip(*self._springs)
        first_i = np.asarray(first, np.intp)
        second_i = np.asarray(second, np.intp)
        on_anchor_b = np.asarray(on_anchor, bool)
        far_end = np.empty((len(first_i), 3))
        far_end[on_anchor_b] = anchors[second_i[on_anchor_b]]
        far_end[~on_anchor_b] = x0[second_i[~on_anchor_b]]
        initial = np.linalg.norm(x0[first_i] - far_end, axis=1)
        rest_length = np.array([initial[i] if r is None else r for i, r in enumerate(rest)], float)
        return SpringSet(tuple(names), _readonly(first_i), _readonly(second_i), _readonly(on_anchor_b),
                         _readonly(np.asarray(stiffness, float)), _readonly(np.asarray(damping, float)),
                         _readonly(rest_length))
