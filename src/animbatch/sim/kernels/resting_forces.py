"""The resting-contact force solve of adaptive methods compiled: :func:`animbatch.sim.contact.impulses.solve_forces`'s
contact matrix, its projected Gauss–Seidel sweeps and the accelerations the forces add, in one call.

An adaptive method evaluates the right-hand side hundreds of times a second of a resting box, and each evaluation
solves its few resting contacts; in numpy the solve was some 40 % of an evaluation (building the 3K × 3K matrix with
an einsum over both ends of every pair of rows, then sweeps of Python floats). Every operation is the numpy code's,
row by row in the same order, so the two agree to round-off (the tests compare them).

Arrays (K contacts, B bodies with the fixed one last): ``a``, ``b`` (K,) the contacts' ends; ``directions`` (3, K, 3)
the normal, first and second tangent; ``pushes`` (K, 3) the direction the normal row's force acts along (the normal,
less ``μk`` times the slip direction for a sliding contact); ``r_a``, ``r_b`` (K, 3) lever arms [m];
``inverse_mass`` (B,), ``inverse_inertia`` (B, 3, 3) world axes; ``v``, ``w`` (B, 3) the bodies' linear and angular
accelerations without the contacts, changed in place; ``bias`` (3K,) the rows' constant terms (normals, then first
and second tangents); ``solution`` (3K,) the forces to start from, updated in place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _ends(row: int, count: int, a: np.ndarray, b: np.ndarray, directions: np.ndarray, pushes: np.ndarray,
          r_a: np.ndarray, r_b: np.ndarray, measure: np.ndarray, force: np.ndarray, body: np.ndarray) -> None:
    """Row ``row``'s ends: what it measures ``[d, r × d]`` (minus at b) and the force it applies, (2, 6) each, and
    its two bodies."""
    which, k = row // count, row % count
    body[row, 0], body[row, 1] = a[k], b[k]
    for end in range(2):
        sign = 1.0 if end == 0 else -1.0
        r = r_a[k] if end == 0 else r_b[k]
        for kind in range(2):  # 0: what the row measures, 1: the force it applies
            d = directions[which, k] if kind == 0 or which > 0 else pushes[k]
            out = measure if kind == 0 else force
            out[row, end, 0] = sign * d[0]
            out[row, end, 1] = sign * d[1]
            out[row, end, 2] = sign * d[2]
            out[row, end, 3] = sign * (r[1] * d[2] - r[2] * d[1])
            out[row, end, 4] = sign * (r[2] * d[0] - r[0] * d[2])
            out[row, end, 5] = sign * (r[0] * d[1] - r[1] * d[0])


@njit(cache=True)
def resting_forces(a: np.ndarray, b: np.ndarray, directions: np.ndarray, pushes: np.ndarray, r_a: np.ndarray,
                   r_b: np.ndarray, inverse_mass: np.ndarray, inverse_inertia: np.ndarray, v: np.ndarray,
                   w: np.ndarray, bias: np.ndarray, solution: np.ndarray, sticking: np.ndarray,
                   static_friction: np.ndarray, iterations: int, tolerance: float) -> None:
    """Solve the resting contacts' forces into ``solution`` (3K,) and add their accelerations to ``v``, ``w``."""
    count = len(a)
    rows = 3 * count
    measure = np.empty((rows, 2, 6))
    force = np.empty((rows, 2, 6))
    body = np.empty((rows, 2), np.int64)
    for row in range(rows):
        _ends(row, count, a, b, directions, pushes, r_a, r_b, measure, force, body)
    # M⁻¹ Fᵀ per end: the bodies' response to a unit force of each row
    response = np.empty((rows, 2, 6))
    for row in range(rows):
        for end in range(2):
            j = body[row, end]
            for c in range(3):
                response[row, end, c] = inverse_mass[j] * force[row, end, c]
                turn = 0.0
                for e in range(3):
                    turn += inverse_inertia[j, c, e] * force[row, end, 3 + e]
                response[row, end, 3 + c] = turn
    # row i's acceleration per unit of force j, through the bodies their ends share
    matrix = np.zeros((rows, rows))
    for i in range(rows):
        for j in range(rows):
            total = 0.0
            for e in range(2):
                for f in range(2):
                    if body[i, e] == body[j, f]:
                        for c in range(6):
                            total += measure[i, e, c] * response[j, f, c]
            matrix[i, j] = total
    # the rows' values without contact forces: the relative acceleration along each direction, plus the bias
    free = np.empty(rows)
    for k in range(count):
        i, j = a[k], b[k]
        relative = np.empty(3)
        for c in range(3):
            c1, c2 = (c + 1) % 3, (c + 2) % 3
            turn_a = w[i, c1] * r_a[k, c2] - w[i, c2] * r_a[k, c1]
            turn_b = w[j, c1] * r_b[k, c2] - w[j, c2] * r_b[k, c1]
            relative[c] = v[i, c] + turn_a - v[j, c] - turn_b
        for which in range(3):
            along = 0.0
            for c in range(3):
                along += relative[c] * directions[which, k, c]
            free[which * count + k] = along + bias[which * count + k]
    pivot = np.empty(rows)
    for i in range(rows):
        pivot[i] = matrix[i, i] if matrix[i, i] > 0 else np.inf
    for _ in range(iterations):
        for k in range(count):
            solution[k] = max(_update(k, matrix, free, pivot, solution), 0.0)
            if sticking[k]:
                j1, j2 = count + k, 2 * count + k
                t1 = _update(j1, matrix, free, pivot, solution)
                solution[j1] = t1
                t2 = _update(j2, matrix, free, pivot, solution)
                size = math.hypot(t1, t2)
                cap = static_friction[k] * solution[k]
                scale = 1.0 if size <= cap else cap / size
                solution[j1], solution[j2] = t1 * scale, t2 * scale
        if _converged(matrix, free, solution, sticking, static_friction, count, tolerance):
            break
    for row in range(rows):
        for end in range(2):
            j = body[row, end]
            for c in range(3):
                v[j, c] += response[row, end, c] * solution[row]
                w[j, c] += response[row, end, 3 + c] * solution[row]


@njit(cache=True, inline="always")
def _update(row: int, matrix: np.ndarray, free: np.ndarray, pivot: np.ndarray, current: np.ndarray) -> float:
    """Row ``row``'s value that meets its target with the others at ``current`` (Gauss–Seidel)."""
    along = 0.0
    for j in range(len(current)):
        along += matrix[row, j] * current[j]
    return current[row] - (free[row] + along) / pivot[row]


@njit(cache=True)
def _converged(matrix: np.ndarray, free: np.ndarray, current: np.ndarray, sticking: np.ndarray, cone: np.ndarray,
               count: int, tolerance: float) -> bool:
    """Every pressing normal row at zero residual and no free one pulled in, and every sticking contact strictly
    inside its cone with no tangential residual, all to ``tolerance``."""
    residual = free.copy()
    for i in range(len(free)):
        for j in range(len(free)):
            residual[i] += matrix[i, j] * current[j]
    for k in range(count):
        if (abs(residual[k]) if current[k] > 0 else max(-residual[k], 0.0)) > tolerance:
            return False
        j1, j2 = count + k, 2 * count + k
        if (sticking[k] and math.hypot(current[j1], current[j2]) < cone[k] * current[k] * (1 - 1e-9)
                and math.hypot(residual[j1], residual[j2]) > tolerance):
            return False
    return True
