"""Distance joints (rigid rods between particles or to anchors), against closed forms and invariants: the pendulum's
period at small and large amplitude (the elliptic-integral period), a double pendulum's energy and rod drift with
adaptive and fixed-step methods, and a free rod's momenta."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ellipk

from animbatch import api
from animbatch.errors import SceneError
from animbatch.stages import parse_scene
from support.scenes import scene

G = 9.81


def pendulum(amplitude_deg: float, solver: str, length: float = 1.0, duration: float = 6.0):
    """A bob on a rod of ``length`` from a pivot, released at rest ``amplitude_deg`` from the vertical; the
    stopwatch times one period between two passes through the bottom moving +x."""
    theta = np.radians(amplitude_deg)
    loaded = scene(f"""
        duration: {duration}
        fps: 50
        solver: {solver}
        anchors: [{{name: pivot, position: [0, 0, 0]}}]
        bodies: [{{name: bob, mass: 0.7, position: [{-length * float(np.sin(theta))!r}, {-length * float(np.cos(theta))!r}, 0]}}]
        joints: [{{type: distance, between: [pivot, bob]}}]
        fields: [{{type: gravity}}]
        stopwatches:
          - name: period
            start: {{body: bob, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
            stop: {{body: bob, point: [0, 0, 0], normal: [1, 0, 0], direction: along}}
    """)
    trajectory = api.simulate(loaded)
    (reading,) = api.stopwatch_readings(loaded.spec.stopwatches, trajectory)
    return trajectory, reading.elapsed


def exact_period(amplitude_deg: float, length: float = 1.0) -> float:
    """T = 4 √(L/g) K(k²), k = sin(θ₀/2): the pendulum's period at any amplitude."""
    return 4 * np.sqrt(length / G) * ellipk(np.sin(np.radians(amplitude_deg) / 2) ** 2)


@pytest.mark.slow
@pytest.mark.parametrize("amplitude", [5.0, 90.0, 170.0])
def test_a_pendulum_on_a_rod_keeps_the_elliptic_integral_period(amplitude):
    trajectory, period = pendulum(amplitude, "{method: DOP853, rtol: 1.0e-11, atol: 1.0e-13}",
                                  duration=3 * exact_period(amplitude))
    assert period == pytest.approx(exact_period(amplitude), rel=1e-7)
    if amplitude == 5.0:
        assert period == pytest.approx(2 * np.pi * np.sqrt(1 / G), rel=1e-3)  # the small-angle period
    assert trajectory.ledger["joints"]["max_violation"] < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("method", ["verlet", "symplectic_euler", "backward_euler"])
def test_fixed_step_methods_keep_the_rod_exactly_and_the_period_to_their_order(method):
    trajectory, period = pendulum(60.0, f"{{method: {method}, dt: 0.001}}", duration=2.5 * exact_period(60.0))
    assert trajectory.ledger["joints"]["max_violation"] < 1e-12  # projected after every step
    assert period == pytest.approx(exact_period(60.0), rel=2e-3)


DOUBLE = """
    duration: {duration}
    fps: 30
    solver: {solver}
    anchors: [{{name: pivot, position: [0, 0, 0]}}]
    bodies:
      - {{name: upper, mass: 1.0, position: [1.0, 0, 0]}}
      - {{name: lower, mass: 0.5, position: [1.0, -0.8, 0.0]}}
    joints:
      - {{type: distance, between: [pivot, upper]}}
      - {{type: distance, between: [upper, lower]}}
    fields: [{{type: gravity}}]
"""


def energy(trajectory) -> np.ndarray:
    mass = np.array([1.0, 0.5])
    kinetic = 0.5 * np.einsum("p,fpi,fpi->f", mass, trajectory.velocities, trajectory.velocities)
    return kinetic + G * trajectory.positions[:, :, 1] @ mass


def test_a_chaotic_double_pendulum_keeps_its_energy_and_its_rods_with_an_adaptive_method():
    """Positions diverge (chaos), so the invariants are checked: at rtol 1e-8 over 10 s the rods stay within
    1e-6 m (the issue's bound) and the energy within 1e-6 of its scale."""
    trajectory = api.simulate(scene(DOUBLE.format(duration=10, solver="{method: DOP853, rtol: 1.0e-8, atol: 1.0e-10}")))
    assert trajectory.ledger["joints"]["max_violation"] < 1e-6
    e = energy(trajectory)
    assert np.abs(e - e[0]).max() < 1e-6 * 15  # scale: M g L ≈ 1.5 · 9.81 · 1
    assert trajectory.ledger["conservation"]["energy"]["conserved"]


@pytest.mark.slow
@pytest.mark.parametrize("method", ["verlet", "symplectic_euler", "backward_euler"])
def test_fixed_step_methods_keep_the_rods_and_any_energy_gain_is_their_error_shrinking_with_the_step(method):
    """The projection keeps the rods to rounding after every step. A chaotic double pendulum moves fast, and a
    first-order method's energy wanders by O(h): halving the step must shrink any gain accordingly (it is the
    method's error, not a leak), and Verlet's stays small."""
    gains = []
    for dt in (0.001, 0.0005):
        trajectory = api.simulate(scene(DOUBLE.format(duration=2, solver=f"{{method: {method}, dt: {dt}}}")))
        assert trajectory.ledger["joints"]["max_violation"] < 1e-10
        e = energy(trajectory)
        gains.append(max((e - e[0]).max(), 0.0))
    assert gains[1] <= 0.6 * gains[0] + 1e-6, gains
    if method == "verlet":
        assert gains[1] < 0.01


ONE_KICK_PENDULUMS = {
    "bob on a rod": """
        anchors: [{name: pivot, position: [0, 0, 0]}]
        bodies: [{name: bob, mass: 0.1, position: [0.05, 0, 0]}]
        joints: [{type: distance, between: [pivot, bob]}]
        """,
    "bar on a hinge": """
        bodies: [{name: bar, type: rigid, shape: {type: box, size: [0.1, 0.02, 0.02]}, mass: 0.1,
                  position: [0.05, 0, 0]}]
        joints: [{type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]}]
        """,
}


@pytest.mark.slow
@pytest.mark.parametrize("method, form, duration", [("symplectic_euler", "compiled", 3.0),
                                                    ("symplectic_euler", "numpy", 1.0),
                                                    ("backward_euler", "compiled", 2.0)])
@pytest.mark.parametrize("name", list(ONE_KICK_PENDULUMS))
def test_one_kick_methods_keep_a_pendulums_energy_bounded_swing_after_swing(name, method, form, duration):
    """A 5 cm pendulum released from the horizontal (ω up to 17 rad/s) at dt 1 ms under the one-kick methods, for
    9 swings (3 s) where a step is one compiled call, 3 where it is numpy: symplectic Euler's energy error is
    O(h ω) and bounded, so it stays within 2 % of m g L all run. The projection that put the bob back on its rod
    without changing its momentum gained about (h ω)² of the kinetic energy a step: the energy doubled every 5 s
    (7-20 % of m g L in the first second; the pendulum swung ever higher) and a 20-bar chain blew up in 1.1 s. Both
    forms of the equations of motion (numpy, compiled); backward Euler takes the same steps with joints."""
    if form == "compiled":
        pytest.importorskip("numba")
    from animbatch.compile.integrator import make_integrator
    from animbatch.compile.model import compile_scene
    from animbatch.sim.model.compiled import CompiledDynamics
    from animbatch.sim.model.dynamics import Dynamics

    body = "\n".join(line[8:] for line in ONE_KICK_PENDULUMS[name].splitlines())
    loaded = scene(f"duration: {duration}\nfps: 100\nsolver: {{method: {method}, dt: 0.001}}\n{body}\n"
                   "fields: [{type: gravity}]\n")
    model = compile_scene(loaded.spec)
    system = CompiledDynamics(model) if form == "compiled" else Dynamics(model)
    result = make_integrator(loaded.spec.solver, model).integrate(system, model.y0, model.frame_times)
    reference = Dynamics(model)
    energy = np.array([reference.energy(0.0, *reference.split(y))[0] for y in result.states])
    scale = 0.1 * G * 0.05  # m g L [J]
    assert np.max(np.abs(energy - energy[0])) < 0.02 * scale
    # and it swings through the bottom at the speed its drop gives it: √(2 g L) for the bob; for the bar (centre
    # 5 cm below the pivot after its drop of L/2, I about the pivot m (L² + w²)/12 + m (L/2)²) ω = √(m g L / I)
    speed = np.linalg.norm(model.velocities(result.states)[:, 0], axis=1)
    inertia = 0.1 * (0.1**2 + 0.02**2) / 12 + 0.1 * 0.05**2
    bottom = np.sqrt(2 * G * 0.05) if name == "bob on a rod" else 0.05 * np.sqrt(0.1 * G * 0.1 / inertia)
    assert speed.max() == pytest.approx(bottom, rel=0.02)


@pytest.mark.slow
def test_a_free_rod_keeps_its_length_momentum_and_angular_momentum():
    """Two particles on a rod, thrown spinning with no forces: the centre of mass moves uniformly and L is
    constant (the rod's tension is internal)."""
    trajectory = api.simulate(scene("""
        duration: 3
        fps: 30
        solver: {method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}
        bodies:
          - {name: a, mass: 1, position: [-0.5, 0, 0], velocity: [0.2, 1.0, 0]}
          - {name: b, mass: 2, position: [0.5, 0, 0], velocity: [0.2, -0.5, 0.3]}
        joints: [{type: distance, between: [a, b]}]
    """))
    mass = np.array([1.0, 2.0])
    momentum = np.einsum("p,fpi->fi", mass, trajectory.velocities)
    np.testing.assert_allclose(momentum, np.broadcast_to(momentum[0], momentum.shape), atol=1e-9)
    spin = np.einsum("p,fpi->fi", mass, np.cross(trajectory.positions, trajectory.velocities))
    np.testing.assert_allclose(spin, np.broadcast_to(spin[0], spin.shape), atol=1e-8)
    length = np.linalg.norm(trajectory.positions[:, 0] - trajectory.positions[:, 1], axis=1)
    np.testing.assert_allclose(length, 1.0, atol=1e-9)
    assert trajectory.ledger["conservation"]["momentum"]["conserved"]


@pytest.mark.parametrize("text, fragment", [
    ("joints: [{type: distance, between: [pivot, bobb]}]", "unknown body or anchor 'bobb'; did you mean 'bob'?"),
    ("joints: [{type: hinge, between: [bob], axis: [0, 0, 1]}]", "'bob' is a particle, which has no orientation"),
    ("joints: [{type: ball, between: [pivot, box]}]", "'pivot' is an anchor; put the body first"),
    ("joints: [{type: hinge, between: [box]}]", "axis"),
    ("joints: [{type: hinge, between: [box], axis: [0, 0, 1], limits: [0.2, 1]}]", "must contain 0"),
    ("joints: [{type: hinge, between: [box], axis: [0, 0, 1], motor: {target: 1}}]", "needs stiffness > 0"),
    ("joints: [{type: slider, between: [box], axis: [1, 0, 0], motor: {damping: 1, max_torque: 2}}]",
     "max_force"),
    ("joints: [{type: ball, between: [box, bob], attach: [[-0.5, 0, 0], null]}]", "1.5 m apart at the start"),
    ("joints: [{type: distance, between: [bob, pivot], attach: [[0, 0, 0], null]}]", "'bob' is a particle"),
    ("joints: [{type: hing, between: [box]}]", "did you mean 'hinge'"),
    ("joints: [{type: distance, between: [bob, bob]}]", "both ends are 'bob'"),
    ("joints: [{type: distance, between: [pivot, bob], length: -1}]", "must be > 0"),
    ("joints: [{type: pulley, between: [bob, pivot], over: [pivot, pivot]}]", "'pivot' is an anchor; a pulley's rope"),
    ("joints: [{type: pulley, between: [bob, box], over: [pivot, pulle]}]", "unknown anchor 'pulle'"),
    ("joints: [{type: pulley, between: [bob, box], over: [pivot, rail]}]", "pulleys are fixed so far"),
])
def test_bad_joints_are_refused_with_the_fix(text, fragment):
    with pytest.raises(SceneError) as error:
        parse_scene("duration: 1\nanchors: [{name: pivot, position: [0, 0, 0]}, {name: rail, keyframes: [{time: 0, position: [0, 0, 0]}, "
              "{time: 1, position: [1, 0, 0]}]}]\nbodies: [{name: bob, position: [1, 0, 0]}, {name: box, "
              "type: rigid, shape: {type: box, size: [1, 1, 1]}, density: 1, position: [3, 0, 0]}]\n" + text,
                    filename="test.yaml")
    assert fragment in str(error.value) and "test.yaml:" in str(error.value)


def test_a_rods_tension_is_a_force_of_its_own_in_the_arrows():
    """A bob hanging at rest on a rod: the rod pulls up with m g, gravity down with m g, and the acceleration is
    zero (the rod's force counts in Σ F)."""
    loaded = scene("""
        duration: 0.5
        fps: 10
        solver: {method: DOP853, rtol: 1.0e-10}
        anchors: [{name: pivot, position: [0, 1, 0]}]
        bodies: [{name: bob, mass: 0.4, position: [0, 0, 0]}]
        joints: [{type: distance, between: [pivot, bob]}]
        fields: [{type: gravity}]
        render: {arrows: {show: [forces, acceleration]}}
    """)
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    arrows = api.frame_geometry(api.plan(loaded, model=model), trajectory).arrows
    vectors = dict(zip(arrows.names, arrows.vectors))
    np.testing.assert_allclose(vectors["joint"][:, 0], np.broadcast_to([0, 0.4 * G, 0], (5, 3)), atol=1e-6)
    np.testing.assert_allclose(vectors["gravity"][:, 0], np.broadcast_to([0, -0.4 * G, 0], (5, 3)), atol=1e-9)
    np.testing.assert_allclose(vectors["acceleration"][:, 0], 0.0, atol=1e-6)


@pytest.mark.slow
def test_a_chain_of_twenty_links_comes_to_rest_as_the_catenary():
    """Twenty rods of 5 cm between anchors 0.8 m apart, settled by light drag. At rest the horizontal tension H is
    the same in every link and each bead turns the chain by its weight, tan θ_k = tan θ₁ + (k − 1) m g / H (the
    discrete catenary, H from the span); the continuous catenary of the same length, 2a sinh(0.4/a) = 1, is within
    the discretisation."""
    from scipy.optimize import brentq

    links, ell, span, m = 20, 0.05, 0.8, 0.01
    alpha = np.arccos(span / (links * ell))  # start as a V with the right link lengths
    corners = np.cumsum([[ell * np.cos(alpha), (-1 if k < links // 2 else 1) * ell * np.sin(alpha), 0]
                         for k in range(links)], axis=0)
    beads = "\n".join(f"  - {{name: b{k}, mass: {m}, position: [{float(corners[k - 1][0])!r}, "
                      f"{float(corners[k - 1][1])!r}, 0]}}" for k in range(1, links))
    ends = ["left"] + [f"b{k}" for k in range(1, links)] + ["right"]
    joints = "\n".join(f"  - {{type: distance, between: [{a}, {b}], length: {ell}}}" for a, b in zip(ends, ends[1:]))
    trajectory = api.simulate(scene(f"""
duration: 8
fps: 10
solver: {{method: verlet, dt: 0.002}}
anchors: [{{name: left, position: [0, 0, 0]}}, {{name: right, position: [{span}, 0, 0]}}]
bodies:
{beads}
joints:
{joints}
fields: [{{type: gravity}}, {{type: drag, model: linear, coefficient: 0.02}}]
"""))
    at_rest = trajectory.positions[-1][:, :2]
    assert np.abs(trajectory.velocities[-1]).max() < 1e-3

    def slopes(tension: float) -> np.ndarray:
        return (np.arange(links) - (links - 1) / 2) * m * G / tension

    tension = brentq(lambda h: np.sum(ell / np.sqrt(1 + slopes(h) ** 2)) - span, 1e-4, 100)
    theta = np.arctan(slopes(tension))
    discrete = np.cumsum(np.stack([ell * np.cos(theta), ell * np.sin(theta)], axis=1), axis=0)[:-1]
    np.testing.assert_allclose(at_rest, discrete, atol=5e-5)
    a = brentq(lambda a: 2 * a * np.sinh(span / 2 / a) - links * ell, 0.05, 10)
    catenary = a * np.cosh((at_rest[:, 0] - span / 2) / a) - a * np.cosh(span / 2 / a)
    assert np.abs(at_rest[:, 1] - catenary).max() < 0.1 * ell  # the discretisation's error, not the solver's


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["{method: DOP853, rtol: 1.0e-9, atol: 1.0e-11}", "{method: verlet, dt: 0.001}"])
def test_a_closed_four_bar_linkage_keeps_its_loop_closed_and_its_energy(solver):
    """Ground link between two fixed pivots, a crank, a coupler and a rocker of point masses: a closed loop of
    rods (maximal coordinates need nothing special for loops). It swings under gravity; every rod keeps its
    length and the energy stays put."""
    trajectory = api.simulate(scene(f"""
        duration: 4
        fps: 30
        solver: {solver}
        anchors: [{{name: a, position: [0, 0, 0]}}, {{name: d, position: [1.0, 0, 0]}}]
        bodies:
          - {{name: b, mass: 0.3, position: [0.0, 0.4, 0]}}
          - {{name: c, mass: 0.5, position: [0.9, 0.5, 0]}}
        joints:
          - {{type: distance, between: [a, b]}}
          - {{type: distance, between: [b, c]}}
          - {{type: distance, between: [c, d]}}
        fields: [{{type: gravity}}]
    """))
    bound = 1e-6 if "DOP853" in solver else 1e-12
    assert trajectory.ledger["joints"]["max_violation"] < bound
    mass = np.array([0.3, 0.5])
    e = 0.5 * np.einsum("p,fpi,fpi->f", mass, trajectory.velocities, trajectory.velocities) \
        + G * trajectory.positions[:, :, 1] @ mass
    assert np.abs(e - e[0]).max() < (1e-6 if "DOP853" in solver else 5e-3) * 10
    assert np.ptp(trajectory.positions[:, 0, 0]) > 0.1, "it moves"


def test_info_lists_the_rods_and_how_they_are_held(tmp_path):
    from click.testing import CliRunner

    from animbatch.cli import cli

    path = tmp_path / "rods.yaml"
    path.write_text("duration: 1\nanchors: [{name: pivot, position: [0, 0, 0]}]\nbodies: [{name: bob, position: [0, -0.5, 0]}]\n"
                    "joints: [{type: distance, between: [pivot, bob]}]\n")
    out = CliRunner().invoke(cli, ["info", str(path)]).output
    assert "joints     1 joint: pivot--bob (rod 0.5 m)" in out


@pytest.mark.parametrize("solver, tolerance", [("{method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}", 1e-8),
                                               ("{method: verlet, dt: 0.001}", 1e-9)])
def test_an_atwood_machine_accelerates_at_the_closed_form_rate(solver, tolerance):
    """Masses of 3 kg and 1 kg on a rope over two pulleys: the heavy one falls at a = (m₁ − m₂) g / (m₁ + m₂) =
    g/2 and the rope's tension is 2 m₁ m₂ g / (m₁ + m₂) = 1.5 g, upwards on each."""
    loaded = scene(f"""
        duration: 0.8
        fps: 20
        solver: {solver}
        anchors: [{{name: p1, position: [-0.2, 2, 0]}}, {{name: p2, position: [0.2, 2, 0]}}]
        bodies:
          - {{name: heavy, mass: 3, position: [-0.2, 1.0, 0]}}
          - {{name: light, mass: 1, position: [0.2, 0.5, 0]}}
        joints: [{{type: pulley, between: [heavy, light], over: [p1, p2]}}]
        fields: [{{type: gravity}}]
        render: {{arrows: {{show: [forces]}}}}
    """)
    model = api.compile_model(loaded)
    trajectory = api.simulate(loaded, model=model)
    t = trajectory.times
    a = (3 - 1) * G / (3 + 1)
    np.testing.assert_allclose(trajectory.positions[:, 0, 1], 1.0 - 0.5 * a * t**2, atol=tolerance)
    np.testing.assert_allclose(trajectory.positions[:, 1, 1], 0.5 + 0.5 * a * t**2, atol=tolerance)
    np.testing.assert_allclose(trajectory.positions[:, :, 0], np.broadcast_to([-0.2, 0.2], (len(t), 2)), atol=1e-9)
    drawn = api.frame_geometry(api.plan(loaded, model=model), trajectory).arrows
    arrows = dict(zip(drawn.names, drawn.vectors))
    np.testing.assert_allclose(arrows["joint"][:, :, 1], 1.5 * G, atol=1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["{method: DOP853, rtol: 1.0e-10, atol: 1.0e-12}", "{method: verlet, dt: 0.001}"])
def test_a_pendulum_from_an_accelerating_anchor_swings_about_the_tilted_vertical(solver):
    """A hand accelerating at a = 3 m/s² sideways (an anchor on keyframes along x = ½ a t²) carries a bob on a 1 m
    rod. In the hand's frame gravity is g' = √(g² + a²), tilted by θ = atan(a/g): released hanging straight down,
    the bob swings between 0 and 2θ with the period 4 √(L/g') K(sin²(θ/2)), and the rod holds."""
    a = 3.0
    keys = ", ".join(f"{{time: {t:.1f}, position: [{float(0.5 * a * t * t)!r}, 0, 0]}}" for t in np.linspace(0, 8, 81))
    loaded = scene(f"""
        duration: 6
        fps: 100
        solver: {solver}
        anchors: [{{name: hand, keyframes: [{keys}], interpolation: cubic}}]
        bodies: [{{name: bob, mass: 1.0, position: [0, -1, 0]}}]
        joints: [{{type: distance, between: [hand, bob]}}]
        fields: [{{type: gravity}}]
    """)
    trajectory = api.simulate(loaded)
    relative = trajectory.positions[:, 0] - np.stack([0.5 * a * trajectory.times**2, 0 * trajectory.times,
                                                      0 * trajectory.times], axis=1)
    angle = np.arctan2(-relative[:, 0], -relative[:, 1])
    tilt = np.arctan(a / G)
    assert angle.max() == pytest.approx(2 * tilt, abs=2e-4)
    assert angle.min() == pytest.approx(0.0, abs=2e-4)
    turning = trajectory.times[1:-1][np.diff(np.sign(np.diff(angle))) > 0]  # the swing's low points
    gravity = np.hypot(G, a)
    assert np.diff(turning).mean() == pytest.approx(4 * np.sqrt(1 / gravity) * ellipk(np.sin(tilt / 2) ** 2),
                                                    abs=0.011)
    assert trajectory.ledger["joints"]["max_violation"] < 1e-9
