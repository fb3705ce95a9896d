"""The command and the run as a whole: entry points, solver statistics, the run report, progress output."""

from __future__ import annotations

import io
import json
import subprocess
import sys

import numpy as np
import pytest

from animbatch import api
from animbatch.progress import Progress
from support.scenes import run

SPRING = """
    duration: 2
    fps: 10
    anchors: [{name: pin, position: [0, 0, 0]}]
    bodies: [{name: bob, mass: 0.5, position: [0, -1.2, 0]}]
    springs: [{between: [pin, bob], stiffness: 30, damping: 0.2, rest_length: 1.0}]
    fields: [{type: gravity}]
"""


@pytest.mark.slow
def test_python_dash_m_runs_the_command():
    """'python -m animbatch' is the same program as the 'animbatch' console script."""
    result = subprocess.run([sys.executable, "-m", "animbatch", "--version"], capture_output=True, text=True,
                            check=True)
    assert result.stdout.startswith("animbatch, version ")


@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_implicit_methods_use_the_analytic_jacobian_for_particle_models(method):
    """With particles only, Radau and BDF get the analytic sparse Jacobian: no finite-difference evaluations, so our
    count of right-hand sides equals scipy's nfev."""
    _, trajectory = run(SPRING, f"solver.method={method}")
    stats = trajectory.solver_stats
    assert stats["jacobian_evaluations"] >= 1 and stats["lu_decompositions"] >= 1
    assert stats["rhs_evaluations"] == stats["scipy_nfev"]


def test_rhs_count_includes_finite_difference_jacobians_for_rigid_bodies():
    """A rigid body has no analytic Jacobian: Radau estimates one by finite differences, at least one evaluation per
    state component (13 for one body; more when it refines a column), which our count includes and scipy's nfev
    leaves out."""
    _, trajectory = run("""
        duration: 1
        fps: 10
        bodies: [{name: box, type: rigid, shape: {type: box, size: [0.3, 0.2, 0.1]}, density: 500,
                  angular_velocity: [0.1, 3, 0.1]}]
    """, "solver.method=Radau")
    stats = trajectory.solver_stats
    assert stats["jacobian_evaluations"] >= 1
    assert stats["rhs_evaluations"] >= stats["scipy_nfev"] + 13 * stats["jacobian_evaluations"]


@pytest.mark.parametrize("method", ["RK45", "DOP853", "LSODA"])
def test_explicit_methods_count_every_evaluation(method):
    """Without Jacobians, our count equals scipy's nfev."""
    _, trajectory = run(SPRING, f"solver.method={method}")
    assert trajectory.solver_stats["rhs_evaluations"] == trajectory.solver_stats["scipy_nfev"]


@pytest.mark.slow
def test_max_step_limits_adaptive_steps():
    """With max_step, an adaptive method takes at least duration / max_step steps."""
    _, loose = run(SPRING, "solver.method=RK45")
    _, limited = run(SPRING, "solver.method=RK45", "solver.max_step=0.001")
    assert limited.solver_stats["steps"] >= 1900 > loose.solver_stats["steps"]
    assert np.allclose(limited.positions, loose.positions, atol=1e-4)


@pytest.mark.render
def test_run_report_records_stages_solver_and_outputs(tmp_cwd):
    """report.json holds timings per stage, solver settings and work, frame count, size, fps and backend."""
    (tmp_cwd / "spring.yaml").write_text(SPRING + "\n    render: {resolution: [64, 48]}\n")
    report = api.run(tmp_cwd / "spring.yaml", out_dir="renders")
    data = json.loads((tmp_cwd / "renders" / "spring" / "report.json").read_text())
    assert list(data["stages"]) == ["load", "compile", "simulate", "render", "encode"]
    assert all(seconds >= 0 for seconds in data["stages"].values())
    assert data["solver"]["method"] == "RK45" and data["solver_stats"]["steps"] > 0
    assert data["frame_count"] == 20 and data["resolution"] == [64, 48] and data["fps"] == 10
    assert data["backend"] in ("egl", "osmesa") and data["outputs"] == ["renders/spring/spring.mp4"]
    assert len(data["physics_hash"]) == 64 and data["package_version"]
    assert report.summary().startswith("spring: 20 frames 64×48 @ 10 fps -> renders/spring/spring.mp4 | load ")


def test_progress_bar_only_when_enabled():
    """An enabled reporter draws a bar with the frame count; a disabled one writes nothing."""
    stream = io.StringIO()
    with Progress(enabled=True, stream=stream).task("simulate", 5) as on_frame:
        for k in range(5):
            on_frame(k, k / 10)
    assert "/5 [" in stream.getvalue() and "simulate" in stream.getvalue()  # tqdm throttles redraws
    quiet = io.StringIO()
    with Progress(enabled=None, stream=quiet).task("simulate", 5) as on_frame:  # not a terminal
        on_frame(0, 0.0)
    assert quiet.getvalue() == ""


EMITTER_ON_A_BODY = """
    duration: 0.5
    fps: 10
    solver: {method: verlet, dt: 0.01}
    bodies: [{name: cart, type: rigid, shape: {type: box, size: [0.2, 0.1, 0.1]}, mass: 1, velocity: [1, 0, 0]}]
    emitters:
      - {name: exhaust, body: cart, rate: 40, lifetime: 1, speed: 0.5, radius: 0.01, mass: 1.0e-4}
    fields: [{type: gravity}]
    render: {resolution: [64, 48]}
"""


def test_a_render_compiles_its_scene_once(tmp_cwd, monkeypatch):
    """A run is plan -> simulate -> draw -> encode: the scene's Model is built once and its emitters compiled once,
    for the cost estimate, the simulation and the drawing alike (a drawing that compiled again would count 2)."""
    from animbatch.compile.particles import ParticleSystems
    from animbatch.sim.model.builder import ModelBuilder

    counts = {"models": 0, "particle systems": 0}
    finalize, systems = ModelBuilder.finalize, ParticleSystems.__init__

    def counted_finalize(self, *args, **kwargs):
        counts["models"] += 1
        return finalize(self, *args, **kwargs)

    def counted_systems(self, *args, **kwargs):
        counts["particle systems"] += 1
        systems(self, *args, **kwargs)

    monkeypatch.setattr(ModelBuilder, "finalize", counted_finalize)
    monkeypatch.setattr(ParticleSystems, "__init__", counted_systems)
    (tmp_cwd / "cart.yaml").write_text(EMITTER_ON_A_BODY)
    report = api.run(tmp_cwd / "cart.yaml", out_dir="renders")
    assert report.frame_count == 5 and report.particle_stats["born"] > 0
    assert counts == {"models": 1, "particle systems": 1}
    counts.update({"models": 0, "particle systems": 0})
    api.run(tmp_cwd / "cart.yaml", out_dir="renders")  # from the cache: compiled once still, for the drawing
    assert counts == {"models": 1, "particle systems": 1}
