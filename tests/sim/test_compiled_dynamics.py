"""The compiled equations of motion (animbatch.sim.kernels.stepper) against the numpy ones they replace: every form
(right-hand side, kick, drift, projection, a frame of fixed steps) on every kind of joint row, motor, spring and
keyframed anchor, to round-off; and the choice between them."""

from __future__ import annotations

import numpy as np
import pytest

from animbatch.compile.model import compile_scene
from animbatch.sim import kernels
from animbatch.sim.integrators.methods import FIXED_STEP_SCHEMES
from animbatch.sim.kernels import tables as T
from animbatch.sim.model.compiled import CompiledDynamics, dynamics_for, stepper_tables
from animbatch.sim.model.dynamics import Dynamics
from support.scenes import scene

pytest.importorskip("numba", reason="numba is not installed: numpy integrates every body")

BAR = "shape: {type: box, size: [0.3, 0.04, 0.04]}, density: 700"

#: Scenes with every kind of row, motor, spring and anchor the compiled equations of motion take.
SCENES = {
    "hinge chain with a limit": f"""
        bodies:
          - {{name: a, type: rigid, {BAR}, position: [0.15, 0, 0]}}
          - {{name: b, type: rigid, {BAR}, position: [0.45, 0, 0], angular_velocity: [0, 0.3, 1]}}
          - {{name: c, type: rigid, {BAR}, position: [0.75, 0, 0]}}
        joints:
          - {{type: hinge, between: [a], anchor: [0, 0, 0], axis: [0, 0, 1]}}
          - {{type: hinge, between: [b, a], anchor: [0.3, 0, 0], axis: [0, 0, 1], limits: [-0.5, 0.05]}}
          - {{type: hinge, between: [c, b], anchor: [0.6, 0, 0], axis: [0, 0.6, 0.8]}}
        """,
    "ball joints and a weld": """
        bodies:
          - {name: torso, type: rigid, shape: {type: box, size: [0.2, 0.4, 0.3]}, density: 900,
              position: [0, 1, 0], angular_velocity: [0.4, -0.2, 0.7]}
          - {name: arm, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.3}, density: 900,
              position: [0, 1.1, 0.3], orientation: {axis: [1, 0, 0], angle: 90}, velocity: [0.2, 0, 0]}
          - {name: hand, type: rigid, shape: {type: sphere, radius: 0.04}, density: 900,
              position: [0, 1.1, 0.5]}
        joints:
          - {type: ball, between: [arm, torso], anchor: [0, 1.1, 0.15]}
          - {type: fixed, between: [hand, arm]}
        """,
    "slider with limits and a keyframed motor": """
        bodies:
          - {name: rail, type: rigid, shape: {type: box, size: [1, 0.05, 0.05]}, density: 500, position: [0, 1, 0],
             angular_velocity: [0, 0, 0.3]}
          - {name: cart, type: rigid, shape: {type: box, size: [0.1, 0.1, 0.1]}, density: 500,
             position: [0.1, 1.05, 0], velocity: [0.4, 0, 0]}
        joints:
          - {type: hinge, between: [rail], anchor: [0, 1, 0], axis: [0, 0, 1]}
          - type: slider
            between: [cart, rail]
            axis: [1, 0, 0]
            limits: [-0.3, 0.02]
            motor: {target: [{time: 0, value: 0}, {time: 0.5, value: 0.2}, {time: 1, value: -0.1}], stiffness: 30,
                    damping: 2, max_force: 5}
        """,
    "hinge motor at a speed": f"""
        bodies:
          - {{name: wheel, type: rigid, {BAR}, position: [0.15, 0, 0]}}
        joints:
          - {{type: hinge, between: [wheel], anchor: [0, 0, 0], axis: [0, 0, 1],
              motor: {{speed: 2.0, damping: 0.5, max_torque: 0.05}}}}
        """,
    "rods, a rope and a pulley": """
        anchors:
          - {name: pivot, position: [0, 2, 0]}
          - {name: p1, position: [1, 2, 0]}
          - {name: p2, position: [1.5, 2, 0]}
        bodies:
          - {name: upper, mass: 1.0, radius: 0.05, position: [0.8, 2.0, 0.1], velocity: [0, 0, 0.3]}
          - {name: lower, mass: 0.5, radius: 0.05, position: [0.8, 1.2, 0]}
          - {name: hung, mass: 0.3, radius: 0.05, position: [0.3, 1.0, 0], velocity: [0.5, 0.2, 0]}
          - {name: heavy, mass: 2.0, radius: 0.05, position: [1, 1, 0]}
          - {name: light, mass: 1.0, radius: 0.05, position: [1.5, 0.8, 0]}
        joints:
          - {type: distance, between: [pivot, upper]}
          - {type: distance, between: [upper, lower]}
          - {type: rope, between: [hung, pivot], length: 1.2}
          - {type: pulley, between: [heavy, light], over: [p1, p2]}
        """,
    "springs at body points and anchors on keyframes": """
        anchors:
          - {name: hook, position: [0, 2.5, 0]}
          - name: hand
            keyframes: [{time: 0, position: [1, 2, 0]}, {time: 0.4, position: [1.3, 2.2, 0.1]},
                        {time: 1.2, position: [0.8, 2.1, 0]}]
            interpolation: cubic
          - name: trolley
            keyframes: [{time: 0, position: [-1, 3, 0]}, {time: 0.6, position: [-0.5, 3, 0.2]}]
        bodies:
          - {name: box, type: rigid, shape: {type: box, size: [0.4, 0.4, 0.4]}, density: 600,
             position: [0.3, 1.6, 0.1], angular_velocity: [0.2, 0.5, 0]}
          - {name: ball, mass: 0.2, radius: 0.05, position: [1, 1.5, 0]}
          - {name: crate, type: rigid, shape: {type: box, size: [0.3, 0.3, 0.3]}, density: 300,
             position: [-1, 1.5, 0]}
        springs:
          - {between: [hook, box], stiffness: 800, damping: 30, rest_length: 0.5, attach: [null, [0.2, 0.2, 0.2]]}
          - {between: [hand, ball], stiffness: 50, damping: 0.4}
          - {between: [ball, box], stiffness: 20, attach: [null, [-0.2, 0.1, 0]]}
        joints:
          - {type: distance, between: [crate, trolley], attach: [[0, 0.15, 0], null]}
        """,
    "gravitation and Coulomb pairs": """
        bodies:
          - {name: star, mass: 1.0, radius: 0.1, velocity: [0, -0.001, 0]}
          - {name: planet, mass: 1.0e-3, radius: 0.04, position: [1, 0, 0], velocity: [0, 1, 0]}
          - {name: plus, mass: 0.1, radius: 0.02, charge: 1.0e-5, position: [0, 1, 0]}
          - {name: minus, mass: 0.1, radius: 0.02, charge: -2.0e-5, position: [0.3, 1.2, 0.1]}
        fields:
          - {type: gravity}
          - {type: gravitation, G: 1.0, bodies: [star, planet], softening: 0.01}
          - {type: coulomb, k: 8.99e9, bodies: [plus, minus]}
        """,
    "drag and wind, at centres and at body points": """
        bodies:
          - {name: ball, mass: 0.2, radius: 0.05, velocity: [3, 4, 0]}
          - {name: grain, mass: 0.001, radius: 0.002, position: [0.2, 0, 0], velocity: [0, -2, 1]}
          - {name: kite, type: rigid, shape: {type: box, size: [0.6, 0.05, 0.4]}, density: 100, position: [1, 2, 0],
             velocity: [1, 0, 0.5], angular_velocity: [0.3, 1, -0.4]}
          - {name: log, type: rigid, shape: {type: cylinder, radius: 0.1, length: 0.8}, density: 600,
             position: [-1, 1, 0], velocity: [0, 0, 2], angular_velocity: [2, 0, 0]}
        fields:
          - {type: gravity}
          - {type: drag, model: quadratic, coefficient: 0.02, bodies: [ball, log]}
          - {type: drag, model: stokes, bodies: [grain]}
          - {type: wind, model: linear, coefficient: 0.3, velocity: [4, 0, -1], bodies: [kite, ball], at: [0.3, 0, 0]}
        """,
    "forces at body points, torques and angular drag": """
        bodies:
          - {name: puck, mass: 0.3, radius: 0.04, velocity: [1, 0, 0]}
          - {name: rocket, type: rigid, shape: {type: cylinder, radius: 0.05, length: 0.6}, density: 800,
             position: [0, 1, 0], orientation: {axis: [1, 0, 1], angle: 40}, angular_velocity: [0.5, 0, 1]}
          - {name: top, type: rigid, shape: {type: box, size: [0.2, 0.1, 0.3]}, density: 500, position: [1, 1, 0],
             angular_velocity: [0, 4, 1]}
        fields:
          - {type: gravity}
          - {type: force, force: [0, 12, 1], frame: body, at: [0, -0.3, 0.02], bodies: [rocket, puck]}
          - {type: force, force: [0.5, 0, 0], bodies: [top]}
          - {type: torque, torque: [0, 0, 0.2], frame: body, bodies: [rocket]}
          - {type: torque, torque: [0.1, 0, 0], bodies: [top]}
          - {type: angular_drag, coefficient: 0.05}
        """,
    "buoyancy of spheres, compounds and particles": """
        bodies:
          - {name: ball, type: rigid, shape: {type: sphere, radius: 0.1}, density: 600, position: [0, 0.02, 0],
             velocity: [0.3, -0.2, 0], angular_velocity: [1, 0, 0.5]}
          - name: dumbbell
            type: rigid
            shape: {type: compound, parts: [{shape: {type: sphere, radius: 0.05}, offset: [-0.1, 0, 0]},
                                            {shape: {type: sphere, radius: 0.08}, offset: [0.12, 0, 0]}]}
            density: 700
            position: [1, -0.03, 0]
            orientation: {axis: [0, 0, 1], angle: 30}
            angular_velocity: [0, 0.4, 0.2]
          - {name: drop, mass: 0.002, radius: 0.02, position: [0.5, 0.01, 0.2], velocity: [0, -1, 0]}
          - {name: dry, mass: 0.1, radius: 0.03, position: [0.5, 2, 0]}
        fields:
          - {type: gravity}
          - {type: buoyancy, density: 1000, level: 0, linear_damping: 3, angular_damping: 0.05}
          - {type: buoyancy, density: 1.2, level: 5, bodies: [drop, dry]}
        """,
}


