"""Shared helpers: build scenes from YAML text and simulate them without touching the file system."""

from __future__ import annotations

import shutil
import textwrap

import numpy as np
import pytest

from animbatch import api
from animbatch.compile.model import compile_scene
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
    loaded = scene(text, *overrides)
    model = compile_scene(loaded.spec)
    return model, api.simulate(loaded, model=model)


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


@pytest.fixture(scope="session")
def dask_scheduler():
    """The address of one LocalCluster of two single-threaded worker processes, for the Dask batches of a test
    process to share through ``batch --scheduler``: starting a cluster and warming its workers (their imports, their
    first OpenGL context) costs more than the small batches under test. Tests that use it are marked
    ``xdist_group("dask")`` so that one test process runs them all."""
    import logging

    distributed = pytest.importorskip("distributed")
    from animbatch.farm.batch import WORKER_ENV

    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, env=WORKER_ENV,
                                       dashboard_address=None, silence_logs=logging.CRITICAL)
    yield cluster.scheduler_address
    cluster.close()


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: As root in a container Chromium needs --no-sandbox; the rest keep it from reaching for the network at start.
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]


@pytest.fixture(scope="module")
def browser():
    """Debian's Chromium, headless, driven by Playwright, for the tests of the pages we write."""
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed: 'bash scripts/dev.sh test' installs it as root "
                    "(apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed: bash scripts/dev.sh "
                                                                 "setup installs it")
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def tmp_cwd(tmp_path, monkeypatch):
    """Run in an empty temporary folder (so relative outputs like renders/ land there)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def counting(monkeypatch, module, name: str) -> list[int]:
    """Patch ``module.name`` to count its calls (and still do its work): a list that grows by one a call."""
    calls: list[int] = []
    original = getattr(module, name)
    monkeypatch.setattr(module, name, lambda *a, **k: calls.append(1) or original(*a, **k))
    return calls


@pytest.fixture
def polydata_built(monkeypatch) -> list[int]:
    """A list that grows by one for every pyvista.PolyData built (to check that frames update meshes in place)."""
    import pyvista as pv

    built: list[int] = []
    original = pv.PolyData

    class CountingPolyData(original):  # type: ignore[misc, valid-type]
        def __init__(self, *args, **kwargs):
            built.append(1)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(pv, "PolyData", CountingPolyData)
    return built


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
