"""A supernodal Cholesky factorisation for the step matrices of particle systems, analysed once, factored every step.

Backward Euler solves ``(M − h D − h² K) Δv = r`` at every step (:mod:`animbatch.sim.integrators.implicit`), with a
symmetric positive definite matrix whose sparsity is the springs' graph, the same at every step; on a 64×64 cloth
this factorisation was three quarters of the run. SuperLU (scipy's only sparse direct solver) factors it column by
column, as an LU, in 150–270 ms; a supernodal Cholesky, which hands dense blocks to BLAS, is several times faster.

Everything that depends only on the sparsity is done once, here, in numpy (:class:`SparseCholesky`):

* the graph of *particles* (3×3 blocks), rather than of unknowns: its three unknowns of a particle always share
  their columns' structure, so they stay together;
* a fill-reducing ordering of that graph: SuperLU's minimum degree on ``Aᵀ + A`` (the one it would use itself),
  read off a factorisation of a small matrix of the same graph;
* the elimination tree, put in postorder (children before parents, each subtree contiguous);
* each particle's column structure in the factor (its children's structures and its own lower neighbours), and
  from them the fundamental supernodes (chains of columns with nested structures), widened by *relaxed
  amalgamation*: a child joins its parent when that adds few explicit zeros, so that BLAS gets blocks worth calling;
* the front of every supernode, and where its factor lives;
* which independent subtrees each thread factors (:func:`schedule_subtrees`), and the supernodes above them that
  follow on one thread. BLAS runs on one thread meanwhile: its own threads, on top of these, made the factorisation
  twice as slow.

The numeric factorisation and the solves are compiled (:mod:`animbatch.sim.kernels.supernodal`). A later matrix may
have fewer entries than the analysed one (scipy drops sums that come out exactly zero) but not more; if it has, it
is analysed again.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from animbatch.sim.blas import blas_threads

#: A child supernode joins its parent when the merged supernode has at most this many particles (three columns
#: each)…
AMALGAMATE_PARTICLES = 16
#: …or when the explicit zeros it adds are at most this fraction of the merged supernode's entries.
AMALGAMATE_ZEROS = 0.1


class NotPositiveDefinite(ValueError):
    """The matrix given to :meth:`SparseCholesky.factor` is not symmetric positive definite."""


class SparseCholesky:
    """``L Lᵀ`` factors of sparse symmetric positive definite (3N, 3N) matrices of one sparsity pattern (3×3 blocks
    per particle pair), reanalysed only when a matrix has entries outside it."""

    def __init__(self, matrix: sp.spmatrix) -> None:
        self._analyse(sp.csr_matrix(matrix))
        self.analyses = 1

    # ------------------------------------------------------------------------------------------ analysis

    def _analyse(self, matrix: sp.csr_matrix) -> None:
        size = matrix.shape[0]
        if size % 3:
            raise ValueError(f"a particle system's matrix has 3 unknowns per particle, not {size}")
        particles = size // 3
        coo = matrix.tocoo()
        graph = sp.csr_matrix((np.ones(len(coo.row)), (coo.row // 3, coo.col // 3)), shape=(particles, particles))
        graph = ((graph + graph.T) != 0).astype(np.float64).tocsr()  # the pattern, symmetric, diagonal included
        graph.setdiag(0)
        graph.eliminate_zeros()
        order = minimum_degree_order(graph)
        parent = elimination_tree(graph[order][:, order].tocsr())
        order = order[postorder(parent)]
        graph = graph[order][:, order].tocsr()
        parent = elimination_tree(graph)
        structures = column_structures(graph, parent)
        first, last = supernodes(parent, structures)
        self._layout(order, parent, structures, first, last, size)

    def _layout(self, order: np.ndarray, parent: np.ndarray, structures: list[np.ndarray], first: np.ndarray,
                last: np.ndarray, size: int) -> None:
        """The kernels' arrays from the particle-level supernodes ``[first[s], last[s]]``."""
        axis = np.arange(3)
        self.perm = (3 * order[:, None] + axis).ravel().astype(np.int64)  # new unknown -> original
        self.inverse = np.empty(size, np.int64)
        self.inverse[self.perm] = np.arange(size)
        count = len(first)
        self.start = (3 * first).astype(np.int64)
        self.width = (3 * (last - first + 1)).astype(np.int64)
        owner = np.repeat(np.arange(count), last - first + 1)  # particle (new) -> supernode
        fronts = []
        for s in range(count):
            below = structures[last[s]]
            rows = (3 * below[:, None] + axis).ravel()
            fronts.append(np.concatenate([np.arange(self.start[s], self.start[s] + self.width[s]), rows]))
        sizes = np.array([len(f) for f in fronts], np.int64)
        self.front_ptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.front_index = np.concatenate(fronts).astype(np.int64)
        parents = np.array([owner[parent[last[s]]] if parent[last[s]] >= 0 else -1 for s in range(count)], np.int64)
        children = np.argsort(parents, kind="stable")
        children = children[parents[children] >= 0]
        self.child_index = children.astype(np.int64)
        self.child_ptr = np.searchsorted(parents[children], np.arange(count + 1)).astype(np.int64)
        self.factor_ptr = np.concatenate([[0], np.cumsum(sizes * self.width)]).astype(np.int64)
        self._schedule(parents, sizes)
        self.factor_data = np.zeros(int(self.factor_ptr[-1]))
        self.size = size
        self.supernode_count = count

    def _schedule(self, parents: np.ndarray, sizes: np.ndarray) -> None:
        """Independent subtrees for the threads (see :func:`schedule_subtrees`), in the kernel's arrays."""
        from numba import get_num_threads

        count = len(parents)
        tasks, top = schedule_subtrees(parents, (sizes.astype(np.float64) ** 2) * self.width, get_num_threads())
        self.bin_ptr = np.concatenate([[0], np.cumsum([len(b) for b in tasks])]).astype(np.int64)
        roots = np.array([root for group in tasks for root in group], np.int64)
        descendants = subtree_sizes(parents)
        self.task_first = (roots - descendants[roots] + 1).astype(np.int64)
        self.task_last = roots
        self.top = np.array(top, np.int64)
        self.external_ptr = np.full(count, -1, np.int64)
        exported = roots[parents[roots] >= 0]
        offsets = np.concatenate([[0], np.cumsum(sizes[exported] ** 2)])
        self.external_ptr[exported] = offsets[:-1]
        self._external = np.empty(int(offsets[-1]))  # the subtrees' root fronts, for the supernodes above

    # ------------------------------------------------------------------------------------------ numeric

    def factor(self, matrix: sp.spmatrix) -> SparseCholesky:
        """Factor ``matrix`` (symmetric positive definite, the analysed pattern or a part of it); returns self, whose
        :meth:`solve` then solves with it. Raises :class:`NotPositiveDefinite`."""
        from animbatch.sim.kernels.supernodal import FACTORED, NOT_COVERED, factor_subtrees, factor_top

        matrix = sp.csr_matrix(matrix)
        for _ in range(2):
            arrays = (matrix.indptr, matrix.indices, matrix.data, self.perm,
                      self.inverse, self.start, self.width, self.front_ptr, self.front_index, self.child_ptr,
                      self.child_index, self.factor_ptr, self.factor_data)
            # BLAS on one thread: beside the subtrees' threads two levels of threads only fight, and on the top
            # part its own threads made the whole factorisation twice as slow (58 ms against 26 on a 64×64 cloth)
            with blas_threads(1):
                status = factor_subtrees(*arrays, self.bin_ptr, self.task_first, self.task_last, self.external_ptr,
                                         self._external)
                if status == FACTORED:
                    status = factor_top(*arrays, self.top, self.external_ptr, self._external)
            if status == FACTORED:
                return self
            if status != NOT_COVERED:
                raise NotPositiveDefinite("the matrix is not positive definite")
            self._analyse(matrix)  # entries outside the analysed pattern: a new pattern
            self.analyses += 1
        raise AssertionError("a freshly analysed pattern does not cover its own matrix")

    def solve(self, right_hand_side: np.ndarray) -> np.ndarray:
        """``x`` with ``A x = b`` for the last factored A; ``b`` (3N,)."""
        from animbatch.sim.kernels.supernodal import solve_factored

        with blas_threads(1):  # many small BLAS calls: waking threads costs more than they save
            return solve_factored(self.perm, self.start, self.width, self.front_ptr, self.front_index,
                                  self.factor_ptr, self.factor_data,
                                  np.ascontiguousarray(right_hand_side, dtype=np.float64))