def _model(name: str, solver: str = "{method: verlet, dt: 0.001}"):
    body = "\n".join(line[8:] for line in SCENES[name].splitlines())
    text = (f"duration: 0.2\nfps: 20\nsolver: {solver}\n" + body
            + ("" if "fields:" in body else "\nfields: [{type: gravity}]\n"))
    return compile_scene(scene(text).spec)


def _states(model, count: int = 3) -> list[np.ndarray]:
    """The start, and states near it (every component nudged), re-normalised and put back on the joints."""
    rng = np.random.default_rng(7)
    found = [model.y0.copy()]
    for _ in range(count - 1):
        y = model.y0 + 0.02 * rng.normal(size=model.y0.shape)
        Dynamics(model).project(y, joints=False)
        found.append(y)
    return found


@pytest.fixture(params=list(SCENES))
def both(request) -> tuple[Dynamics, CompiledDynamics]:
    """A scene's numpy and compiled Dynamics."""
    model = _model(request.param)
    return Dynamics(model), CompiledDynamics(model)


def _close(numpy_value: np.ndarray, compiled_value: np.ndarray, scale: float | None = None) -> None:
    scale = max(float(np.max(np.abs(numpy_value))), 1.0) if scale is None else scale
    np.testing.assert_allclose(compiled_value, numpy_value, rtol=0, atol=1e-11 * scale)


