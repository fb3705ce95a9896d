"""Compiled spring forces and assembly of force Jacobians: the springs' forces, their 3×3 blocks, the blocks' scatter
into a fixed sparse pattern, and their product with a vector, without building the (K, 3, 3) copies and sparse sums
the numpy code goes through.

The numpy forms they replace: :meth:`animbatch.sim.forces.springs.SpringForces.accumulate` (forces, for springs
between points or to anchors; ends at body points stay with numpy), ``SpringForces.jacobian`` (blocks),
:meth:`animbatch.sim.forces.term.ForceJacobian.matrix` and scipy's sparse sums (scatter),
``ForceJacobian.matrix(which) @ vector`` (product). The tests compare each pair.

Blocks are (K, 3, 3), row-major. A *pair* part holds one block B per pair of particles (i, j), standing for the four
blocks of a spring or damper between them: ``+B`` at (i, i) and (j, j), ``−B`` at (i, j) and (j, i). Its slots are
(K, 36): the data positions of those four blocks' nine entries, in that order; a plain part's are (K, 9).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def spring_forces(x: np.ndarray, v: np.ndarray, first: np.ndarray, second: np.ndarray, to_anchor: np.ndarray,
                  anchor_x: np.ndarray, anchor_v: np.ndarray, stiffness: np.ndarray, damping: np.ndarray,
                  rest_length: np.ndarray, force: np.ndarray) -> None:
    """Add the forces [N] of springs between points (``x``, ``v`` (P, 3)), or from a point to an anchor
    (``anchor_x``, ``anchor_v`` (A, 3)) where ``to_anchor``, onto ``force`` (P, 3):
    ``f1 = -(ks (|L| - r) + kd (ṗ1 - ṗ2)·u) u`` on the first end, ``-f1`` on the second (none for an anchor); a
    spring of zero length exerts none."""
    for s in range(len(first)):
        i, j = first[s], second[s]
        anchored = to_anchor[s]
        if anchored:
            ax, ay, az = x[i, 0] - anchor_x[j, 0], x[i, 1] - anchor_x[j, 1], x[i, 2] - anchor_x[j, 2]
            wx, wy, wz = v[i, 0] - anchor_v[j, 0], v[i, 1] - anchor_v[j, 1], v[i, 2] - anchor_v[j, 2]
        else:
            ax, ay, az = x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2]
            wx, wy, wz = v[i, 0] - v[j, 0], v[i, 1] - v[j, 1], v[i, 2] - v[j, 2]
        length = math.sqrt(ax * ax + ay * ay + az * az)
        if length <= 0.0:
            continue
        ux, uy, uz = ax / length, ay / length, az / length
        magnitude = stiffness[s] * (length - rest_length[s]) + damping[s] * (wx * ux + wy * uy + wz * uz)
        fx, fy, fz = -magnitude * ux, -magnitude * uy, -magnitude * uz
        force[i, 0] += fx
        force[i, 1] += fy
        force[i, 2] += fz
        if not anchored:
            force[j, 0] -= fx
            force[j, 1] -= fy
            force[j, 2] -= fz


@njit(cache=True)
def spring_blocks(axis: np.ndarray, relative: np.ndarray, stiffness: np.ndarray, damping: np.ndarray,
                  rest_length: np.ndarray, definite: bool) -> tuple[np.ndarray, np.ndarray]:
    """``∂f1/∂p1`` and ``∂f1/∂ṗ1`` (S, 3, 3) of springs with end-to-end vectors ``axis`` [m] and relative velocities
    ``relative`` [m/s] (S, 3): the formulas of ``SpringForces.jacobian``, exact or definite."""
    count = axis.shape[0]
    dfdx = np.empty((count, 3, 3))
    dfdv = np.empty((count, 3, 3))
    for s in range(count):
        ax, ay, az = axis[s, 0], axis[s, 1], axis[s, 2]
        length = math.sqrt(ax * ax + ay * ay + az * az)
        ks, kd = stiffness[s], damping[s]
        if length < 1e-12:  # no direction: a zero-length spring, f = -ks L - kd L̇
            for a in range(3):
                for b in range(3):
                    dfdx[s, a, b] = -ks if a == b else 0.0
                    dfdv[s, a, b] = -kd if a == b else 0.0
            continue
        safe = max(length, 1e-12)
        u = (ax / safe, ay / safe, az / safe)
        w = (relative[s, 0], relative[s, 1], relative[s, 2])
        along = w[0] * u[0] + w[1] * u[1] + w[2] * u[2]
        if definite:
            stretch = max(0.0, 1.0 - rest_length[s] / safe)
            for a in range(3):
                for b in range(3):
                    outer = u[a] * u[b]
                    dfdx[s, a, b] = -ks * (outer + stretch * ((1.0 if a == b else 0.0) - outer))
                    dfdv[s, a, b] = -kd * outer
        else:
            magnitude = ks * (length - rest_length[s]) + kd * along
            for a in range(3):
                for b in range(3):
                    outer = u[a] * u[b]
                    across = (1.0 if a == b else 0.0) - outer
                    across_relative = w[b] - along * u[b]
                    dfdx[s, a, b] = (-ks * outer - (kd / safe) * u[a] * across_relative
                                     - (magnitude / safe) * across)
                    dfdv[s, a, b] = -kd * outer
    return dfdx, dfdv


@njit(cache=True)
def scatter_plain(data: np.ndarray, slots: np.ndarray, blocks: np.ndarray, scale: float) -> None:
    """``data[slots[k, e]] += scale · blocks[k].flat[e]``."""
    flat = blocks.reshape(-1)
    for k in range(slots.shape[0]):
        for e in range(9):
            data[slots[k, e]] += scale * flat[9 * k + e]


@njit(cache=True)
def scatter_pairs(data: np.ndarray, slots: np.ndarray, blocks: np.ndarray, scale: float) -> None:
    """The four blocks ``±scale · B`` of every pair (see the module notes) into ``data``."""
    flat = blocks.reshape(-1)
    for k in range(slots.shape[0]):
        for e in range(9):
            value = scale * flat[9 * k + e]
            data[slots[k, e]] += value
            data[slots[k, 9 + e]] += value
            data[slots[k, 18 + e]] -= value
            data[slots[k, 27 + e]] -= value


@njit(cache=True)
def multiply_plain(out: np.ndarray, i: np.ndarray, j: np.ndarray, blocks: np.ndarray, vector: np.ndarray) -> None:
    """``out[3i:3i+3] += B_k vector[3j:3j+3]`` for every block."""
    for k in range(len(i)):
        for a in range(3):
            total = 0.0
            for b in range(3):
                total += blocks[k, a, b] * vector[3 * j[k] + b]
            out[3 * i[k] + a] += total


@njit(cache=True)
def multiply_pairs(out: np.ndarray, first: np.ndarray, second: np.ndarray, blocks: np.ndarray,
                   vector: np.ndarray) -> None:
    """The product of every pair's four blocks with ``vector``: ``B (v_i − v_j)`` at i, its opposite at j."""
    for k in range(len(first)):
        i, j = first[k], second[k]
        for a in range(3):
            total = 0.0
            for b in range(3):
                total += blocks[k, a, b] * (vector[3 * i + b] - vector[3 * j + b])
            out[3 * i + a] += total
            out[3 * j + a] -= total
