"""Collisions and contact against closed forms: impacts, restitution, friction, rolling, resting, tunnelling."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from animbatch.sim.contact import detection
from animbatch.sim.contact.materials import BUILT_IN, MaterialTable
from animbatch.sim.invariants import kinetic_energy, linear_momentum
from animbatch.sim.preflight import StabilityWarning
from support.scenes import counting, run, states

G = 9.81
BOTH = ["RK45", "symplectic_euler"]  # the event-driven and the time-stepping paths


class Sweeps:
    """Which contact-impulse sweeps a test runs with: the default choice by size (numpy for a few contacts), or the
    compiled ones forced; :meth:`check` then asserts that the compiled sweeps did the solving."""

    def __init__(self, compiled: bool, calls: list[int]) -> None:
        self.compiled, self.calls = compiled, calls

    def check(self) -> None:
        assert not self.compiled or self.calls, "the compiled sweeps solved no contact"


@pytest.fixture(params=["default sweeps", pytest.param("compiled sweeps", marks=pytest.mark.slow)])
def sweeps(request, monkeypatch) -> Sweeps:
    """The closed forms below hold with either sweeps: each test that takes this fixture runs with both."""
    if request.param == "default sweeps":
        return Sweeps(False, [])
    pytest.importorskip("numba", reason="numba is not installed: numpy solves every contact")
    from animbatch.sim import kernels
    from animbatch.sim.kernels import contact_impulses

    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    return Sweeps(True, counting(monkeypatch, contact_impulses, "solve_contacts"))


def solver(method: str, dt: float = 1e-3) -> str:
    return f"solver: {{method: {method}, dt: {dt}, rtol: 1.0e-10, atol: 1.0e-12}}"


def materials(e: float, mu_s: float = 0.5, mu_k: float = 0.3) -> str:
    return f"materials: {{m: {{restitution: {e}, static_friction: {mu_s}, kinetic_friction: {mu_k}}}}}"


# ------------------------------------------------------------------------------------------------ materials


def test_built_in_materials_follow_the_notes_table_and_combine_as_documented():
    """Same-material pairs give the table's coefficients; mixed pairs: geometric-mean friction, smaller e."""
    table = MaterialTable.build()
    steel, wood = table.pair("steel", "steel"), table.pair("wood", "wood")
    assert (steel.static_friction, steel.kinetic_friction) == (0.78, 0.42)
    assert (wood.static_friction, wood.kinetic_friction) == (0.38, 0.20)
    assert table.pair("rubber", "pavement").static_friction == 0.55  # measured pair in the notes
    assert table.pair("oiled_steel", "steel").kinetic_friction == 0.08
    mixed = table.pair("steel", "wood")
    assert mixed.static_friction == pytest.approx(np.sqrt(0.78 * 0.38))
    assert mixed.restitution == min(BUILT_IN["steel"].restitution, BUILT_IN["wood"].restitution)
    custom = MaterialTable.build(pairs={frozenset({"steel", "wood"}): {"restitution": 0.1, "static_friction": None,
                                                                     "kinetic_friction": None}})
    assert custom.pair("wood", "steel").restitution == 0.1
    assert custom.pair("wood", "steel").static_friction == pytest.approx(np.sqrt(0.78 * 0.38))


# ------------------------------------------------------------------------------------------------ impacts


def head_on(method: str, e: float) -> tuple:
    model, trajectory = run(f"""
        duration: 1
        fps: 20
        {solver(method)}
        {materials(e)}
        contacts: {{}}
        bodies:
          - {{name: a, mass: 2, radius: 0.1, position: [-0.5, 0, 0], velocity: [1.5, 0, 0], material: m}}
          - {{name: b, mass: 1, radius: 0.1, position: [0.5, 0, 0], velocity: [-0.5, 0, 0], material: m}}
    """)
    return model, trajectory, states(model, trajectory)


