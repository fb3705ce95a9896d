"""Helpers the test modules share: scenes from YAML text simulated without touching the file system, the method
lists, call counters, and the contacts of a box on a surface."""

from __future__ import annotations

import textwrap

import numpy as np

from animbatch import api
from animbatch.scene import LoadedScene
from animbatch.sim.contact.contacts import PLANE, STATIC, Contacts
from animbatch.sim.model import Model
from animbatch.stages import parse_scene
from animbatch.trajectory import Trajectory


def scene(text: str, *overrides: str) -> LoadedScene:
    """A validated scene from (indented) YAML text."""
    return parse_scene(textwrap.dedent(text), filename="test.yaml", overrides=list(overrides))


def run(text: str, *overrides: str) -> tuple[Model, Trajectory]:
    """Compile and simulate a scene given as YAML text."""
    plan = api.plan(scene(text, *overrides))
    return plan.model, api.simulate(plan)


def states(model: Model, trajectory: Trajectory) -> np.ndarray:
    """The flat states (F, n) behind a trajectory's per-body arrays."""
    return model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                             trajectory.angular_velocities)


def body(trajectory: Trajectory, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of one body over all frames, each (F, 3)."""
    index = trajectory.body_names.index(name)
    return trajectory.positions[:, index], trajectory.velocities[:, index]


ADAPTIVE = ["RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA"]
FIXED_STEP = ["euler", "midpoint", "symplectic_euler", "verlet", "backward_euler"]


def counting(monkeypatch, module, name: str) -> list[int]:
    """Patch ``module.name`` to count its calls (and still do its work): a list that grows by one a call."""
    calls: list[int] = []
    original = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **k: calls.append(1) or original(*a, **k))
    return calls


def assert_velocity_is_the_paths_derivative(path, times, step: float = 1e-5, atol: float = 1e-5) -> None:
    """A kinematic path's velocity and angular velocity are the central differences of its poses at ``times``."""
    for t in times:
        (ahead, turn_ahead), (behind, turn_behind) = path.pose(t + step), path.pose(t - step)
        velocity, omega = path.velocity(t)
        np.testing.assert_allclose(velocity, (ahead - behind) / (2 * step), atol=atol)
        spin = (turn_ahead - turn_behind) / (2 * step) @ path.pose(t)[1].T  # Ṙ Rᵀ = [ω]×
        np.testing.assert_allclose(omega, [spin[2, 1], spin[0, 2], spin[1, 0]], atol=atol)


# Contacts of a box on a surface (the resting-force and impulse solvers' tests)


def box_inverse_inertia(mass: float, size: tuple[float, float, float]) -> np.ndarray:
    x, y, z = size
    return np.diag(12.0 / (mass * np.array([y * y + z * z, x * x + z * z, x * x + y * y])))


def corners_on_floor(body: int, centre: np.ndarray, size: tuple[float, float, float], mu: float,
                     solid_body: int = STATIC, normal: np.ndarray | None = None) -> Contacts:
    """The four bottom corners of a box (``size`` [m], centre ``centre``) touching a surface below them."""
    half = np.array(size) / 2
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]])
    points = np.stack([centre[0] + signs[:, 0] * half[0], np.full(4, centre[1] - half[1]),
                       centre[2] + signs[:, 1] * half[2]], axis=1)
    k = len(points)
    return Contacts(np.full(k, body), np.full(k, solid_body), points,
                    np.tile([0.0, 1.0, 0.0] if normal is None else normal, (k, 1)), np.zeros(k), np.zeros(k),
                    np.full(k, mu), np.full(k, mu), np.arange(k), np.full(k, PLANE), np.zeros(k, np.intp))
