"""Distance joints: rigid rods between particles, or from a particle to a fixed anchor (a pendulum, a chain).

Formulation (the choice issue 22 asks to justify). The rods are holonomic constraints ``C_k = |x_i − x_j| − L_k``
on the maximal coordinates the rest of animbatch integrates, so loops (a four-bar) and trees need nothing different,
unlike reduced coordinates (Featherstone), which suit trees only.

* **Adaptive methods** integrate the index-1 form: at every right-hand side the rod tensions λ solve
  ``J M⁻¹ Jᵀ λ = −J M⁻¹ f − J̇ v − 2 ω Ċ − ω² C`` (Baumgarte stabilisation, critically damped at ω), so the
  accelerations keep ``C̈ + 2 ω Ċ + ω² C = 0``: the drift that integration error feeds into C decays in ~1/ω
  instead of growing. ``J`` has a unit vector n̂ per rod (+n̂ on i, −n̂ on j) and ``J̇ v = (|Δv|² − (n̂·Δv)²)/|d|``.
* **Fixed-step methods** take the same tensions in their kicks, and after every step the state is projected back
  onto the constraints (as SHAKE and RATTLE do): positions by Gauss–Newton steps ``Δx = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ C``
  until |C| is below a nanometre-scale tolerance, then velocities by ``Δv = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ J v``. The
  projection is the orthogonal one in the mass metric, so it never adds kinetic energy.

The matrix ``J M⁻¹ Jᵀ`` (rods × rods) is sparse — rods that share a particle couple — and is factored once per
evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

#: Baumgarte's stabilisation rate ω [1/s]: constraint drift decays as e^(−ω t) (critically damped).
STABILISATION_RATE = 20.0
#: Position projection stops when every rod is within this fraction of its length, or after PROJECTION_ITERATIONS.
PROJECTION_TOLERANCE = 1e-13
PROJECTION_ITERATIONS = 8
#: Up to this many rods the tension system is solved dense.
DENSE_LIMIT = 48


@dataclass(frozen=True, eq=False)
class DistanceJoints:
    """Rods of ``length`` (K,) [m] from particle ``first`` (K,) to particle ``second`` (K,), or, where
    ``second_is_anchor``, to the fixed anchor point ``anchor_position[second]``; ``names`` (K,) for messages."""

    first: np.ndarray
    second: np.ndarray
    second_is_anchor: np.ndarray
    length: np.ndarray
    anchor_position: np.ndarray
    names: tuple[str, ...]
    _cache: dict = field(default_factory=dict, repr=False)  # the coupling matrix, built on first use

    @property
    def count(self) -> int:
        return len(self.first)

    def _ends(self, x: np.ndarray) -> np.ndarray:
        """The far end of each rod (K, 3): its second particle, or its anchor."""
        far = np.empty((self.count, 3))
        anchored = self.second_is_anchor
        far[anchored] = self.anchor_position[self.second[anchored]]
        far[~anchored] = x[self.second[~anchored]]
        return far

    def violation(self, x: np.ndarray) -> np.ndarray:
        """C (K,) [m]: how much longer than its length each rod is at positions ``x`` (N, 3)."""
        return np.linalg.norm(x[self.first] - self._ends(x), axis=1) - self.length

    def _far(self, u: np.ndarray) -> np.ndarray:
        """A per-particle quantity (N, 3) at each rod's second end (K, 3); zero at anchors (they are fixed)."""
        far = np.zeros((self.count, 3))
        free = ~self.second_is_anchor
        far[free] = u[self.second[free]]
        return far

    def _apply(self, unit: np.ndarray, u: np.ndarray) -> np.ndarray:
        """J u (K,) for a per-particle vector field u (N, 3): n̂ · (u_i − u_j)."""
        return np.einsum("ij,ij->i", unit, u[self.first] - self._far(u))

    def _apply_transpose(self, unit: np.ndarray, tension: np.ndarray, particles: int) -> np.ndarray:
        """Jᵀ λ (N, 3): each rod pulls its first end along λ n̂ and its second against it."""
        result = np.zeros((particles, 3))
        pull = tension[:, None] * unit
        np.add.at(result, self.first, pull)
        free = ~self.second_is_anchor
        np.add.at(result, self.second[free], -pull[free])
        return result

    def _coupling(self, inverse_mass: np.ndarray) -> sp.csr_matrix | np.ndarray:
        """M = E M⁻¹ Eᵀ (K, K) for the rods' signed incidence E: rods a and b that share particle p have
        M_ab = ±1/m_p, and M_aa = 1/m_i + 1/m_j. Two rods share at most their common particle, so
        J M⁻¹ Jᵀ = M ⊙ (n̂ n̂ᵀ). It depends only on the topology and the masses: built once."""
        cached = self._cache.get("coupling")
        if cached is not None:
            return cached
        particles = len(inverse_mass)
        free = ~self.second_is_anchor
        rows = np.concatenate([np.arange(self.count), np.flatnonzero(free)])
        columns = np.concatenate([self.first, self.second[free]])
        signs = np.concatenate([np.ones(self.count), -np.ones(int(free.sum()))])
        incidence = sp.csr_matrix((signs, (rows, columns)), shape=(self.count, particles))
        coupling = (incidence @ sp.diags(inverse_mass) @ incidence.T).tocsr()
        coupling.sort_indices()
        result: sp.csr_matrix | np.ndarray = coupling.toarray() if self.count <= DENSE_LIMIT else coupling
        self._cache["coupling"] = result
        return result

    def _solve(self, unit: np.ndarray, inverse_mass: np.ndarray, right: np.ndarray) -> np.ndarray:
        """λ with (J M⁻¹ Jᵀ) λ = right: dense for a few rods, sparse LU for many."""
        coupling = self._coupling(inverse_mass)
        if isinstance(coupling, np.ndarray):
            return np.linalg.solve(coupling * (unit @ unit.T), right)
        rows = np.repeat(np.arange(self.count), np.diff(coupling.indptr))
        data = coupling.data * np.einsum("ij,ij->i", unit[rows], unit[coupling.indices])
        system = sp.csc_matrix(sp.csr_matrix((data, coupling.indices, coupling.indptr), shape=coupling.shape))
        return splu(system).solve(right)

    def _geometry(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rods' unit vectors n̂ (K, 3), from second end to first, and lengths |d| (K,) at positions x."""
        d = x[self.first] - self._ends(x)
        distance = np.linalg.norm(d, axis=1)
        return d / distance[:, None], distance

    def forces(self, x: np.ndarray, v: np.ndarray, force: np.ndarray, inverse_mass: np.ndarray) -> np.ndarray:
        """The rods' forces (N, 3) [N] on the particles at positions ``x`` and velocities ``v`` (N, 3) under the
        other forces ``force`` (N, 3), with Baumgarte stabilisation (see the module notes)."""
        unit, distance = self._geometry(x)
        dv = v[self.first] - self._far(v)
        along = np.einsum("ij,ij->i", unit, dv)  # Ċ
        curvature = (np.einsum("ij,ij->i", dv, dv) - along**2) / distance  # J̇ v
        free_acceleration = self._apply(unit, force * inverse_mass[:, None])
        c = distance - self.length
        omega = STABILISATION_RATE
        tension = self._solve(unit, inverse_mass, -free_acceleration - curvature - 2 * omega * along - omega**2 * c)
        return self._apply_transpose(unit, tension, len(x))

    def project(self, x: np.ndarray, v: np.ndarray, inverse_mass: np.ndarray) -> None:
        """Move positions ``x`` and velocities ``v`` (N, 3), in place, back onto the rods (see the module notes)."""
        weights = inverse_mass[:, None]
        scale = float(np.max(self.length, initial=1.0))
        for _ in range(PROJECTION_ITERATIONS):
            unit, distance = self._geometry(x)
            c = distance - self.length
            if np.max(np.abs(c), initial=0.0) <= PROJECTION_TOLERANCE * scale:
                break
            x -= weights * self._apply_transpose(unit, self._solve(unit, inverse_mass, c), len(x))
        unit, _ = self._geometry(x)
        v -= weights * self._apply_transpose(unit, self._solve(unit, inverse_mass, self._apply(unit, v)), len(x))
