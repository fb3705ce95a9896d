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
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def normalized(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4); ``q`` need not be exactly unit (it is normalised)."""
    w, x, y, z = np.moveaxis(normalized(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


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
    pure = np.concatenate([np.zeros((*omega.shape[:-1], 1)), omega], axis=-1)
    return 0.5 * multiply(pure, q)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R(q) v`` for vectors (..., 3)."""
    return np.einsum("...ij,...j->...i", to_matrix(q), v)
