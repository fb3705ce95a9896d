"""The compiled supernodal Cholesky (backward Euler's solver for large cloth) against direct solves, its symbolic
steps against their definitions, and when it is chosen over SuperLU."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from animbatch.compile.model import compile_scene
from animbatch.sim import kernels
from animbatch.sim.integrators import cholesky
from animbatch.sim.integrators.linear_algebra import StepMatrixSolver
from animbatch.sim.model import Dynamics
from support.scenarios import cloth
from support.scenes import run, scene

pytest.importorskip("numba", reason="numba is not installed: SuperLU solves every step")


def step_matrix(resolution: str = "[12, 10]", h: float = 1 / 30, stiffness: float = 2000.0) -> sp.csr_matrix:
    """Backward Euler's ``M − h D − h² K`` (definite derivatives) for a cloth hanging from two corners, at its start
    crumpled a little so that no block is zero by symmetry."""
    model = compile_scene(scene(cloth("{method: backward_euler}", stiffness=stiffness, damping=0.3,
                                      size=resolution)).spec)
    system = Dynamics(model)
    y = model.y0.copy()
    config, motion = system.split(y)
    config[: 3 * system.particles] += np.random.default_rng(1).normal(0, 0.01, 3 * system.particles)
    derivatives, _ = system.force_jacobian(0.0, config, motion, definite=True)
    mass = sp.diags(np.repeat(model.bodies.mass[: system.particles], 3))
    return sp.csr_matrix(mass - h * derivatives.matrix("v") - h * h * derivatives.matrix("x"))


def test_factors_of_a_cloth_step_matrix_solve_it_to_round_off():
    matrix = step_matrix()
    factors = cholesky.SparseCholesky(matrix)
    assert factors.supernode_count < matrix.shape[0] // 3  # particles were grouped into supernodes
    rng = np.random.default_rng(2)
    for _ in range(2):  # and again with new values on the same pattern
        right = rng.standard_normal(matrix.shape[0])
        x = factors.factor(matrix).solve(right)
        assert np.abs(matrix @ x - right).max() < 1e-10 * np.abs(right).max()
        np.testing.assert_allclose(x, spsolve(sp.csc_matrix(matrix), right), rtol=1e-9, atol=1e-12)
        matrix = matrix * 1.5 + sp.identity(matrix.shape[0])
    assert factors.analyses == 1


def test_a_matrix_with_fewer_entries_reuses_the_analysis_and_one_with_more_is_analysed_again():
    matrix = step_matrix()
    factors = cholesky.SparseCholesky(matrix)
    fewer = sp.csr_matrix(sp.diags(matrix.diagonal()))  # scipy drops sums that come out exactly zero
    right = np.ones(matrix.shape[0])
    assert np.abs(fewer @ factors.factor(fewer).solve(right) - right).max() < 1e-10
    assert factors.analyses == 1
    size = matrix.shape[0]
    coupling = sp.csr_matrix(([1e-3, 1e-3], ([0, size - 1], [size - 1, 0])), shape=(size, size))  # far corners
    more = matrix + coupling
    assert np.abs(more @ factors.factor(more).solve(right) - right).max() < 1e-10
    assert factors.analyses == 2


def test_an_indefinite_matrix_is_refused():
    matrix = step_matrix() - 10 * sp.identity(step_matrix().shape[0])
    with pytest.raises(cholesky.NotPositiveDefinite):
        cholesky.SparseCholesky(matrix).factor(matrix)


def test_elimination_tree_and_structures_of_a_path_and_of_an_arrow():
    # a path 0-1-2-3 eliminates in a chain, each column touching only the next
    path = sp.csr_matrix(sp.diags([1.0, 1.0], [-1, 1], shape=(4, 4)))
    parent = cholesky.elimination_tree(path)
    assert parent.tolist() == [1, 2, 3, -1]
    assert [s.tolist() for s in cholesky.column_structures(path, parent)] == [[1], [2], [3], []]
    # an arrow whose hub is last: every column hangs from the hub, and no fill
    arrow = sp.lil_matrix((5, 5))
    arrow[4, :4] = 1.0
    arrow[:4, 4] = 1.0
    arrow = sp.csr_matrix(arrow)
    assert cholesky.elimination_tree(arrow).tolist() == [4, 4, 4, 4, -1]
    # the hub first instead: eliminating it fills everything in, a chain
    hub_first = sp.csr_matrix(arrow[[4, 0, 1, 2, 3]][:, [4, 0, 1, 2, 3]])
    parent = cholesky.elimination_tree(hub_first)
    assert parent.tolist() == [1, 2, 3, 4, -1]
    assert [len(s) for s in cholesky.column_structures(hub_first, parent)] == [4, 3, 2, 1, 0]
    order = cholesky.postorder(np.array([2, 2, -1, 4, -1]))
    assert order.tolist() == [0, 1, 2, 3, 4]
    assert cholesky.postorder(np.array([2, 3, 3, -1])).tolist() == [1, 0, 2, 3]


def test_subtrees_shared_among_threads_cover_every_supernode_once_and_solve_to_round_off():
    """On a 32×32 cloth's matrix, two threads get independent subtrees of about equal cost, everything else (the
    separators above them) is factored after them, each supernode exactly once; the factors still solve it."""
    matrix = step_matrix("[32, 32]")
    factors = cholesky.SparseCholesky(matrix)
    count = factors.supernode_count
    covered = np.zeros(count, int)
    for first, last in zip(factors.task_first, factors.task_last):
        covered[first: last + 1] += 1
    covered[factors.top] += 1
    assert np.all(covered == 1)
    assert len(factors.bin_ptr) - 1 == 2  # both threads have work
    right = np.random.default_rng(3).standard_normal(matrix.shape[0])
    assert np.abs(matrix @ factors.factor(matrix).solve(right) - right).max() < 1e-10 * np.abs(right).max()
    # the scheduler alone, on a tree of unit costs: 0, 1 -> 2; 3 -> 4; 2, 4 -> 5. Splitting at 5 leaves subtrees of
    # 3 and 2; the one of 3 is more than half of 5, so it is split too: {4} and {0, 1}, two each, 2 and 5 on top
    parents = np.array([2, 2, 5, 4, 5, -1])
    tasks, top = cholesky.schedule_subtrees(parents, np.ones(6), 2)
    assert top == [2, 5] and tasks == [[4], [0, 1]]
    assert cholesky.subtree_sizes(parents).tolist() == [1, 1, 3, 1, 2, 6]
    tasks, top = cholesky.schedule_subtrees(parents, np.ones(6), 1)
    assert tasks == [[5]] and top == []


@pytest.mark.slow
def test_backward_euler_gives_the_same_cloth_with_either_solver(monkeypatch):
    """A 16×16 cloth falling from horizontal, one step per frame: the compiled Cholesky (forced) and SuperLU give
    the same motion to round-off, and the run reports the same work."""
    text = cloth("{method: backward_euler, dt: 0.0333333}", stiffness=2000, size="[16, 16]", duration=0.5)
    runs = {}
    for choice in ("numba", "numpy"):
        monkeypatch.setenv(kernels.KERNELS_VARIABLE, choice)
        runs[choice] = run(text, "bodies[sheet].orientation={axis: [1, 0, 0], angle: -90}")[1]
    compiled, plain = runs["numba"], runs["numpy"]
    assert np.abs(compiled.positions - plain.positions).max() < 1e-9
    assert np.ptp(plain.positions[:, :, 1]) > 0.1  # it did fall and swing
    assert compiled.solver_stats["lu_decompositions"] == plain.solver_stats["lu_decompositions"]


def test_the_solver_takes_the_cholesky_for_large_symmetric_matrices_only(monkeypatch):
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "auto")
    solver = StepMatrixSolver()
    small = step_matrix()
    solver.factor(small)
    assert solver.method == "SuperLU"  # below CHOLESKY_MIN_UNKNOWNS numba would not repay its loading
    large = step_matrix("[32, 32]")
    assert large.shape[0] >= 3000
    solver.factor(large)
    assert solver.method == "supernodal Cholesky"
    size = large.shape[0]
    twist = sp.csr_matrix(([0.1, -0.1], ([0, 1], [1, 0])), shape=(size, size))  # antisymmetric, as a magnet's
    factors = solver.factor(large + twist)
    assert solver.method == "SuperLU"
    right = np.ones(size)
    assert np.abs((large + twist) @ factors.solve(right) - right).max() < 1e-9
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
    solver.factor(large)
    assert solver.method == "SuperLU"


def test_kernels_that_fail_to_build_leave_the_cloth_to_superlu_and_say_so(monkeypatch):
    """numba loads but cannot compile the cloth solver's kernels: backward Euler warns once, before the first step,
    and gives the same cloth with the numpy assembly and factorisation (an array's Cholesky, for a cloth this
    small; SuperLU for larger ones)."""
    from numba.core.errors import TypingError

    from animbatch.sim.integrators import linear_algebra
    from animbatch.sim.kernels import spring_assembly

    def broken(*args, **kwargs):
        raise TypingError("no implementation for this machine")

    text = cloth("{method: backward_euler, dt: 0.0333333}", size="[8, 6]", duration=0.2)
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numpy")
    reference = run(text)[1]
    monkeypatch.setenv(kernels.KERNELS_VARIABLE, "numba")
    monkeypatch.setattr(spring_assembly, "scatter_pairs", broken)
    linear_algebra.build_step_kernels.cache_clear()
    try:
        with pytest.warns(RuntimeWarning, match=r"compiled cloth solver could not be built \(TypingError: no impl"):
            fallen = run(text)[1]
    finally:
        linear_algebra.build_step_kernels.cache_clear()
    # the same cloth to rounding: the spring forces still run compiled (their kernel built), which agree with
    # numpy's to the last bit or two, and a position's last bit may round either way
    np.testing.assert_allclose(fallen.positions, reference.positions, rtol=0, atol=1e-12)
