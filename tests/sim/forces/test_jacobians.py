"""The analytic force Jacobians (for implicit integration) match finite differences at random states."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from animbatch.compile.model import compile_scene
from animbatch.sim.forces.jacobian import ForceJacobian
from animbatch.sim.model import Dynamics
from support.scenes import scene

SCENE = """
    duration: 1
    anchors:
      - {name: hook, position: [0, 2, 0]}
      - {name: rail, keyframes: [{time: 0, position: [1, 2, 0]}, {time: 2, position: [2, 2, 1]}]}
    bodies:
      - {name: a, mass: 0.3, position: [0, 1, 0]}
      - {name: b, mass: 0.7, position: [0.4, 0.8, 0.1]}
      - {name: bead, mass: 0.2, position: [0.5, 0.1, 0], charge: 0.3}
      - {name: crate, type: rigid, shape: {type: box, size: [0.2, 0.2, 0.2]}, density: 300, position: [2, 1, 0]}
      - name: sheet
        type: cloth
        grid: {size: [0.6, 0.4], resolution: [5, 4]}
        position: [0, 0, 1]
        density: 0.3
        structural: {stiffness: 300, damping: 0.4}
        shear: {stiffness: 80, damping: 0.1}
        bend: {stiffness: 10, damping: 0.05}
        dihedral: {stiffness: 0.02, damping: 0.003}
        pin: [{corners: [top-left]}, {vertices: [4], to: crate}]
    springs:
      - {between: [hook, a], stiffness: 120, damping: 0.8, rest_length: 0.5}
      - {between: [a, b], stiffness: 60, damping: 0.3}
      - {between: [b, rail], stiffness: 40, damping: 0.2, rest_length: 0.3}
      - {between: [b, crate], stiffness: 25, damping: 0.1, attach: [null, [0.1, 0.1, 0]]}
    controllers:
      - {body: bead, stiffness: 50, damping: 0.7, target: {type: polyline, points: [[0, 0, 0], [1, 0, 0], [1, 1, 0]]}}
      - {body: a, stiffness: 20, damping: 0.2, target: {type: point, position: [0, 1.5, 0]}}
      - {body: b, stiffness: 30, damping: 0.9, target: {type: parametric, x: "0.5 * cos(s)", y: "0.8 + 0.3 * sin(s)",
         z: "0.1 * s", range: [0, 3]}}
      - {body: b, stiffness: 10, damping: 0.4, target: {type: keyframes, keyframes: [{time: 0, position: [0, 0, 0]},
         {time: 1, position: [1, 1, 1]}], interpolation: cubic}}
    fields:
      - {type: gravity}
      - {type: drag, model: quadratic, coefficient: 0.05, bodies: [a, b]}
      - {type: wind, model: linear, coefficient: 0.02, velocity: [1, 0, 0], bodies: [bead]}
      - {type: electromagnetic, E: [0.5, 0, 0], B: [0.2, -0.4, 1.0]}
"""


def random_state(text: str, seed: int) -> tuple:
    """The model of a scene, its Dynamics, and a state (n,) with the particles moved by up to 10 cm and given random
    velocities (rigid bodies as the scene places them)."""
    model = compile_scene(scene(text).spec)
    dynamics = Dynamics(model)
    rng = np.random.default_rng(seed)
    y = model.y0.copy()
    config, motion = dynamics.split(y)
    n = dynamics.particles
    config[: 3 * n] += rng.uniform(-0.1, 0.1, 3 * n)
    motion[: 3 * n] = rng.normal(0, 1, 3 * n)
    return model, dynamics, y


def finite_difference(dynamics: Dynamics, term, t: float, y: np.ndarray, which: str) -> np.ndarray:
    """Central differences of one term's force on the particles with respect to their positions or velocities."""
    n = dynamics.particles
    config, motion = dynamics.split(y)
    target = config if which == "x" else motion
    result = np.zeros((3 * n, 3 * n))

    def forces() -> np.ndarray:
        state = dynamics.kinematics(*dynamics.split(y), t=t, copy=True)
        force = np.zeros((dynamics.particles + dynamics.rigid, 3))
        torque = np.zeros((dynamics.rigid, 3)) if dynamics.rigid else None
        term.accumulate(t, state, force, torque)
        return force[:n].ravel()

    for column in range(3 * n):
        step = 1e-6 * max(1.0, abs(target[column]))
        saved = target[column]
        target[column] = saved + step
        ahead = forces()
        target[column] = saved - step
        behind = forces()
        target[column] = saved
        result[:, column] = (ahead - behind) / (2 * step)
    return result


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_analytic_jacobian_matches_finite_differences(seed):
    """Springs (to particles, anchors, moving anchors and body points), dampers, quadratic and linear drag, wind, PD
    controllers (point, keyframes, polyline and parametric curve), dihedral springs and the Lorentz force: ∂f/∂x and ∂f/∂v agree with central differences at a
    random state (positions moved by up to 10 cm, random velocities)."""
    model, dynamics, y = random_state(SCENE, seed)
    n = dynamics.particles
    t = 0.7
    checked = set()
    for term in model.force_terms:
        jacobian = ForceJacobian(n)
        state = dynamics.kinematics(*dynamics.split(y), t=t, copy=True)
        if not term.jacobian(t, state, jacobian):
            continue
        checked.add(term.kind)
        for which in ("x", "v"):
            analytic = jacobian.matrix(which).toarray()
            numeric = finite_difference(dynamics, term, t, y, which)
            scale = max(1.0, np.abs(numeric).max())
            assert np.abs(analytic - numeric).max() < 1e-5 * scale, (term.kind, which)
    assert checked >= {"gravity", "spring", "drag", "controller", "dihedral", "electromagnetic"}


