"""Scalar constraint rows between two bodies, and the solve for their multipliers.

Every joint is a few scalar constraints ``C_i(configuration) = 0`` (bilateral) or ``≥ 0`` (unilateral: limits,
slack ropes). Each row acts on at most two bodies, its *ends* 0 and 1; an end that is the world has index ``world``
(the last slot of :class:`JoinedMotion`, with no inverse mass). The row's velocity Jacobian is, per end, a linear part
``l`` (3,) and an angular part ``k`` (3,)::

    Ċ_i = Σ_ends  l · v_body + k · ω_body

(``k = r × l`` for a point of the body at lever r). Its time derivative adds the *bias* ``J̇ u`` (the centripetal
terms), so that ``C̈_i = J u̇ + bias_i``. For rows i, j that share a body c, the coupling matrix ``A = J M⁻¹ Jᵀ`` has
``l_i·l_j / m_c + k_iᵀ I_c⁻¹ k_j`` (I_c⁻¹ in world axes); which pairs of ends meet at a body depends only on the
topology, so it is found once and each evaluation only sums those products into fixed slots (dense for a few rows,
a sparse LU for many).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.sparse.linalg import splu

from animbatch.quaternion import cross

#: Up to this many rows the coupling system is solved dense.
DENSE_LIMIT = 48


@dataclass(frozen=True)
class JoinedMotion:
    """The joined bodies' motion at one instant, J bodies and the world as slot J.

    ``x``, ``v`` (J+1, 3): centres of mass [m] and their velocities [m/s] (the world: origin, at rest); ``rotation``
    (J+1, 3, 3) body-to-world (identity for particles and the world); ``omega`` (J+1, 3) [rad/s], world axes;
    ``inverse_mass`` (J+1,) [1/kg] and ``inverse_inertia`` (J+1, 3, 3) [1/(kg·m²)], world axes (zero for the world
    and, for inertia, for particles); ``spin`` (J+1, 3) [rad/s²]: the angular acceleration with no torque,
    ``−I⁻¹ (ω × L)``, which constrained bodies still have.
    """

    x: np.ndarray
    v: np.ndarray
    rotation: np.ndarray
    omega: np.ndarray
    inverse_mass: np.ndarray
    inverse_inertia: np.ndarray
    spin: np.ndarray
    turning: bool = True  # whether any slot turns (else every rotation is the identity and every ω zero)

    def points(self, body: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, ...]:
        """For body points at ``offset`` (K, 3) (body axes, from the centre of mass; for the world: the point
        itself) of bodies ``body`` (K,): levers r, world positions p, velocities ``v + ω × r`` and the centripetal
        accelerations ``ω × (ω × r)``, each (K, 3)."""
        if not self.turning:  # particles only: no turning to account for
            return offset, self.x[body] + offset, self.v[body], np.zeros_like(offset)
        lever = np.einsum("kij,kj->ki", self.rotation[body], offset)
        omega = self.omega[body]
        spin = cross(omega, lever)
        return lever, self.x[body] + lever, self.v[body] + spin, cross(omega, spin)

    def directions(self, body: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Body-fixed directions (K, 3) (body axes) of bodies ``body`` (K,) in world axes."""
        return np.einsum("kij,kj->ki", self.rotation[body], direction)


@dataclass(frozen=True)
class Rows:
    """K rows at one instant: ``violation`` C (K,), per end the ``linear`` and ``angular`` Jacobian parts
    (K, 2, 3), and ``bias`` J̇u (K,). Their bodies (K, 2) are fixed and held by the row kind."""

    violation: np.ndarray
    linear: np.ndarray
    angular: np.ndarray
    bias: np.ndarray

    @staticmethod
    def concatenate(parts: list[Rows]) -> Rows:
        return Rows(*(np.concatenate([getattr(p, name) for p in parts]) for name in
                      ("violation", "linear", "angular", "bias")))


