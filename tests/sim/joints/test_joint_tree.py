"""Trees of hinges and sliders stepped in joint coordinates (animbatch.sim.joints.tree and its compiled form): which
joints make one, the articulated-body accelerations against the maximal-coordinates equations, closed forms (the
compound pendulum's period at a finite amplitude, a block on a spring), energy, joints held exactly, and the
compiled steps against the numpy reference."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
from scipy.special import ellipk

from animbatch.compile.integrator import make_integrator
from animbatch.compile.model import compile_scene
from animbatch.sim.forces import Kinematics
from animbatch.sim.integrators.methods import FIXED_STEP_SCHEMES
from animbatch.sim.joints import tree as reference
from animbatch.sim.joints.tree import JointTree, joint_tree
from animbatch.sim.model.dynamics import Dynamics
from support.scenes import scene

pytest.importorskip("numba", reason="numba is not installed: maximal coordinates step every joint")

from animbatch.sim.kernels import joint_tree as tree_kernel  # noqa: E402
from animbatch.sim.model.compiled import CompiledDynamics  # noqa: E402
from support.paths import REPO

BAR = "type: rigid, shape: {type: box, size: [0.3, 0.04, 0.04]}, density: 700"

#: A branching tree in 3-D: a bar on the world, one child listed first on a tilted hinge, one listed second on
#: a hinge across the first, all moving.
TREE = f"""
    bodies:
      - {{name: a, {BAR}, position: [0.15, 0, 0], angular_velocity: [0, 0, 1.5]}}
      - {{name: b, {BAR}, position: [0.45, 0, 0], angular_velocity: [0, 1.2, 3.1]}}
      - {{name: c, {BAR}, position: [0.3, -0.15, 0], orientation: {{axis: [0, 0, 1], angle: 90}},
         angular_velocity: [2, 0, 1.5]}}
    joints:
      - {{type: hinge, between: [a], anchor: [0, 0, 0], axis: [0, 0, 1]}}
      - {{type: hinge, between: [b, a], anchor: [0.3, 0, 0], axis: [0, 0.6, 0.8]}}
      - {{type: hinge, between: [a, c], anchor: [0.3, 0, 0], axis: [1, 0, 0]}}
    fields: [{{type: gravity}}]
