"""BLAS runs on one thread while a small system is integrated (its calls are too small to split, and under load the
threads only wait for each other, see animbatch.sim.blas), keeps its own setting for a large one, and gets it back
after the run."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from animbatch.compile.integrator import make_integrator
from animbatch.compile.model import compile_scene
from animbatch.sim import blas
from animbatch.sim.model.dynamics import Dynamics
from support.scenes import scene

SPRING = """\
duration: 0.2
fps: 10
solver: {method: %s}
anchors:
  - {name: a, position: [0, 0, 0]}
bodies:
  - {name: b, mass: 0.5, position: [1.2, 0, 0]}
springs:
  - {between: [a, b], stiffness: 20, rest_length: 1.0}
"""


def _blas_threads() -> set[int]:
    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


@pytest.mark.parametrize("method", ["verlet", "RK45"])
@pytest.mark.parametrize("small", [True, False])
def test_a_small_system_integrates_with_blas_on_one_thread_and_gives_the_setting_back(method, small, monkeypatch):
    loaded = scene(SPRING % method)
    model = compile_scene(loaded.spec)
    if not small:  # the same system counted as large
        monkeypatch.setattr(blas, "SMALL_STATE", len(model.y0) - 1)
    seen: dict[int, set[int]] = {}
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        result = make_integrator(loaded.spec.solver, model).integrate(
            Dynamics(model), model.y0, model.frame_times, on_frame=lambda frame, t: seen.__setitem__(frame, _blas_threads()))
        after = _blas_threads()
    assert before == after == {2}
    # every frame the run computed (the first is the start, given)
    assert sorted(seen)[1:] == list(range(1, len(model.frame_times)))
    assert all(seen[frame] == ({1} if small else {2}) for frame in range(1, len(model.frame_times)))
    # and the run is the spring's: the bob oscillates about the rest length at ω = √(k/m)
    omega = np.sqrt(20 / 0.5)
    x = 1.0 + 0.2 * np.cos(omega * model.frame_times)
    np.testing.assert_allclose(result.states[:, 0], x, atol=2e-3)