@pytest.mark.parametrize("method", BOTH)
def test_elastic_head_on_collision_gives_the_textbook_velocities(method, sweeps):
    """e = 1: v₁' = ((m₁ - m₂) v₁ + 2 m₂ v₂)/(m₁ + m₂), v₂' likewise; momentum and energy conserved."""
    model, trajectory, y = head_on(method, 1.0)
    m1, m2, v1, v2 = 2.0, 1.0, 1.5, -0.5
    after1 = ((m1 - m2) * v1 + 2 * m2 * v2) / (m1 + m2)
    after2 = ((m2 - m1) * v2 + 2 * m1 * v1) / (m1 + m2)
    assert np.allclose(trajectory.velocities[-1, :, 0], [after1, after2], atol=1e-9)
    momentum, energy = linear_momentum(model, y), kinetic_energy(model, y)
    assert np.allclose(momentum, momentum[0], atol=1e-12)
    assert np.allclose(energy, energy[0], rtol=1e-9)
    sweeps.check()


@pytest.mark.parametrize("method", BOTH)
def test_inelastic_collision_loses_half_mu_one_minus_e_squared_dv_squared(method, sweeps):
    """e = 0.4: momentum is conserved and kinetic energy drops by exactly ½ μ (1 - e²) Δv²."""
    model, trajectory, y = head_on(method, 0.4)
    reduced, approach = 2.0 * 1.0 / 3.0, 2.0
    momentum, energy = linear_momentum(model, y), kinetic_energy(model, y)
    assert np.allclose(momentum, momentum[0], atol=1e-12)
    assert energy[0] - energy[-1] == pytest.approx(0.5 * reduced * (1 - 0.4**2) * approach**2, rel=1e-9)
    sweeps.check()


def test_oblique_collision_in_2d():
    """Off-centre impact of smooth spheres (impact parameter b, no friction): the impulse acts along the line of
    centres at the exact contact time, so the velocities follow from that normal; momentum and energy are
    conserved (e = 1)."""
    radius, b = 0.1, 0.12
    model, trajectory = run(f"""
        duration: 1
        fps: 20
        {solver("RK45")}
        {materials(1.0, 0.0, 0.0)}
        contacts: {{}}
        bodies:
          - {{name: a, mass: 1, radius: {radius}, position: [-0.6, {b}, 0], velocity: [2, 0, 0], material: m}}
          - {{name: b, mass: 3, radius: {radius}, position: [0, 0, 0], material: m}}
    """)
    y = states(model, trajectory)
    angle = np.arcsin(b / (2 * radius))
    normal = np.array([-np.cos(angle), np.sin(angle), 0.0])  # from b's centre to a's at contact
    approach = np.dot([2.0, 0, 0], normal)
    impulse = -(1 + 1.0) * approach / (1 / 1 + 1 / 3)
    assert np.allclose(trajectory.velocities[-1, 0], np.array([2.0, 0, 0]) + impulse * normal, atol=1e-8)
    assert np.allclose(trajectory.velocities[-1, 1], -impulse / 3 * normal, atol=1e-8)
    assert np.allclose(linear_momentum(model, y), [2, 0, 0], atol=1e-10)
    assert np.allclose(kinetic_energy(model, y), 2.0, rtol=1e-9)


def bouncing(method: str, e: float = 0.8, duration: float = 6, fps: int = 200) -> tuple:
    model, trajectory = run(f"""
        duration: {duration}
        fps: {fps}
        {solver(method)}
        {materials(e)}
        bodies: [{{name: ball, radius: 0.1, position: [0, 1.1, 0], material: m}}]
        colliders: [{{type: plane, material: m}}]
        fields: [{{type: gravity}}]
    """)
    return trajectory, trajectory.positions[:, 0, 1] - 0.1


