"""Contacts on jointed bodies: how the bodies answer a contact impulse within the joints' constraints.

A contact on a body that a joint holds moves the bodies joined to it too. Solved one after the other (contact
impulses with each body's own mass, then a projection onto the joints), a light plank under a heavy weight is
pushed up by its contacts with the plank's own 0.1 kg, and the projection hands nearly all of it to the 10 kg
weight: the contacts gain 1 % a round, and the plank sinks through the floor. So contacts and joints are solved as
one system instead: with the joint rows ``G`` (R, 6N) over the flat velocity ``V`` and the mass matrix ``M``,
an impulse ``p`` changes the velocities by

    ΔV = K p,    K = M⁻¹ − M⁻¹ Gᵀ (G M⁻¹ Gᵀ)⁻¹ G M⁻¹,

the response of the articulated bodies (``K`` keeps ``G V`` unchanged: the joints hold after every contact
update, at no cost per iteration). A contact's effective mass is then the articulation's, not its body's: the
plank's contacts carry the weight's mass. (Featherstone, "Rigid Body Dynamics Algorithms", 2008, ch. 7 and 11:
the articulated-body inertia; Tonge, Benevolenski & Voroshilov, "Mass splitting for jitter-free parallel rigid
body simulation", SIGGRAPH 2012, for splitting it among contacts.)

Only the columns of contacts on jointed bodies change; a pile of free bodies next to a ragdoll costs what it did.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu

#: Joint systems up to this many rows are solved dense (a pseudo-inverse: redundant rows, as in closed loops, are
#: fine); larger ones by sparse LU.
DENSE_ROWS = 600


#: Systems of up to this many velocity components (6 per body) keep the joint rows and ``M⁻¹ Gᵀ`` dense: a ragdoll's
#: or a welded body's few dozen columns cost microseconds as arrays, and a hundred scipy.sparse constructions a step
#: (each some 20 µs of checks) were most of a jointed contact step.
DENSE_COLUMNS = 1200
#: A Cholesky factor whose smallest pivot² falls below this times the largest diagonal entry is too near singular
#: (redundant rows): the pseudo-inverse is used instead.
RANK_TOLERANCE = 1e-10


def _dense_solver(system: np.ndarray) -> tuple[Callable[[np.ndarray], np.ndarray], np.ndarray, bool]:
    """``right ↦ system⁺ right`` for the symmetric positive semi-definite ``G M⁻¹ Gᵀ``: by Cholesky when it is
    well inside full rank (a tree of joints: a ragdoll, a chain; about fifty times cheaper than an eigen-solve),
    else by the pseudo-inverse (redundant rows, as closed loops have). Also the factor itself, for the compiled
    rows: the Cholesky factor (lower triangle; True), or the pseudo-inverse (False)."""
    if len(system):
        try:
            factor = cho_factor(system, lower=True, check_finite=False)
            pivots = np.diag(factor[0])
            if np.min(pivots) ** 2 > RANK_TOLERANCE * np.max(np.diag(system)):
                return (lambda right: cho_solve(factor, right, check_finite=False)), factor[0], True
        except np.linalg.LinAlgError:
            pass
    pseudo = np.linalg.pinv(system, hermitian=True)
    return (lambda right: pseudo @ right), pseudo, False


def _array(matrix: sp.spmatrix | np.ndarray) -> np.ndarray:
    """A sparse matrix's entries as an array (an array as it is)."""
    return np.asarray(matrix.toarray()) if isinstance(matrix, sp.spmatrix | sp.sparray) else np.asarray(matrix)


#: Body groups of recent joint structures (see :meth:`JointedResponse.groups`), oldest first, at most this many.
GROUPS_KEPT = 16
_GROUPS: dict[tuple[int, bytes], np.ndarray] = {}


class BlockInverse:
    """The inverse mass matrix ``M⁻¹`` (6N, 6N) over the flat velocity ``V = [v.ravel(), ω.ravel()]`` of N bodies,
    as its product with columns: ``inverse_mass`` (N,) [1/kg] on the linear part, ``inverse_inertia`` (N, 3, 3)
    [1/(kg·m²)], world axes, on the angular part. (A small jointed system's products, without building the matrix.)"""

    def __init__(self, inverse_mass: np.ndarray, inverse_inertia: np.ndarray) -> None:
        self.inverse_mass = inverse_mass
        self.inverse_inertia = inverse_inertia

    def __matmul__(self, columns: np.ndarray) -> np.ndarray:
        """``M⁻¹ columns`` for columns (6N, m)."""
        count, width = len(self.inverse_mass), columns.shape[1]
        linear = columns[:3 * count].reshape(count, 3, width) * self.inverse_mass[:, None, None]
        angular = np.einsum("nij,njm->nim", self.inverse_inertia, columns[3 * count:].reshape(count, 3, width))
        return np.concatenate([linear.reshape(3 * count, width), angular.reshape(3 * count, width)])


