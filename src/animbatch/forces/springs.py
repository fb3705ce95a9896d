"""Hooke springs with dampers along their axis, between two particles or a particle and a fixed anchor.

For a spring from end 1 to end 2 with ``L = x1 - x2``, unit vector ``u = L / |L|``, rest length ``r``, stiffness
``ks`` and damping ``kd`` (lecture notes, spring-damper)::

    f1 = -(ks (|L| - r) + kd (v1 - v2)·u) u,     f2 = -f1

All springs are evaluated at once; forces are scattered onto particles with a sparse incidence matrix (one matrix
product instead of a Python loop or ``np.add.at``). A spring of zero length exerts no force (its direction is
undefined).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from animbatch.forces.base import ForceTerm


@dataclass(frozen=True, eq=False)
class SpringSet:
    """Spring topology and constants, shape (S,) each.

    ``first`` indexes particles. ``second`` indexes particles, or anchors where ``second_is_anchor`` is true.
    """

    names: tuple[str, ...]
    first: np.ndarray
    second: np.ndarray
    second_is_anchor: np.ndarray
    stiffness: np.ndarray  # ks [N/m]
    damping: np.ndarray  # kd [N·s/m]
    rest_length: np.ndarray  # r [m]

    @property
    def count(self) -> int:
        return len(self.first)


def _incidence(rows: np.ndarray, signs: np.ndarray, columns: np.ndarray, shape: tuple[int, int]) -> sp.csr_matrix:
    return sp.csr_matrix((signs, (rows, columns)), shape=shape)


@dataclass(frozen=True, eq=False)
class SpringForces(ForceTerm):
    """The spring term for a model: particle–particle springs and particle–anchor springs, each vectorised."""

    kind = "spring"
    has_potential = True

    springs: SpringSet
    anchor_position: np.ndarray  # (A, 3) [m]
    particle_count: int
    scatter: sp.csr_matrix  # (N, S): +1 at (first, s), -1 at (second, s) for particle–particle springs

    @classmethod
    def build(cls, springs: SpringSet, anchor_position: np.ndarray, particle_count: int) -> SpringForces:
        s = np.arange(springs.count)
        pp = ~springs.second_is_anchor
        rows = np.concatenate([springs.first, springs.second[pp]])
        cols = np.concatenate([s, s[pp]])
        signs = np.concatenate([np.ones(springs.count), -np.ones(int(pp.sum()))])
        scatter = _incidence(rows, signs, cols, (particle_count, springs.count))
        return cls(springs, np.asarray(anchor_position, float).reshape(-1, 3), particle_count, scatter)

    def _second_end(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of every spring's second end, shape (S, 3); anchors are at rest."""
        springs = self.springs
        on_anchor = springs.second_is_anchor
        if not on_anchor.any():
            return x[springs.second], v[springs.second]
        position = np.empty((springs.count, 3))
        velocity = np.zeros((springs.count, 3))
        position[on_anchor] = self.anchor_position[springs.second[on_anchor]]
        position[~on_anchor] = x[springs.second[~on_anchor]]
        velocity[~on_anchor] = v[springs.second[~on_anchor]]
        return position, velocity

    def spring_forces(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Force on each spring's first end, ``f1`` [N], shape (S, 3)."""
        springs = self.springs
        x2, v2 = self._second_end(x, v)
        axis = x[springs.first] - x2  # L
        length = np.sqrt(np.einsum("ij,ij->i", axis, axis))
        unit = np.divide(axis, length[:, None], out=np.zeros_like(axis), where=length[:, None] > 0)
        closing = np.einsum("ij,ij->i", v[springs.first] - v2, unit)  # (v1 - v2)·u
        magnitude = springs.stiffness * (length - springs.rest_length) + springs.damping * closing
        return -magnitude[:, None] * unit

    def accumulate(self, t: float, x: np.ndarray, v: np.ndarray, force: np.ndarray) -> None:
        force += self.scatter @ self.spring_forces(x, v)

    def potential_energy(self, x: np.ndarray) -> float:
        """Elastic energy ½ ks (|L| - r)² summed over springs [J] (dampers store none)."""
        x2, _ = self._second_end(x, np.zeros_like(x))
        length = np.linalg.norm(x[self.springs.first] - x2, axis=1)
        return float(0.5 * np.sum(self.springs.stiffness * (length - self.springs.rest_length) ** 2))

    @property
    def dissipative(self) -> bool:
        return bool(np.any(self.springs.damping))

    def describe(self) -> str:
        springs = self.springs
        anchored = int(springs.second_is_anchor.sum())
        parts = f"{springs.count - anchored} body–body, {anchored} body–anchor"
        k = f"ks {springs.stiffness.min():g}…{springs.stiffness.max():g} N/m"
        c = f"kd {springs.damping.min():g}…{springs.damping.max():g} N·s/m"
        return f"{springs.count} spring{'s' if springs.count != 1 else ''} ({parts}), {k}, {c}"
