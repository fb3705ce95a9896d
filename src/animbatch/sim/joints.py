"""Joints between particles: rigid rods (distance joints) and ropes over pulleys, as holonomic constraints.

Formulation (the choice issue 22 asks to justify). Each joint is a constraint ``C_k = Σ_s |d_s| − L_k`` on the
maximal coordinates the rest of animbatch integrates, summed over its *segments* ``d_s = x_p − x_q`` (``x_q`` a
particle or a fixed anchor): a rod has one segment (its two ends), a rope over two pulleys two (each end to its
pulley), so loops (a four-bar) and trees need nothing different, unlike reduced coordinates (Featherstone), which
suit trees only.

* **Adaptive methods** integrate the index-1 form: at every right-hand side the joints' tensions λ solve
  ``J M⁻¹ Jᵀ λ = −J M⁻¹ f − J̇ v − 2 ω Ċ − ω² C`` (Baumgarte stabilisation, critically damped at ω), so the
  accelerations keep ``C̈ + 2 ω Ċ + ω² C = 0``: the drift that integration error feeds into C decays in ~1/ω
  instead of growing. ``J`` has, per segment, the unit vector n̂_s (+n̂_s on p, −n̂_s on q), and
  ``J̇ v = Σ_s (|Δv_s|² − (n̂_s·Δv_s)²)/|d_s|``.
* **Fixed-step methods** take the same tensions in their kicks, and after every step the state is projected back
  onto the constraints (as SHAKE and RATTLE do): positions by Gauss–Newton steps ``Δx = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ C``
  until |C| is below a nanometre-scale tolerance, then velocities by ``Δv = −M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ J v``. The
  projection is the orthogonal one in the mass metric, so it never adds kinetic energy.

``J M⁻¹ Jᵀ`` (joints × joints) couples joints that share a particle. Its pattern depends only on the topology, so
which pairs of segment ends meet at a particle is worked out once; each evaluation only sums ``n̂ · n̂ / m`` into
those slots (dense for a few joints, a sparse LU for many).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

#: Baumgarte's stabilisation rate ω [1/s]: constraint drift decays as e^(−ω t) (critically damped).
STABILISATION_RATE = 20.0
#: Position projection stops when every joint is within this fraction of its length, or after PROJECTION_ITERATIONS.
PROJECTION_TOLERANCE = 1e-13
PROJECTION_ITERATIONS = 8
#: Up to this many joints the tension system is solved dense.
DENSE_LIMIT = 48


@dataclass(frozen=True, eq=False)
class Joints:
    """K joints made of S segments: segment s belongs to joint ``segment_joint[s]`` and runs from particle
    ``segment_from[s]`` to particle ``segment_to[s]``, or, where that is −1, to the fixed point
    ``segment_anchor[s]`` (S, 3) [m] (anchor ``segment_anchor_index[s]``). Joint k keeps the sum of its segments'
    lengths at ``length[k]`` [m]; ``names`` (K,) for messages."""

    segment_joint: np.ndarray
    segment_from: np.ndarray
    segment_to: np.ndarray
    segment_anchor: np.ndarray
    segment_anchor_index: np.ndarray  # (S,) the scene anchor of a fixed far end (−1: a particle), for drawing
    length: np.ndarray
    names: tuple[str, ...]
    _cache: dict = field(default_factory=dict, repr=False)  # the coupling pattern, built on first use

    @property
    def count(self) -> int:
        return len(self.length)

    @property
    def anchored(self) -> bool:
        """Whether some joint holds on to a fixed point (so it is not internal to the bodies)."""
        return bool(np.any(self.segment_to < 0))

    # -------------------------------------------------------------------------------- geometry

    def _far(self, u: np.ndarray, anchors: np.ndarray | None) -> np.ndarray:
        """A per-particle quantity (N, 3) at each segment's far end (S, 3); ``anchors`` where it is fixed."""
        free = self.segment_to >= 0
        far = np.zeros((len(self.segment_to), 3)) if anchors is None else anchors.copy()
        far[free] = u[self.segment_to[free]]
        return far

    def _segments(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The segments' unit vectors n̂ (S, 3), far end to near end, and lengths |d| (S,) at positions x."""
        d = x[self.segment_from] - self._far(x, self.segment_anchor)
        distance = np.linalg.norm(d, axis=1)
        return d / distance[:, None], distance

    def _per_joint(self, values: np.ndarray) -> np.ndarray:
        return np.bincount(self.segment_joint, weights=values, minlength=self.count)

    def violation(self, x: np.ndarray) -> np.ndarray:
        """C (K,) [m]: how much longer than its length each joint is at positions ``x`` (N, 3)."""
        return self._per_joint(self._segments(x)[1]) - self.length

    # -------------------------------------------------------------------------------- J, Jᵀ and J M⁻¹ Jᵀ

    def _apply(self, unit: np.ndarray, u: np.ndarray) -> np.ndarray:
        """J u (K,) for a per-particle vector field u (N, 3): Σ_s n̂_s · (u_p − u_q)."""
        return self._per_joint(np.einsum("ij,ij->i", unit, u[self.segment_from] - self._far(u, None)))

    def _apply_transpose(self, unit: np.ndarray, tension: np.ndarray, particles: int) -> np.ndarray:
        """Jᵀ λ (N, 3): each segment pulls its near end along λ n̂ and its far end (a particle) against it."""
        result = np.zeros((particles, 3))
        pull = tension[self.segment_joint][:, None] * unit
        np.add.at(result, self.segment_from, pull)
        free = self.segment_to >= 0
        np.add.at(result, self.segment_to[free], -pull[free])
        return result

    def _pattern(self) -> tuple[np.ndarray, ...]:
        """Pairs of segment ends that meet at a particle, (a, b) as end indices, with their signs and particle, and
        the slot of (joint of a, joint of b) in the coupling matrix's pattern (built once)."""
        cached = self._cache.get("pattern")
        if cached is not None:
            return cached
        segments = len(self.segment_joint)
        free = np.flatnonzero(self.segment_to >= 0)
        end_segment = np.concatenate([np.arange(segments), free])
        end_particle = np.concatenate([self.segment_from, self.segment_to[free]])
        end_sign = np.concatenate([np.ones(segments), -np.ones(len(free))])
        order = np.argsort(end_particle, kind="stable")
        first, second = [], []
        boundaries = np.flatnonzero(np.diff(end_particle[order])) + 1
        for group in np.split(order, boundaries):  # once, over particles that joints touch
            first.append(np.repeat(group, len(group)))
            second.append(np.tile(group, len(group)))
        a, b = np.concatenate(first), np.concatenate(second)
        rows, columns = self.segment_joint[end_segment[a]], self.segment_joint[end_segment[b]]
        keys, slot = np.unique(rows.astype(np.int64) * self.count + columns, return_inverse=True)
        pattern = (end_segment[a], end_segment[b], end_sign[a] * end_sign[b], end_particle[a], slot,
                   (keys // self.count).astype(np.int32), (keys % self.count).astype(np.int32))
        self._cache["pattern"] = pattern
        return pattern

    def _solve(self, unit: np.ndarray, inverse_mass: np.ndarray, right: np.ndarray) -> np.ndarray:
        """λ with (J M⁻¹ Jᵀ) λ = right: dense for a few joints, sparse LU for many."""
        segment_a, segment_b, sign, particle, slot, rows, columns = self._pattern()
        values = sign * inverse_mass[particle] * np.einsum("ij,ij->i", unit[segment_a], unit[segment_b])
        data = np.bincount(slot, weights=values, minlength=len(rows))
        if self.count <= DENSE_LIMIT:
            system = np.zeros((self.count, self.count))
            system[rows, columns] = data
            return np.linalg.solve(system, right)
        return splu(sp.csc_matrix((data, (rows, columns)), shape=(self.count, self.count))).solve(right)

    # -------------------------------------------------------------------------------- what the dynamics use

    def forces(self, x: np.ndarray, v: np.ndarray, force: np.ndarray, inverse_mass: np.ndarray) -> np.ndarray:
        """The joints' forces (N, 3) [N] on the particles at positions ``x`` and velocities ``v`` (N, 3) under the
        other forces ``force`` (N, 3), with Baumgarte stabilisation (see the module notes)."""
        unit, distance = self._segments(x)
        dv = v[self.segment_from] - self._far(v, None)
        along = np.einsum("ij,ij->i", unit, dv)
        rate = self._per_joint(along)  # Ċ
        curvature = self._per_joint((np.einsum("ij,ij->i", dv, dv) - along**2) / distance)  # J̇ v
        free_acceleration = self._apply(unit, force * inverse_mass[:, None])
        c = self._per_joint(distance) - self.length
        omega = STABILISATION_RATE
        tension = self._solve(unit, inverse_mass, -free_acceleration - curvature - 2 * omega * rate - omega**2 * c)
        return self._apply_transpose(unit, tension, len(x))

    def project(self, x: np.ndarray, v: np.ndarray, inverse_mass: np.ndarray) -> None:
        """Move positions ``x`` and velocities ``v`` (N, 3), in place, back onto the joints (see the module notes)."""
        weights = inverse_mass[:, None]
        scale = float(np.max(self.length, initial=1.0))
        for _ in range(PROJECTION_ITERATIONS):
            unit, distance = self._segments(x)
            c = self._per_joint(distance) - self.length
            if np.max(np.abs(c), initial=0.0) <= PROJECTION_TOLERANCE * scale:
                break
            x -= weights * self._apply_transpose(unit, self._solve(unit, inverse_mass, c), len(x))
        unit, _ = self._segments(x)
        v -= weights * self._apply_transpose(unit, self._solve(unit, inverse_mass, self._apply(unit, v)), len(x))
