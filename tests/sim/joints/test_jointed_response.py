"""The articulated response of contacts on jointed bodies (animbatch.sim.contact.jointed): ``K = M⁻¹ − M⁻¹ Gᵀ
(G M⁻¹ Gᵀ)⁺ G M⁻¹`` keeps the joints (``G K = 0``), takes away a non-negative part of each row's inverse effective
mass, and the dense form for small systems is the sparse one to round-off, with the Cholesky solve for a tree of
joints and the pseudo-inverse for redundant rows."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from animbatch.sim.contact import jointed
from animbatch.sim.contact.jointed import JointedResponse


def _system(redundant: bool, seed: int = 3) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """Joint rows G (R, 6N) on 5 bodies, an inverse mass matrix (6N, 6N) (SPD 3×3 blocks) and 7 contact responses
    M⁻¹ Jᵀ (6N, 7); with ``redundant``, G repeats a combination of its rows (a closed loop's redundancy)."""
    rng = np.random.default_rng(seed)
    bodies = 5
    rows = rng.normal(size=(9, 6 * bodies)) * (rng.random((9, 6 * bodies)) < 0.4)
    if redundant:
        rows = np.vstack([rows, rows[0] + 2 * rows[3]])
    blocks = [np.eye(3) / rng.uniform(0.5, 3.0) for _ in range(bodies)]
    for _ in range(bodies):
        a = rng.normal(size=(3, 3))
        blocks.append(a @ a.T + np.eye(3))
    inverse = sp.csr_matrix(sp.block_diag(blocks))
    contacts = inverse @ sp.csr_matrix(rng.normal(size=(6 * bodies, 7)) * (rng.random((6 * bodies, 7)) < 0.3))
    return sp.csr_matrix(rows), inverse, sp.csr_matrix(contacts)


@pytest.mark.parametrize("redundant", [False, True])
def test_the_corrected_response_keeps_the_joints_and_loses_effective_mass(redundant):
    rows, inverse, response = _system(redundant)
    system = JointedResponse(rows, inverse)
    corrected = system.correct(response).toarray()
    # a contact impulse moves the bodies within the joints: G K Jᵀ = 0
    np.testing.assert_allclose(rows @ corrected, 0.0, atol=1e-10 * np.abs(response.toarray()).max())
    lost = system.lost(response)
    assert np.all(lost >= -1e-12)
    # what is lost is J M⁻¹ Jᵀ − J K Jᵀ on the diagonal, for J = response rows through the mass
    jacobian = sp.linalg.spsolve(sp.csc_matrix(inverse), sp.csc_matrix(response)).toarray().T
    np.testing.assert_allclose(lost, np.einsum("kj,jk->k", jacobian, response.toarray() - corrected), rtol=1e-9,
                               atol=1e-12)


@pytest.mark.parametrize("redundant", [False, True])
def test_the_dense_form_is_the_sparse_one(redundant, monkeypatch):
    rows, inverse, response = _system(redundant)
    dense = JointedResponse(rows, inverse)
    monkeypatch.setattr(jointed, "DENSE_COLUMNS", 0)
    monkeypatch.setattr(jointed, "DENSE_ROWS", 0)  # the sparse LU too: the other road entirely
    sparse = JointedResponse(rows, inverse)
    assert dense.dense and not sparse.dense
    if redundant:  # a singular system has no LU: only the dense pseudo-inverse takes it
        monkeypatch.setattr(jointed, "DENSE_ROWS", 600)
        sparse = JointedResponse(rows, inverse)
    np.testing.assert_allclose(dense.correct(response).toarray(), sparse.correct(response).toarray(), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(dense.lost(response), sparse.lost(response), rtol=1e-10, atol=1e-13)


def test_a_tree_of_joints_is_solved_by_cholesky_and_redundant_rows_by_the_pseudo_inverse():
    for redundant, by_cholesky in ((False, True), (True, False)):
        rows, inverse, _ = _system(redundant)
        matrix = (rows @ inverse @ rows.T).toarray()
        solve, factor, cholesky = jointed._dense_solver(matrix)
        right = np.arange(len(matrix), dtype=float)
        np.testing.assert_allclose(solve(right), np.linalg.pinv(matrix, hermitian=True) @ right, rtol=1e-8,
                                   atol=1e-10)
        assert ("cho_solve" in solve.__code__.co_names) == by_cholesky == cholesky
        # the factor the compiled rows read: L Lᵀ from the lower triangle, or the pseudo-inverse itself
        lower = np.tril(factor)
        np.testing.assert_allclose(lower @ lower.T if cholesky else factor,
                                   matrix if cholesky else np.linalg.pinv(matrix, hermitian=True), rtol=1e-10,
                                   atol=1e-10)


def test_the_inverse_mass_matrix_moves_each_body_by_its_mass_and_world_inertia():
    """``M⁻¹ V`` over the flat velocity ``[v, ω]`` of particles (no inertia), rigid bodies, a body of no mass (a
    moving collider) and the fixed body: ``v / m`` and ``I⁻¹ ω`` body by body."""
    from animbatch.sim.contact.impulses import BodyVelocities, inverse_mass_matrix

    rng = np.random.default_rng(5)
    count = 7
    inverse_inertia = np.zeros((count, 3, 3))
    for body in range(2, 5):
        a = rng.normal(size=(3, 3))
        inverse_inertia[body] = np.linalg.inv(a @ a.T + np.eye(3))
    inverse_mass = np.concatenate([rng.uniform(0.2, 3.0, 5), [0.0, 0.0]])
    bodies = BodyVelocities(np.zeros((count, 3)), np.zeros((count, 3)), inverse_mass, inverse_inertia)
    v, omega = rng.normal(size=(count, 3)), rng.normal(size=(count, 3))
    moved = inverse_mass_matrix(bodies) @ np.concatenate([v.ravel(), omega.ravel()])
    np.testing.assert_allclose(moved[:3 * count], (inverse_mass[:, None] * v).ravel(), rtol=1e-15)
    np.testing.assert_allclose(moved[3 * count:], np.einsum("bij,bj->bi", inverse_inertia, omega).ravel(),
                               rtol=1e-14, atol=1e-15)


def test_bodies_joined_directly_or_through_others_share_a_group():
    """Joints 0–1 and 1–2 (one through the other), 3–4, and a limit row on body 5 alone: three groups, {0, 1, 2},
    {3, 4}, {5}, and body 6 that nothing holds is its own; an entry stored as zero joins nothing."""
    size = 7
    entries = []  # (row, column, value)
    for row, bodies in enumerate(((0, 1), (1, 2), (3, 4), (5,))):
        for body in bodies:
            entries += [(row, 3 * body, 1.0), (row, 3 * size + 3 * body + 2, 0.5)]  # a linear and an angular column
    entries.append((3, 3 * 6, 0.0))  # body 6 in body 5's row, stored but zero (and row 4 empty)
    row, column, value = map(np.array, zip(*entries))
    matrix = sp.csr_matrix((value, (row, column)), shape=(5, 6 * size))
    assert matrix.nnz == len(entries)
    response = JointedResponse(matrix, sp.identity(6 * size, format="csr"))
    labels = response.groups(size)
    assert labels[0] == labels[1] == labels[2] and labels[3] == labels[4]
    assert len({labels[0], labels[3], labels[5], labels[6]}) == 4
    assert np.array_equal(response.groups(size), labels)  # kept: the same labels from the cache


def test_the_block_inverse_is_the_inverse_mass_matrix():
    """``BlockInverse @ columns`` (a small jointed system's M⁻¹) is the sparse inverse mass matrix's product, body
    by body: particles (no inertia), rigid bodies, a massless moving collider and the fixed body."""
    from animbatch.sim.contact.impulses import BodyVelocities, inverse_mass_matrix
    from animbatch.sim.contact.jointed import BlockInverse

    rng = np.random.default_rng(8)
    count = 6
    inverse_inertia = np.zeros((count, 3, 3))
    for body in (1, 2, 3):
        a = rng.normal(size=(3, 3))
        inverse_inertia[body] = np.linalg.inv(a @ a.T + np.eye(3))
    inverse_mass = np.array([2.0, 0.5, 1.5, 3.0, 0.0, 0.0])
    columns = rng.normal(size=(6 * count, 5))
    expected = inverse_mass_matrix(BodyVelocities(np.zeros((count, 3)), np.zeros((count, 3)), inverse_mass,
                                                  inverse_inertia)) @ columns
    np.testing.assert_allclose(BlockInverse(inverse_mass, inverse_inertia) @ columns, expected, rtol=1e-14,
                               atol=1e-15)


#: A jointed scene small enough for arrays: a plank under a weight on a hinge, a ball-jointed pair tumbling onto it, a
#: particle on a rod to the plank, and a platform on keyframes under them.
JOINTED_SCENE = """
        duration: 0.5
        fps: 10
        solver: {method: symplectic_euler, dt: 0.001}
        bodies:
          - {name: plank, type: rigid, shape: {type: box, size: [0.6, 0.04, 0.2]}, density: 300, position: [0, 0.1, 0]}
          - {name: weight, type: rigid, shape: {type: sphere, radius: 0.08}, density: 8000, position: [0.25, 0.38, 0]}
          - {name: upper, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.38, 0.05], angular_velocity: [1, 0, 2]}
          - {name: lower, type: rigid, shape: {type: capsule, radius: 0.03, length: 0.2}, density: 900,
             position: [-0.1, 0.18, 0.05]}
          - {name: bead, mass: 0.05, radius: 0.02, position: [-0.25, 0.3, -0.05], velocity: [0, 0, 0.5]}
        joints:
          - {type: hinge, between: [weight, plank], anchor: [0.25, 0.12, 0], axis: [0, 0, 1]}
          - {type: ball, between: [upper, lower], anchor: [-0.1, 0.28, 0.05]}
          - {type: distance, between: [bead, plank], attach: [null, [-0.25, 0.0, -0.05]]}
        colliders:
          - {type: plane}
          - type: box
            position: [0, 0.04, 0]
            size: [1.2, 0.08, 0.8]
            keyframes: [{time: 0, offset: [0, 0, 0]}, {time: 0.5, offset: [0.1, 0, 0]}]
        fields: [{type: gravity}]
"""


@pytest.mark.slow
def test_a_small_jointed_systems_rows_are_the_piecewise_ones(monkeypatch):
    """Every third contact step of a jointed scene small enough for arrays (a plank under a weight on a hinge, a
    ball-jointed pair tumbling onto it, a particle on a rod to the plank, and a platform on keyframes under them):
    the rows built at once (``ContactRows._small_jointed``) are the ones built piece by piece as for large systems:
    the Jacobians, the responses within the joints and the effective masses."""
    from animbatch import api
    from animbatch.sim.contact import impulses
    from support.scenes import scene

    original, checked, calls = impulses.ContactRows._small_jointed, [], []

    def compared(rows, jointed):
        original(rows, jointed)
        calls.append(1)
        if len(calls) % 3:  # every third step: the piecewise build is the slow one (tens of milliseconds)
            return
        directions = (rows.normal_row, rows.first_row, rows.second_row)
        expected = {"_jacobian_normal": rows._sparse(directions[:1], response=False),
                    "_jacobian_tangent": rows._sparse(directions[1:], response=False),
                    "_response_normal": jointed.correct(rows._sparse(directions[:1], response=True)),
                    "_response_tangent": jointed.correct(rows._sparse(directions[1:], response=True))}
        for name, matrix in expected.items():
            scale = max(1.0, float(np.abs(matrix).max()))
            np.testing.assert_allclose(rows.__dict__[name], matrix, rtol=0, atol=1e-12 * scale, err_msg=name)
        losses = rows._jointed_losses(directions, jointed)
        for found, row, lost in zip((rows.w_n, rows.w_1, rows.w_2), directions, losses):
            np.testing.assert_allclose(found, rows._jointed_weight(row, *lost), rtol=1e-9)
        checked.append((rows.count, bool(np.any(rows.bodies.driven[rows.b])) if rows.bodies.driven is not None
                        else False))

    monkeypatch.setattr(impulses.ContactRows, "_small_jointed", compared)
    monkeypatch.setenv("ANIMBATCH_KERNELS", "numpy")  # the numpy build at every step (a long run goes compiled)
    # what is checked is the rows; the sweeps that use them (numpy's here, up to 300 a step) are tested elsewhere
    api.simulate(scene(JOINTED_SCENE + "        contacts: {iterations: 20}\n"))
    assert len(checked) > 100 // 3
    assert any(count > 1 for count, _ in checked) and any(on_platform for _, on_platform in checked)


def test_rows_between_two_bodies_of_one_jointed_group_are_the_piecewise_ones():
    """Contacts whose two ends the joints tie together (a forearm on the torso: bodies 0 and 2, joined through 1),
    beside contacts of a body of the group on a free body and on the fixed one: the rows built at once take the pair's
    joint response together (``J K Jᵀ`` of both ends at once), as the piecewise build does."""
    from animbatch.sim.contact.contacts import Contacts
    from animbatch.sim.contact.impulses import BodyVelocities, ContactRows
    from animbatch.sim.contact.jointed import BlockInverse

    rng = np.random.default_rng(11)
    size = 5  # bodies 0, 1, 2 joined in a chain, body 3 free, the fixed body last
    inverse_inertia = np.zeros((size, 3, 3))
    for body in range(4):
        a = rng.normal(size=(3, 3))
        inverse_inertia[body] = np.linalg.inv(a @ a.T + np.eye(3))
    inverse_mass = np.array([1.0, 0.4, 2.0, 0.7, 0.0])
    bodies = BodyVelocities(rng.normal(size=(size, 3)), rng.normal(size=(size, 3)), inverse_mass, inverse_inertia)
    x = rng.normal(size=(size, 3))
    rows = np.zeros((6, 6 * size))  # three rows for each joint, on the linear and angular columns of its two bodies
    for joint, (first, second) in enumerate(((0, 1), (1, 2))):
        for body in (first, second):
            for columns in (slice(3 * body, 3 * body + 3), slice(3 * (size + body), 3 * (size + body) + 3)):
                rows[3 * joint:3 * joint + 3, columns] = rng.normal(size=(3, 3))
    normal = rng.normal(size=(4, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    contacts = Contacts(np.array([0, 2, 1, 3]), np.array([2, 0, -1, 1]), rng.normal(size=(4, 3)), normal,
                        np.zeros(4), np.full(4, 0.5), np.full(4, 0.6), np.full(4, 0.4), np.arange(4),
                        np.zeros(4, np.intp), np.zeros(4, np.intp))
    jointed = JointedResponse(rows, BlockInverse(inverse_mass, inverse_inertia))
    built = ContactRows(contacts, bodies, x, jointed=jointed)
    directions = (built.normal_row, built.first_row, built.second_row)
    assert built.dense
    np.testing.assert_allclose(built._response_normal, jointed.correct(built._sparse(directions[:1], response=True)),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(built._response_tangent, jointed.correct(built._sparse(directions[1:], response=True)),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(built._jacobian_normal, built._sparse(directions[:1], response=False), rtol=0,
                               atol=1e-15)
    losses = built._jointed_losses(directions, jointed)
    for found, row, lost in zip((built.w_n, built.w_1, built.w_2), directions, losses):
        np.testing.assert_allclose(found, built._jointed_weight(row, *lost), rtol=1e-10)
    # and the pair's weight is the pair's own, 1 / (J K Jᵀ) of the normal row through both ends at once, split
    # among the six contact ends on the group
    jacobian = built._jacobian_normal[0]
    assert built.w_n[0] == pytest.approx(1.0 / (6 * (jacobian @ built._response_normal[:, 0])), rel=1e-9)
    # the compiled build, the same
    pytest.importorskip("numba")
    compiled = ContactRows(contacts, bodies, x, jointed=jointed, compiled=True)
    for name in ("_jacobian_normal", "_jacobian_tangent", "_response_normal", "_response_tangent", "w_n", "w_1",
                 "w_2"):
        np.testing.assert_allclose(getattr(compiled, name), getattr(built, name), rtol=1e-10, atol=1e-13,
                                   err_msg=name)


@pytest.mark.slow
def test_the_compiled_small_jointed_rows_are_the_numpy_ones(monkeypatch):
    """Every contact step of the jointed scene above (a plank under a hinged weight, a ball-jointed pair, a particle
    on a rod, a platform on keyframes) and of two bars joined in a closed loop (redundant rows: the pseudo-inverse
    instead of the Cholesky factor): the compiled build of the rows gives numpy's Jacobians, responses within the
    joints and effective masses to round-off."""
    pytest.importorskip("numba")
    from animbatch import api
    from animbatch.sim.contact import impulses
    from support.scenes import scene

    original, checked = impulses.ContactRows._compiled_small_jointed, []

    def compared(rows, jointed, directions):
        original(rows, jointed, directions)
        names = ("_jacobian_normal", "_jacobian_tangent", "_response_normal", "_response_tangent")
        compiled = [rows.__dict__[name].copy() for name in names] + [rows.w_n, rows.w_1, rows.w_2]
        impulses.ContactRows._small_jointed(rows, jointed)
        expected = [rows.__dict__[name] for name in names] + [rows.w_n, rows.w_1, rows.w_2]
        for name, got, want in zip(names + ("w_n", "w_1", "w_2"), compiled, expected):
            scale = max(1.0, float(np.abs(want).max()))
            np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * scale, err_msg=name)
        checked.append(jointed.cholesky)

    monkeypatch.setattr(impulses.ContactRows, "_compiled_small_jointed", compared)
    monkeypatch.setenv("ANIMBATCH_KERNELS", "numba")
    api.simulate(scene(JOINTED_SCENE))
    loop = """
        duration: 0.3
        fps: 10
        solver: {method: symplectic_euler, dt: 0.001}
        bodies:
          - {name: left, type: rigid, shape: {type: box, size: [0.3, 0.04, 0.04]}, density: 500,
             position: [-0.15, 0.1, 0]}
          - {name: right, type: rigid, shape: {type: box, size: [0.3, 0.04, 0.04]}, density: 500,
             position: [0.15, 0.1, 0]}
        joints:
          - {type: hinge, between: [left, right], anchor: [0, 0.1, 0], axis: [0, 0, 1]}
          - {type: ball, between: [left, right], anchor: [0, 0.1, 0]}
        colliders: [{type: plane}]
        fields: [{type: gravity}]
    """
    api.simulate(scene(loop))
    assert len(checked) > 100 and any(checked) and not all(checked)
