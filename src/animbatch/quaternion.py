"""Unit quaternions for orientation, vectorised over bodies.

Convention: ``q = [w, x, y, z]`` (scalar first), unit length, rotating body coordinates into world coordinates:
``p_world = R(q) p_body + x``. With world-frame angular velocity ω, ``dq/dt = ½ (0, ω) ⊗ q``.

All functions take arrays of shape (..., 4) / (..., 3) and work on the last axis.
"""

from __future__ import annotations

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q``, shape (..., 4)."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(p.shape if p.shape == q.shape else np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


#: Components 1, 2, 0 and 2, 0, 1 of a vector: ``a × b = a[NEXT] b[AFTER] − a[AFTER] b[NEXT]``.
_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])
#: Up to this many numbers in each operand, the cross product gathers the components (four gathers, three
#: operations: half the time of the nine strided ones below on a few vectors, the resting-contact right-hand side's
#: case); beyond, the gathers' copies cost more (6.5 ms against 1 ms at 1e5 vectors).
_GATHERED = 192


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis; for small arrays several times cheaper than ``np.cross``."""
    if a.size <= _GATHERED and b.size <= _GATHERED and a.dtype == b.dtype == np.float64:
        return a.take(_NEXT, axis=-1) * b.take(_AFTER, axis=-1) - a.take(_AFTER, axis=-1) * b.take(_NEXT, axis=-1)
    # (np.broadcast_shapes costs more than the products on a few vectors: only when the shapes differ)
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def normalized(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _products_to_matrix() -> np.ndarray:
    """The constant (16, 9) map from a quaternion's products ``q_a q_b`` (flattened 4 × 4) to ``R(q) − I`` times
    ``|q|² / 2``: each entry of R is 1 or 0 plus two of those products (``1 − 2 (y² + z²)``, ``2 (xy − wz)``, …)."""
    w, x, y, z = range(4)
    entries = {(0, 0): ((y, y, -1), (z, z, -1)), (0, 1): ((x, y, 1), (w, z, -1)), (0, 2): ((x, z, 1), (w, y, 1)),
               (1, 0): ((x, y, 1), (w, z, 1)), (1, 1): ((x, x, -1), (z, z, -1)), (1, 2): ((y, z, 1), (w, x, -1)),
               (2, 0): ((x, z, 1), (w, y, -1)), (2, 1): ((y, z, 1), (w, x, 1)), (2, 2): ((x, x, -1), (y, y, -1))}
    table = np.zeros((16, 9))
    for (row, column), terms in entries.items():
        for a, b, sign in terms:
            table[4 * a + b, 3 * row + column] = sign
    return table


_PRODUCTS_TO_MATRIX = _products_to_matrix()
_IDENTITY_MATRIX = np.eye(3).ravel()


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4); ``q`` need not be exactly unit (it is normalised).

    One product with a constant table (:func:`_products_to_matrix`) instead of thirty operations on the components:
    for the few bodies of a small scene those cost a microsecond each, and this runs at every right-hand side."""
    # dividing by |q|² instead of normalising q first gives the same matrix with fewer operations
    scale = 2.0 / np.einsum("...i,...i->...", q, q)
    products = (q[..., :, None] * q[..., None, :]).reshape(*q.shape[:-1], 16)
    return (_IDENTITY_MATRIX + (products @ _PRODUCTS_TO_MATRIX) * scale[..., None]).reshape(*q.shape[:-1], 3, 3)


def from_rotation_vector(v: np.ndarray) -> np.ndarray:
    """Quaternion of a rotation by angle |v| [rad] about axis v/|v| (the exponential map), shape (..., 4)."""
    v = np.asarray(v, float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle -> 1/2 as angle -> 0; the series keeps tiny rotations accurate
    scale = np.where(angle > 1e-8, np.sin(half) / np.where(angle > 1e-8, angle, 1.0), 0.5 - angle**2 / 48)
    return np.concatenate([np.cos(half), scale * v], axis=-1)


def _rate_table() -> np.ndarray:
    """The constant (3, 16) map from ω to the 4 × 4 matrix Ω(ω) (flattened) with ``(0, ω) ⊗ q = Ω(ω) q``."""
    table = np.zeros((3, 4, 4))
    for j, rows in enumerate((((0, 1, -1), (1, 0, 1), (2, 3, -1), (3, 2, 1)),   # ωx
                              ((0, 2, -1), (1, 3, 1), (2, 0, 1), (3, 1, -1)),   # ωy
                              ((0, 3, -1), (1, 2, -1), (2, 1, 1), (3, 0, 1)))):  # ωz
        for i, k, sign in rows:
            table[j, i, k] = sign
    return table.reshape(3, 16)


_RATE_TABLE = _rate_table()


def rate(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``dq/dt = ½ (0, ω) ⊗ q`` for world angular velocity ω (..., 3): ``½ Ω(ω) q`` (:func:`_rate_table`), two
    products whatever the number of bodies."""
    turning = (omega @ _RATE_TABLE).reshape(*np.shape(omega)[:-1], 4, 4)
    return 0.5 * (turning @ q[..., None])[..., 0]


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q) v`` for vectors (..., 3)."""
    return np.einsum("...ij,...j->...i", to_matrix(q), v)


def _shepperd_table() -> np.ndarray:
    """(11, 16): the four candidate quaternions [x, y, z, w] of Shepperd's method, each entry a linear combination of
    a matrix's nine entries (row by row), its trace and 1."""
    def entry(i: int, j: int) -> int:
        return 3 * i + j

    trace, one = 9, 10
    table = np.zeros((4, 4, 11))
    for i in range(3):  # candidate i: from the diagonal entry m_ii
        j, k = (i + 1) % 3, (i + 2) % 3
        table[i, i, [entry(i, i), trace, one]] = [2.0, -1.0, 1.0]  # 1 − trace + 2 m_ii
        table[i, j, [entry(j, i), entry(i, j)]] = 1.0
        table[i, k, [entry(k, i), entry(i, k)]] = 1.0
        table[i, 3, [entry(k, j), entry(j, k)]] = [1.0, -1.0]
        table[3, i, [entry(k, j), entry(j, k)]] = [1.0, -1.0]  # candidate 3 (from the trace): the axis part
    table[3, 3, [trace, one]] = 1.0  # 1 + trace
    return table.reshape(16, 11).T.copy()


_SHEPPERD = _shepperd_table()


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternions [w, x, y, z] (..., 4) of rotation matrices (..., 3, 3), by Shepperd's method: each from
    the largest of the trace and the diagonal, so that no division is by a small number (SciPy's
    ``Rotation.from_matrix`` on rotations, same signs, in one product instead of its per-call checks: a keyframed
    body asks for one every step)."""
    m = np.asarray(m, float)
    entries = m.reshape(*m.shape[:-2], 9)
    trace = entries[..., 0] + entries[..., 4] + entries[..., 8]
    extended = np.concatenate([entries, trace[..., None], np.ones((*trace.shape, 1))], axis=-1)
    candidates = (extended @ _SHEPPERD).reshape(*trace.shape, 4, 4)
    choice = np.argmax(np.stack([entries[..., 0], entries[..., 4], entries[..., 8], trace], axis=-1), axis=-1)
    xyzw = np.take_along_axis(candidates, choice[..., None, None], axis=-2)[..., 0, :]
    xyzw = xyzw / np.linalg.norm(xyzw, axis=-1, keepdims=True)
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)
