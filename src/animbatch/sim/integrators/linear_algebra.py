"""Sparse factorisations for the implicit methods, shaped by the mechanics of particles.

Every implicit method here solves, for particles of masses M under forces with derivatives ``K = ∂f/∂x`` and
``D = ∂f/∂v`` (3N × 3N, see :class:`~animbatch.sim.forces.term.ForceJacobian`), a system whose matrix has the sparsity
of the springs' graph and is symmetric, or nearly so, once its rows are scaled by the masses:

* backward Euler: ``M - h D - h² K`` (:func:`factor_symmetric`);
* Radau and BDF: the first-order matrix ``P = [[p I, -q I], [-q A, p I - q B]]`` (6N × 6N), with ``A = M⁻¹ K``,
  ``B = M⁻¹ D``; BDF factors ``I - c J`` (p = 1, q = c) and Radau ``μ/h I - J`` (p = μ/h, q = 1, μ complex for
  one of its two systems). Eliminating the positions leaves a 3N × 3N system for the velocities
  (:class:`SecondOrderFactor`)::

      p x - q v = r₁,   -q A x + (p I - q B) v = r₂
      ⇒  M (p P₂₂ + q P₂₁) v = M (p r₂ - P₂₁ r₁),   x = (r₁ + q v) / p

  where ``M (p P₂₂ + q P₂₁) = p² M - p q D - q² K``: half the size, and the same shape as backward Euler's.

Both are factored by SuperLU in symmetric mode (diagonal pivots preferred, a minimum-degree ordering of ``Aᵀ + A``).
Measured on a 64×64 cloth (12 288 unknowns): 0.15–0.25 s per factorisation, against 0.5 s with SuperLU's default
ordering for the same matrix, and minutes for the unreduced 6N system that scipy would factor by itself.

Radau's and BDF's Newton matrices need only approximate the true one: the Newton residual is always the exact
right-hand side, and a matrix off by a relative δ slows the iteration by a contraction of about δ. So their reduced
matrix drops the couplings between two particles that are weak beside both particles' own diagonal blocks
(:func:`drop_weak_couplings`, below 2 % of the geometric mean of the two diagonal blocks, so each row loses at most a
few per cent): on a cloth, the bend springs (40× softer than the structural ones on the benchmark cloth, about 1 %
of the diagonal) reach two vertices across and add half again to the factor's fill. Without them a 64×64 cloth's
factorisation takes 86 ms instead of 153 ms and a solve 2.4 ms instead of 4.5 ms. Backward Euler's single linear
solve *is* the step, so its matrix is never thinned.
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import SuperLU, splu

from animbatch.sim.forces.jacobian import DENSE_STEP_UNKNOWNS

#: Backward Euler's step matrices of at least this many unknowns are factored by the compiled supernodal Cholesky
#: (:mod:`animbatch.sim.integrators.cholesky`) unless ``ANIMBATCH_KERNELS=numpy``; smaller ones by SuperLU, which
#: finishes them before numba has loaded (``ANIMBATCH_KERNELS=numba`` takes the Cholesky at any size). Measured on a
#: 64×64 cloth (12 282 unknowns): 24 ms per factorisation on two cores (33 ms on one) against SuperLU's 155–190 ms.
CHOLESKY_MIN_UNKNOWNS = 3000


def compiled_solves(size: int) -> bool:
    """Whether step matrices of ``size`` unknowns are assembled and factored by the compiled kernels (see
    :data:`CHOLESKY_MIN_UNKNOWNS`): where they pay, and once they are built (:func:`build_step_kernels`)."""
    from animbatch.sim.kernels import MIN_WORK, kernels_ready

    return bool(size) and size % 3 == 0 and kernels_ready(
        MIN_WORK if size >= CHOLESKY_MIN_UNKNOWNS else 0.0, build_step_kernels, "cloth solver",
        "SuperLU and numpy assemble and solve the steps")


@functools.cache
def build_step_kernels() -> str | None:
    """Build (or load from numba's disk cache: about 11 s the first time on a machine, a fraction of a second after)
    the assembly and Cholesky kernels on a system of two particles joined by a spring, so that a kernel numba cannot
    build is found before the first step; None, or what failed."""
    from animbatch.sim.kernels import build_failure

    def build() -> None:
        from animbatch.sim.forces.jacobian import ForceJacobian
        from animbatch.sim.integrators.cholesky import SparseCholesky
        from animbatch.sim.kernels.spring_assembly import spring_blocks

        dfdx, dfdv = spring_blocks(np.array([[1.0, 0.0, 0.0]]), np.zeros((1, 3)), np.ones(1), np.ones(1), np.ones(1),
                                   True)
        jacobian = ForceJacobian(2, definite=True, compiled=True)
        pair = np.array([0]), np.array([1])
        jacobian.add_pairs(*pair, dfdx, dfdv)
        jacobian.add(*pair, dfdx=np.zeros((1, 3, 3)), dfdv=np.zeros((1, 3, 3)))
        matrix = jacobian.step_matrix(np.ones(6), 0.1)
        jacobian.product("x", np.ones(6))
        SparseCholesky(matrix).factor(matrix).solve(np.ones(6))

    return build_failure(build)


class StepMatrixSolver:
    """Factors the successive step matrices ``M − h D − h² K`` of one implicit scheme (one sparsity pattern, new
    values at every step): by the compiled supernodal Cholesky, analysed once, where it pays and the matrix is
    symmetric positive definite; by SuperLU otherwise (a magnetic field's ∂f/∂v is antisymmetric)."""

    def __init__(self, compiled: bool | None = None) -> None:
        """``compiled``: whether the Cholesky may be used (decided once by the scheme, :func:`compiled_solves`);
        None decides by each matrix's size."""
        self._compiled = compiled
        self._cholesky: Any = None
        self._probe: np.ndarray | None = None
        self.method = "SuperLU"  # of the last factorisation

    def factor(self, matrix: sp.spmatrix | np.ndarray) -> Any:
        """Factors of ``matrix`` with a ``solve(b)`` method. Raises RuntimeError (SuperLU's) if it is singular. An
        array (a small system) is factored densely (:class:`DenseFactors`)."""
        if isinstance(matrix, np.ndarray):
            factors = DenseFactors(matrix)
            self.method = factors.method
            return factors
        matrix = sp.csr_matrix(matrix)
        size = matrix.shape[0]
        compiled = self._compiled if self._compiled is not None else compiled_solves(size)
        if compiled and self._symmetric(matrix):
            from animbatch.sim.integrators.cholesky import NotPositiveDefinite, SparseCholesky

            try:
                if self._cholesky is None or self._cholesky.size != size:
                    self._cholesky = SparseCholesky(matrix)
                factors = self._cholesky.factor(matrix)
                self.method = "supernodal Cholesky"
                return factors
            except NotPositiveDefinite:
                pass  # SuperLU pivots on what it finds (and says when the matrix is singular)
        self.method = "SuperLU"
        return factor_symmetric(matrix)

    def _symmetric(self, matrix: sp.csr_matrix) -> bool:
        """Whether ``A z = Aᵀ z`` to rounding for a fixed random ``z``: an antisymmetric part would show in it."""
        if self._probe is None or len(self._probe) != matrix.shape[0]:
            self._probe = np.random.default_rng(0).standard_normal(matrix.shape[0])
        product = matrix @ self._probe
        transposed = matrix.T @ self._probe
        return bool(np.abs(product - transposed).max() <= 1e-12 * np.abs(product).max())


class DenseFactors:
    """Factors of a small step matrix (n, n) held as an array: Cholesky when it is real, symmetric and positive
    definite (the definite Jacobians make it so), LU with partial pivoting otherwise (a magnetic field's
    antisymmetric ∂f/∂v, Radau's complex Newton matrix).
    Raises RuntimeError when it is singular, as SuperLU does."""

    def __init__(self, matrix: np.ndarray) -> None:
        from scipy.linalg import LinAlgError, LinAlgWarning, cho_factor, lu_factor

        self._cholesky: Any = None
        self._lu: Any = None
        # real and symmetric to rounding (the blocks' sums may meet in another order on either side of the diagonal);
        # Radau's complex matrices are symmetric, not Hermitian, which is what a complex Cholesky would take them for
        if np.isrealobj(matrix) and (np.abs(matrix - matrix.T).max(initial=0.0)
                                     <= 1e-12 * np.abs(matrix).max(initial=0.0)):
            try:
                self._cholesky = cho_factor(matrix, lower=True, check_finite=False)
                self.method = "dense Cholesky"
                return
            except LinAlgError:
                pass
        with warnings.catch_warnings():  # a singular matrix is said below, as SuperLU says it
            warnings.simplefilter("ignore", LinAlgWarning)
            self._lu = lu_factor(matrix, check_finite=False)
        if not np.all(np.diag(self._lu[0])):
            raise RuntimeError("Factor is exactly singular")
        self.method = "dense LU"

    def solve(self, right: np.ndarray) -> np.ndarray:
        """``matrix⁻¹ right``."""
        from scipy.linalg import cho_solve, lu_solve

        if self._cholesky is not None:
            return cho_solve(self._cholesky, right, check_finite=False)
        return lu_solve(self._lu, right, check_finite=False)


def factor_symmetric(matrix: sp.spmatrix, *, pivot_threshold: float = 0.0) -> SuperLU:
    """LU factors of a sparse matrix that is symmetric (or nearly) with a strong diagonal.

    ``pivot_threshold`` 0 always takes the diagonal pivot (right for symmetric positive definite matrices); a small
    positive value lets SuperLU pivot off the diagonal where a diagonal entry is tiny (indefinite matrices).
    """
    return splu(sp.csc_matrix(matrix), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=pivot_threshold,
                options={"SymmetricMode": True})


#: Couplings between two particles whose 3×3 block is smaller than this fraction of the geometric mean of the two
#: diagonal blocks (Frobenius norms) are left out of Radau's and BDF's Newton matrices.
WEAK_COUPLING = 0.02


def drop_weak_couplings(matrix: sp.spmatrix, fraction: float = WEAK_COUPLING) -> sp.csr_matrix:
    """``matrix`` (3N, 3N), made of 3×3 blocks per particle pair, without the off-diagonal blocks ``(i, j)`` whose
    norm is below ``fraction · √(‖A_ii‖ ‖A_jj‖)``; the test is symmetric, so a symmetric matrix stays symmetric."""
    blocks = sp.bsr_matrix(matrix, blocksize=(3, 3))
    blocks.sort_indices()
    norms = np.sqrt(np.einsum("kij,kij->k", blocks.data, blocks.data.conj()).real)  # Radau's matrix is complex
    rows = np.repeat(np.arange(blocks.shape[0] // 3), np.diff(blocks.indptr))
    cols = blocks.indices
    diagonal = np.zeros(blocks.shape[0] // 3)
    diagonal[rows[rows == cols]] = norms[rows == cols]
    keep = (rows == cols) | (norms >= fraction * np.sqrt(diagonal[rows] * diagonal[cols]))
    if keep.all():
        return sp.csr_matrix(matrix)
    kept = sp.bsr_matrix((blocks.data[keep], cols[keep], np.concatenate([[0], np.cumsum(
        np.bincount(rows[keep], minlength=len(diagonal)))])), shape=blocks.shape)
    kept = kept.tocsr()
    kept.eliminate_zeros()  # zeros inside kept blocks (a flat cloth has many) would only add fill
    return kept


#: Newton matrices of Radau and BDF whose velocity system has at most this many unknowns (3 per particle) are
#: reduced and factored as arrays: the size up to which backward Euler's step matrices are.
DENSE_NEWTON_UNKNOWNS = DENSE_STEP_UNKNOWNS


class SecondOrderFactor:
    """Solves ``P z = r`` for the 6N × 6N matrix ``P`` that Radau or BDF builds from a particle model's Jacobian,
    through the 3N × 3N velocity system (see the module docstring). ``mass`` (3N,) [kg] per velocity component."""

    def __init__(self, matrix: sp.spmatrix, mass: np.ndarray) -> None:
        size = matrix.shape[0] // 2
        self.size = size
        self.mass = mass
        if size <= DENSE_NEWTON_UNKNOWNS:  # a few particles: arrays, the whole matrix (nothing to gain by dropping)
            dense = matrix.toarray() if isinstance(matrix, sp.spmatrix | sp.sparray) else np.asarray(matrix)
            self.p, self.q = dense[0, 0], -dense[0, size]
            self.lower_left: Any = dense[size:, :size]
            self.factors: Any = DenseFactors(mass[:, None] * (self.p * dense[size:, size:]
                                                              + self.q * self.lower_left))
            return
        matrix = sp.csr_matrix(matrix)
        self.p = matrix[0, 0]  # P₁₁ = p I and P₁₂ = -q I, as J = [[0, I], [A, B]]
        self.q = -matrix[0, size]
        self.lower_left = matrix[size:, :size]  # P₂₁ = -q A
        reduced = self.p * matrix[size:, size:] + self.q * self.lower_left  # p P₂₂ + q P₂₁
        # diagonal pivots: measured, a threshold of 0.01 already pivots off it and fills half as much again
        self.factors = factor_symmetric(drop_weak_couplings(sp.diags(mass) @ reduced))

    def solve(self, right_hand_side: np.ndarray) -> np.ndarray:
        first, second = right_hand_side[: self.size], right_hand_side[self.size:]
        velocity = self.factors.solve(self.mass * (self.p * second - self.lower_left @ first))
        return np.concatenate([(first + self.q * velocity) / self.p, velocity])


#: Reuse a Newton matrix's factors while the step coefficient has changed by less than this fraction (CVODE's
#: ``dgmax``, 0.3) and the Jacobian is the same; Newton then converges a little slower instead of refactoring.
FACTOR_REUSE_CHANGE = 0.3


def use_second_order_factors(solver: Any, mass: np.ndarray) -> None:
    """Make a scipy ``Radau`` or ``BDF`` solver, created with our sparse particle Jacobian, factor its Newton matrices
    through :class:`SecondOrderFactor`. Both solvers call only ``self.lu(matrix)`` and ``self.solve_lu(factors, b)``
    with such matrices (scipy ≥ 1.0), and count factorisations in ``nlu``.

    scipy asks for new factors after every change of step size, which on BDF is every ``order + 1`` steps, so on a
    cloth most of the time went into factorisations of nearly the same matrix. Here, as in CVODE, factors are reused
    while the Jacobian is unchanged and the step coefficient ``q / p`` (h/α for BDF, h/μ for Radau) is within
    :data:`FACTOR_REUSE_CHANGE` of the one they were made for: the Newton iteration is then a modified Newton one with
    a slightly stale matrix, whose convergence scipy checks as it always does (and on failure it evaluates a fresh
    Jacobian, which forces new factors).
    """
    made: dict[complex, tuple[int, complex, SecondOrderFactor]] = {}  # by p's phase (Radau has two): njev, q/p, factors

    def lu(matrix: sp.spmatrix) -> SecondOrderFactor:
        size = matrix.shape[0] // 2
        p, q = matrix[0, 0], -matrix[0, size]
        kind = complex(p / abs(p))
        cached = made.get(kind)
        if cached is not None and cached[0] == solver.njev and abs(q / p / cached[1] - 1) < FACTOR_REUSE_CHANGE:
            return cached[2]
        solver.nlu += 1
        factors = SecondOrderFactor(matrix, mass)
        made[kind] = (solver.njev, q / p, factors)
        return factors

    solver.lu = lu
    solver.solve_lu = lambda factors, right_hand_side: factors.solve(right_hand_side)