class JointedResponse:
    """The joints' rows ``rows`` (R, 6N; sparse, or an array for a small system) and the inverse mass matrix
    ``inverse`` (6N, 6N; sparse, or a :class:`BlockInverse`), both over the flat velocity of N bodies, and the
    factorised ``G M⁻¹ Gᵀ``."""

    def __init__(self, rows: sp.csr_matrix | np.ndarray, inverse: sp.spmatrix | BlockInverse) -> None:
        self._groups: np.ndarray | None = None
        self.count, self.columns = rows.shape
        # small systems: the same products on arrays, with no sparse form of M⁻¹ Gᵀ at all (see DENSE_COLUMNS)
        self._dense = self.columns <= DENSE_COLUMNS
        self._rows_array = self._push_array = None
        self.rows: Any = None  # G as a sparse matrix, for large systems only
        self.push: Any = None  # M⁻¹ Gᵀ (6N, R) as a sparse matrix, for large systems only
        if self._dense:
            self._rows_array = _array(rows)
            self._push_array = np.asarray(inverse @ np.ascontiguousarray(self._rows_array.T))  # M⁻¹ Gᵀ (6N, R)
            system: Any = self._rows_array @ self._push_array
        else:
            self.rows = sp.csr_matrix(rows)
            self.push = (inverse @ self.rows.T).tocsc()
            system = self.rows @ self.push
        #: a dense system's factor (``_dense_solver``): the lower Cholesky factor (``cholesky``) or the pseudo-inverse
        self.factor: np.ndarray | None = None
        self.cholesky = False
        if system.shape[0] <= DENSE_ROWS:
            self._solve, self.factor, self.cholesky = _dense_solver(_array(system))
        else:
            factor = splu(sp.csc_matrix(system))
            self._solve = factor.solve

    def _touched(self, response: sp.spmatrix | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For a response (6N, K): the columns that move jointed bodies, their ``G response`` (R, k) and
        ``(G M⁻¹ Gᵀ)⁻¹ G response``."""
        if self._rows_array is not None:
            rates = self._rows_array @ _array(response)
            touched = np.flatnonzero(np.any(rates != 0, axis=0))
            rates = rates[:, touched]
            return touched, rates, (np.asarray(self._solve(rates)) if len(touched)
                                    else np.zeros((self.count, 0)))
        moved = sp.csc_matrix(self.rows @ response)
        touched = np.flatnonzero(np.diff(moved.indptr) > 0)
        if not len(touched):
            return touched, np.zeros((self.count, 0)), np.zeros((self.count, 0))
        rates = moved[:, touched].toarray()
        return touched, rates, np.asarray(self._solve(rates))

    def correct(self, response: sp.spmatrix | np.ndarray) -> sp.csc_matrix | np.ndarray:
        """``K Jᵀ`` from ``M⁻¹ Jᵀ`` (6N, K): the response within the joints (an array for an array)."""
        touched, _, multipliers = self._touched(response)
        if self._push_array is not None:
            corrected = np.array(_array(response))
            corrected[:, touched] -= self._push_array @ multipliers
            return corrected if isinstance(response, np.ndarray) else sp.csc_matrix(corrected)
        response = sp.csc_matrix(response)
        if not len(touched):
            return response
        correction = sp.csc_matrix(self.push @ multipliers)  # (6N, k), rows of jointed bodies only
        place = sp.csr_matrix((np.ones(len(touched)), (np.arange(len(touched)), touched)),
                              shape=(len(touched), response.shape[1]))
        return sp.csc_matrix(response - correction @ place)

    @property
    def rows_array(self) -> np.ndarray:
        """The joint rows ``G`` (R, 6N) of a small system (:attr:`dense`)."""
        assert self._rows_array is not None, "only small systems keep G as an array"
        return self._rows_array

    @property
    def push_array(self) -> np.ndarray:
        """``M⁻¹ Gᵀ`` (6N, R) of a small system (:attr:`dense`)."""
        assert self._push_array is not None, "only small systems keep M⁻¹ Gᵀ as an array"
        return self._push_array

    @property
    def dense(self) -> bool:
        """Whether :meth:`lost` takes responses as arrays (small systems)."""
        return self._dense

    def lost(self, response: sp.spmatrix | np.ndarray) -> np.ndarray:
        """For each column (K,) of ``M⁻¹ Jᵀ``: how much of ``J M⁻¹ Jᵀ`` (a row's inverse effective mass) the joints
        take away, ``J M⁻¹ Gᵀ (G M⁻¹ Gᵀ)⁻¹ G M⁻¹ Jᵀ`` ≥ 0."""
        lost = np.zeros(response.shape[1])
        touched, rates, multipliers = self._touched(response)
        lost[touched] = np.einsum("rk,rk->k", rates, multipliers)
        return lost

    def groups(self, size: int) -> np.ndarray:
        """A label (size,) per body: bodies joined (directly or through others) share one; a body no joint holds
        has its own. (Asked for by every row direction and the normal block: found once, and kept across steps for
        the same joints, which a new response each step would otherwise find again.)"""
        if self._groups is None or len(self._groups) != size:
            if self._rows_array is not None and self.columns == 6 * size:
                # which bodies each row touches (R, size), the key itself: a ragdoll's few hundred booleans
                touches = np.any(self._rows_array.reshape(self.count, 2, size, 3) != 0, axis=(1, 3))
                key = (size, touches.tobytes())
                entries, body = np.nonzero(touches)  # each entry's row (sorted) and body
            else:
                rows = sp.csr_matrix(self._rows_array) if self.rows is None else self.rows
                stored = rows.data != 0  # an entry stored as zero joins nothing
                entries = np.repeat(np.arange(rows.shape[0]), np.diff(rows.indptr))[stored]
                body = (rows.indices[stored] % (3 * size)) // 3
                key = (size, np.stack([entries, body]).tobytes())
            found = _GROUPS.get(key)
            if found is None:
                # each body a row touches, linked to the first body that row touches
                _, first_entry, per_row = np.unique(entries, return_index=True, return_counts=True)
                links = np.stack([np.repeat(body[first_entry], per_row), body])
                graph = sp.csr_matrix((np.ones(links.shape[1]), (links[0], links[1])), shape=(size, size))
                found = _GROUPS[key] = connected_components(graph, directed=False)[1]
                if len(_GROUPS) > GROUPS_KEPT:
                    _GROUPS.pop(next(iter(_GROUPS)))
            self._groups = found
        return self._groups.copy()