@pytest.mark.slow
def test_frames_on_both_sides_of_an_impact_are_exact():
    """Frames just before and after the first impact (t_c = sqrt(2 h / g)) lie on the closed-form fall and
    rebound: the impact is found at its exact time, without overshoot."""
    trajectory, height = bouncing("RK45", fps=240)
    t = trajectory.times
    impact = np.sqrt(2 / G)
    speed = G * impact
    fall = 1.0 - 0.5 * G * t**2
    rise = 0.8 * speed * (t - impact) - 0.5 * G * (t - impact) ** 2
    near = np.abs(t - impact) < 0.05
    expected = np.where(t < impact, fall, rise)
    assert np.allclose(height[near], expected[near], atol=1e-9)
    assert height.min() >= -1e-12  # never below the floor


@pytest.mark.slow
def test_apex_heights_follow_e_to_the_2n_and_bouncing_ends_at_the_series_time():
    """Apex n is at e^(2n) h₀, and the ball stops at t₀ (1 + 2e/(1-e)) minus the bounces below the rest speed."""
    e = 0.8
    trajectory, height = bouncing("RK45", e)
    t = trajectory.times
    velocity = trajectory.velocities[:, 0, 1]
    # apex times are known: t0 + (2n - 1) e^n t0 after... compare heights at the analytic apex times
    t0 = np.sqrt(2 / G)
    for n in range(1, 6):
        apex_time = t0 + 2 * t0 * sum(e**k for k in range(1, n)) + e**n * t0
        frame = int(round(apex_time * 200))
        assert height[frame] == pytest.approx(e ** (2 * n), abs=0.5 * G * (1 / 200) ** 2 + 1e-9)
    series = t0 * (1 + 2 * e / (1 - e))
    rest_speed = 0.01
    unresolved = 2 * rest_speed / G / (1 - e)  # the bounces slower than the rest speed, which do not happen
    at_rest = t[np.flatnonzero(np.abs(height) > 1e-9)[-1] + 1]
    assert series - unresolved - 0.01 <= at_rest <= series
    assert np.abs(height[t > at_rest]).max() < 1e-12 and np.abs(velocity[t > at_rest]).max() < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("method, accuracy", [("RK45", 1e-8), ("symplectic_euler", 3e-3), ("verlet", 3e-3),
                                              ("backward_euler", 3e-3)])
def test_impact_times_are_logged_and_follow_the_bounce_series(method, accuracy):
    """Every path logs its bounces (time, body) in the run's statistics: for e = 0.5 from 1 m, impact k is at
    t₀ (1 + 2 Σ_{j≤k} e^j); events find them to the tolerance, fixed steps (1 ms) to a few steps per bounce (a
    speculative contact bounces up to a step early).
    Verlet bounces too (its end-of-step re-projection must not stop an arriving ball dead)."""
    e = 0.5
    _, trajectory = run(f"""
        duration: 1.4
        fps: 50
        {solver(method)}
        {materials(e)}
        bodies: [{{name: ball, radius: 0.1, position: [0, 1.1, 0], material: m}}]
        colliders: [{{type: plane, material: m}}]
        fields: [{{type: gravity}}]
    """)
    t0 = np.sqrt(2 / G)
    exact = [t0 * (1 + 2 * sum(e**j for j in range(1, k + 1))) for k in range(4)]
    impacts = trajectory.solver_stats["impacts"]
    assert [body for _, body in impacts[:4]] == [0, 0, 0, 0]
    for k, (time, _) in enumerate(impacts[:4]):
        assert time == pytest.approx(exact[k], abs=accuracy * (k + 1))


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_resting_contact_is_still(method):
    """A ball and a box placed on the ground stay where they are, with zero velocity, frame after frame. (With
    fixed steps the box's four corner contacts settle within its first step, by less than 0.1 µm; from then on
    warm-started impulses hold it exactly.)"""
    _, trajectory = run(f"""
        duration: 2
        fps: 10
        {solver(method)}
        bodies:
          - {{name: ball, radius: 0.1, position: [0, 0.1, 0]}}
          - {{name: crate, type: rigid, shape: {{type: box, size: [0.4, 0.2, 0.3]}}, density: 500,
             position: [1, 0.1, 0]}}
        colliders: [{{type: plane}}]
        fields: [{{type: gravity}}]
    """)
    settled = trajectory.positions[1]
    assert np.abs(settled - trajectory.positions[0]).max() < (1e-12 if method == "RK45" else 1e-7)
    assert np.abs(trajectory.positions[1:] - settled).max() < 1e-12
    assert np.abs(trajectory.velocities).max() < 1e-10  # round-off of the contact forces' tolerance
    assert np.abs(trajectory.angular_velocities).max() < 1e-10