def test_the_right_hand_side_is_the_numpy_one(both):
    """dy/dt, with Baumgarte stabilisation and without, at the start and at states off the joints."""
    numpy_system, compiled = both
    for stabilisation in (20.0, 0.0):
        numpy_system.joint_stabilisation = compiled.joint_stabilisation = stabilisation
        for t, y in zip((0.0, 0.13, 0.61), _states(numpy_system.model)):
            _close(numpy_system.rhs(t, y), compiled.rhs(t, y))


def test_the_kick_and_the_drift_are_the_numpy_ones(both):
    numpy_system, compiled = both
    for t, y in zip((0.0, 0.37, 0.9), _states(numpy_system.model)):
        config, motion = numpy_system.split(y)
        _close(numpy_system.motion_rate(t, config, motion), compiled.motion_rate(t, config, motion))
        moved = [y.copy(), y.copy()]
        for system, state in zip((numpy_system, compiled), moved):
            system.drift(*system.split(state), 0.01)
        _close(moved[0], moved[1])


def test_the_projection_is_the_numpy_one(both):
    """Positions, orientations and velocities put back on the joints (ropes and limits within reach stop)."""
    numpy_system, compiled = both
    for t, y in zip((0.0, 0.2, 0.7), _states(numpy_system.model)):
        projected = [y.copy(), y.copy()]
        for system, state in zip((numpy_system, compiled), projected):
            system.project(state, reach=1e-3, t=t)
        _close(projected[0], projected[1])


