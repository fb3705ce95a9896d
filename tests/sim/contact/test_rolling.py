"""A cylinder on an incline (issue 22, contact between any shapes): it touches the plane on its exact rim, so it
rolls as a circle: at 2/3 g sin θ without slipping when friction allows (μs ≥ tan θ / 3), and slides at
g (sin θ − μk cos θ) when it does not. Rolling, under a fixed-step method, which finds the rim contact each step,
and under RK45, whose events follow each end's rim (issue 41; before, RK45 rolled it on its 16 rim probes, a
polygon, 22 % slower)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from animbatch import api
from animbatch.compile.model import compile_scene
from animbatch.sim.contact.detection import rim_index, rim_pairs
from animbatch.sim.model.dynamics import Dynamics
from support.scenes import scene

G = 9.81
SLOPE = np.radians(20)
RADIUS = 0.1


def log_on_incline(friction: float, method: str) -> tuple:
    normal = [float(-np.sin(SLOPE)), float(np.cos(SLOPE)), 0.0]
    solver = "{method: RK45}" if method == "RK45" else f"{{method: {method}, dt: 5.0e-4}}"
    loaded = scene(f"""
        duration: 1.0
        fps: 50
        solver: {solver}
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
@pytest.mark.parametrize("method", ["symplectic_euler", "RK45"])
def test_a_solid_cylinder_rolls_down_an_incline_at_two_thirds_g_sin_theta(method):
    trajectory, travel, normal = log_on_incline(1.0, method)
    t = trajectory.times
    np.testing.assert_allclose(travel, (2 / 3) * G * np.sin(SLOPE) * t**2 / 2, rtol=2e-3, atol=1e-4)
    speed = np.gradient(travel, t)
    spin = np.abs(trajectory.angular_velocities[:, 0, 2])
    np.testing.assert_allclose(spin[5:], speed[5:] / RADIUS, rtol=1.5e-2)  # rolling: v = ω r (a little creep)
    height = trajectory.positions[:, 0] @ normal
    np.testing.assert_allclose(height, RADIUS, atol=2e-4)  # a circle, not a polygon of rim probes


@pytest.mark.slow
def test_on_a_slippery_incline_it_slides_at_g_sin_theta_minus_mu_cos_theta():
    mu = 0.05  # below tan θ / 3 = 0.12: it cannot roll without slipping (under RK45 too: 4.6 s more of the suite)
    trajectory, travel, _ = log_on_incline(mu, "symplectic_euler")
    t = trajectory.times
    expected = G * (np.sin(SLOPE) - mu * np.cos(SLOPE)) * t**2 / 2
    np.testing.assert_allclose(travel, expected, rtol=5e-3, atol=1e-4)
    assert np.abs(trajectory.angular_velocities[-1, 0, 2]) * RADIUS < 0.9 * np.gradient(travel, t)[-1]  # slipping


def test_each_end_s_rim_is_followed_at_its_closed_form_height():
    """A cylinder (radius r, half length h, its axis body z) tilted β up, its centre c over the floor: the rim of its raised
    end is c + h sin β − r cos β over the floor, the other's c − h sin β − r cos β, and the plain name follows the
    lower; lying flat, both ends' rims touch, a line."""
    r, h, c = 0.1, 0.15, 0.2
    for beta in (30.0, 0.0):
        model = compile_scene(scene(f"""
            bodies:
              - {{name: log, type: rigid, shape: {{type: cylinder, radius: {r}, length: {2 * h}}}, density: 500,
                 position: [0, {c}, 0], orientation: {{axis: [1, 0, 0], angle: {-beta}}}}}
            colliders: [{{type: plane}}]
        """).spec, Path("."))
        system, world = Dynamics(model), model.contact_world
        state = system.kinematics(*system.split(model.y0), t=0.0, copy=True)
        rim = np.full(3, world.probes.count + 12 * world.boxes.count)  # the one cylinder's rim number
        plane = np.zeros(3, np.intp)
        index = np.array([0, rim_index(world, plane[:1], 0)[0], rim_index(world, plane[:1], 1)[0]])
        gaps = rim_pairs(world, state, rim, index).gap
        tilt = np.radians(beta)
        lower, raised = c - h * np.sin(tilt) - r * np.cos(tilt), c + h * np.sin(tilt) - r * np.cos(tilt)
        np.testing.assert_allclose(gaps, [lower, lower, raised], atol=1e-12)  # its axis, body z, turned up