class Coupling:
    """``J M⁻¹ Jᵀ`` for rows between fixed bodies ``bodies`` (R, 2) (``world``: the world), and its solve;
    ``turning``: whether some of the bodies are rigid (else the angular parts are skipped)."""

    def __init__(self, bodies: np.ndarray, world: int, turning: bool = True) -> None:
        self._turning = turning  # whether any joined body is rigid (else the angular parts are all zero)
        count = len(bodies)
        end_row = np.repeat(np.arange(count), 2)
        end_body = bodies.ravel()
        keep = np.flatnonzero(end_body != world)
        order = keep[np.argsort(end_body[keep], kind="stable")]
        first, second = [], []
        for group in np.split(order, np.flatnonzero(np.diff(end_body[order])) + 1):  # once, over joined bodies
            first.append(np.repeat(group, len(group)))
            second.append(np.tile(group, len(group)))
        a, b = (np.concatenate(first), np.concatenate(second)) if first else (np.zeros(0, int), np.zeros(0, int))
        rows, columns = end_row[a], end_row[b]
        # slots in column-major order, so that the summed values are the data of a CSC matrix as they stand
        keys, self._slot = np.unique(columns.astype(np.int64) * count + rows, return_inverse=True)
        self._rows, self._columns = (keys % count).astype(np.int32), (keys // count).astype(np.int32)
        self._indptr = np.searchsorted(self._columns, np.arange(count + 1)).astype(np.int32)
        self._diagonal = np.flatnonzero(self._rows == self._columns)
        missing = np.setdiff1d(np.arange(count), self._rows[self._diagonal])
        if len(missing):  # a row with both ends on the world: the builder refuses these
            raise ValueError(f"constraint rows {missing.tolist()} join nothing but the world")
        self._a, self._b = a, b  # flat end indices (2 row + slot) of the pairs that meet at a body
        self._end_body = end_body
        self._row_a, self._row_b = end_row[a], end_row[b]
        self.count = count

    def matrix(self, rows: Rows, motion: JoinedMotion, active: np.ndarray | None = None) -> sp.spmatrix | np.ndarray:
        """A = J M⁻¹ Jᵀ (R, R) at ``rows``; rows not ``active`` are decoupled (their own 1 on the diagonal), so that
        their multiplier comes out zero for a zero right-hand side."""
        linear, angular = rows.linear.reshape(-1, 3), rows.angular.reshape(-1, 3)
        # M⁻¹ Jᵀ once per end, then one dot product per pair of ends that meet at a body
        scaled = linear * motion.inverse_mass[self._end_body][:, None]
        values = np.einsum("ij,ij->i", linear[self._a], scaled[self._b])
        if self._turning:
            turned = np.einsum("eij,ej->ei", motion.inverse_inertia[self._end_body], angular)
            values += np.einsum("ij,ij->i", angular[self._a], turned[self._b])
        if active is not None:
            values *= active[self._row_a] & active[self._row_b]
        data = np.bincount(self._slot, weights=values, minlength=len(self._rows))
        if active is not None:
            data[self._diagonal] += ~active[self._rows[self._diagonal]]
        if self.count <= DENSE_LIMIT:
            system = np.zeros((self.count, self.count))
            system[self._rows, self._columns] = data
            return system
        return sp.csc_matrix((data, self._rows, self._indptr), shape=(self.count, self.count))

    def solve(self, rows: Rows, motion: JoinedMotion, right: np.ndarray,
              active: np.ndarray | None = None) -> np.ndarray:
        """λ (R,) with ``(J M⁻¹ Jᵀ) λ = right``, rows not ``active`` held at zero."""
        return self.factored(rows, motion, active).solve(right)

    def factored(self, rows: Rows, motion: JoinedMotion, active: np.ndarray | None = None) -> FactoredCoupling:
        """A factorised at ``rows``, to solve with as many right-hand sides as needed."""
        return FactoredCoupling(self.matrix(rows, motion, active), active)


class FactoredCoupling:
    """A factorised coupling matrix ``system`` (R, R) whose rows not ``active`` are held at zero."""

    def __init__(self, system: sp.spmatrix | np.ndarray, active: np.ndarray | None) -> None:
        self._active = active
        self._dense = isinstance(system, np.ndarray)
        self._factor: Any = None  # None: singular
        try:
            if self._dense:
                with warnings.catch_warnings():  # an exactly singular system is told by its zero pivot, below
                    warnings.simplefilter("ignore", LinAlgWarning)
                    lu, pivots = lu_factor(system, check_finite=False)
                if np.all(np.diag(lu) != 0):  # as numpy's solve, only an exactly zero pivot is singular
                    self._factor = lu, pivots
            else:
                self._factor = splu(system)
        except (np.linalg.LinAlgError, RuntimeError, ValueError):
            pass

    def solve(self, right: np.ndarray) -> np.ndarray:
        """λ (R,) for ``right`` (R,)."""
        if self._factor is None:
            # a singular system (a state gone to pieces, or rows that fix the same motion twice): no multipliers,
            # so the state stops being finite and the integrator reports where, as for any divergence
            return np.full(len(right), np.nan)
        if self._active is not None:
            right = np.where(self._active, right, 0.0)
        if self._dense:
            return lu_solve(self._factor, right, check_finite=False)
        return self._factor.solve(right)


def apply(rows: Rows, bodies: np.ndarray, u: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """J u (R,) for body velocities ``u = (v, ω)``, each (J+1, 3)."""
    v, omega = u
    return (np.einsum("kej,kej->k", rows.linear, v[bodies])
            + np.einsum("kej,kej->k", rows.angular, omega[bodies]))


def accumulate(index: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Sums of the rows of ``values`` (K, 3) into ``count`` slots by ``index`` (K,): (count, 3). (Several times
    faster than ``np.add.at``.)"""
    return np.stack([np.bincount(index, weights=values[:, c], minlength=count) for c in range(3)], axis=1)


def apply_transpose(rows: Rows, bodies: np.ndarray, multiplier: np.ndarray,
                    count: int) -> tuple[np.ndarray, np.ndarray]:
    """Jᵀ λ: the forces and torques (J+1, 3) each, that rows with multipliers λ (R,) exert on the bodies (the
    world's slot, the last, collects what the world takes)."""
    index = bodies.ravel()
    force = accumulate(index, (multiplier[:, None, None] * rows.linear).reshape(-1, 3), count)
    torque = accumulate(index, (multiplier[:, None, None] * rows.angular).reshape(-1, 3), count)
    return force, torque