def test_the_shake_projection_after_a_one_kick_step_is_the_numpy_one(both):
    """After a symplectic Euler step (kick, drift), the projection that moves along the rows at the step's start and
    changes the momenta with the positions, over the bilateral rows (limits and ropes at their stops then by the
    plain projection): the same state from both forms, a keyframed anchor placed at the step's start for those
    rows."""
    numpy_system, compiled = both
    model = numpy_system.model
    if model.joints is None:
        pytest.skip("no joints")
    h = 0.004
    for t, y in zip((0.0, 0.2, 0.7), _states(model)):
        numpy_system.project(y, t=t)
        start = numpy_system.split(y)[0].copy()
        config, motion = numpy_system.split(y)
        motion += h * numpy_system.motion_rate(t, config, motion)
        numpy_system.drift(config, motion, h)
        projected = [y.copy(), y.copy()]
        for system, state in zip((numpy_system, compiled), projected):
            system.project(state, t=t + h, start=start, step=h)
        _close(projected[0], projected[1])
        plain = y.copy()
        numpy_system.project(plain, t=t + h)
        assert np.max(np.abs(plain - projected[0])) > 1e-12  # SHAKE's momenta differ from the plain projection's


def test_the_projection_lands_on_the_joints_from_states_well_off_them(both):
    """From states 2 cm and 0.02 rad off every joint, both forms end within the projection's tolerance of holding,
    whether a step reuses the last factorisation (a chord step) or factors again. (Chord steps from far off
    converge too slowly to get there in the iterations allowed: the test fails if they are taken whatever the last
    step cut.)"""
    numpy_system, compiled = both
    model = numpy_system.model
    if model.joints is None:
        pytest.skip("no joints")
    for t, y in zip((0.2, 0.7), _states(model)[1:]):
        for system in (numpy_system, compiled):
            state = y.copy()
            system.project(state, reach=1e-3, t=t)
            motion = model.joints.motion(numpy_system.kinematics(*numpy_system.split(state), t=t))
            assert np.max(model.joints.violation(motion)) <= 1e-12, type(system).__name__


def test_the_velocity_projection_of_a_contact_solve_is_the_numpy_one(both):
    """The joints' share of a jointed contact solve (velocities only, at given positions, limits within reach of
    their stops losing an approaching rate): the same v and ω, from states on and off the joints."""
    numpy_system, compiled = both
    if numpy_system.model.joints is None:
        pytest.skip("no joints")
    for t, y in zip((0.0, 0.3, 0.8), _states(numpy_system.model)):
        results = []
        for system in (numpy_system, compiled):
            state = numpy_system.kinematics(*numpy_system.split(y), t=t, copy=True)
            v = state.v + 0.1  # velocities the joints do not allow
            omega = None if state.omega is None else state.omega - 0.2
            given = np.concatenate([v.ravel(), [] if omega is None else omega.ravel()])
            system.project_velocities(state, v, omega)
            results.append(np.concatenate([v.ravel(), [] if omega is None else omega.ravel()]))
        assert np.max(np.abs(results[0] - given)) > 1e-3  # the projection did change them
        _close(*results)


