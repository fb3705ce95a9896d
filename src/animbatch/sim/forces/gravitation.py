"""Newtonian gravitation between all pairs of selected bodies (as point masses), with Plummer softening.

``f_i = Σ_j G m_i m_j (x_j - x_i) / (|x_j - x_i|² + ε²)^(3/2)``; potential ``-Σ_{i<j} G m_i m_j / sqrt(r² + ε²)``.
The pair sums are vectorised in row blocks, so memory stays bounded for thousands of bodies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.base import BodyTable, ForceTerm, Kinematics, add_at, selection_text

#: Pairs evaluated at once (rows × columns); bounds the temporary arrays to a few tens of MB.
PAIR_BLOCK = 1 << 20


@dataclass(frozen=True, eq=False)
class Gravitation(ForceTerm):
    """Mutual attraction. ``mass``: masses of the selected particles [kg], shape (S,)."""

    kind = "gravitation"
    has_potential = True

    G: float
    softening: float
    mass: np.ndarray
    index: np.ndarray | None
    names: tuple[str, ...]

    def _row_blocks(self, count: int) -> range:
        return range(0, count, max(1, PAIR_BLOCK // max(count, 1)))

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        points = state.x if self.index is None else state.x[self.index]
        count = len(points)
        result = np.empty_like(points)
        eps2 = self.softening**2
        rows = self._row_blocks(count)
        for start in rows:
            stop = min(start + rows.step, count)
            separation = points[None, :, :] - points[start:stop, None, :]  # x_j - x_i, shape (rows, S, 3)
            r2 = np.einsum("ijk,ijk->ij", separation, separation) + eps2
            with np.errstate(divide="ignore"):
                inv_r3 = r2**-1.5
            inv_r3[np.arange(stop - start), np.arange(start, stop)] = 0.0  # no self-attraction
            result[start:stop] = np.einsum("ij,ijk->ik", inv_r3 * self.mass[None, :], separation)
        result *= (self.G * self.mass)[:, None]
        add_at(force, self.index, result)

    def potential_energy(self, state: Kinematics) -> float:
        points = state.x if self.index is None else state.x[self.index]
        count = len(points)
        total = 0.0
        rows = self._row_blocks(count)
        for start in rows:
            stop = min(start + rows.step, count)
            separation = points[None, :, :] - points[start:stop, None, :]
            r = np.sqrt(np.einsum("ijk,ijk->ij", separation, separation) + self.softening**2)
            upper = np.arange(count)[None, :] > np.arange(start, stop)[:, None]  # each pair once (j > i)
            pair_mass = self.mass[start:stop, None] * self.mass[None, :]
            total -= float(np.sum(np.where(upper, pair_mass / np.where(upper, r, 1.0), 0.0)))
        return self.G * total

    def describe(self) -> str:
        return (f"G = {self.G:g} m³/(kg·s²), softening ε = {self.softening:g} m, between "
                f"{selection_text(self.index, self.names)}")


def build_gravitation(bodies: BodyTable, index: np.ndarray | None, *, G: float, softening: float) -> Gravitation:
    """Newton's mutual gravitation with constant ``G`` [m³/(kg·s²)] and Plummer ``softening`` [m] between the
    selected points."""
    mass = bodies.mass if index is None else bodies.mass[index]
    return Gravitation(G, softening, mass, index, bodies.names)
