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
        solve = jointed._dense_solver(matrix)
        right = np.arange(len(matrix), dtype=float)
        np.testing.assert_allclose(solve(right), np.linalg.pinv(matrix, hermitian=True) @ right, rtol=1e-8,
                                   atol=1e-10)
        assert ("cho_solve" in solve.__code__.co_names) == by_cholesky


def test_the_inverse_mass_matrix_moves_each_body_by_its_mass_and_world_inertia():
    """``M⁻¹ V`` over the flat velocity ``[v, ω]`` of particles (no inertia), rigid bodies, a body of no mass (a
    moving collider) and the fixed body: ``v / m`` and ``I⁻¹ ω`` body by body."""
    from animbatch.sim.contact.solver import BodyVelocities, inverse_mass_matrix

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
