"""Conservation laws: energy, linear and angular momentum, Kepler's period; and the energy behaviour of each method."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.sim.invariants import (
    angular_momentum,
    centre_of_mass,
    kinetic_energy,
    linear_momentum,
    potential_energy,
    total_energy,
)
from support.scenes import run, states

ORBIT = """
    duration: 6
    fps: 30
    solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
    bodies:
      - {name: star,   mass: 3.0, position: [-0.25, 0, 0], velocity: [0, -0.4, 0]}
      - {name: planet, mass: 1.0, position: [ 0.75, 0, 0], velocity: [0,  1.2, 0]}
    fields: [{type: gravitation, G: 1.0}]
"""


def test_two_body_orbit_conserves_energy_and_angular_momentum_with_dop853():
    """DOP853 at rtol 1e-10 keeps relative energy and angular-momentum drift below 1e-8 over three orbits."""
    model, trajectory = run(ORBIT)
    y = states(model, trajectory)
    energy = total_energy(model, y)
    momentum = angular_momentum(model, y)
    assert energy[0] == pytest.approx(0.5 * 3 * 0.16 + 0.5 * 1.44 - 3.0)  # ½Σmv² - G m1 m2 / r
    assert np.abs(energy - energy[0]).max() < 1e-8 * abs(energy[0])
    assert np.abs(momentum - momentum[0]).max() < 1e-8 * np.linalg.norm(momentum[0])
    assert np.abs(linear_momentum(model, y)).max() < 1e-12  # started in the centre-of-mass frame
    assert np.abs(centre_of_mass(model, y)).max() < 1e-10


def test_two_body_orbit_has_keplers_period():
    """The separation returns to its start after T = 2π sqrt(a³/(G M)), a from the vis-viva equation."""
    total_mass, r, v_rel = 4.0, 1.0, 1.6
    a = 1 / (2 / r - v_rel**2 / total_mass)
    period = 2 * np.pi * np.sqrt(a**3 / total_mass)
    _, trajectory = run(ORBIT, "fps=240", "duration=2.2")
    separation = trajectory.positions[:, 1] - trajectory.positions[:, 0]
    distance = np.linalg.norm(separation - separation[0], axis=1)
    late = trajectory.times > period / 2
    closest = trajectory.times[late][np.argmin(distance[late])]
    assert closest == pytest.approx(period, abs=1 / 240)
    # slower than circular speed, the start is the apoapsis; the periapsis is at 2a - r
    assert np.linalg.norm(separation, axis=1).max() == pytest.approx(r, rel=1e-9)
    assert np.linalg.norm(separation, axis=1).min() == pytest.approx(2 * a - r, rel=1e-4)


def test_softened_gravitation_force_matches_plummer_formula():
    """With softening ε, the pair force is G m1 m2 r / (r² + ε²)^(3/2), and the potential -G m1 m2 / sqrt(r²+ε²)."""
    model, _ = run("""
        duration: 0.1
        bodies: [{name: a, mass: 2, position: [0, 0, 0]}, {name: b, mass: 5, position: [0.3, 0.4, 0]}]
        fields: [{type: gravitation, G: 1.5, softening: 0.2}]
    """)
    from animbatch.sim.model import Dynamics

    dynamics = Dynamics(model)
    force, _ = dynamics.loads(0.0, dynamics.kinematics(*dynamics.split(model.y0.copy())))
    expected = 1.5 * 2 * 5 * np.array([0.3, 0.4, 0]) / (0.25 + 0.04) ** 1.5
    assert np.allclose(force[0], expected) and np.allclose(force[1], -expected)
    assert potential_energy(model, model.y0) == pytest.approx(-1.5 * 2 * 5 / np.sqrt(0.29))


def test_free_spring_pair_conserves_momentum_and_energy():
    """Two free masses joined by an undamped spring: momentum is exact, energy kept by DOP853, COM moves uniformly."""
    model, trajectory = run("""
        duration: 4
        fps: 25
        solver: {method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}
        bodies:
          - {name: a, mass: 1, position: [0, 0, 0], velocity: [0, 1, 0]}
          - {name: b, mass: 3, position: [1.5, 0, 0], velocity: [0.4, 0, 0.2]}
        springs: [{between: [a, b], stiffness: 30, rest_length: 1.0}]
    """)
    y = states(model, trajectory)
    momentum = linear_momentum(model, y)
    assert np.allclose(momentum, momentum[0], atol=1e-10)
    com = centre_of_mass(model, y)
    assert np.allclose(com, com[0] + trajectory.times[:, None] * momentum[0] / model.bodies.mass.sum(), atol=1e-9)
    energy = total_energy(model, y)
    assert energy[0] == pytest.approx(0.5 * 1 + 0.5 * 3 * 0.2 + 0.5 * 30 * 0.25)
    assert np.abs(energy - energy[0]).max() < 1e-8


def test_dampers_only_remove_energy():
    """With damped springs and gravity, mechanical energy never increases from frame to frame."""
    model, trajectory = run("""
        duration: 3
        fps: 30
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        anchors: [{name: pin, position: [0, 0, 0]}]
        bodies:
          - {name: a, mass: 0.2, position: [0.3, 0, 0]}
          - {name: b, mass: 0.2, position: [0.6, 0, 0]}
        springs:
          - {between: [pin, a], stiffness: 80, damping: 0.3}
          - {between: [a, b], stiffness: 80, damping: 0.3}
        fields: [{type: gravity}]
    """)
    energy = total_energy(model, states(model, trajectory))
    assert np.all(np.diff(energy) <= 1e-9)
    assert energy[-1] < energy[0] - 0.1  # and it does lose a noticeable amount


def energy_drift(method: str, dt: float) -> np.ndarray:
    model, trajectory = run("""
        duration: 10
        fps: 10
        anchors: [{name: wall, position: [0, 0, 0]}]
        bodies: [{name: mass, mass: 1, position: [1.5, 0, 0]}]
        springs: [{between: [wall, mass], stiffness: 4, rest_length: 1.0}]
    """, f"solver.method={method}", f"solver.dt={dt}")
    energy = total_energy(model, states(model, trajectory))
    return energy / energy[0] - 1


def test_explicit_euler_gains_energy_while_symplectic_methods_stay_bounded():
    """On an undamped oscillator, explicit Euler's energy grows every step; symplectic Euler and Verlet oscillate
    within O(h) and O(h²) bands without drifting."""
    euler = energy_drift("euler", 0.01)
    assert np.all(np.diff(euler) > 0) and euler[-1] > 0.3  # (1 + ω²h²)^n - 1 = 0.49 for ω = 2, n = 990
    assert euler[-1] == pytest.approx((1 + 4 * 0.01**2) ** 990 - 1, rel=1e-3)  # last frame at t = 9.9 s
    symplectic = energy_drift("symplectic_euler", 0.01)
    verlet = energy_drift("verlet", 0.01)
    assert np.abs(symplectic).max() < 0.02  # ~ω h
    assert np.abs(verlet).max() < 1e-4  # ~(ω h)²
    assert abs(np.mean(verlet[:50]) - np.mean(verlet[-50:])) < 1e-5  # no secular drift


def test_kinetic_energy_of_particles_and_a_spinning_body():
    """½ Σ m |v|² for particles plus ½ M v² + ½ ω·L = ½ ω·I ω for a rigid body."""
    model, _ = run("""
        duration: 0.1
        bodies:
          - {name: a, mass: 1, velocity: [1, 0, 0]}
          - {name: b, mass: 2, velocity: [0, 2, 0]}
          - {name: box, type: rigid, shape: {type: box, size: [1, 2, 3]}, mass: 12, velocity: [0, 0, 1],
             angular_velocity: [1, 0, 2]}
    """)
    rotational = 0.5 * (13 * 1**2 + 5 * 2**2)  # I = diag(13, 10, 5) for m = 12, sides 1, 2, 3
    assert kinetic_energy(model, model.y0) == pytest.approx(0.5 + 4.0 + 6.0 + rotational)
