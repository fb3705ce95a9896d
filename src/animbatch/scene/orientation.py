"""Orientation specs (quaternion, Euler angles or axis–angle) as rotations: read by the compiler and the renderer."""

from __future__ import annotations

import numpy as np

from animbatch import quaternion
from animbatch.scene.schema import OrientationSpec


def orientation_matrix(spec: OrientationSpec | None) -> np.ndarray:
    """Rotation matrix (3, 3) of an orientation spec (identity when None)."""
    return quaternion.to_matrix(orientation_quaternion(spec))


def orientation_quaternion(spec: OrientationSpec | None) -> np.ndarray:
    """Unit quaternion [w, x, y, z] of an orientation spec (identity when None)."""
    if spec is None:
        return quaternion.IDENTITY.copy()
    if spec.quaternion is not None:
        return quaternion.normalized(np.asarray(spec.quaternion, float))
    if spec.euler is not None:
        from scipy.spatial.transform import Rotation  # kept off the start-up path of validate and --help

        x, y, z, w = Rotation.from_euler("xyz", spec.euler, degrees=True).as_quat()  # scipy: scalar last
        return np.array([w, x, y, z])
    axis = np.asarray(spec.axis, float)
    assert spec.angle is not None  # the schema asks for an angle with an axis
    return quaternion.from_rotation_vector(axis / np.linalg.norm(axis) * np.radians(spec.angle))
