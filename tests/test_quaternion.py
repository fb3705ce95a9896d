"""Quaternion helpers against their definitions: the rotation matrix against Rodrigues' formula, the rate against
the derivative of a rotation at constant angular velocity, over single quaternions and stacks of them."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import quaternion


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """R = I + sin θ K + (1 − cos θ) K² for the unit axis's cross-product matrix K."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


@pytest.mark.parametrize("shape", [(), (1,), (7,), (3, 5)])
def test_the_matrix_of_a_quaternion_is_rodrigues_rotation_by_its_angle_about_its_axis(shape):
    rng = np.random.default_rng(len(shape))
    axes = rng.normal(size=(*shape, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = rng.uniform(-np.pi, np.pi, shape)
    q = np.concatenate([np.cos(angles / 2)[..., None], np.sin(angles / 2)[..., None] * axes], axis=-1)
    scaled = q * rng.uniform(0.5, 2.0, (*shape, 1))  # not unit: the matrix is the same rotation
    matrices = quaternion.to_matrix(scaled)
    assert matrices.shape == (*shape, 3, 3)
    for index in np.ndindex(shape):
        np.testing.assert_allclose(matrices[index], rodrigues(axes[index], angles[index]), atol=1e-14)


def test_the_rate_is_the_derivative_of_a_turn_at_constant_angular_velocity():
    """q(t) = exp(ω t / 2) ⊗ q₀ turns at the world angular velocity ω: its derivative at t = 0 (central difference)
    is ``rate(q₀, ω)``, for each of a stack of bodies and for one body alone."""
    rng = np.random.default_rng(3)
    start = rng.normal(size=(6, 4))
    start /= np.linalg.norm(start, axis=-1, keepdims=True)
    omega = rng.normal(size=(6, 3)) * 3

    def turned(t: float) -> np.ndarray:
        return quaternion.multiply(quaternion.from_rotation_vector(omega * t), start)

    h = 1e-5
    difference = (turned(h) - turned(-h)) / (2 * h)
    np.testing.assert_allclose(quaternion.rate(start, omega), difference, atol=1e-9)
    np.testing.assert_allclose(quaternion.rate(start[2], omega[2]), difference[2], atol=1e-9)


def test_from_matrix_gives_the_quaternion_of_every_rotation_even_half_turns():
    """Rotation matrices of random turns, half turns about each axis and near them, and the identity: the quaternion
    found turns vectors as the matrix does, has unit length, and (being Shepperd's method, as SciPy's) has SciPy's
    sign; arrays of any leading shape keep it."""
    from scipy.spatial.transform import Rotation

    vectors = np.concatenate([Rotation.random(500, random_state=7).as_rotvec(),
                              np.pi * np.eye(3), (np.pi - 1e-9) * np.eye(3), -np.pi * np.eye(3),
                              [[1e-12, 0, 0], [0, 0, 0]]])
    turns = Rotation.from_rotvec(vectors)
    matrices = turns.as_matrix()
    found = quaternion.from_matrix(matrices)
    np.testing.assert_allclose(np.linalg.norm(found, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(quaternion.to_matrix(found), matrices, atol=1e-14)
    xyzw = Rotation.from_matrix(matrices).as_quat()
    np.testing.assert_allclose(found, np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1), atol=1e-15)
    assert quaternion.from_matrix(matrices[0]).shape == (4,)
    np.testing.assert_array_equal(quaternion.from_matrix(matrices[:6].reshape(3, 2, 3, 3)), found[:6].reshape(3, 2, 4))


@pytest.mark.parametrize("shape_a, shape_b", [((3,), (3,)), ((4, 3), (4, 3)), ((3,), (5, 3)), ((5, 7, 3), (7, 3)),
                                              ((64, 3), (64, 3)), ((65, 3), (65, 3)), ((1000, 3), (3,))])
def test_cross_is_the_cross_product_for_a_few_vectors_and_for_many(shape_a, shape_b):
    """Gathered components for a few vectors, strided ones for many: the same products either way (numpy's cross
    to round-off, and the right-handed basis exactly), broadcast like numpy, float64 even from integers."""
    rng = np.random.default_rng(len(shape_a) + shape_a[0])
    a, b = rng.normal(size=shape_a), rng.normal(size=shape_b)
    found = quaternion.cross(a, b)
    assert found.shape == np.broadcast_shapes(shape_a, shape_b)
    np.testing.assert_allclose(found, np.cross(a, b), rtol=0, atol=1e-15)
    x, y, z = np.eye(3)
    np.testing.assert_array_equal(quaternion.cross(np.stack([x, y, z]), np.stack([y, z, x])), np.stack([z, x, y]))
    whole = quaternion.cross(np.array([1, 0, 0]), np.array([0, 1, 0]))
    assert whole.dtype == np.float64 and whole.tolist() == [0.0, 0.0, 1.0]
