"""A diverging or failing simulation stops before any frame is written, naming the time, body and fix."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.errors import SimulationError
from animbatch.integrators import ScipyIntegrator
from animbatch.model import ModelBuilder, Dynamics
from conftest import run

# ω = sqrt(k/m) = 1e4 rad/s, so explicit Euler at h = 1e-3 (ω h = 10) multiplies the energy by ~100 per step.
STIFF = """
    name: stiff
    duration: 2
    fps: 10
    solver: {method: euler, dt: 1.0e-3}
    anchors: [{name: pin, position: [0, 0, 0]}]
    bodies: [{name: calm, position: [5, 5, 5]}, {name: wobbly, mass: 0.01, position: [1.1, 0, 0]}]
    springs: [{between: [pin, wobbly], stiffness: 1.0e6, rest_length: 1.0}]
"""


def test_fixed_step_divergence_names_time_step_body_and_fix():
    """The error gives the exact step where the state became non-finite, the body, dt and what to change."""
    with pytest.raises(SimulationError) as caught:
        run(STIFF)
    error = caught.value
    assert error.body == "wobbly"
    message = str(error)
    assert "the simulation diverged at t = " in message and "body 'wobbly'" in message
    assert "euler is unstable at dt = 0.001 s" in message and "reduce solver.dt (try 0.0001)" in message
    # |growth| per step is |1 + i ω h| = sqrt(101), so doubles overflow (1e308) after about 300 steps
    assert 0.1 < error.time < 0.5
    step = int(message.split("(step ")[1].split(")")[0])
    assert error.time == pytest.approx(step * 1e-3)


def test_divergence_writes_no_frames(tmp_cwd):
    """'animbatch render' on a diverging scene exits 3 and leaves no video, frame or report behind."""
    (tmp_cwd / "stiff.yaml").write_text(STIFF)
    result = CliRunner().invoke(cli, ["render", "stiff.yaml", "--formats", "mp4,png"])
    assert result.exit_code == 3
    assert result.output.startswith("error: the simulation diverged at t = ") and "Traceback" not in result.output
    assert not (tmp_cwd / "renders").exists()


def two_particles(second: str):
    """A model of two free particles ('steady' and ``second``), 1 s at 10 fps, for sabotaged right-hand sides."""
    builder = ModelBuilder()
    builder.add_particle("steady")
    builder.add_particle(second, position=(1, 0, 0), velocity=(1, 0, 0))
    return builder.finalize(duration=1.0, fps=10)


def test_adaptive_method_stops_at_non_finite_forces_and_names_the_body():
    """Non-finite forces make an adaptive method reject every step; the run stops there, naming time and body."""
    model = two_particles("runaway")

    class Exploding(Dynamics):
        def rhs(self, t, y):
            dydt = super().rhs(t, y)
            if t > 0.35:
                dydt[9] = np.inf  # the acceleration (rate of velocity x) of body 1 blows up
            return dydt

    with pytest.raises(SimulationError) as caught:
        ScipyIntegrator("RK45").integrate(Exploding(model), model.y0, model.frame_times)
    assert caught.value.body == "runaway"
    assert caught.value.time == pytest.approx(0.35, abs=1e-6)
    assert "RK45 failed at t = 0.35 s: the rate of change of body 'runaway' velocity x became non-finite" in str(
        caught.value)


def test_solver_failure_names_the_fastest_body():
    """When scipy gives up (step size too small), the error names the time and the fastest-changing body."""
    model = two_particles("singular")

    class Singular(Dynamics):
        def rhs(self, t, y):
            dydt = super().rhs(t, y)
            dydt[4] = 1.0 / (0.5 - t) ** 2  # finite-time blow-up at t = 0.5 for body 1
            return dydt

    with pytest.raises(SimulationError) as caught:
        ScipyIntegrator("RK45", rtol=1e-8).integrate(Singular(model), model.y0, model.frame_times)
    assert "singular" in str(caught.value)
    assert caught.value.time == pytest.approx(0.5, abs=0.01)