def test_the_joint_rows_a_contact_solve_reads_are_the_numpy_ones(both):
    """The rows that hold at a state, as the Jacobian over the flat velocity that the jointed contact solve takes:
    the same entries, at states on and off the joints."""
    numpy_system, compiled = both
    if numpy_system.model.joints is None:
        pytest.skip("no joints")
    size = numpy_system.model.body_count + 1
    for t, y in zip((0.0, 0.3, 0.8), _states(numpy_system.model)):
        state = numpy_system.kinematics(*numpy_system.split(y), t=t, copy=True)
        matrices = [system.velocity_rows(state, size).toarray() for system in (numpy_system, compiled)]
        assert matrices[0].shape == matrices[1].shape and np.count_nonzero(matrices[0])
        _close(*matrices)
        for system, sparse in zip((numpy_system, compiled), matrices):  # the array form (small systems): the same
            np.testing.assert_array_equal(system.velocity_rows(state, size, dense=True), sparse)


def test_engaged_stops_are_the_numpy_ones():
    """The adaptive methods' events choose which limits act: the compiled forces follow the same choice."""
    model = _model("hinge chain with a limit")
    numpy_system, compiled = Dynamics(model), CompiledDynamics(model)
    y = _states(model)[1]
    lower = np.zeros(len(model.joints.row_is_unilateral), bool)
    lower[np.flatnonzero(model.joints.row_is_unilateral)[0]] = True  # both stops at once would be singular
    for engaged in (np.zeros_like(lower), lower):
        numpy_system.engaged_stops = compiled.engaged_stops = engaged
        _close(numpy_system.rhs(0.1, y), compiled.rhs(0.1, y))


@pytest.mark.parametrize("method", [name for name, scheme in FIXED_STEP_SCHEMES.items()
                                    if name != "backward_euler"])
def test_a_frame_of_fixed_steps_in_one_call_is_the_numpy_schemes(method):
    """Twenty steps of each explicit method, one compiled call, against the numpy scheme step by step: states and
    right-hand sides counted."""
    model = _model("rods, a rope and a pulley", f"{{method: {method}, dt: 0.001}}")
    results = []
    for system in (Dynamics(model), CompiledDynamics(model)):
        scheme = FIXED_STEP_SCHEMES[method](system)
        system.joint_stabilisation = 0.0
        y = model.y0.copy()
        system.project(y)
        scheme.start(0.0, y)
        if isinstance(system, CompiledDynamics):
            scheme.evaluations += system.advance(scheme.compiled_form(), y, 0.0, 0.001, 20)
        else:
            for i in range(20):
                scheme.step(i * 0.001, y, 0.001)
        results.append((y, scheme.evaluations))
    (numpy_y, numpy_count), (compiled_y, compiled_count) = results
    _close(numpy_y, compiled_y)
    assert compiled_count == numpy_count


@pytest.mark.parametrize("name", ["ball joints and a weld", "springs at body points and anchors on keyframes"])
def test_a_frame_of_symplectic_euler_steps_with_shake_is_the_numpy_schemes(name):
    """Twenty symplectic Euler steps on joints without limits or ropes (each projected by SHAKE from its start),
    one compiled call, against the numpy scheme step by step."""
    model = _model(name, "{method: symplectic_euler, dt: 0.002}")
    results = []
    for system in (Dynamics(model), CompiledDynamics(model)):
        scheme = FIXED_STEP_SCHEMES["symplectic_euler"](system)
        system.joint_stabilisation = 0.0
        y = model.y0.copy()
        system.project(y)
        if isinstance(system, CompiledDynamics):
            system.advance(scheme.compiled_form(), y, 0.0, 0.002, 20)
        else:
            for i in range(20):
                scheme.step(i * 0.002, y, 0.002)
        results.append(y)
    _close(*results)


