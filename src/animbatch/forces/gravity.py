"""Uniform gravity: ``f = m g`` on each selected particle."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.scene.schema import GravitySpec
from animbatch.forces.base import ForceTerm, ParticleProperties, field_term, selection_text, vector_text


@dataclass(frozen=True, eq=False)
class UniformGravity(ForceTerm):
    """Weight ``m g``, precomputed per particle since neither mass nor g changes.

    ``weight``: force per selected particle [N], shape (S, 3); ``index``: the selected particles, or None for all.
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

    def accumulate(self, t: float, x: np.ndarray, v: np.ndarray, force: np.ndarray) -> None:
        if self.index is None:
            force += self.weight
        else:
            force[self.index] += self.weight  # indices are unique, so fancy-index += is exact

    def potential_energy(self, x: np.ndarray) -> float:
        selected = x if self.index is None else x[self.index]
        return -float(np.sum(self.weight * selected))

    def describe(self) -> str:
        return f"g = {vector_text(self.g)} m/s² on {selection_text(self.index, self.names)}"


@field_term("gravity")
def _gravity(spec: GravitySpec, particles: ParticleProperties, index: np.ndarray | None) -> UniformGravity:
    return UniformGravity.build(np.asarray(spec.g), particles.mass, index, particles.names)
