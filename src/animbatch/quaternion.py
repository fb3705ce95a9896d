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


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis; for small arrays several times cheaper than ``np.cross``."""
    # (np.broadcast_shapes costs more than the products on a few vectors: only when the shapes differ)
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def normalized(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4); ``q`` need not be exactly unit (it is normalised)."""
    # dividing by |q|² instead of normalising q first gives the same matrix with fewer operations
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    scale = 2.0 / (w * w + x * x + y * y + z * z)
    xx, yy, zz = scale * x * x, scale * y * y, scale * z * z
    xy, xz, yz = scale * x * y, scale * x * z, scale * y * z
    wx, wy, wz = scale * w * x, scale * w * y, scale * w * z
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = 1 - yy - zz, xy - wz, xz + wy
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2] = xy + wz, 1 - xx - zz, yz - wx
    out[..., 2, 0], out[..., 2, 1], out[..., 2, 2] = xz - wy, yz + wx, 1 - xx - yy
    return out


def from_rotation_vector(v: np.ndarray) -> np.ndarray:
    """Quaternion of a rotation by angle |v| [rad] about axis v/|v| (the exponential map), shape (..., 4)."""
    v = np.asarray(v, float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle -> 1/2 as angle -> 0; the series keeps tiny rotations accurate
    scale = np.where(angle > 1e-8, np.sin(half) / np.where(angle > 1e-8, angle, 1.0), 0.5 - angle**2 / 48)
    return np.concatenate([np.cos(half), scale * v], axis=-1)


def rate(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``dq/dt = ½ (0, ω) ⊗ q`` for world angular velocity ω (..., 3)."""
    wx, wy, wz = 0.5 * omega[..., 0], 0.5 * omega[..., 1], 0.5 * omega[..., 2]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape)
    out[..., 0] = -wx * qx - wy * qy - wz * qz
    out[..., 1] = wx * qw + wy * qz - wz * qy
    out[..., 2] = -wx * qz + wy * qw + wz * qx
    out[..., 3] = wx * qy - wy * qx + wz * qw
    return out


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q) v`` for vectors (..., 3)."""
    return np.einsum("...ij,...j->...i", to_matrix(q), v)


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternions [w, x, y, z] (..., 4) of rotation matrices (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(np.reshape(m, (-1, 3, 3))).as_quat()
    return np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1).reshape(*np.shape(m)[:-2], 4)