@pytest.mark.parametrize("definite", [False, True])
def test_compiled_assembly_gives_the_numpy_step_matrix_and_products(definite):
    """The compiled kernels (spring blocks, their scatter into backward Euler's ``M − h D − h² K`` and the product
    ``K v`` straight from the blocks) against the numpy path, at a random state of the scene above: springs between
    particles, to fixed and moving anchors and to a body point (pairs and single blocks), drag, controllers,
    dihedral springs and a magnetic field (plain blocks, some antisymmetric)."""
    pytest.importorskip("numba")
    model, dynamics, y = random_state(SCENE, 4)
    config, motion = dynamics.split(y)
    n = dynamics.particles
    rng = np.random.default_rng(4)
    mass = np.repeat(model.bodies.mass[:n], 3)
    vector = rng.normal(0, 1, 3 * n)
    results = {}
    for compiled in (False, True):
        jacobian, _ = dynamics.force_jacobian(0.7, config, motion, definite=definite, compiled=compiled)
        step = jacobian.step_matrix(mass, 0.02)
        results[compiled] = (step if isinstance(step, np.ndarray) else step.toarray(), jacobian.product("x", vector),
                             jacobian.product("v", vector))
        if not compiled:  # a few particles: an array, the sum of the sparse matrices to rounding
            assert isinstance(step, np.ndarray)
            summed = (sp.diags(mass) - 0.02 * jacobian.matrix("v") - 0.02**2 * jacobian.matrix("x")).toarray()
            assert np.abs(step - summed).max() <= 1e-12 * np.abs(summed).max()
    for plain, fast in zip(results[False], results[True]):
        assert np.abs(plain - fast).max() <= 1e-12 * np.abs(plain).max()
    assert np.abs(results[True][0] - results[True][0].T).max() > 1e-6  # the magnetic field's ∂f/∂v is in it
    # and the spring blocks of the kernel are the numpy code's, a zero-length spring included
    from animbatch.sim.kernels.spring_assembly import spring_blocks

    springs = next(term for term in model.force_terms if term.kind == "spring")
    axis, relative = rng.normal(0, 1, (springs.springs.count, 3)), rng.normal(0, 1, (springs.springs.count, 3))
    axis[0] = 0.0
    for expected, got in zip(springs._blocks(axis, relative, definite),
                             spring_blocks(axis, relative, springs.springs.stiffness, springs.springs.damping,
                                           springs.springs.rest_length, definite)):
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_system_jacobian_has_the_first_order_form():
    """Dynamics.jacobian is [[0, I], [M⁻¹ ∂f/∂x, M⁻¹ ∂f/∂v]]: compared with differences of the whole rhs."""
    model = compile_scene(scene("""
        duration: 1
        anchors: [{name: top, position: [0, 1, 0]}]
        bodies: [{name: a, mass: 0.5, position: [0.1, 0, 0]}, {name: b, mass: 2, position: [0.3, -0.5, 0.2]}]
        springs: [{between: [top, a], stiffness: 30, damping: 0.5}, {between: [a, b], stiffness: 70, damping: 1}]
        fields: [{type: gravity}, {type: drag, model: quadratic, coefficient: 0.1}]
    """).spec)
    dynamics = Dynamics(model)
    y = model.y0.copy()
    y[6:] = [0.3, -0.2, 0.1, -0.4, 0.5, 0.2]
    analytic = dynamics.jacobian(0.0, y).toarray()
    numeric = np.zeros_like(analytic)
    for column in range(len(y)):
        shifted = y.copy()
        shifted[column] += 1e-6
        ahead = dynamics.rhs(0.0, shifted)
        shifted[column] -= 2e-6
        numeric[:, column] = (ahead - dynamics.rhs(0.0, shifted)) / 2e-6
    assert np.allclose(analytic, numeric, atol=1e-6)