# ---------------------------------------------------------------------------------------------- symbolic steps


def minimum_degree_order(graph: sp.csr_matrix) -> np.ndarray:
    """A fill-reducing order (new -> original) of a symmetric graph (no diagonal): SuperLU's multiple minimum degree
    on ``Aᵀ + A``, taken from its factorisation of the graph's Laplacian plus the identity (positive definite, so
    the diagonal pivots SuperLU takes in symmetric mode leave the column order alone)."""
    degree = np.asarray(graph.sum(axis=1)).ravel()
    laplacian = sp.diags(degree + 1.0) - graph
    factors = splu(sp.csc_matrix(laplacian), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    # Pr A Pc = L U with Pc[perm_c[k], k]… scipy's SuperLU maps original column k to new column perm_c[k]
    return np.argsort(factors.perm_c).astype(np.int64)


def elimination_tree(graph: sp.csr_matrix) -> np.ndarray:
    """Parent of each column in the elimination tree of a symmetric pattern (−1 at roots), by Liu's algorithm with
    path compression."""
    n = graph.shape[0]
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    indptr, indices = graph.indptr, graph.indices
    for j in range(n):
        for i in indices[indptr[j]: indptr[j + 1]]:
            while i < j:  # climb from i to the root of its current subtree, pointing the path at j
                following = ancestor[i]
                ancestor[i] = j
                if following == -1:
                    parent[i] = j
                    break
                if following == j:
                    break
                i = following
    return parent


def postorder(parent: np.ndarray) -> np.ndarray:
    """The columns in a postorder of the forest ``parent`` (children before their parent, subtrees contiguous),
    children in their original order."""
    n = len(parent)
    children: list[list[int]] = [[] for _ in range(n)]
    roots: list[int] = []
    for j in range(n):
        (children[parent[j]] if parent[j] >= 0 else roots).append(j)
    order: list[int] = []
    for root in roots:
        stack = [(root, 0)]
        while stack:
            node, next_child = stack.pop()
            if next_child < len(children[node]):
                stack.append((node, next_child + 1))
                stack.append((children[node][next_child], 0))
            else:
                order.append(node)
    return np.array(order, np.int64)


def column_structures(graph: sp.csr_matrix, parent: np.ndarray) -> list[np.ndarray]:
    """For each column j, the rows below j where the factor has entries (sorted): j's own neighbours below it and
    its children's structures, less j."""
    n = graph.shape[0]
    structures: list[np.ndarray] = []
    gathered: list[list[np.ndarray]] = [[] for _ in range(n)]
    for j in range(n):
        neighbours = graph.indices[graph.indptr[j]: graph.indptr[j + 1]]
        parts = [neighbours[neighbours > j]] + [child[child > j] for child in gathered[j]]
        structure = np.unique(np.concatenate(parts)) if len(parts) > 1 else np.sort(parts[0])
        structures.append(structure.astype(np.int64))
        gathered[j] = []
        if parent[j] >= 0:
            gathered[parent[j]].append(structure)
    return structures


def supernodes(parent: np.ndarray, structures: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """First and last column of each supernode, in order: fundamental supernodes (a column joins the one before it
    when it is that column's parent, its only child, and its structure that column's less itself), then relaxed
    amalgamation of a child into its parent, when it is the column just before the parent's first, while the
    merged supernode stays small or its added zeros few (:data:`AMALGAMATE_PARTICLES`, :data:`AMALGAMATE_ZEROS`)."""
    n = len(parent)
    child_count = np.bincount(parent[parent >= 0], minlength=n)
    starts = [0]
    for j in range(1, n):
        if not (parent[j - 1] == j and child_count[j] == 1 and len(structures[j - 1]) == len(structures[j]) + 1):
            starts.append(j)
    first = np.array(starts, np.int64)
    last = np.concatenate([first[1:] - 1, [n - 1]]).astype(np.int64)
    # relaxed amalgamation: merge supernode s into s + 1 when s's last column's parent is in s + 1 and it is cheap
    merged_first, merged_last = [int(first[0])], [int(last[0])]
    for s in range(1, len(first)):
        a, b = merged_first[-1], merged_last[-1]
        c, d = int(first[s]), int(last[s])
        if parent[b] == c and b + 1 == c:
            width = d - a + 1
            # rows of the merged supernode: c's columns and structure, for every column of it
            below = len(structures[d])
            entries = width * (width + 1) // 2 + width * below
            true_entries = sum(len(structures[k]) + 1 for k in range(a, d + 1))
            added = entries - true_entries
            if width <= AMALGAMATE_PARTICLES or added <= AMALGAMATE_ZEROS * entries:
                merged_last[-1] = d
                continue
        merged_first.append(c)
        merged_last.append(d)
    return np.array(merged_first, np.int64), np.array(merged_last, np.int64)


def subtree_sizes(parents: np.ndarray) -> np.ndarray:
    """How many nodes each node's subtree holds (itself included), for a forest in postorder (children first)."""
    sizes = np.ones(len(parents), np.int64)
    for node in range(len(parents)):
        if parents[node] >= 0:
            sizes[parents[node]] += sizes[node]
    return sizes


def schedule_subtrees(parents: np.ndarray, cost: np.ndarray, threads: int) -> tuple[list[list[int]], list[int]]:
    """Share a postordered forest of supernodes (``cost`` (S,) each) among ``threads``: the roots of independent
    subtrees for each thread, and the supernodes left above them, to be factored after them on one thread.

    Starting from the forest's roots, the costliest subtree is split (its root goes on top, its children become
    subtrees) while it alone holds more than a thread's share of what the subtrees hold; then the subtrees go to
    the thread with the least work so far, costliest first."""
    count = len(parents)
    children: list[list[int]] = [[] for _ in range(count)]
    for node in range(count):
        if parents[node] >= 0:
            children[parents[node]].append(node)
    total = cost.copy()
    for node in range(count):  # postorder: children before parents
        if parents[node] >= 0:
            total[parents[node]] += total[node]
    subtrees = [node for node in range(count) if parents[node] < 0]
    top: list[int] = []
    for _ in range(8 * threads):
        if threads < 2:
            break
        largest = max(subtrees, key=lambda node: total[node])
        share = sum(total[node] for node in subtrees) / threads
        if total[largest] <= share or not children[largest]:
            break
        subtrees.remove(largest)
        subtrees += children[largest]
        top.append(largest)
    bins: list[list[int]] = [[] for _ in range(max(1, threads))]
    load = [0.0] * len(bins)
    for node in sorted(subtrees, key=lambda node: -total[node]):
        lightest = int(np.argmin(load))
        bins[lightest].append(node)
        load[lightest] += float(total[node])
    return [group for group in bins if group], sorted(top)
