"""Compiled ``L D Lᵀ`` factorisation and solves of the joints' coupling matrix ``A = J M⁻¹ Jᵀ`` on a sparsity
pattern found once (:func:`animbatch.sim.joints.pattern.coupling_pattern`; fields ``ORDER`` … ``UPDATES`` of
:mod:`animbatch.sim.kernels.tables`).

A joint's rows couple only with the rows of joints that share one of its bodies, so A is sparse, and for a tree of
bodies (a chain, a ragdoll) eliminating the rows leaves first fills nothing in: the factorisation costs O(rows)
where a dense one costs O(rows³) (a 20-link hinge chain has 100 rows). Closed loops add a little fill, which the
pattern holds. Numerically this is a right-looking elimination whose updates were listed when the pattern was found,
so the loops below are all arithmetic.

A is symmetric positive semi-definite. A pivot that is not clearly positive (at most ``PIVOT_TOLERANCE`` times its
row's diagonal) belongs to a row that other rows already fix (a redundant constraint, as in a planar loop); its
multiplier is set to zero and the others carry the load, where a dense solve would have failed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from animbatch.sim.kernels import tables as T
from animbatch.sim.kernels.rigid_motion import column, table

#: A pivot at most this fraction of its diagonal entry before elimination marks a redundant row.
PIVOT_TOLERANCE = 1e-12


@njit(cache=True, error_model="numpy")
def assemble(integers: np.ndarray, layout: np.ndarray, jac: np.ndarray, row_bodies: np.ndarray,
             inverse_mass: np.ndarray, inverse_inertia: np.ndarray, active: np.ndarray, values: np.ndarray,
             diagonal: np.ndarray) -> None:
    """The lower triangle of ``A = J M⁻¹ Jᵀ`` (in elimination order) into ``values`` (E,), and its diagonal into
    ``diagonal`` (R,), from the rows' Jacobian ``jac`` (R, 2, 6: per end the linear part, then the angular one),
    their slots ``row_bodies`` (R, 2), and the slots' inverse masses (S,) and world inverse inertias (S, 3, 3). Rows
    not ``active`` are decoupled: their own 1 on the diagonal (their multiplier comes out zero for a zero right-hand
    side)."""
    pairs = table(integers, layout, T.PAIRS, 5)
    order = column(integers, layout, T.ORDER)
    column_start = column(integers, layout, T.COLUMN_START)
    # M⁻¹ Jᵀ once per row end (flat: end e of row e // 2), then one dot product of six per pair of ends that meet
    # at a body, written out (a quarter quicker than loops over the six)
    count = len(jac)
    ends = jac.reshape((2 * count, 6))
    scaled = np.empty((2 * count, 6))
    for e in range(2 * count):
        body = row_bodies[e // 2, e % 2]
        tensor, mass = inverse_inertia[body], inverse_mass[body]
        for c in range(3):
            scaled[e, c] = ends[e, c] * mass
            scaled[e, 3 + c] = tensor[c, 0] * ends[e, 3] + tensor[c, 1] * ends[e, 4] + tensor[c, 2] * ends[e, 5]
    every_row = True
    for r in range(count):
        every_row = every_row and active[r]
    values[:] = 0.0
    for p in range(len(pairs)):
        row_a, row_b = pairs[p, 0], pairs[p, 2]
        if not every_row and not (active[row_a] and active[row_b]):
            continue
        a, b = 2 * row_a + pairs[p, 1], 2 * row_b + pairs[p, 3]
        values[pairs[p, 4]] += (ends[a, 0] * scaled[b, 0] + ends[a, 1] * scaled[b, 1] + ends[a, 2] * scaled[b, 2]
                                + ends[a, 3] * scaled[b, 3] + ends[a, 4] * scaled[b, 4] + ends[a, 5] * scaled[b, 5])
    for k in range(len(order)):
        if not active[order[k]]:
            values[column_start[k]] += 1.0
        diagonal[k] = values[column_start[k]]


@njit(cache=True, error_model="numpy")
def factor(integers: np.ndarray, layout: np.ndarray, values: np.ndarray, diagonal: np.ndarray) -> None:
    """Factor the assembled ``values`` in place into L (unit diagonal implied; the diagonal entries are left as
    they are) and ``diagonal`` into D (R,), which holds A's diagonal on entry (the scale pivots are judged by); a
    redundant row's D is infinite (its multiplier comes out zero)."""
    column_start = column(integers, layout, T.COLUMN_START)
    update_start = column(integers, layout, T.UPDATE_START)
    updates = table(integers, layout, T.UPDATES, 3)
    for k in range(len(diagonal)):
        pivot = values[column_start[k]]
        if not pivot > PIVOT_TOLERANCE * diagonal[k]:
            diagonal[k] = np.inf
            for p in range(column_start[k] + 1, column_start[k + 1]):
                values[p] = 0.0
            continue
        inverse = 1.0 / pivot
        for u in range(update_start[k], update_start[k + 1]):
            values[updates[u, 0]] -= values[updates[u, 1]] * values[updates[u, 2]] * inverse
        for p in range(column_start[k] + 1, column_start[k + 1]):
            values[p] *= inverse
        diagonal[k] = pivot


@njit(cache=True, error_model="numpy")
def solve(integers: np.ndarray, layout: np.ndarray, values: np.ndarray, diagonal: np.ndarray, right: np.ndarray,
          out: np.ndarray) -> None:
    """``x`` (R,) with ``L D Lᵀ x = right`` (rows in their own order), into ``out``."""
    order = column(integers, layout, T.ORDER)
    column_start = column(integers, layout, T.COLUMN_START)
    column_rows = column(integers, layout, T.COLUMN_ROWS)
    count = len(order)
    work = np.empty(count)
    for k in range(count):
        work[k] = right[order[k]]
    for k in range(count):
        value = work[k]
        if value != 0.0:
            for p in range(column_start[k] + 1, column_start[k + 1]):
                work[column_rows[p]] -= values[p] * value
    for k in range(count):
        work[k] = work[k] / diagonal[k] if diagonal[k] != np.inf else 0.0
    for k in range(count - 1, -1, -1):
        value = work[k]
        for p in range(column_start[k] + 1, column_start[k + 1]):
            value -= values[p] * work[column_rows[p]]
        work[k] = value
    for k in range(count):
        out[order[k]] = work[k]
