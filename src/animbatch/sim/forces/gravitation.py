"""Inverse-square forces between every pair of selected bodies (as points), with Plummer softening: Newton's
gravitation between masses and Coulomb's law between charges.

Both are ``f_i = κ s_i Σ_j s_j (x_j - x_i) / (|x_j - x_i|² + ε²)^(3/2)`` with potential
``-κ Σ_{i<j} s_i s_j / sqrt(r² + ε²)``: for gravitation the sources ``s`` are masses and ``κ = G`` (like sources
attract); for Coulomb's law they are charges and ``κ = -k`` (like charges repel). The pair sums are vectorised in
row blocks, so memory stays bounded for thousands of bodies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.term import BodyTable, ForceTerm, Kinematics, add_at, selection_text

#: Pairs evaluated at once (rows × columns); bounds the temporary arrays to a few tens of MB.
PAIR_BLOCK = 1 << 20


@dataclass(frozen=True, eq=False)
class InverseSquarePairs(ForceTerm):
    """A pair law of coupling ``coupling`` (κ) between ``source`` (S,) strengths of the selected points, whose
    inertial masses are ``mass`` (S,) [kg] (for the frequency of a close pair, see :meth:`pair_frequency`)."""

    has_potential = True

    coupling: float
    softening: float
    source: np.ndarray
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
            inv_r3[np.arange(stop - start), np.arange(start, stop)] = 0.0  # no force on itself
            result[start:stop] = np.einsum("ij,ijk->ik", inv_r3 * self.source[None, :], separation)
        result *= (self.coupling * self.source)[:, None]
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
            pair_source = self.source[start:stop, None] * self.source[None, :]
            total -= float(np.sum(np.where(upper, pair_source / np.where(upper, r, 1.0), 0.0)))
        return self.coupling * total

    def pair_frequency(self, r2: np.ndarray, first: int | np.ndarray, second: int | np.ndarray) -> np.ndarray:
        """ω² [rad²/s²] of the relative motion of points ``first`` and ``second`` (of the selection) at squared
        separation ``r2`` [m²]: ``|κ s_i s_j| (1/m_i + 1/m_j) / r³``, the orbital (or fly-by) rate of a close pair."""
        source, mass = np.asarray(self.source, float), np.asarray(self.mass, float)
        strength = np.abs(self.coupling * source[first] * source[second])
        return strength * (1 / mass[first] + 1 / mass[second]) / r2**1.5


@dataclass(frozen=True, eq=False)
class Gravitation(InverseSquarePairs):
    """Mutual attraction of masses (``source`` = ``mass``, ``coupling`` = G)."""

    kind = "gravitation"

    @property
    def G(self) -> float:  # noqa: N802 - the constant's own name
        return self.coupling

    def describe(self) -> str:
        return (f"G = {self.G:g} m³/(kg·s²), softening ε = {self.softening:g} m, between "
                f"{selection_text(self.index, self.names)}")


@dataclass(frozen=True, eq=False)
class Coulomb(InverseSquarePairs):
    """Coulomb's law between charges (``source``: charges [C], ``coupling`` = -k)."""

    kind = "coulomb"

    def describe(self) -> str:
        return (f"k = {-self.coupling:g} N·m²/C², softening ε = {self.softening:g} m, between "
                f"{selection_text(self.index, self.names)} (charges "
                + ", ".join(f"{q:g}" for q in self.source[:6]) + (" …" if len(self.source) > 6 else "") + " C)")


def build_gravitation(bodies: BodyTable, index: np.ndarray | None, *, G: float, softening: float) -> Gravitation:
    """Newton's mutual gravitation with constant ``G`` [m³/(kg·s²)] and Plummer ``softening`` [m] between the
    selected points."""
    mass = bodies.mass if index is None else bodies.mass[index]
    return Gravitation(G, softening, mass, mass, index, bodies.names)


def build_coulomb(bodies: BodyTable, index: np.ndarray | None, *, k: float, softening: float,
                  charge: np.ndarray) -> Coulomb:
    """Coulomb's law with constant ``k`` [N·m²/C²] and Plummer ``softening`` [m] between the selected points, of
    charges ``charge`` [C] (one per selected point, in the order of ``index``; all points when it is None)."""
    mass = bodies.mass if index is None else bodies.mass[index]
    return Coulomb(-k, softening, np.asarray(charge, float), mass, index, bodies.names)