"""

RK4 = (np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0.0]]), np.array([1, 2, 2, 1]) / 6,
       np.array([0, 0.5, 0.5, 1]))


def _model(text: str, solver: str = "{method: verlet, dt: 0.001}", duration: float = 1.0):
    return compile_scene(scene(f"duration: {duration}\nfps: 50\nsolver: {solver}\n" + textwrap.dedent(text)).spec)


def _tree(model) -> JointTree | str:
    rigid = model.rigid
    return joint_tree(model.joints, rigid.mass, rigid.inertia, rigid.inverse_inertia, model.rigid_count,
                      model.particle_count)


def _start(model) -> np.ndarray:
    y = model.y0.copy()
    Dynamics(model).project(y)
    return y


def _forces(model):
    """The applied forces at a maximal state, from the numpy force terms."""
    system = Dynamics(model)

    def forces(t, x, v, rotation, omega):
        force, torque = system.loads(t, Kinematics(x, v, rotation, omega, 0, t))
        return force.copy(), torque.copy()

    return forces


def _energy(model, y: np.ndarray) -> float:
    system = Dynamics(model)
    return system.energy(0.0, *system.split(y))[0]


def test_hinges_from_the_world_out_make_a_tree_parents_first():
    """Each body's parent comes before it; the offsets are the hinge's point in each body; the axis is the hinge's,
    in the body's own axes, whichever end of the joint the body is."""
    model = _model(TREE)
    tree = _tree(model)
    assert isinstance(tree, JointTree)
    names = [model.rigid.names[b] for b in tree.body]
    assert names == ["a", "b", "c"]
    np.testing.assert_array_equal(tree.parent, [-1, 0, 0])
    # c is turned 90° about z: its body x is the world's y, and the hinge sits above it
    np.testing.assert_allclose(tree.child_offset, [[-0.15, 0, 0], [-0.15, 0, 0], [0.15, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(tree.parent_offset, [[0, 0, 0], [0.15, 0, 0], [0.15, 0, 0]], atol=1e-12)
    # b: the world axis (0, 0.6, 0.8) in b's axes (b starts unturned); c: the world x in c's axes (c turned 90° about z)
    np.testing.assert_allclose(np.abs(tree.axis[1]), [0, 0.6, 0.8], atol=1e-12)
    np.testing.assert_allclose(np.abs(tree.axis[2]), [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize("change, reason", [
    ("limits: [-0.5, 0.5]", "not all hinges and sliders without limits"),
    ("motor: {speed: 1.0, damping: 0.5, max_torque: 1.0}", "motors"),
])
def test_a_hinge_with_limits_or_a_motor_keeps_maximal_coordinates(change, reason):
    """Limits and motors are rows the tree does not carry: the joints say why they stay maximal."""
    text = TREE.replace("axis: [1, 0, 0]}", f"axis: [1, 0, 0], {change}}}")
    assert reason in _tree(_model(text))


@pytest.mark.parametrize("change, reason", [
    ("      - {type: hinge, between: [c], anchor: [0.3, -0.3, 0], axis: [1, 0, 0]}\n", "close a loop"),
    ("      - {type: ball, between: [b, c], anchor: [0.6, 0, 0]}\n", "not all hinges and sliders"),
])
def test_a_loop_or_a_ball_joint_keeps_maximal_coordinates(change, reason):
    """A closed loop has no tree; a ball joint is not a hinge."""
    text = TREE.replace("    fields:", change + "    fields:")
    assert reason in _tree(_model(text))


def test_a_particle_or_a_free_body_or_contacts_keep_maximal_coordinates():
    """Every body must hang on the tree, and nothing may touch it."""
    particle = TREE.replace("    joints:", "      - {name: p, mass: 1, radius: 0.05, position: [2, 0, 0]}\n"
                                            "    joints:")
    assert "particles" in _tree(_model(particle))
    free = TREE.replace("    joints:", f"      - {{name: d, {BAR}, position: [2, 0, 0]}}\n    joints:")
    assert "hangs" in _tree(_model(free))
    floor = TREE + "    colliders: [{type: plane, normal: [0, 1, 0], point: [0, -2, 0]}]\n"
    system = CompiledDynamics(_model(floor))
    assert system.tree == "it has contacts"


def _in_both_coordinates(model) -> tuple[np.ndarray, np.ndarray]:
    """The bodies' positions (B, 3) after 0.4 s of RK4 on the joint coordinates (numpy reference, 1 ms) and of RK4
    on the maximal state with its constraint forces and projection (the compiled maximal stepper, 0.1 ms)."""
    tree = _tree(model)
    assert isinstance(tree, JointTree)
    y_tree, y_maximal = _start(model), _start(model)
    reference.advance(tree, ("runge_kutta", RK4), y_tree, 0.0, 1e-3, 400, _forces(model))
    system = CompiledDynamics(model)
    # the maximal stepper itself (CompiledDynamics.advance would take the tree)
    from animbatch.sim.kernels import stepper

    cache = np.zeros(stepper.factor_cache_size(system.tables.layout))
    stepper.advance(y_maximal, 0.0, 1e-4, 4000, stepper.FORM_RUNGE_KUTTA, *RK4, np.zeros(0), system.tables.floats,
                    system.tables.integers, system.tables.layout, cache, system._config_size)
    positions = slice(0, 3 * model.rigid_count)
    return y_tree[positions].reshape(-1, 3), y_maximal[positions].reshape(-1, 3)


def test_the_articulated_body_accelerations_are_the_maximal_coordinates_ones():
    """RK4 on the hinge angles (4th order, 1 ms) against RK4 on the maximal state with its constraint forces and
    projection (0.1 ms), over 0.4 s of a branching 3-D tree: the same motion to the methods' error."""
    model = _model(TREE)
    tree_positions, maximal_positions = _in_both_coordinates(model)
    assert np.abs(tree_positions - maximal_positions).max() < 1e-8
    assert np.abs(tree_positions.ravel() - _start(model)[: 3 * model.rigid_count]).max() > 0.05  # it moved


def _period(text: str, method: str, dt: float, swings: float) -> float:
    """A hinged bar's period [s], stepped compiled, from the times its angle crosses zero downwards (linearly
    interpolated between frames 5 ms apart)."""
    loaded = scene(f"duration: {swings}\nfps: 200\nsolver: {{method: {method}, dt: {dt}}}\n"
                   + textwrap.dedent(text))
    model = compile_scene(loaded.spec)
    system = CompiledDynamics(model)
    assert isinstance(system.tree, JointTree)
    times = np.arange(0.0, swings, 5e-3)
    states = make_integrator(loaded.spec.solver, model).integrate(system, model.y0, times).states
    angle = np.arctan2(states[:, 0], -states[:, 1])  # the centre of mass from the pivot, measured from straight down
    down = np.flatnonzero((angle[:-1] > 0) & (angle[1:] <= 0))
    crossing = times[down] + 5e-3 * angle[down] / (angle[down] - angle[down + 1])
    return float(np.mean(np.diff(crossing)))


@pytest.mark.parametrize("method", ["verlet", "midpoint"])
def test_a_hinged_bar_swings_at_the_compound_pendulum_period_at_a_finite_amplitude(method):
    """A 0.3 m bar hung from one end, let go at 60°: T = 4 √(I_p / (m g d)) K(sin²(θ₀/2)), I_p about the pivot,
    d = 0.15 m; the tree's steps give it to the method's error (2nd order: 1e-7 at 0.2 ms)."""
    text = """
        bodies:
          - {name: bar, type: rigid, shape: {type: box, size: [0.3, 0.04, 0.04]}, density: 700,
             position: [0.1299038106, -0.075, 0], orientation: {axis: [0, 0, 1], angle: -30}}
        joints:
          - {type: hinge, between: [bar], anchor: [0, 0, 0], axis: [0, 0, 1]}
        fields: [{type: gravity}]
    """
    mass = 700 * 0.3 * 0.04 * 0.04
    length, width, d, g = 0.3, 0.04, 0.15, 9.81
    pivot_inertia = mass * (length**2 + width**2) / 12 + mass * d**2
    amplitude = math.radians(60)
    expected = 4 * math.sqrt(pivot_inertia / (mass * g * d)) * ellipk(math.sin(amplitude / 2) ** 2)
    assert _period(text, method, 2e-4, 3.2) == pytest.approx(expected, rel=2e-6)


def test_the_tree_conserves_energy_and_midpoint_converges_at_second_order():
    """No applied force but gravity: the energy changes only by the method's error, and halving the step cuts the
    midpoint method's error four times."""
    model = _model(TREE)
    system = CompiledDynamics(model)
    start = _start(model)
    drift = []
    for dt in (2e-3, 1e-3):
        y = start.copy()
        system.advance(("runge_kutta", (np.array([[0, 0], [0.5, 0]]), np.array([0.0, 1.0]), np.array([0, 0.5]))),
                       y, 0.0, dt, round(1.0 / dt))
        drift.append(abs(_energy(model, y) - _energy(model, start)))
    assert drift[1] < 1e-3 * abs(_energy(model, start)) + 1e-4
    assert 3.0 < drift[0] / drift[1] < 5.5


def test_joints_hold_exactly_and_verlet_takes_two_evaluations_a_step():
    """A run of the tree leaves every hinge row at round-off, and Verlet's closing half kick is corrected once."""
    model = _model(TREE)
    system = CompiledDynamics(model)
    y = _start(model)
    rate = system.motion_rate(0.0, *system.split(y))
    assert system.advance(("verlet", rate), y, 0.0, 1e-3, 500) == 2 * 500 + 1
    joints = model.joints
    state = system.kinematics(*system.split(y), copy=True)
    assert np.abs(joints.violation(joints.motion(state))).max() < 1e-12
    # and the rate it leaves is the maximal dm/dt there, to the step's error
    expected = Dynamics(model).motion_rate(0.5, *system.split(y))
    assert np.abs(rate - expected).max() < 0.05 * np.abs(expected).max()


def test_semi_implicit_euler_keeps_maximal_coordinates_on_a_tree():
    """Symplectic Euler steps the maximal state with its SHAKE projection (which holds a whipping chain's energy
    far better than Euler on the angles): the compiled call is the numpy scheme's, step for step."""
    model = _model(TREE, "{method: symplectic_euler, dt: 0.001}")
    results = []
    for system in (Dynamics(model), CompiledDynamics(model)):
        scheme = FIXED_STEP_SCHEMES["symplectic_euler"](system)
        system.joint_stabilisation = 0.0
        y = _start(model)
        if isinstance(system, CompiledDynamics):
            system.advance(scheme.compiled_form(), y, 0.0, 1e-3, 20)
        else:
            for i in range(20):
                scheme.step(i * 1e-3, y, 1e-3)
        results.append(y)
    np.testing.assert_allclose(results[1], results[0], rtol=0, atol=1e-11)


@pytest.mark.parametrize("form", ["runge_kutta", "symplectic_euler", "verlet"])
@pytest.mark.parametrize("text", ["TREE", "CART_AND_ARM"])
def test_the_compiled_tree_steps_are_the_numpy_reference(form, text):
    """Thirty steps of each form on the branching tree of hinges and on the cart and arm (sliders), from a moving
    state: the compiled call against animbatch.sim.joints.tree.advance, states, evaluations and Verlet's rate to
    round-off."""
    model = _model(globals()[text])
    tree = _tree(model)
    assert isinstance(tree, JointTree)
    system = CompiledDynamics(model)
    start = _start(model)
    reference.advance(tree, ("runge_kutta", RK4), start, 0.0, 1e-3, 100, _forces(model))
    data = {"runge_kutta": RK4, "symplectic_euler": None, "verlet": np.zeros(6 * model.rigid_count)}[form]
    y_numpy, y_compiled = start.copy(), start.copy()
    numpy_count = reference.advance(tree, (form, data), y_numpy, 0.1, 1e-3, 30, _forces(model))
    a, weights, nodes = RK4 if form == "runge_kutta" else (np.zeros((0, 0)), np.zeros(0), np.zeros(0))
    rate = np.zeros(6 * model.rigid_count)
    codes = {"runge_kutta": 0, "symplectic_euler": 1, "verlet": 2}
    compiled_count = tree_kernel.advance(y_compiled, 0.1, 1e-3, 30, codes[form], a, weights, nodes, rate,
                                        *system._tree_tables)
    assert compiled_count == numpy_count
    np.testing.assert_allclose(y_compiled, y_numpy, rtol=0, atol=1e-12)
    assert np.abs(y_numpy - start).max() > 1e-3
    if form == "verlet":
        np.testing.assert_allclose(rate, data, rtol=0, atol=1e-11 * np.abs(data).max())


def test_a_whipping_chain_stays_stable_under_verlet_on_the_angles():
    """20 bars falling from the horizontal, 4 s at 1 ms: the tip whips at tens of rad/s. With the closing half
    kick only predicted, Verlet on the angles goes unstable within 3.2 s; corrected, the energy (scale ~20 J)
    stays within a few joules, as maximal Verlet's does."""
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))
    import peers  # the benchmarks' chain, which MuJoCo's is compared with

    model = compile_scene(scene(peers.chain_scene(duration=4.0)).spec)
    system = CompiledDynamics(model)
    y = _start(model)
    rate = system.motion_rate(0.0, *system.split(y))
    start_energy, worst = _energy(model, y), 0.0
    for frame in range(200):
        system.advance(("verlet", rate), y, frame * 0.02, 1e-3, 20)
        worst = max(worst, abs(_energy(model, y) - start_energy))
    assert np.isfinite(y).all()
    assert worst < 8.0


@pytest.mark.parametrize("method", ["verlet", "midpoint"])
def test_numpy_and_compiled_runs_step_a_tree_alike(method):
    """The numpy equations of motion step a hinge tree in its angles too (numba is only ever an optimisation): a
    run of each, frame for frame, to round-off, with the joints exact in both."""
    loaded = scene(f"duration: 0.4\nfps: 25\nsolver: {{method: {method}, dt: 0.001}}\n" + textwrap.dedent(TREE))
    model = compile_scene(loaded.spec)
    runs = []
    for system in (Dynamics(model), CompiledDynamics(model)):
        assert system.advances((method if method == "verlet" else "runge_kutta", None))
        runs.append(make_integrator(loaded.spec.solver, model).integrate(system, model.y0, model.frame_times))
    numpy_run, compiled_run = runs
    np.testing.assert_allclose(compiled_run.states, numpy_run.states, rtol=0, atol=1e-10)
    assert compiled_run.stats.rhs_evaluations == numpy_run.stats.rhs_evaluations
    joints = model.joints
    system = Dynamics(model)
    for y in numpy_run.states:
        state = system.kinematics(*system.split(y), copy=True)
        assert np.abs(joints.violation(joints.motion(state))).max() < 1e-12
    assert np.abs(numpy_run.states[-1] - numpy_run.states[0]).max() > 0.01  # it moved


#: A cart on a slider along x with a pendulum on a hinge, and a block on a slider along a spinning arm (the arm on
#: a vertical hinge): sliders at the root and under a turning parent (Coriolis and centrifugal terms).
CART_AND_ARM = f"""
    bodies:
      - {{name: cart, type: rigid, shape: {{type: box, size: [0.3, 0.1, 0.2]}}, density: 500, position: [0, 0, 0],
         velocity: [0.4, 0, 0]}}
      - {{name: pole, {BAR}, position: [0.1299, -0.075, 0], orientation: {{axis: [0, 0, 1], angle: -30}}}}
      - {{name: arm, type: rigid, shape: {{type: box, size: [0.6, 0.04, 0.04]}}, density: 700, position: [0.3, 1, 0],
         angular_velocity: [0, 3, 0]}}
      - {{name: block, type: rigid, shape: {{type: box, size: [0.06, 0.06, 0.06]}}, density: 2000,
         position: [0.2, 1.05, 0]}}
    joints:
      - {{type: slider, between: [cart], axis: [1, 0, 0]}}
      - {{type: hinge, between: [pole, cart], anchor: [0, 0, 0], axis: [0, 0, 1]}}
      - {{type: hinge, between: [arm], anchor: [0, 1, 0], axis: [0, 1, 0]}}
      - {{type: slider, between: [arm, block], axis: [1, 0, 0]}}
    fields: [{{type: gravity}}]
"""


def test_sliders_join_the_tree_with_their_axis_in_the_body():
    """A slider at the root and one whose moving body is its second end: both are tree joints, each axis in its
    body's axes."""
    model = _model(CART_AND_ARM)
    tree = _tree(model)
    assert isinstance(tree, JointTree)
    names = [model.rigid.names[b] for b in tree.body]
    assert names == ["cart", "arm", "pole", "block"]
    np.testing.assert_array_equal(tree.slider, [True, False, False, True])
    np.testing.assert_allclose(np.abs(tree.axis[[0, 3]]), [[1, 0, 0], [1, 0, 0]], atol=1e-12)


def test_sliders_in_joint_coordinates_move_as_in_maximal_coordinates():
    """RK4 on the joint positions (1 ms) against RK4 in maximal coordinates with constraint forces (0.1 ms), over
    0.4 s: the cart and pole trade momentum, the block is flung out along the spinning arm; the same motion to the
    methods' error."""
    model = _model(CART_AND_ARM)
    tree_positions, maximal_positions = _in_both_coordinates(model)
    assert np.abs(tree_positions - maximal_positions).max() < 1e-8
    block = list(model.rigid.names).index("block")
    assert np.linalg.norm(tree_positions[block] - _start(model)[3 * block: 3 * block + 3]) > 0.02  # flung out


def test_a_block_on_a_slider_and_a_spring_oscillates_at_its_closed_form_period():
    """A 1 kg block on a horizontal slider, tied to an anchor by a 40 N/m spring, pulled 10 cm: x(t) = 0.1 cos(ω t),
    ω = √(k/m), to Verlet's error on the slider's travel at 1 ms."""
    text = """
        anchors: [{name: wall, position: [-1, 0, 0]}]
        bodies:
          - {name: block, type: rigid, shape: {type: box, size: [0.1, 0.1, 0.1]}, mass: 1.0, position: [0.1, 0, 0]}
        joints: [{type: slider, between: [block], axis: [1, 0, 0]}]
        springs: [{between: [wall, block], stiffness: 40, rest_length: 1.0}]
    """
    loaded = scene("duration: 2\nfps: 50\nsolver: {method: verlet, dt: 0.001}\n" + textwrap.dedent(text))
    model = compile_scene(loaded.spec)
    for system in (Dynamics(model), CompiledDynamics(model)):
        assert isinstance(system.tree, JointTree)
        states = make_integrator(loaded.spec.solver, model).integrate(system, model.y0, model.frame_times).states
        expected = 0.1 * np.cos(np.sqrt(40.0) * model.frame_times)
        np.testing.assert_allclose(states[:, 0], expected, atol=2e-6)
        np.testing.assert_allclose(states[:, 1:3], 0.0, atol=1e-14)  # held on its axis exactly


def test_a_cart_pole_keeps_its_centre_of_mass_where_it_was_along_the_rail():
    """scenes/cart_pole.yaml: nothing pushes along the rail, so the cart and pole's common centre of mass keeps its
    x while the cart runs several centimetres each way (to Verlet's error, 1e-7 m at 1 ms), and the energy holds."""

    from animbatch import api

    loaded = api.load_scene(REPO / "scenes" / "cart_pole.yaml")
    trajectory = api.simulate(loaded)
    masses = np.array([2.0, 0.5])
    x = trajectory.positions[:, :, 0]
    centre = (x * masses).sum(axis=1) / masses.sum()
    assert np.ptp(centre) < 1e-6
    assert np.ptp(x[:, 0]) > 0.05
    assert trajectory.ledger["joints"]["max_violation"] < 1e-12
    assert trajectory.ledger["conservation"]["energy"]["drift"] < 1e-5