def test_the_projection_settings_are_the_numpy_ones():
    """The kernels keep their own copies of the projection's settings (a constant imported from the numpy side
    would be frozen into numba's cache, which only the kernels' own sources key): each must equal the numpy one."""
    from animbatch.sim import joints
    from animbatch.sim.kernels import stepper

    for name in ("PROJECTION_ITERATIONS", "PROJECTION_TOLERANCE", "ACTIVE_SET_PASSES", "CHORD_CONTRACTION",
                 "SHAKE_CONTRACTION"):
        assert getattr(stepper, name) == getattr(joints, name), name


def test_a_wrong_table_is_caught():
    """The comparison is sharp: a joint offset moved by a tenth of a millimetre in the tables shows."""
    model = _model("ball joints and a weld")
    numpy_system = Dynamics(model)
    tables = stepper_tables(model)
    tables[T.POINT_OFFSETS][0, 0, 0] += 1e-4
    y = _states(model)[1]
    with pytest.raises(AssertionError):
        _close(numpy_system.rhs(0.1, y), CompiledDynamics(model, tables).rhs(0.1, y))


def test_models_the_kernels_do_not_cover_say_why():
    """Clocks and terms without a compiled form keep the numpy equations, and the reason is given (buoyancy is
    compiled for bodies of spheres, not for the surface pieces of a box)."""
    cases = {
        "its electromagnetic term has no compiled form": "fields: [{type: electromagnetic, E: [0, 1, 0]}]",
        "its buoyancy term has no compiled form": "  - {name: b, type: rigid, shape: {type: box, size: [1, 1, 1]}, "
                                                  "density: 500}\nfields: [{type: buoyancy, density: 1000}]",
        "it has proper-time clocks": "clocks: {bodies: [p], c: 100}",
    }
    for reason, extra in cases.items():
        text = ("duration: 1\nfps: 10\nbodies:\n  - {name: p, type: rigid, shape: {type: sphere, radius: 0.1}, "
                "density: 500, charge: 1.0e-6, position: [0, 1, 0]}\n" + extra + "\n")
        model = compile_scene(scene(text).spec)
        assert stepper_tables(model) == reason
        assert type(dynamics_for(model, 100.0)) is Dynamics


def test_a_long_run_with_nothing_to_compile_is_not_marked_long(monkeypatch):
    """A long run marks its contacts for the compiled search and solve (loading numba, most of a second). A model
    with no compiled form and no contacts (a body in an electric field) has nothing that would use them: it stays an
    ordinary numpy run, and numba is not asked for. The same body over a floor is marked."""
    asked = []
    monkeypatch.setattr(kernels, "compiled_kernels", lambda work=float("inf"): asked.append(work) or work > 0)
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "auto")
    text = ("duration: 1\nfps: 10\nbodies:\n  - {name: p, type: rigid, shape: {type: sphere, radius: 0.1}, "
            "density: 500, charge: 1.0e-6, position: [0, 1, 0]}\nfields: [{type: electromagnetic, E: [0, 1, 0]}]\n")
    free = dynamics_for(compile_scene(scene(text).spec), 100.0)
    assert type(free) is Dynamics and not free.long_run and asked == [0.0]
    floored = dynamics_for(compile_scene(scene(text + "colliders: [{type: plane}]\n").spec), 100.0)
    assert type(floored) is Dynamics and floored.long_run and asked[-1] == kernels.MIN_WORK


