"""Compiled numeric phase of a supernodal multifrontal Cholesky factorisation, and its triangular solves.

The analysis (ordering, elimination tree, supernodes, each front's index set) is done once per sparsity pattern by
:class:`animbatch.sim.integrators.cholesky.SparseCholesky`, in numpy; these kernels do the work of every step.

Notation (new = the analysis' ordering): supernode ``s`` owns the consecutive new columns ``start[s] …
start[s] + width[s] - 1``. Its *front* is the index set ``front_index[front_ptr[s]:front_ptr[s + 1]]``: its own
columns, then (sorted) the rows below them where the factor L has entries. The factor of ``s`` is stored as one dense
row-major block (f, width) at ``factor_ptr[s]`` in ``factor``: ``[L₁₁; L₂₁]``, L₁₁ lower triangular.

Multifrontal method (Duff & Reid 1983; Liu 1992): for each supernode, children first,

1. assemble the dense front F (f × f): the matrix's columns of ``s`` plus the update matrices of its children
   (extend-add: each child's update is indexed by its rows, a subset of this front);
2. factor its leading block, ``L₁₁ L₁₁ᵀ = F₁₁``, and ``L₂₁ = F₂₁ L₁₁⁻ᵀ``;
3. leave the update ``U = F₂₂ − L₂₁ L₂₁ᵀ`` for the parent.

Dense blocks go to LAPACK and BLAS, which is what makes a supernodal factorisation several times faster than a
column-by-column one such as SuperLU's on a cloth's matrix: ``dpotrf``, ``dtrsm`` and ``dsyrk`` from scipy's own
libraries (``scipy.linalg.cython_lapack`` and ``cython_blas``), called in place on the front, which is row-major,
so Fortran sees its transpose (lower triangles here are upper ones there).

Independent subtrees are factored on parallel threads (:func:`factor_subtrees`), the supernodes above them after
(:func:`factor_top`); the analysis chooses which.

The matrix is given as CSR of the *original* ordering (symmetric, so its rows are its columns), with ``perm`` (new →
original) and ``inverse`` (original → new): it is never permuted in memory.
"""

from __future__ import annotations

from typing import Any

import llvmlite.binding
import numpy as np
from numba import njit, prange, types
from numba.extending import get_cython_function_address


def _fortran(library: str, name: str, arguments: int) -> Any:
    """A BLAS or LAPACK routine of scipy's, callable from compiled code (every argument a pointer). It is linked by
    a symbol name, not held as a pointer, so that the kernels can be cached on disk."""
    symbol = f"animbatch_{name}"
    llvmlite.binding.add_symbol(symbol, get_cython_function_address(f"scipy.linalg.cython_{library}", name))
    return types.ExternalFunction(symbol, types.void(*([types.voidptr] * arguments)))


_dpotrf = _fortran("lapack", "dpotrf", 5)
_dtrsm = _fortran("blas", "dtrsm", 11)
_dsyrk = _fortran("blas", "dsyrk", 10)
_dtrsv = _fortran("blas", "dtrsv", 8)
_dgemv = _fortran("blas", "dgemv", 11)

#: Returned by :func:`factor_subtrees` and :func:`factor_top`: done; an entry of the matrix outside the analysed
#: pattern (analyse again); a front whose leading block is not positive definite.
FACTORED, NOT_COVERED, NOT_POSITIVE_DEFINITE = 0, 1, 2


