"""A cylinder on an incline (issue 22, contact between any shapes): it touches the plane on its exact rim, so it
rolls as a circle: at 2/3 g sin θ without slipping when friction allows (μs ≥ tan θ / 3), and slides at
g (sin θ − μk cos θ) when it does not."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch import api
from support.scenes import scene

G = 9.81
SLOPE = np.radians(20)
RADIUS = 0.1


def log_on_incline(friction: float) -> tuple:
    normal = [float(-np.sin(SLOPE)), float(np.cos(SLOPE)), 0.0]
    loaded = scene(f"""
        duration: 1.0
        fps: 50
        solver: {{method: symplectic_euler, dt: 5.0e-4}}
        materials:
          grip: {{restitution: 0, static_friction: {friction}, kinetic_friction: {friction}}}
        bodies:
          - {{name: log, type: rigid, shape: {{type: cylinder, radius: {RADIUS}, length: 0.3}}, density: 500,
             material: grip, position: {[RADIUS * c for c in normal]}}}
        colliders: [{{type: plane, normal: {normal}, material: grip}}]
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    down = np.array([-np.cos(SLOPE), -np.sin(SLOPE), 0.0])
    travel = (trajectory.positions[:, 0] - trajectory.positions[0, 0]) @ down
    return trajectory, travel, np.array(normal)


@pytest.mark.slow
def test_a_solid_cylinder_rolls_down_an_incline_at_two_thirds_g_sin_theta():
    trajectory, travel, normal = log_on_incline(1.0)
    t = trajectory.times
    np.testing.assert_allclose(travel, (2 / 3) * G * np.sin(SLOPE) * t**2 / 2, rtol=2e-3, atol=1e-4)
    speed = np.gradient(travel, t)
    spin = np.abs(trajectory.angular_velocities[:, 0, 2])
    np.testing.assert_allclose(spin[5:], speed[5:] / RADIUS, rtol=1.5e-2)  # rolling: v = ω r (a little creep)
    height = trajectory.positions[:, 0] @ normal
    np.testing.assert_allclose(height, RADIUS, atol=2e-4)  # a circle, not a polygon of rim probes


@pytest.mark.slow
def test_on_a_slippery_incline_it_slides_at_g_sin_theta_minus_mu_cos_theta():
    mu = 0.05  # below tan θ / 3 = 0.12: it cannot roll without slipping
    trajectory, travel, _ = log_on_incline(mu)
    t = trajectory.times
    expected = G * (np.sin(SLOPE) - mu * np.cos(SLOPE)) * t**2 / 2
    np.testing.assert_allclose(travel, expected, rtol=5e-3, atol=1e-4)
    assert np.abs(trajectory.angular_velocities[-1, 0, 2]) * RADIUS < 0.9 * np.gradient(travel, t)[-1]  # slipping