# ------------------------------------------------------------------------------------------------ friction


def on_slope(method: str, degrees: float, speed: float = 0.0, duration: float = 1.0) -> tuple:
    theta = np.radians(degrees)
    normal = np.array([-np.sin(theta), np.cos(theta), 0.0])
    down = -np.array([np.cos(theta), np.sin(theta), 0.0])  # gravity's component along this plane points this way
    _, trajectory = run(f"""
        duration: {duration}
        fps: 50
        {solver(method)}
        {materials(0.0, 0.5, 0.3)}
        bodies: [{{name: block, radius: 0.05, position: {(0.05 * normal).tolist()},
                   velocity: {(speed * down).tolist()}, material: m}}]
        colliders: [{{type: plane, normal: {normal.tolist()}, material: m}}]
        fields: [{{type: gravity}}]
    """)
    along = (trajectory.positions[:, 0] - trajectory.positions[0, 0]) @ down
    return trajectory, along, normal, down


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_block_sticks_when_tan_theta_is_below_mu_s(method, sweeps):
    """μs = 0.5: at 25° (tan = 0.47) the block stays put, exactly."""
    _, along, _, _ = on_slope(method, 25)
    assert np.abs(along).max() < 1e-12
    sweeps.check()


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_block_slides_with_a_equal_g_sin_minus_mu_k_cos(method, sweeps):
    """At 35° (tan = 0.7 > μs) it slides with a = g (sin θ - μk cos θ)."""
    trajectory, along, _, _ = on_slope(method, 35)
    theta = np.radians(35)
    expected = 0.5 * G * (np.sin(theta) - 0.3 * np.cos(theta)) * trajectory.times**2
    tolerance = 1e-9 if method == "RK45" else 2e-3
    assert np.allclose(along, expected, atol=tolerance)
    sweeps.check()


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_sliding_block_stops_and_stays_stopped(method, sweeps):
    """Pushed down a 10° slope at 2 m/s with μk > tan θ, it slows at g (μk cos θ - sin θ), stops at the predicted
    time and distance, and then stays exactly still: no sign flipping."""
    trajectory, along, _, down = on_slope(method, 10, speed=2.0, duration=2.0)
    theta = np.radians(10)
    deceleration = G * (0.3 * np.cos(theta) - np.sin(theta))
    stop = 2.0 / deceleration
    t = trajectory.times
    expected = np.where(t < stop, 2.0 * t - 0.5 * deceleration * t**2, 2.0**2 / (2 * deceleration))
    assert np.allclose(along, expected, atol=1e-9 if method == "RK45" else 3e-3)
    speed_along = trajectory.velocities[:, 0] @ down
    assert np.abs(speed_along[t > stop + 0.02]).max() < 1e-9  # stopped (to round-off)
    assert np.all(speed_along >= -1e-9)  # and never backwards
    sweeps.check()


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_sliding_sphere_starts_rolling_at_the_predicted_time(method, sweeps):
    """A ball launched sliding (v₀, ω = 0) slows under kinetic friction until v = ω r at t* = 2 v₀ / (7 μ g),
    with v = 5/7 v₀; then it rolls without slipping."""
    _, trajectory = run(f"""
        duration: 0.6
        fps: 100
        {solver(method, 5e-4)}
        {materials(0.0, 0.2, 0.2)}
        bodies: [{{name: ball, type: rigid, shape: {{type: sphere, radius: 0.1}}, density: 1000,
                   position: [0, 0.1, 0], velocity: [2, 0, 0], material: m}}]
        colliders: [{{type: plane, material: m}}]
        fields: [{{type: gravity}}]
    """)
    t = trajectory.times
    v, omega = trajectory.velocities[:, 0, 0], trajectory.angular_velocities[:, 0, 2]
    slip = v + 0.1 * omega
    rolling = 2 * 2.0 / (7 * 0.2 * G)
    before = t < rolling - 0.01
    assert np.allclose(v[before], 2.0 - 0.2 * G * t[before], atol=1e-9 if method == "RK45" else 2e-3)
    after = t > rolling + 0.01
    assert np.abs(slip[after]).max() < 1e-9
    assert np.allclose(v[after], 5 / 7 * 2.0, atol=1e-9 if method == "RK45" else 2e-3)
    assert np.allclose(trajectory.positions[:, 0, 1], 0.1, atol=1e-9)  # it never sinks or hops
    sweeps.check()


