"""Uniform gravity: ``f = m g`` on each selected body, at its centre of mass (so it makes no torque)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from animbatch.sim.forces.on_particles import ParticleLaw, Slots
from animbatch.sim.forces.term import (
    BodyTable,
    ForceJacobian,
    ForceTerm,
    Kinematics,
    add_at,
    selection_text,
    vector_text,
)


@dataclass(frozen=True, eq=False)
class UniformGravity(ForceTerm):
    """Weight ``m g``, precomputed per body since neither mass nor g changes.

    ``weight``: force per selected body [N], shape (S, 3); ``index``: the selected points, or None for all.
    """

    kind = "gravity"
    has_potential = True

    g: np.ndarray
    weight: np.ndarray
    index: np.ndarray | None
    names: tuple[str, ...]

    @classmethod
    def build(cls, g: np.ndarray, mass: np.ndarray, index: np.ndarray | None, names: tuple[str, ...]) -> UniformGravity:
        selected_mass = mass if index is None else mass[index]
        return cls(np.asarray(g, float), selected_mass[:, None] * np.asarray(g, float), index, names)

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        add_at(force, self.index, self.weight)

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        return True  # a constant force: both derivatives are zero

    def potential_energy(self, state: Kinematics) -> float:
        selected = state.x if self.index is None else state.x[self.index]
        return -float(np.sum(self.weight * selected))

    def describe(self) -> str:
        return f"g = {vector_text(self.g)} m/s² on {selection_text(self.index, self.names)}"


def build_gravity(bodies: BodyTable, index: np.ndarray | None, *, g: np.ndarray) -> UniformGravity:
    """Uniform gravity ``g`` [m/s²] (3,) on the selected points."""
    return UniformGravity.build(np.asarray(g, float), bodies.mass, index, bodies.names)


def gravity_magnitude(terms: Iterable[ForceTerm]) -> float:
    """The strongest uniform gravity among force terms [m/s²] (0 without gravity): the scale of free-flight speeds."""
    return max((float(np.linalg.norm(term.g)) for term in terms if isinstance(term, UniformGravity)), default=0.0)


@dataclass(frozen=True, eq=False)
class GravityOnParticles(ParticleLaw):
    """Gravity on emitted particles: ``a = g`` (3,) [m/s²]."""

    g: np.ndarray

    def describe(self) -> str:
        return f"gravity g = {vector_text(self.g)} m/s²"

    def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
        out += self.g

    @property
    def gravity(self) -> np.ndarray:
        return self.g

    @property
    def compiled(self) -> bool:
        return True

    def kernel_row(self, row: np.ndarray, kernel: ModuleType) -> None:
        row[kernel.KIND] = kernel.FIELD_GRAVITY
        row[kernel.VECTOR:kernel.VECTOR + 3] = self.g
