"""A diverging or failing simulation stops before any frame is written, naming the time, body and fix."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.errors import SimulationError
from animbatch.sim.integrators import FixedStepIntegrator, ScipyIntegrator
from animbatch.sim.model import Dynamics, ModelBuilder
from support.scenes import run

# ω = sqrt(k/m) = 1e4 rad/s, so explicit Euler at h = 1e-3 (ω h = 10) multiplies the amplitude by ~10 per step.
STIFF = """
    name: stiff
    duration: 2
    fps: 10
    solver: {method: euler, dt: 1.0e-3}
    anchors: [{name: pin, position: [0, 0, 0]}]
    bodies: [{name: calm, position: [5, 5, 5]}, {name: wobbly, mass: 0.01, position: [1.1, 0, 0]}]
    springs: [{name: piano-wire, between: [pin, wobbly], stiffness: 1.0e6, rest_length: 1.0}]
"""


def test_a_step_that_cannot_hold_the_springs_is_refused_before_the_run_naming_the_stiffest_spring():
    """The pre-flight check predicts the blow-up (amplification sqrt(1 + (ω h)²) ≈ 10 per step), names the spring,
    its ks and ω, and gives a step that works for a stable method, before anything is simulated."""
    with pytest.raises(SimulationError) as caught:
        run(STIFF)
    message = str(caught.value)
    assert "euler at dt = 0.001 s cannot hold this scene's springs" in message
    assert "the stiffest spring 'piano-wire' (ks = 1e+06 N/m, between 0.01 kg and an anchor)" in message
    assert "vibrates at ω = 1e+04 rad/s" in message and "multiplies that vibration by 10.05 per step" in message
    assert "backward_euler (stable at any dt)" in message and "symplectic_euler: dt ≤ 0.00018 s" in message
    assert caught.value.body == "wobbly" and caught.value.details["spring"] == "piano-wire"


def test_the_pre_flight_limit_is_the_real_stability_limit():
    """Symplectic Euler just under the limit it names runs and stays bounded (its ellipse stretches to
    0.1 / sqrt(1 - (ω h / 2)²) = 0.32 m at ω h = 1.9, and no further); a step 5 % over it is refused (the exact
    limit for an undamped spring is ω h = 2)."""
    _, trajectory = run(STIFF, "solver.method=symplectic_euler", "solver.dt=1.9e-4", "duration=0.5")
    assert np.abs(trajectory.positions[:, 1, 0] - 1.0).max() < 0.1 / np.sqrt(1 - 0.95**2) + 1e-6
    with pytest.raises(SimulationError, match="symplectic_euler at dt = 0.00021 s cannot hold"):
        run(STIFF, "solver.method=symplectic_euler", "solver.dt=2.1e-4", "duration=0.5")


def test_fixed_step_divergence_names_time_step_body_and_fix():
    """When the state becomes non-finite during a fixed-step run (here forces sabotaged from t = 0.2345 s), the
    error gives the exact step, the body, dt and what to change."""
    model = two_particles("runaway")

    class Exploding(Dynamics):
        def motion_rate(self, t, config, motion, out=None):
            rate = super().motion_rate(t, config, motion, out)
            if t > 0.2345:
                rate[4] = np.inf  # body 1, velocity y
            return rate

    with pytest.raises(SimulationError) as caught:
        FixedStepIntegrator("symplectic_euler", dt=1e-3).integrate(Exploding(model), model.y0, model.frame_times)
    error = caught.value
    assert error.body == "runaway"
    message = str(error)
    assert "the simulation diverged at t = 0.236 s (step 236)" in message and "body 'runaway'" in message
    assert "symplectic_euler is unstable at dt = 0.001 s" in message and "reduce solver.dt (try 0.0001)" in message


def test_refused_run_writes_no_frames(tmp_cwd):
    """'animbatch render' on a scene whose step cannot hold its springs exits 3 and leaves no video or frame
    behind: only a report that says why, with the same message."""
    (tmp_cwd / "stiff.yaml").write_text(STIFF)
    result = CliRunner().invoke(cli, ["render", "stiff.yaml", "--formats", "mp4,png"])
    assert result.exit_code == 3
    assert result.output.startswith("error: euler at dt = 0.001 s cannot hold") and "Traceback" not in result.output
    written = sorted(p.relative_to(tmp_cwd).as_posix() for p in (tmp_cwd / "renders").rglob("*") if p.is_file())
    assert written == ["renders/stiff/report.json"]
    report = json.loads((tmp_cwd / "renders/stiff/report.json").read_text())
    assert report["status"] == "failed" and report["exit_code"] == 3 and report["outputs"] == []
    assert report["error"] == result.output.removeprefix("error: ").strip()


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


# ------------------------------------------------------------------------------------------------ advice that fits

# Two bodies released from rest 1 m apart under their mutual gravitation (G = 1, M = 4 kg) fall straight into each
# other: r(t) reaches 0 at the free-fall time t_ff = (π/2) sqrt(r₀³ / (2 G M)) = 0.5554 s, where 1/r² diverges.
PLUNGE = """
    duration: 1
    solver: {{method: {method}, rtol: 1.0e-8, atol: 1.0e-10}}
    bodies:
      - {{name: star, mass: 3.0, radius: 0.08, position: [-0.5, 0, 0]}}
      - {{name: planet, mass: 1.0, radius: 0.05, position: [0.5, 0, 0]}}
    fields: [{{type: gravitation, G: 1.0}}]