def test_the_compiled_equations_are_chosen_where_they_pay(monkeypatch):
    """Compiled when the numpy run is estimated at half a second or more (or when asked for), numpy when it is not
    (loading numba costs about a second, and numpy runs take two to four times their estimate) or when asked for.
    Once a process has loaded the kernels (an earlier run did), a run estimated at 50 ms goes compiled: it pays only
    their setup."""
    model = _model("hinge chain with a limit")
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "auto")
    monkeypatch.setattr(kernels, "_loaded", set())  # as in a fresh process
    assert type(dynamics_for(model, 0.1)) is Dynamics
    assert type(dynamics_for(model, 5.0)) is CompiledDynamics
    assert kernels.kernels_loaded(kernels.STEPPER_KERNELS)
    assert type(dynamics_for(model, 0.1)) is CompiledDynamics
    assert type(dynamics_for(model, 0.01)) is Dynamics
    floored = compile_scene(scene("duration: 1\nfps: 10\nbodies:\n  - {name: p, mass: 1, radius: 0.1, "
                                  "position: [0, 1, 0]}\nfields: [{type: gravity}]\n"
                                  "colliders: [{type: plane}]\n").spec)
    monkeypatch.setattr(kernels, "_loaded", {kernels.STEPPER_KERNELS})  # contacts need theirs loaded too
    assert not dynamics_for(floored, 0.1).long_run
    monkeypatch.setattr(kernels, "_loaded", {kernels.STEPPER_KERNELS, kernels.CONTACT_KERNELS})
    assert dynamics_for(floored, 0.1).long_run
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    assert type(dynamics_for(model, 0.1)) is CompiledDynamics
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
    assert type(dynamics_for(model, 100.0)) is Dynamics


@pytest.mark.slow
def test_with_contacts_the_compiled_forms_take_the_steps_around_the_numpy_contact_solve(monkeypatch):
    """A hinged bar swinging down onto a floor and a box landing beside it: the compiled kick, drift and projection
    with the numpy contact solve between them give the numpy run's motion, frame by frame: to round-off until the
    bar lands (after 0.12 s), and to a centimetre after. (The bar lands on two corners at once and the box on
    several, redundant contacts whose impulse solve stops at its iteration limit somewhere along the directions
    the contacts leave free; where it stops moves by a percent of an impulse when its inputs move by round-off.)"""
    from animbatch import api

    text = f"""
        duration: 0.5
        fps: 20
        solver: {{method: symplectic_euler, dt: 0.001}}
        bodies:
          - {{name: bar, type: rigid, {BAR}, position: [0.15, 0.1, 0]}}
          - {{name: box, type: rigid, shape: {{type: box, size: [0.1, 0.1, 0.1]}}, density: 500,
              position: [-0.3, 0.2, 0], angular_velocity: [1, 2, 0]}}
        joints:
          - {{type: hinge, between: [bar], anchor: [0, 0.1, 0], axis: [0, 0, 1]}}
        colliders: [{{type: plane}}]
        fields: [{{type: gravity}}]
    """
    runs = {}
    for choice in ("numpy", "numba"):
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, choice)
        runs[choice] = api.simulate(scene(text))
    assert runs["numba"].solver_stats["impacts"]  # the bodies did meet the floor
    before = runs["numpy"].times < 0.12
    for name, landed in (("positions", 1e-2), ("orientations", 1e-2)):
        compiled, numpy_run = getattr(runs["numba"], name), getattr(runs["numpy"], name)
        np.testing.assert_allclose(compiled[before], numpy_run[before], rtol=0, atol=1e-9)
        np.testing.assert_allclose(compiled, numpy_run, rtol=0, atol=landed)


def test_info_says_whether_a_scene_has_compiled_equations_of_motion_and_why_not():
    """'animbatch info' names the kernels line: compiled where every part has a compiled form, else the reason."""
    from animbatch.compile.plan import plan_run
    from animbatch.info import describe_model

    jointed = scene("duration: 1\nfps: 10\n" + "\n".join(line[8:] for line in SCENES["rods, a rope and a pulley"]
                                                          .splitlines()))
    assert "kernels    the equations of motion have a compiled form" in describe_model(
        plan_run(jointed))
    dragged = scene("duration: 1\nfps: 10\nbodies: [{name: p, type: rigid, shape: {type: sphere, radius: 0.1}, "
                    "density: 500, charge: 1.0e-6}]\nfields: [{type: electromagnetic, E: [0, 1, 0]}]\n")
    assert ("kernels    numpy equations of motion: its electromagnetic term has no compiled form"
            in describe_model(plan_run(dragged)))