@njit(cache=True)
def _factor_supernode(s: int, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, perm: np.ndarray,
                      inverse: np.ndarray, start: np.ndarray, width: np.ndarray, front_ptr: np.ndarray,
                      front_index: np.ndarray, child_ptr: np.ndarray, child_index: np.ndarray,
                      factor_ptr: np.ndarray, factor: np.ndarray, where: np.ndarray, updates: list,
                      external_ptr: np.ndarray, external: np.ndarray) -> int:
    """Steps 1–3 for supernode ``s``, leaving its front (whose block below its columns is its update) in
    ``updates[s]``. A child's front is in ``updates`` or, for the root of a subtree factored by another thread, in
    ``external`` at ``external_ptr[child]`` (−1 for the others). ``where``: −1 everywhere, on entry and return."""
    first, last = front_ptr[s], front_ptr[s + 1]
    size = last - first
    columns = width[s]
    column0 = start[s]
    for k in range(size):
        where[front_index[first + k]] = k
    front = np.empty((size, size))
    for a in range(size):  # only the lower triangle is ever read
        front[a, : a + 1] = 0.0
    # 1a. the matrix's own entries in these columns, at or below the supernode's first row
    for local in range(columns):
        original = perm[column0 + local]
        for p in range(indptr[original], indptr[original + 1]):
            row = inverse[indices[p]]
            if row < column0:
                continue
            position = where[row]
            if position < 0:
                for k in range(size):
                    where[front_index[first + k]] = -1
                return NOT_COVERED
            front[position, local] += data[p]
    # 1b. extend-add the children's updates (the lower triangles; the upper ones are never read)
    for c in range(child_ptr[s], child_ptr[s + 1]):
        child = child_index[c]
        child_size = front_ptr[child + 1] - front_ptr[child]
        if external_ptr[child] >= 0:
            update = external[external_ptr[child]: external_ptr[child] + child_size * child_size]
        else:
            update = updates[child].reshape(-1)
        offset = width[child]
        rows = front_index[front_ptr[child] + offset: front_ptr[child + 1]]
        for a in range(len(rows)):
            target = where[rows[a]]
            base = (offset + a) * child_size + offset
            for b in range(a + 1):
                front[target, where[rows[b]]] += update[base + b]
        updates[child] = np.empty((0, 0))
    for k in range(size):
        where[front_index[first + k]] = -1
    # 2. the supernode's columns of L, in place: L₁₁ = chol(F₁₁), then L₂₁ = F₂₁ L₁₁⁻ᵀ
    chars = np.array([ord("U"), ord("L"), ord("T"), ord("N")], np.uint8)  # Fortran's view of our triangles
    ints = np.array([columns, size - columns, size], np.int32)  # columns, rows below, the front's leading dimension
    scalars = np.array([1.0, -1.0])
    info = np.zeros(1, np.int32)
    flat = front.reshape(-1)
    below = size - columns
    _dpotrf(chars[0:].ctypes, ints[0:].ctypes, flat.ctypes, ints[2:].ctypes, info.ctypes)
    if info[0] != 0:
        return NOT_POSITIVE_DEFINITE
    if below:
        # Fortran sees F₂₁ᵀ (columns × below): L₁₁ Y = F₂₁ᵀ, with L₁₁ as the transpose of its upper triangle
        _dtrsm(chars[1:].ctypes, chars[0:].ctypes, chars[2:].ctypes, chars[3:].ctypes, ints[0:].ctypes,
               ints[1:].ctypes, scalars[0:].ctypes, flat.ctypes, ints[2:].ctypes, flat[columns * size:].ctypes,
               ints[2:].ctypes)
        # 3. U = F₂₂ − L₂₁ L₂₁ᵀ, its lower triangle (Fortran's upper) in place
        _dsyrk(chars[0:].ctypes, chars[2:].ctypes, ints[1:].ctypes, ints[0:].ctypes, scalars[1:].ctypes,
               flat[columns * size:].ctypes, ints[2:].ctypes, scalars[0:].ctypes,
               flat[columns * size + columns:].ctypes, ints[2:].ctypes)
        updates[s] = front
    block = factor[factor_ptr[s]: factor_ptr[s] + size * columns].reshape(size, columns)
    block[:, :] = front[:, :columns]
    for a in range(columns):  # the upper triangle of L₁₁ is what the front held there, not L
        for b in range(a + 1, columns):
            block[a, b] = 0.0
    return FACTORED


@njit(parallel=True, cache=True)
def factor_subtrees(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, perm: np.ndarray,
                    inverse: np.ndarray, start: np.ndarray, width: np.ndarray, front_ptr: np.ndarray,
                    front_index: np.ndarray, child_ptr: np.ndarray, child_index: np.ndarray, factor_ptr: np.ndarray,
                    factor: np.ndarray, bin_ptr: np.ndarray, task_first: np.ndarray, task_last: np.ndarray,
                    external_ptr: np.ndarray, external: np.ndarray) -> int:
    """Factor independent subtrees (*tasks*: supernodes ``task_first[t] … task_last[t]``, consecutive in postorder)
    on parallel threads, bin by bin (bin b: tasks ``bin_ptr[b] … bin_ptr[b + 1] − 1``), each task leaving its root's
    front in ``external`` for :func:`factor_top`; FACTORED, NOT_COVERED or NOT_POSITIVE_DEFINITE."""
    supernodes = len(start)
    n = len(perm)
    bins = len(bin_ptr) - 1
    status = np.zeros(bins, np.int64)
    for b in prange(bins):
        where = np.full(n, -1, np.int64)
        updates = [np.empty((0, 0)) for _ in range(supernodes)]
        for t in range(bin_ptr[b], bin_ptr[b + 1]):
            for s in range(task_first[t], task_last[t] + 1):
                result = _factor_supernode(s, indptr, indices, data, perm, inverse, start, width, front_ptr,
                                           front_index, child_ptr, child_index, factor_ptr, factor, where, updates,
                                           external_ptr, external)
                if result != FACTORED:
                    status[b] = result
                    break
            if status[b] != FACTORED:
                break
            root = task_last[t]
            if external_ptr[root] >= 0:
                front = updates[root].reshape(-1)
                external[external_ptr[root]: external_ptr[root] + len(front)] = front
    for b in range(bins):
        if status[b] != FACTORED:
            return status[b]
    return FACTORED


