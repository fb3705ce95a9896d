"""The sparsity of the joints' coupling matrix and of its factor, found once per model for the compiled solve
(:mod:`animbatch.sim.kernels.sparse_ldl`).

Rows i and j of ``A = J M⁻¹ Jᵀ`` couple when they act on a common body. Eliminating a row couples all the rows it
was coupled with (fill); the order chosen here is the minimum degree one (each time the row with the fewest
couplings left, ties to the lower row), which for a tree of bodies, a chain or a ragdoll, fills nothing in: such a
coupling graph is chordal, and a leaf's rows are always among the least coupled. The elimination itself gives the
pattern of L, and each column's updates are listed for the numeric factorisation.
"""

from __future__ import annotations

import heapq
from collections import defaultdict
from typing import NamedTuple

import numpy as np


class CouplingPattern(NamedTuple):
    """The pattern of ``A = J M⁻¹ Jᵀ`` (R, R) and of its factor ``L D Lᵀ``.

    Rows are eliminated in the order ``order`` (new → row); ``position`` (R,) is its inverse. L is stored by
    columns in that order: column k's entries are ``column_start[k] : column_start[k + 1]``, the diagonal first, at
    the (new) rows ``column_rows``. ``pair_first``, ``pair_second`` (Q,): flat row ends (2 row + end) that meet at
    one body, whose product adds to entry ``pair_target`` (each unordered pair once). ``update_start`` (R+1,),
    ``update_target``, ``update_first``, ``update_second``: eliminating column k subtracts ``first · second / d_k``
    from ``target`` for each of its updates (the fill included)."""

    order: np.ndarray
    position: np.ndarray
    column_start: np.ndarray
    column_rows: np.ndarray
    pair_first: np.ndarray
    pair_second: np.ndarray
    pair_target: np.ndarray
    update_start: np.ndarray
    update_target: np.ndarray
    update_first: np.ndarray
    update_second: np.ndarray


def _elimination(adjacency: list[set[int]]) -> tuple[list[int], list[list[int]]]:
    """Minimum degree order of the rows, and each eliminated row's neighbours at its elimination (its column of
    L below the diagonal, as rows)."""
    graph = [set(neighbours) for neighbours in adjacency]
    heap = [(len(neighbours), row) for row, neighbours in enumerate(graph)]
    heapq.heapify(heap)
    eliminated = [False] * len(graph)
    order: list[int] = []
    columns: list[list[int]] = []
    while heap:
        degree, row = heapq.heappop(heap)
        if eliminated[row] or degree != len(graph[row]):
            continue  # a stale entry: the row was eliminated, or gained neighbours since
        eliminated[row] = True
        neighbours = graph[row]
        order.append(row)
        columns.append(sorted(neighbours))
        for other in neighbours:
            graph[other].discard(row)
            graph[other] |= neighbours - {other}
            heapq.heappush(heap, (len(graph[other]), other))  # its degree changed: a fresh entry
        graph[row] = set()
    return order, columns


def coupling_pattern(row_bodies: np.ndarray, movable: np.ndarray) -> CouplingPattern:
    """The :class:`CouplingPattern` of rows acting on slots ``row_bodies`` (R, 2);
    ``movable`` (S,): the slots that move under impulses (the joined bodies; anchors and the world do not)."""
    count = len(row_bodies)
    ends_at: dict[int, list[int]] = defaultdict(list)
    for row in range(count):
        for end in range(2):
            slot = int(row_bodies[row, end])
            if movable[slot]:
                ends_at[slot].append(2 * row + end)
    adjacency: list[set[int]] = [set() for _ in range(count)]
    for ends in ends_at.values():
        rows = {end // 2 for end in ends}
        for row in rows:
            adjacency[row] |= rows - {row}
    order, columns = _elimination(adjacency)
    position = np.empty(count, np.int64)
    position[order] = np.arange(count)
    column_start = [0]
    column_rows: list[int] = []
    where: dict[tuple[int, int], int] = {}  # (row, column), new indices -> entry
    for k, neighbours in enumerate(columns):
        below = sorted(int(position[row]) for row in neighbours)
        assert all(i > k for i in below), "a neighbour was eliminated before its row"
        for i in [k, *below]:
            where[(i, k)] = len(column_rows)
            column_rows.append(i)
        column_start.append(len(column_rows))
    pair_first, pair_second, pair_target = [], [], []
    for ends in ends_at.values():
        for first in ends:
            for second in ends:
                i, j = int(position[first // 2]), int(position[second // 2])
                if i >= j:
                    pair_first.append(first)
                    pair_second.append(second)
                    pair_target.append(where[(i, j)])
    update_start = [0]
    update_target, update_first, update_second = [], [], []
    for k in range(count):
        below = column_rows[column_start[k] + 1: column_start[k + 1]]
        for a, i in enumerate(below):
            for j in below[: a + 1]:
                update_target.append(where[(i, j)])
                update_first.append(where[(i, k)])
                update_second.append(where[(j, k)])
        update_start.append(len(update_target))
    integers = lambda values: np.asarray(values, np.int64)  # noqa: E731
    return CouplingPattern(integers(order), position, integers(column_start), integers(column_rows),
                           integers(pair_first), integers(pair_second), integers(pair_target),
                           integers(update_start), integers(update_target), integers(update_first),
                           integers(update_second))