"""
FREE_FALL_TIME = np.pi / 2 * np.sqrt(1.0 / (2 * 4.0))


@pytest.mark.slow
@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "BDF", "LSODA"])
def test_a_gravitational_plunge_names_the_pair_and_softening_not_another_solver(method):
    """Every adaptive method stops at the free-fall time (LSODA by the stall check, which turns a five-minute crawl
    of 1e-16 s steps into a second), naming the two bodies, their radii, softening and collisions as the fix; an
    implicit method is never told to try an implicit method."""
    with pytest.raises(SimulationError) as caught:
        run(PLUNGE.format(method=method))
    message = str(caught.value)
    assert caught.value.time == pytest.approx(FREE_FALL_TIME, abs=1e-3)
    assert "Bodies 'star' and 'planet' come" in message and "closer than their radii together (0.13 m)" in message
    assert "softening: 0.065" in message and "'contacts: {}'" in message
    assert "Radau or BDF" not in message
    if method == "LSODA":
        assert "stalled" in message


def test_a_fixed_step_through_a_plunge_is_stopped_by_the_energy_guard_naming_the_pair():
    """Verlet jumps across the singularity and leaves with thousands of times the scene's energy: the guard stops the
    run and names the pair that came closer than their radii, near the free-fall time, and softening."""
    with pytest.raises(SimulationError) as caught:
        run(PLUNGE.format(method="verlet").replace("rtol: 1.0e-8, atol: 1.0e-10", "dt: 1.0e-3"))
    message = str(caught.value)
    assert "is adding energy" in message and "Bodies 'star' and 'planet' come" in message
    when = float(message.split("at t ≈ ")[1].split(" s")[0])
    assert when == pytest.approx(FREE_FALL_TIME, abs=0.04)  # on the straight path between two frames
    assert "softening: 0.065" in message


def spring_model(stiffness: float):
    builder = ModelBuilder()
    hook = builder.add_anchor("hook", (0, 0, 0))
    bob = builder.add_particle("bob", position=(1.1, 0, 0), mass=0.01)
    builder.add_spring(bob, hook, stiffness=stiffness, rest_length=1.0, second_is_anchor=True, name="wire")
    return builder.finalize(duration=1.0, fps=10)


def test_advice_names_a_stiff_spring_and_fits_the_kind_of_method():
    """With a stiff spring, an explicit method is pointed to Radau, BDF or backward_euler, an implicit one that
    failed anyway to backward_euler or a softer spring, never to Radau or BDF; both name the spring and its ω."""
    from animbatch.sim.integrators.advice import failure_advice

    model = spring_model(1.0e8)
    explicit = failure_advice(model, "RK45", model.y0, 0.1, "bob")
    implicit = failure_advice(model, "Radau", model.y0, 0.1, "bob")
    for advice in (explicit, implicit):
        assert "spring 'wire' (ks = 1e+08 N/m" in advice and "ω = 1e+05 rad/s" in advice
    assert "Radau or BDF" in explicit
    assert "Radau is already implicit: try backward_euler" in implicit and "Radau or BDF" not in implicit


def test_advice_without_springs_or_encounters_names_the_fastest_body():
    """Nothing stiff and no close pair: the fastest-changing body is named; an explicit method hears that the scene
    may be stiff, an implicit one that a jump or singularity in a force is the likelier cause."""
    from animbatch.sim.integrators.advice import failure_advice

    model = two_particles("runaway")
    assert "Radau or BDF" in failure_advice(model, "DOP853", model.y0, 0.3, "runaway")
    implicit = failure_advice(model, "BDF", model.y0, 0.3, "runaway")
    assert "'runaway'" in implicit and "already implicit, so stiffness is not the cause" in implicit
    assert "Radau or BDF" not in implicit and "verlet" in implicit


@pytest.mark.slow
def test_a_plunge_in_a_scene_with_contacts_gets_the_same_advice_fitted_to_its_contact_settings():
    """With a floor and contacts between bodies switched off, Radau fails at the same free-fall time inside the
    contact path: the message names the pair and says how to let them collide in this scene (contacts.bodies)."""
    text = PLUNGE.format(method="Radau").replace("position: [-0.5, 0, 0]", "position: [-0.5, 5, 0]").replace(
        "position: [0.5, 0, 0]", "position: [0.5, 5, 0]")
    text += "    colliders: [{type: plane}]\n    contacts: {bodies: false}\n"
    with pytest.raises(SimulationError) as caught:
        run(text)
    message = str(caught.value)
    assert caught.value.time == pytest.approx(FREE_FALL_TIME, abs=1e-3)
    assert "with contacts" in message and "Bodies 'star' and 'planet' come" in message
    assert "let the bodies collide (contacts.bodies: true)" in message and "Radau or BDF" not in message


def test_emitted_particles_that_blow_up_stop_the_run_naming_the_emitter_and_the_fix(monkeypatch):
    """Quadratic drag of 1 N·s²/m² on 1 mg particles at 5 m/s: a = c v² / m = 2.5e7 m/s², so Verlet's 10 ms step
    overshoots by orders of magnitude each step. The pre-flight refuses it (a rate of 2 C v / m = 1e7 /s); with the
    pre-flight out of the way, the run itself stops naming the emitter, a smaller dt and backward_euler (the
    backstop for whatever the pre-flight cannot bound)."""
    jet = """
        duration: 0.5
        solver: {method: verlet, dt: 0.01}
        emitters:
          - {name: jet, rate: 100, lifetime: 1, speed: 5, mass: 1.0e-6, source: {type: point}}
        fields: [{type: drag, model: quadratic, coefficient: 1.0}]
    """
    with pytest.raises(SimulationError, match=r"emitter 'jet': drag quadratic.*rate of 1e\+07 /s"):
        run(jet)
    monkeypatch.setattr("animbatch.sim.particles.simulate.check_stability", lambda *arguments: None)
    with pytest.raises(SimulationError) as caught:
        run(jet)
    message = str(caught.value)
    assert "particles of emitter 'jet' left the finite numbers" in message
    assert "lower solver.dt" in message and "backward_euler" in message and caught.value.body == "jet"