@njit(cache=True)
def factor_top(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, perm: np.ndarray, inverse: np.ndarray,
               start: np.ndarray, width: np.ndarray, front_ptr: np.ndarray, front_index: np.ndarray,
               child_ptr: np.ndarray, child_index: np.ndarray, factor_ptr: np.ndarray, factor: np.ndarray,
               top: np.ndarray, external_ptr: np.ndarray, external: np.ndarray) -> int:
    """Factor the supernodes ``top`` (in order) above the subtrees :func:`factor_subtrees` did, on one thread."""
    where = np.full(len(perm), -1, np.int64)
    updates = [np.empty((0, 0)) for _ in range(len(start))]
    for s in top:
        result = _factor_supernode(s, indptr, indices, data, perm, inverse, start, width, front_ptr, front_index,
                                   child_ptr, child_index, factor_ptr, factor, where, updates, external_ptr,
                                   external)
        if result != FACTORED:
            return result
    return FACTORED


@njit(cache=True)
def solve_factored(perm: np.ndarray, start: np.ndarray, width: np.ndarray, front_ptr: np.ndarray,
                   front_index: np.ndarray, factor_ptr: np.ndarray, factor: np.ndarray,
                   right_hand_side: np.ndarray) -> np.ndarray:
    """``x`` with ``L Lᵀ x = b`` in the original ordering, from the factor left by :func:`factor_numeric`."""
    n = len(perm)
    y = np.empty(n)
    for k in range(n):
        y[k] = right_hand_side[perm[k]]
    supernodes = len(start)
    chars = np.array([ord("U"), ord("T"), ord("N")], np.uint8)
    ints = np.zeros(3, np.int32)  # columns, rows below, an increment of 1
    ints[2] = 1
    scalars = np.array([1.0, 0.0, -1.0])
    gathered = np.empty(n)
    # Fortran sees each block (size × columns, row-major) transposed: L₁₁ᵀ upper triangular, then L₂₁ᵀ
    for s in range(supernodes):  # L y = b
        first, size, columns, column0 = front_ptr[s], front_ptr[s + 1] - front_ptr[s], width[s], start[s]
        block = factor[factor_ptr[s]: factor_ptr[s] + size * columns]
        below = size - columns
        ints[0], ints[1] = columns, below
        _dtrsv(chars[0:].ctypes, chars[1:].ctypes, chars[2:].ctypes, ints[0:].ctypes, block.ctypes,
               ints[0:].ctypes, y[column0:].ctypes, ints[2:].ctypes)
        if below:
            _dgemv(chars[1:].ctypes, ints[0:].ctypes, ints[1:].ctypes, scalars[0:].ctypes,
                   block[columns * columns:].ctypes, ints[0:].ctypes, y[column0:].ctypes, ints[2:].ctypes,
                   scalars[1:].ctypes, gathered.ctypes, ints[2:].ctypes)
            for r in range(below):
                y[front_index[first + columns + r]] -= gathered[r]
    for s in range(supernodes - 1, -1, -1):  # Lᵀ x = y
        first, size, columns, column0 = front_ptr[s], front_ptr[s + 1] - front_ptr[s], width[s], start[s]
        block = factor[factor_ptr[s]: factor_ptr[s] + size * columns]
        below = size - columns
        ints[0], ints[1] = columns, below
        if below:
            for r in range(below):
                gathered[r] = y[front_index[first + columns + r]]
            _dgemv(chars[2:].ctypes, ints[0:].ctypes, ints[1:].ctypes, scalars[2:].ctypes,
                   block[columns * columns:].ctypes, ints[0:].ctypes, gathered.ctypes, ints[2:].ctypes,
                   scalars[0:].ctypes, y[column0:].ctypes, ints[2:].ctypes)
        _dtrsv(chars[0:].ctypes, chars[2:].ctypes, chars[2:].ctypes, ints[0:].ctypes, block.ctypes,
               ints[0:].ctypes, y[column0:].ctypes, ints[2:].ctypes)
    x = np.empty(n)
    for k in range(n):
        x[perm[k]] = y[k]
    return x