# ------------------------------------------------------------------------------------------------ tunnelling


@pytest.mark.parametrize("method", BOTH)
def test_fast_ball_does_not_tunnel_through_a_thin_wall(method):
    """A 2 cm ball at 150 m/s towards a 1 cm wall bounces back. Its free path, sampled at the 1 ms steps or the
    frames, never overlaps the wall: a naive per-step overlap check would have let it through. The fixed-step run
    is warned about beforehand (150 m/s × 1 ms is 15 wall thicknesses); the adaptive one finds the impact time."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, trajectory = run(f"""
        duration: 0.1
        fps: 100
        {solver(method)}
        bodies: [{{name: bullet, radius: 0.01, velocity: [150, 0, 0], material: steel}}]
        colliders: [{{type: box, position: [1.005, 0, 0], size: [0.01, 1, 1], material: steel}}]
    """)
    warned = [str(w.message) for w in caught if issubclass(w.category, StabilityWarning)]
    if method == "symplectic_euler":
        assert len(warned) == 1 and warned[0].startswith("body 'bullet' may reach 150 m/s and so move 0.15 m")
    else:
        assert warned == []
    x = trajectory.positions[:, 0, 0]
    assert np.all(x < 1.0 - 0.01 + 1e-9)  # always on the near side of the wall
    assert trajectory.velocities[-1, 0, 0] < 0  # bounced back
    samples = 150 * np.arange(0, 0.1, 1e-3)  # where the unobstructed ball is at each step
    overlapping = (samples + 0.01 > 1.0) & (samples - 0.01 < 1.01)
    assert not overlapping.any()


# ------------------------------------------------------------------------------------------------ rigid


@pytest.mark.slow
@pytest.mark.parametrize("method", BOTH)
def test_box_dropped_on_its_edge_tumbles_and_lands_flat(method, sweeps):
    """A cube dropped resting on an edge (turned 30°) gets spin from the impact at the edge, topples and ends flat
    on a face, its centre half a side above the ground."""
    if sweeps.compiled and method == "RK45":
        pytest.skip("the event-driven path spends 4 s on the tumbling box for no contact rows the others lack")
    _, trajectory = run(f"""
        duration: 1.5
        fps: 30
        {solver(method)}
        bodies: [{{name: cube, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500,
                   position: [0, 0.4, 0], orientation: {{axis: [0, 0, 1], angle: 30}}, material: wood}}]
        colliders: [{{type: plane, material: wood}}]
        fields: [{{type: gravity}}]
    """)
    spin = trajectory.angular_velocities[:, 0, 2]
    assert np.abs(spin).max() > 1.0
    from animbatch import quaternion

    axes = quaternion.to_matrix(trajectory.orientations[-1, 0])
    assert np.max(np.abs(axes[1])) > np.cos(np.radians(0.5))  # some body axis points straight up
    assert trajectory.positions[-1, 0, 1] == pytest.approx(0.1, abs=1e-3)
    sweeps.check()


@pytest.mark.slow
def test_stacked_boxes_cylinders_and_a_compound_come_to_rest_at_their_shapes_heights():
    """Box on box (a moving body's box as a solid for another's corners, here with flush side faces, where the
    corners lie on the lower box's sides as much as on its top), a cylinder lying and one standing, and a dumbbell
    (compound of two spheres and a rod) settle with their centres where their geometry puts them, and stay still.
    The stacked box is placed at rest, off-centre: it must not move at all."""
    _, trajectory = run(f"""
        duration: 1.5
        fps: 10
        {solver("symplectic_euler")}
        bodies:
          - {{name: lower, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500,
             position: [0, 0.1, 0], material: wood}}
          - {{name: upper, type: rigid, shape: {{type: box, size: [0.2, 0.2, 0.2]}}, density: 500,
             position: [0.03, 0.3, 0], material: wood}}
          - {{name: lying, type: rigid, shape: {{type: cylinder, radius: 0.05, length: 0.3}}, density: 500,
             position: [1, 0.1, 0], material: wood}}
          - {{name: standing, type: rigid, shape: {{type: cylinder, radius: 0.05, length: 0.3}}, density: 500,
             position: [2, 0.2, 0], orientation: {{axis: [1, 0, 0], angle: 90}}, material: wood}}
          - name: dumbbell
            type: rigid
            density: 500
            material: wood
            position: [3, 0.1, 0]
            shape:
              type: compound
              parts:
                - {{shape: {{type: sphere, radius: 0.05}}, offset: [-0.2, 0, 0]}}
                - {{shape: {{type: sphere, radius: 0.05}}, offset: [0.2, 0, 0]}}
                - {{shape: {{type: cylinder, radius: 0.01, length: 0.3}}, orientation: {{axis: [0, 1, 0], angle: 90}}}}
        colliders: [{{type: plane, material: wood}}]
        fields: [{{type: gravity}}]
    """)
    names = list(trajectory.body_names)
    heights = {"lower": 0.1, "upper": 0.3, "lying": 0.05, "standing": 0.15, "dumbbell": 0.05}
    for name, height in heights.items():
        index = names.index(name)
        assert trajectory.positions[-1, index, 1] == pytest.approx(height, abs=3e-4), name
        assert np.abs(trajectory.velocities[-3:, index]).max() < 1e-6, name
    for name in ("upper", "lower"):
        index = names.index(name)
        assert np.abs(trajectory.positions[:, index] - trajectory.positions[0, index]).max() < 1e-6, name


def test_broad_phase_finds_exactly_the_pairs_a_brute_force_search_finds():
    """With 300 random spheres, the k-d tree broad phase reports the same touching pairs as checking all pairs."""
    rng = np.random.default_rng(1)
    centres = rng.uniform(0, 1.5, (300, 3))
    radii = rng.uniform(0.02, 0.06, 300)
    bodies = "\n".join(f"          - {{name: s{i}, radius: {float(r)!r}, position: {c.tolist()}}}"
                       for i, (c, r) in enumerate(zip(centres, radii)))
    model, _ = run(f"""
        duration: 0.01
        {solver("symplectic_euler")}
        contacts: {{}}
        bodies:
{bodies}
    """)
    from animbatch.sim.model import Dynamics

    dynamics = Dynamics(model)
    found = detection.detect(model.contact_world, dynamics.kinematics(*dynamics.split(model.y0.copy())), 0.0)
    reported = {tuple(sorted(pair)) for pair in zip(found.probe_body.tolist(), found.solid_body.tolist())}
    distance = np.linalg.norm(centres[:, None] - centres[None, :], axis=2) - radii[:, None] - radii[None, :]
    brute = {(i, j) for i in range(300) for j in range(i + 1, 300) if distance[i, j] < 0}
    assert reported == brute and len(brute) > 10


@pytest.mark.slow
def test_static_sphere_box_and_mesh_colliders_hold_a_resting_ball(tmp_path):
    """A ball comes to rest on top of a fixed sphere, a fixed box and a mesh slab at the heights their shapes give."""
    import trimesh

    trimesh.creation.box((1.0, 0.2, 1.0)).export(tmp_path / "slab.stl")
    path = tmp_path / "s.yaml"
    path.write_text(f"""
duration: 1
fps: 10
{solver("symplectic_euler")}
{materials(0.0, 0.9, 0.9)}
bodies:
  - {{name: on_sphere, radius: 0.1, position: [0, 0.75, 0], material: m}}
  - {{name: on_box, radius: 0.1, position: [3, 0.75, 0], material: m}}
  - {{name: on_mesh, radius: 0.1, position: [6, 0.75, 0], material: m}}
colliders:
  - {{type: sphere, position: [0, 0, 0], radius: 0.5, material: m}}
  - {{type: box, position: [3, 0, 0], size: [1, 1, 1], material: m}}
  - {{type: mesh, file: slab.stl, position: [6, 0.4, 0], material: m}}
fields: [{{type: gravity}}]
""")
    from animbatch import api

    trajectory = api.simulate(api.load_scene(path))
    assert np.allclose(trajectory.positions[-1, :, 1], [0.6, 0.6, 0.6], atol=1e-3)
    assert np.abs(trajectory.velocities[-1]).max() < 1e-3


def test_contact_code_runs_only_when_declared(monkeypatch):
    """Without colliders or a contacts section, contact detection never runs."""
    calls = []
    monkeypatch.setattr(detection, "detect", lambda *a, **k: calls.append(1))
    run("""
        duration: 0.2
        bodies: [{name: a, velocity: [1, 0, 0]}, {name: b, position: [0.05, 0, 0]}]
        fields: [{type: gravity}]
    """, "solver.method=symplectic_euler")
    assert calls == []


def test_an_event_loop_that_stops_advancing_is_stopped_with_a_clear_error(monkeypatch):
    """A safety net: should impact location ever keep reporting an impact at the step's start (no progress), the
    run stops after MAX_STALLED_EVENTS events at that instant, naming the time and a method that copes, instead of
    spinning forever."""
    from animbatch.errors import SimulationError
    from animbatch.sim.contact import impact_events

    monkeypatch.setattr(impact_events.ContactEvents, "_first_impact", lambda self, solver, candidates, closing: solver.t_old)
    with pytest.raises(SimulationError, match=r"contact events stopped advancing at t = 0 s \(101 events at that "
                                              r"time\).*symplectic_euler"):
        run(f"""
            duration: 0.5
            {solver("RK45")}
            bodies: [{{name: ball, radius: 0.1, position: [0, 0.5, 0]}}]
            colliders: [{{type: plane}}]
            fields: [{{type: gravity}}]
        """)


def test_the_gaps_alone_are_the_gaps_of_the_evaluated_pairs():
    """The event search asks for pairs' gaps alone (detection.pair_gaps, without building the contacts): over the
    frames of balls and boxes bouncing among a plane, a fixed box and each other, every pair found near touching has
    the gap that evaluating it as a contact gives, to the last bit."""
    from animbatch.sim.model.dynamics import Dynamics

    model, trajectory = run("""
        duration: 0.6
        fps: 10
        solver: {method: symplectic_euler, dt: 1.0e-3}
        bodies:
          - {name: a, radius: 0.1, position: [0, 0.3, 0], velocity: [1, 0, 0]}
          - {name: b, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 500, position: [0.4, 0.5, 0],
             angular_velocity: [1, 2, 3]}
          - {name: c, type: rigid, shape: {type: sphere, radius: 0.1}, density: 500, position: [0.8, 0.2, 0.05]}
        colliders:
          - {type: plane}
          - {type: box, position: [1.2, 0.2, 0], size: [0.4, 0.4, 0.4]}
        fields: [{type: gravity}]
        """)
    system, world = Dynamics(model), model.contact_world
    compared = 0
    for y, t in zip(states(model, trajectory), model.frame_times):
        state = system.kinematics(*system.split(y), t=float(t), copy=True)
        near = detection.detect(world, state, 0.5)
        gaps = detection.pair_gaps(world, state, near.probe, near.solid_kind, near.solid_index)
        evaluated = detection.evaluate_pairs(world, state, near.probe, near.solid_kind, near.solid_index)
        assert np.array_equal(gaps, evaluated.gap) and np.array_equal(gaps, near.gap)
        compared += near.count
    assert compared > 100


SLOPE_DEGREES = 20


def block_on_slope(duration: float, mu_s: float, mu_k: float) -> str:
    """A 0.2 × 0.1 × 0.2 m block resting on its four bottom corners on a plane tilted by SLOPE_DEGREES, under RK45."""
    theta = np.radians(SLOPE_DEGREES)
    normal = [-float(np.sin(theta)), float(np.cos(theta)), 0.0]
    return f"""
        duration: {duration}
        fps: 20
        solver: {{method: RK45, rtol: 1.0e-8}}
        {materials(0.0, mu_s, mu_k)}
        bodies:
          - {{name: block, type: rigid, shape: {{type: box, size: [0.2, 0.1, 0.2]}}, density: 500, material: m,
             position: {(0.05 * np.array(normal)).tolist()}, orientation: {{axis: [0, 0, 1], angle: {SLOPE_DEGREES}}}}}
        colliders: [{{type: plane, normal: {normal}, material: m}}]
        fields: [{{type: gravity}}]
    """


def test_a_block_sliding_down_a_slope_under_rk45_solves_its_resting_forces_once_per_state(monkeypatch):
    """RK45 ends each step with the right-hand side at the step's end (first same as last), and the contact modes
    are checked at that same state: the resting forces found there are used again, not solved again (only a
    restart, or the first settling of the contacts, solves them anew). The block slides at g (sin θ − μk cos θ)
    all the same."""
    from animbatch.sim.contact.impact_events import ContactEvents

    forces = counting(monkeypatch, ContactEvents, "_contact_forces")
    right_hand_sides = counting(monkeypatch, ContactEvents, "rhs")
    restarts = counting(monkeypatch, ContactEvents, "restart")
    _, trajectory = run(block_on_slope(0.6, 0.1, 0.1))
    theta = np.radians(SLOPE_DEGREES)
    assert len(right_hand_sides) > 50 and len(forces) - len(right_hand_sides) <= len(restarts) + 1  # + the settling
    down = np.array([-np.cos(theta), -np.sin(theta), 0.0])
    along = (trajectory.positions[:, 0] - trajectory.positions[0, 0]) @ down
    expected = 0.5 * G * (np.sin(theta) - 0.1 * np.cos(theta)) * trajectory.times ** 2
    np.testing.assert_allclose(along, expected, atol=1e-6)


def test_resting_forces_on_python_floats_are_the_array_ones(monkeypatch):
    """A box held by friction on its four corners on a 20° slope under RK45 (μs = 0.5 > tan 20°): the resting-contact
    solve of a few contacts sweeps on Python floats; forced onto numpy arrays it gives the same motion, and in both
    the box stays where it was put."""
    from animbatch.sim.contact import impulses

    text = block_on_slope(0.3, 0.5, 0.3)
    _, floats = run(text)
    monkeypatch.setattr(impulses, "SMALL_FORCE_ROWS", 0)
    _, arrays = run(text)
    np.testing.assert_allclose(floats.positions, arrays.positions, rtol=0, atol=1e-12)
    assert np.abs(floats.positions - floats.positions[0]).max() < 1e-9
