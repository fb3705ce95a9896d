"""Fixtures the whole suite shares (a temporary working folder, a Dask cluster, a browser, a PolyData counter).
Helper functions live in the ``support`` package (tests/support/), which test modules import."""

from __future__ import annotations

import shutil

import pytest


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