@pytest.mark.slow
def test_newton_matrices_drop_only_the_weak_couplings_and_keep_the_solution():
    """Radau's and BDF's Newton matrices leave out the bend springs of a cloth whose structural springs are 40×
    stiffer (blocks two vertices apart, at most 1.2 % of the diagonal blocks; shear ones are 5 % or more) and keep
    every structural and shear coupling and the diagonal, dropping (i, j) and (j, i) together; BDF then reaches the
    same cloth at every frame, to its tolerance, as with the full matrix."""
    import scipy.sparse as sp

    import animbatch.sim.integrators.linear_algebra as linear_algebra
    from animbatch.sim.integrators import ScipyIntegrator

    loaded = scene("""
        duration: 0.2
        fps: 30
        bodies:
          - name: sheet
            type: cloth
            grid: {size: [0.5, 0.5], resolution: [6, 6]}
            position: [0, 1, 0]
            orientation: {axis: [1, 0, 0], angle: -90}
            density: 0.2
            structural: {stiffness: 2000, damping: 0.3}
            shear: {stiffness: 500, damping: 0.075}
            bend: {stiffness: 50, damping: 0.0075}
            pin: [{corners: [top-left, top-right]}]
        fields: [{type: gravity}]
    """)
    model = compile_scene(loaded.spec)
    dynamics = Dynamics(model)
    y = model.y0 + 1e-3 * np.random.default_rng(3).normal(size=model.y0.shape)
    derivatives, _ = dynamics.force_jacobian(0.0, *dynamics.split(y))
    n = dynamics.particles
    mass = sp.diags(np.repeat(model.bodies.mass[:n], 3))
    h = 0.01  # the springs, not the masses, dominate the diagonal (as at the steps where factorisations cost)
    newton = sp.csr_matrix(mass - h * derivatives.matrix("v") - h * h * derivatives.matrix("x"))
    thinned = linear_algebra.drop_weak_couplings(newton)
    kept_pairs = {(i // 3, j // 3) for i, j in zip(*thinned.nonzero())}
    assert kept_pairs == {(j, i) for i, j in kept_pairs}  # a symmetric matrix would stay symmetric
    assert np.array_equal(thinned.diagonal(), newton.diagonal())
    springs = next(term for term in model.force_terms if term.kind == "spring").springs
    between = ~springs.second_is_anchor
    for first, second, stiffness in zip(springs.first[between], springs.second[between],
                                        springs.stiffness[between]):
        assert ((first, second) in kept_pairs) == (stiffness > 50), (first, second, stiffness)
    solver = {}
    for fraction in (0.0, linear_algebra.WEAK_COUPLING):
        original = linear_algebra.drop_weak_couplings
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(linear_algebra, "drop_weak_couplings", lambda m, f=fraction: original(m, f))
            patch.setattr(linear_algebra, "DENSE_NEWTON_UNKNOWNS", 0)  # sparse factors, as a large cloth's
            solver[fraction] = ScipyIntegrator("BDF", rtol=1e-8, atol=1e-10).integrate(
                Dynamics(model), model.y0, model.frame_times).states
    assert np.abs(solver[0.0] - solver[linear_algebra.WEAK_COUPLING]).max() < 1e-6
    # this cloth's 34 free vertices are few enough for dense factors of the whole matrix: the same cloth again
    assert 3 * n <= linear_algebra.DENSE_NEWTON_UNKNOWNS
    dense = ScipyIntegrator("BDF", rtol=1e-8, atol=1e-10).integrate(Dynamics(model), model.y0, model.frame_times)
    assert np.abs(dense.states - solver[0.0]).max() < 1e-6


@pytest.mark.slow
def test_compiled_spring_forces_are_the_numpy_ones(monkeypatch):
    """Springs between particles, to a fixed anchor and to a moving one, in a cloth and alone: the compiled forces
    (forced) and the numpy ones agree to round-off at a random state; springs at a body point keep to numpy."""
    pytest.importorskip("numba")
    from animbatch.sim import kernels

    text = SCENE.replace("{vertices: [4], to: crate}", "{corners: [top-right]}").replace(
        "      - {between: [b, crate], stiffness: 25, damping: 0.1, attach: [null, [0.1, 0.1, 0]]}\n", "")
    rates, kinds = {}, {}
    for choice in ("numpy", "numba"):
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, choice)
        model, dynamics, y = random_state(text, 5)
        config, motion = dynamics.split(y)
        rates[choice] = dynamics.motion_rate(0.7, config, motion)
        kinds[choice] = next(term for term in model.force_terms if term.kind == "spring").compiled
    assert kinds == {"numpy": False, "numba": True}
    assert np.abs(rates["numba"] - rates["numpy"]).max() <= 1e-12 * np.abs(rates["numpy"]).max()
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    attached = compile_scene(scene(SCENE).spec)  # a spring ends at a point of the crate: numpy
    assert not next(term for term in attached.force_terms if term.kind == "spring").compiled


def test_small_step_matrices_are_factored_densely_and_a_singular_one_is_refused():
    """A step matrix held as an array (a few particles) is solved by Cholesky when symmetric positive definite and
    by LU otherwise (a magnetic field's antisymmetric part), both to rounding; a singular one raises as SuperLU's
    does, so that backward Euler names the springs and masses involved."""
    from animbatch.sim.integrators.linear_algebra import StepMatrixSolver

    rng = np.random.default_rng(2)
    a = rng.normal(size=(9, 9))
    right = rng.normal(size=9)
    for matrix, method in ((a @ a.T + 9 * np.eye(9), "dense Cholesky"), (a @ a.T + 9 * np.eye(9) + (a - a.T), "dense LU")):
        solver = StepMatrixSolver()
        solved = solver.factor(matrix).solve(right)
        assert solver.method == method
        np.testing.assert_allclose(matrix @ solved, right, rtol=0, atol=1e-12 * np.abs(right).max())
    singular = np.ones((3, 3)) - np.eye(3)  # indefinite, and with a zero pivot once its last row is the first's
    singular[2] = singular[0]
    with pytest.raises(RuntimeError, match="singular"):
        StepMatrixSolver().factor(singular)


@pytest.mark.parametrize("coefficients", [(1.0, 0.05), (1.0 + 0.5j, 0.05)], ids=["BDF", "Radau complex"])
@pytest.mark.parametrize("dense", [True, False])
def test_the_newton_matrix_solved_at_half_size_is_the_full_solve(dense, coefficients, monkeypatch):
    """Radau's and BDF's Newton matrix ``P = p I − q J`` of a particle model's ``J = [[0, I], [A, B]]`` solved
    through the velocity system (dense for a few particles, sparse with the weak couplings kept otherwise) gives the
    full system's solution, for BDF's real coefficients and Radau's complex ones (a complex symmetric matrix, which
    no Cholesky may take)."""
    import scipy.sparse as sp

    import animbatch.sim.integrators.linear_algebra as linear_algebra

    rng = np.random.default_rng(6)
    size = 9
    stiffness = rng.normal(size=(size, size))
    a, b = -(stiffness @ stiffness.T) - size * np.eye(size), -0.1 * np.eye(size)
    jacobian = np.block([[np.zeros((size, size)), np.eye(size)], [a, b]])
    p, q = coefficients
    newton = p * np.eye(2 * size) - q * jacobian
    if not dense:
        monkeypatch.setattr(linear_algebra, "DENSE_NEWTON_UNKNOWNS", 0)
        monkeypatch.setattr(linear_algebra, "drop_weak_couplings", sp.csr_matrix)  # every coupling kept
    factors = linear_algebra.SecondOrderFactor(sp.csr_matrix(newton), np.ones(size))
    assert isinstance(factors.factors, linear_algebra.DenseFactors) == dense
    right = rng.normal(size=2 * size) + (1j * rng.normal(size=2 * size) if np.iscomplexobj(newton) else 0.0)
    np.testing.assert_allclose(factors.solve(right), np.linalg.solve(newton, right), rtol=1e-10, atol=1e-12)
