"""Contact impulses and contact forces: restitution, non-penetration and Coulomb friction, for all contacts at once.

For contact k between bodies a (the probe's) and b (the solid's, or a fixed collider), with normal n and lever arms
``r_a``, ``r_b`` from the centres of mass to the contact point, the relative velocity at the contact is
``u = (v_a + ω_a × r_a) - (v_b + ω_b × r_b)``. An impulse ``λ d`` along a direction d changes it by
``λ / w(d)`` along d, with ``w(d) = 1/m_a + (r_a × d)·I_a⁻¹(r_a × d) + (same for b)``: impulses change both
linear and angular momentum (``ΔP = λ d``, ``ΔL = r × λ d``), so a box landing on an edge tumbles and a sliding
ball starts to roll. The same rows, with accelerations for velocities and forces for impulses, give the forces of
resting contacts.

Impacts (:func:`solve_impulses`), with Newton's impact law and the lecture notes' coefficient of restitution:

* normal: ``u_n ≥ target``, impulse ``λ_n ≥ 0``, and no impulse where the contact separates by itself. The target is
  ``-e u_n⁻`` (bounce) when the contact approaches faster than ``rest_speed``, 0 (rest) when slower, and, for a
  contact still ``gap`` away, ``-gap / h``: it may close the gap during the step but not pass it (speculative
  contact);
* friction: the tangential impulse makes ``u_t = 0`` if that needs no more than ``μs λ_n`` (sticking: the contact
  holds exactly, and stays stopped once stopped), and is ``μk λ_n`` against the sliding direction otherwise.

Overlapping bodies (depth beyond ``slop``) are pushed apart by a separate *pseudo-velocity* that moves positions only
(split impulse): a velocity bias would turn overlap into kinetic energy and make bodies pop out.

Resting contacts (:func:`solve_forces`): normal forces ``f_n ≥ 0`` keep the gap's second derivative at the value
that holds the contact (plus a small stabilising term), sticking contacts hold the contact point's tangential
acceleration at zero within ``|f_t| ≤ μs f_n``, and sliding ones feel ``μk f_n`` against their slip direction.

All contacts are solved at once by projected Jacobi iterations with *mass splitting* (each of a body's n contacts
sees it with n times its inverse mass, and the updates are summed), which is fully vectorised and converges to the
simultaneous solution; for one contact per body it is exact in one iteration. Contacts that happen one after the
other in time (a Newton's cradle with small gaps, successive bounces) are resolved one after the other.

An elastic impact (e = 1) between two bodies conserves momentum and kinetic energy; an inelastic one (e < 1) loses
exactly ``½ μ (1 - e²) Δv²`` (μ: reduced mass, Δv: approach speed) — the tests check both.
"""

from __future__ import annotations

import functools
import math
import operator
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from animbatch.quaternion import cross
from animbatch.sim.contact.contacts import Contacts
from animbatch.sim.contact.jointed import JointedResponse
from animbatch.sim.kernels.stall import stalled  # (the compiled sweeps' rule too)

#: Fraction of an overlap (beyond the slop) removed per step.
BAUMGARTE = 0.2
#: Overlaps beyond the slop smaller than this fraction of the slop are left alone.
OVERLAP_TOLERANCE = 1e-2
#: With joints, the normals of the contacts on jointed bodies are solved directly every this many sweeps (the sweeps
#: in between settle friction and the other contacts; see JointedNormals).
BLOCK_EVERY = 8
#: Pseudo-velocities are converged when every push meets its target to this fraction of the largest target, or
#: after this many iterations: they only correct positions, a fraction of the overlap per step, so a partly
#: converged push (which pushes less, never the wrong way) is corrected in the next steps.
PUSH_TOLERANCE = 1e-3
PUSH_ITERATIONS = 50


@dataclass
class BodyVelocities:
    """Velocities (or accelerations) and inverse inertias of P bodies, then M moving colliders, and one fixed "body"
    last (the colliders that stay put).

    ``v``, ``omega``: (P + M + 1, 3); ``inverse_mass``: (P + M + 1,); ``inverse_inertia``: (P + M + 1, 3, 3), world
    axes (zero for particles, which do not turn, for the moving colliders and for the fixed body); ``driven``
    (P + M + 1,): the moving colliders, whose velocities are prescribed (None: there are none).
    """

    v: np.ndarray
    omega: np.ndarray
    inverse_mass: np.ndarray
    inverse_inertia: np.ndarray
    driven: np.ndarray | None = None


def inverse_mass_matrix(bodies: BodyVelocities) -> sp.csr_matrix:
    """``M⁻¹`` (6 N, 6 N) over the flat velocity ``V = [v.ravel(), ω.ravel()]`` of the N bodies: the nonzero inverse
    masses on the first 3 N diagonal entries, then each body's world inverse inertia as a full 3 × 3 block, written
    straight into compressed rows (it is built at every contact step of a jointed scene, where scipy's block
    assembly took milliseconds)."""
    count = len(bodies.inverse_mass)
    linear = 3 * count
    masses = np.repeat(np.asarray(bodies.inverse_mass, float), 3)
    moving = np.flatnonzero(masses)
    blocks = np.arange(linear, 2 * linear).reshape(count, 3)  # each body's three angular columns
    indices = np.concatenate([moving, np.repeat(blocks, 3, axis=0).ravel()])
    data = np.concatenate([masses[moving], np.asarray(bodies.inverse_inertia, float).ravel()])
    per_row = np.concatenate([masses != 0, np.full(linear, 3)])
    return sp.csr_matrix((data, indices, np.concatenate([[0], np.cumsum(per_row)])), shape=(2 * linear, 2 * linear))


def tangent_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (K, 3) spanning the plane perpendicular to each normal."""
    helper = np.where(np.abs(normal[:, [0]]) < 0.6, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = cross(normal, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return first, cross(normal, first)


@dataclass(frozen=True)
class _Direction:
    """One row direction d for every contact, with its Jacobian and response precomputed.

    ``ang_a = r_a × d`` (and b): the relative velocity along d is ``(v_a - v_b)·d + ω_a·ang_a - ω_b·ang_b``.
    ``lin_a = d / m_a``, ``turn_a = I_a⁻¹ (r_a × d)`` (and b): what a unit impulse along d does to the bodies.
    """

    d: np.ndarray
    ang_a: np.ndarray
    ang_b: np.ndarray
    lin_a: np.ndarray
    lin_b: np.ndarray
    turn_a: np.ndarray
    turn_b: np.ndarray


#: Row matrices (J, or the response M⁻¹ Jᵀ) of at most this many entries are built as arrays: a product with a few
#: thousand entries costs a microsecond as an array and some twenty as a scipy.sparse matrix (its checks), and the
#: sweeps of a small scene take hundreds of them a step.
DENSE_ENTRIES = 20_000


class FlatVelocities:
    """The flat velocity vector ``V = [v.ravel(), ω.ravel()]`` (6 (P + 1),) of ``bodies`` (``size`` P + 1 of them),
    which the contact sweeps iterate on."""

    bodies: BodyVelocities
    size: int

    def flat(self, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        """``V`` (6 (P + 1),) from linear and angular velocities (default: the bodies')."""
        v = self.bodies.v if v is None else v
        w = self.bodies.omega if w is None else w
        return np.concatenate([v.ravel(), w.ravel()])

    def unflat(self, velocity: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> None:
        """Write ``V`` back into linear and angular velocity arrays (default: the bodies')."""
        v = self.bodies.v if v is None else v
        w = self.bodies.omega if w is None else w
        half = 3 * self.size
        v[:] = velocity[:half].reshape(-1, 3)
        w[:] = velocity[half:].reshape(-1, 3)


def contact_ends(contacts: Contacts, size: int, kinematic: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each contact's two ends (K,) as slots of ``size`` bodies: its probe's body, and the solid's body, the fixed
    one (the last slot) for fixed solids, or the slot ``kinematic`` (K,) gives for a moving collider (−1: none)."""
    b = np.where(contacts.solid_body < 0, size - 1, contacts.solid_body)
    if kinematic is not None:
        b = np.where(kinematic >= 0, kinematic, b)
    return contacts.probe_body, b


@dataclass(frozen=True, eq=False)
class ContactFrame:
    """Where and along what K contacts act: their ends ``a``, ``b`` (K,) (indices into the bodies, the fixed one
    last; a moving collider's slot for contacts with one), the normal ``n`` and tangents ``t1``, ``t2`` (K, 3) and
    each end's lever arm ``r_a``, ``r_b`` (K, 3) [m] from its centre to the contact point."""

    a: np.ndarray
    b: np.ndarray
    n: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    r_a: np.ndarray
    r_b: np.ndarray

    @classmethod
    def of(cls, contacts: Contacts, x: np.ndarray, kinematic: np.ndarray | None = None) -> ContactFrame:
        """The frame of ``contacts`` on bodies centred at ``x`` (P + 1, 3) [m]; ``kinematic`` (K,): the slot of the
        moving collider each contact touches (−1: none)."""
        a, b = contact_ends(contacts, len(x), kinematic)
        t1, t2 = tangent_basis(contacts.normal)
        return cls(a, b, contacts.normal, t1, t2, contacts.point - x[a], contacts.point - x[b])

    def along(self, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Relative velocity (or acceleration) of the contact points along the normal, first and second tangent
        (3, K), for the bodies' linear and angular velocities (or accelerations) ``v``, ``w`` (P + 1, 3): the points'
        ``v + w × r`` on body a minus on body b, read along each direction (one product for the three)."""
        a, b = self.a, self.b
        relative = v[a] + cross(w[a], self.r_a) - v[b] - cross(w[b], self.r_b)
        return np.einsum("ki,dki->dk", relative, self.directions)

    @functools.cached_property
    def directions(self) -> np.ndarray:
        """The normal, first and second tangent stacked (3, K, 3)."""
        return np.stack([self.n, self.t1, self.t2])

    def ends(self, directions: np.ndarray) -> np.ndarray:
        """What rows along ``directions`` (R, K, 3) measure at each end: ``[d, r_a × d]`` on body a and
        ``−[d, r_b × d]`` on body b, (R K, 2, 6), rows in the order of ``directions``."""
        d = np.broadcast_to(directions.reshape(-1, 1, 3), (directions.shape[0] * directions.shape[1], 2, 3))
        lever = np.tile(np.stack([self.r_a, self.r_b], axis=1), (directions.shape[0], 1, 1))
        sign = np.array([1.0, -1.0])[None, :, None]
        return np.concatenate([sign * d, sign * cross(lever, d)], axis=2)


class ContactRows(FlatVelocities):
    """The rows of K contacts on the bodies of ``bodies``: directions, lever arms, effective masses, and how to read
    relative motion along a row and apply impulses (or forces) to the bodies.

    Everything that does not change between solver iterations is computed once here, as two sparse matrices over
    the flat velocity vector ``V = [v.ravel(), ω.ravel()]`` (6 (P + 1),): the Jacobian ``J`` (3K rows: normals, then
    first and second tangents), with ``J V`` the relative velocities along the rows, and the response
    ``B = M⁻¹ Jᵀ``, with ``B λ`` the velocity change from row impulses λ. An iteration is then a few sparse
    products, one C call each, whatever the number of contacts.
    """

    def __init__(self, contacts: Contacts, bodies: BodyVelocities, x: np.ndarray,
                 kinematic: np.ndarray | None = None, jointed: JointedResponse | None = None,
                 compiled: bool = False) -> None:
        """``compiled``: a small jointed system's rows are built by one compiled call
        (:func:`animbatch.sim.kernels.contact_impulses.small_jointed_rows`; the same to round-off)."""
        self.bodies = bodies
        self.count = contacts.count
        self.size = len(x)
        frame = ContactFrame.of(contacts, x, kinematic)
        self.a, self.b, self.n, self.t1, self.t2 = frame.a, frame.b, frame.n, frame.t1, frame.t2
        self.r_a, self.r_b = frame.r_a, frame.r_b
        # mass splitting: each body is shared by the contacts touching it
        shares = np.bincount(np.concatenate([self.a, self.b]), minlength=len(x)).astype(float)
        shares[-1] = 1.0
        self._shares = shares
        self._jointed = jointed
        if jointed is not None and jointed.dense and 3 * self.count * 6 * self.size <= DENSE_ENTRIES:
            if compiled and jointed.factor is not None:
                self._compiled_small_jointed(jointed, frame.directions)
            else:
                self._small_jointed(jointed)
            return
        self.w_n, self.w_1, self.w_2 = (self._weight(row) for row in (self.normal_row, self.first_row,
                                                                     self.second_row))
        if jointed is not None:  # contacts on jointed bodies move them within the joints (sim/contact/jointed.py)
            rows = (self.normal_row, self.first_row, self.second_row)
            lost = self._jointed_losses(rows, jointed)
            self.w_n, self.w_1, self.w_2 = (self._jointed_weight(row, *losses)
                                            for row, losses in zip(rows, lost))

    # each row direction with its Jacobian and response (_Direction), found on first use: the compiled build of a
    # small jointed system's rows does without them
    @functools.cached_property
    def normal_row(self) -> _Direction:
        return self._direction(self.n)

    @functools.cached_property
    def first_row(self) -> _Direction:
        return self._direction(self.t1)

    @functools.cached_property
    def second_row(self) -> _Direction:
        return self._direction(self.t2)

    @functools.cached_property
    def _entries_kept(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Which bodies (P + 1,) have linear and angular entries in the responses (they move, they turn), then in the
        Jacobians (also the moving colliders: their velocity is read, not changed). The others' entries can only
        meet zeros: they are left out (sparse) or left 0 (arrays)."""
        moving = self.bodies.inverse_mass > 0
        turning = np.any(self.bodies.inverse_inertia != 0, axis=(1, 2))
        driven = self.bodies.driven
        if driven is None:
            return moving, turning, moving, turning
        return moving, turning, moving | driven, turning | driven

    @functools.cached_property
    def _contact_groups(self) -> np.ndarray:
        """With the joints: each body's jointed group (P + 1,), the fixed body in none (−1: it takes no share)."""
        assert self._jointed is not None
        group = self._jointed.groups(self.size)
        group[-1] = -1
        return group

    def _keep_arrays(self, jacobian: np.ndarray, response: np.ndarray) -> None:
        """Take a small system's Jacobian (3K, 6 (P + 1)) and response (6 (P + 1), 3K) as the row matrices."""
        k = self.count
        self.__dict__["_jacobian_normal"] = jacobian[:k]
        self.__dict__["_jacobian_tangent"] = jacobian[k:]
        self.__dict__["_response_normal"] = np.ascontiguousarray(response[:, :k])
        self.__dict__["_response_tangent"] = np.ascontiguousarray(response[:, k:])

    @property
    def dense(self) -> bool:
        """Whether the row matrices are arrays (small systems, :data:`DENSE_ENTRIES`)."""
        return isinstance(self._jacobian_normal, np.ndarray) and isinstance(self._response_tangent, np.ndarray)

    # the sparse forms, built on first use (the compiled iterations read the rows themselves)
    @functools.cached_property
    def _jacobian_normal(self) -> sp.csr_matrix | np.ndarray:
        return self._sparse((self.normal_row,), response=False)

    @functools.cached_property
    def _jacobian_tangent(self) -> sp.csr_matrix | np.ndarray:
        return self._sparse((self.first_row, self.second_row), response=False)

    @functools.cached_property
    def _response_normal(self) -> sp.csr_matrix | sp.csc_matrix | np.ndarray:
        response = self._sparse((self.normal_row,), response=True)
        return self._jointed.correct(response) if self._jointed is not None else response

    @functools.cached_property
    def _response_tangent(self) -> sp.csr_matrix | sp.csc_matrix | np.ndarray:
        response = self._sparse((self.first_row, self.second_row), response=True)
        return self._jointed.correct(response) if self._jointed is not None else response

    def _sparse(self, rows: tuple[_Direction, ...], *, response: bool, ends: tuple[bool, bool] = (True, True)
                ) -> sp.csr_matrix | sp.csc_matrix | np.ndarray:
        """``J`` (R K, 6 (P + 1)) for the given row directions, or the response ``B`` (6 (P + 1), R K); as an array
        for small systems (:data:`DENSE_ENTRIES`).

        Entries that can only ever meet zeros are left out: the fixed body's (its velocity is zero and its inverse
        mass too) and the angular ones of bodies that do not turn (particles). For a pile of particles on the ground
        that halves the work per iteration. Built directly in compressed form (no sorting): row k holds body a's
        linear and angular entries, then body b's.
        """
        k, size, a, b = self.count, self.size, self.a, self.b
        kept = self._entries_kept
        moving, turning = kept[:2] if response else kept[2:]
        keep = np.stack([moving[a], turning[a], moving[b], turning[b]], axis=1)  # (K, 4) blocks of 3 entries
        keep &= np.repeat(ends, 2)  # only the ends asked for
        columns = (np.stack([3 * a, 3 * (size + a), 3 * b, 3 * (size + b)], axis=1)[:, :, None] + np.arange(3))
        per_row = 3 * keep.sum(axis=1)
        data = np.concatenate([
            np.stack([row.lin_a, row.turn_a, -row.lin_b, -row.turn_b] if response
                     else [row.d, row.ang_a, -row.d, -row.ang_b], axis=1)[keep].ravel() for row in rows])
        indices = np.tile(columns[keep].ravel(), len(rows))
        indptr = np.concatenate([[0], np.cumsum(np.tile(per_row, len(rows)))])
        if len(rows) * k * 6 * size <= DENSE_ENTRIES:
            dense = np.zeros((len(rows) * k, 6 * size))
            dense[np.repeat(np.arange(len(rows) * k), np.diff(indptr)), indices] = data
            return dense.T if response else dense
        matrix = sp.csr_matrix((data, indices, indptr), shape=(len(rows) * k, 6 * size))
        return matrix.T if response else matrix

    def _small_jointed(self, jointed: JointedResponse) -> None:
        """The rows of a small jointed system, all at once as arrays: the Jacobian ``J`` (3K, 6 (P + 1)) of the
        normals and both tangents, each end's response ``M⁻¹ Jᵀ`` (6 (P + 1), 3K), one solve for what the joints do
        to both ends' columns, and from it the response within the joints and the effective masses — the same
        matrices as the piecewise build (:meth:`_sparse`, :meth:`JointedResponse.correct`, :meth:`_jointed_losses`)
        to round-off, without its three solves and dozen assemblies a step (a ragdoll's contact step)."""
        k, size, a, b = self.count, self.size, self.a, self.b
        rows = (self.normal_row, self.first_row, self.second_row)
        moving, turning, read_moving, read_turning = self._entries_kept
        line = np.arange(3 * k)[:, None]
        step = np.arange(3)
        linear_a, angular_a = 3 * np.tile(a, 3)[:, None] + step, 3 * (size + np.tile(a, 3))[:, None] + step
        linear_b, angular_b = 3 * np.tile(b, 3)[:, None] + step, 3 * (size + np.tile(b, 3))[:, None] + step

        # which blocks of 3 entries a row keeps (3K, 8): the Jacobian's at a and b, then the response's (entries of
        # bodies that cannot take them are left 0, as the piecewise build leaves them out)
        keep = np.tile(np.stack([read_moving[a], read_turning[a], read_moving[b], read_turning[b],
                                 moving[a], turning[a], moving[b], turning[b]], axis=1), (3, 1)).astype(float)

        def kept(name: str, block: int, sign: float = 1.0) -> np.ndarray:  # a row field (3K, 3), three directions
            return np.concatenate([getattr(row, name) for row in rows]) * (sign * keep[:, block:block + 1])

        jacobian = np.zeros((3 * k, 6 * size))
        jacobian[line, linear_a] = kept("d", 0)
        jacobian[line, angular_a] = kept("ang_a", 1)
        jacobian[line, linear_b] = kept("d", 2, -1.0)
        jacobian[line, angular_b] = kept("ang_b", 3, -1.0)
        ends = np.zeros((6 * size, 6 * k))  # M⁻¹ Jᵀ of end a's rows, then of end b's
        ends[linear_a, line] = kept("lin_a", 4)
        ends[angular_a, line] = kept("turn_a", 5)
        ends[linear_b, line + 3 * k] = kept("lin_b", 6, -1.0)
        ends[angular_b, line + 3 * k] = kept("turn_b", 7, -1.0)
        touched, rates, multipliers = jointed._touched(ends)
        both = np.zeros((jointed.count, 6 * k))  # what the joints' impulses answer each column with
        both[:, touched] = multipliers
        end_rates = np.zeros((jointed.count, 6 * k))
        end_rates[:, touched] = rates
        lost_ends = np.einsum("rk,rk->k", end_rates, both)
        lost_pairs = np.einsum("rk,rk->k", end_rates[:, :3 * k] + end_rates[:, 3 * k:],
                               both[:, :3 * k] + both[:, 3 * k:])
        self._keep_arrays(jacobian, ends[:, :3 * k] + ends[:, 3 * k:]
                          - jointed.push_array @ (both[:, :3 * k] + both[:, 3 * k:]))
        self.w_n, self.w_1, self.w_2 = (
            self._jointed_weight(row, lost_ends[r * k:(r + 1) * k], lost_ends[(3 + r) * k:(4 + r) * k],
                                 lost_pairs[r * k:(r + 1) * k]) for r, row in enumerate(rows))

    def _compiled_small_jointed(self, jointed: JointedResponse, directions: np.ndarray) -> None:
        """:meth:`_small_jointed` in one compiled call (:func:`animbatch.sim.kernels.contact_impulses.
        small_jointed_rows`) from the row directions (3, K, 3): the same matrices and effective masses to round-off."""
        from animbatch.sim.kernels import contact_impulses

        build: Any = contact_impulses.small_jointed_rows
        bodies = self.bodies
        moving, turning, read_moving, read_turning = self._entries_kept
        assert jointed.factor is not None

        def floats(values: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(values, np.float64)

        jacobian, response, weight = build(
            np.asarray(self.a, np.int64), np.asarray(self.b, np.int64), floats(directions), floats(self.r_a),
            floats(self.r_b), floats(bodies.inverse_mass), floats(bodies.inverse_inertia), read_moving, read_turning,
            moving, turning, self._contact_groups.astype(np.int64), floats(jointed.rows_array),
            floats(jointed.push_array), floats(jointed.factor), bool(jointed.cholesky))
        self._keep_arrays(jacobian, response)
        self.w_n, self.w_1, self.w_2 = weight

    def _direction(self, d: np.ndarray) -> _Direction:
        a, b, inverse_mass, inverse_inertia = self.a, self.b, self.bodies.inverse_mass, self.bodies.inverse_inertia
        ang_a, ang_b = cross(self.r_a, d), cross(self.r_b, d)
        return _Direction(d, ang_a, ang_b, inverse_mass[a][:, None] * d, inverse_mass[b][:, None] * d,
                          np.einsum("kij,kj->ki", inverse_inertia[a], ang_a),
                          np.einsum("kij,kj->ki", inverse_inertia[b], ang_b))

    def _weight(self, row: _Direction) -> np.ndarray:
        """Effective mass along a row, with each body's inverse mass and inertia multiplied by its share."""
        a, b = self.a, self.b
        inverse = (self._shares[a] * (np.einsum("ki,ki->k", row.lin_a, row.d) + np.einsum("ki,ki->k", row.turn_a,
                                                                                          row.ang_a))
                   + self._shares[b] * (np.einsum("ki,ki->k", row.lin_b, row.d) + np.einsum("ki,ki->k", row.turn_b,
                                                                                            row.ang_b)))
        return 1.0 / inverse

    def _dense_response(self, row: _Direction, first: bool) -> np.ndarray:
        """The response ``M⁻¹ Jᵀ`` (6 (P + 1), K) of one end of a row as an array: body a's ``lin_a``, ``turn_a``
        (``first``), or body b's ``−lin_b``, ``−turn_b``. (Entries of bodies that cannot move are zero already.)"""
        body, linear, angular = (self.a, row.lin_a, row.turn_a) if first else (self.b, -row.lin_b, -row.turn_b)
        response = np.zeros((6 * self.size, self.count))
        columns = np.arange(self.count)[:, None]
        response[3 * body[:, None] + np.arange(3), columns] = linear
        response[3 * (self.size + body[:, None]) + np.arange(3), columns] = angular
        return response

    def _jointed_losses(self, rows: tuple[_Direction, ...], jointed: JointedResponse
                        ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per row direction, what the joints take from the inverse effective mass (K,) of its first end, its
        second end and both together (:meth:`JointedResponse.lost`). Small systems: all nine responses as one array,
        one product and one solve."""
        if jointed.dense:
            responses = []
            for row in rows:
                end_a, end_b = self._dense_response(row, True), self._dense_response(row, False)
                responses += [end_a, end_b, end_a + end_b]
            lost = jointed.lost(np.concatenate(responses, axis=1)).reshape(len(rows), 3, self.count)
            return [(lost[r, 0], lost[r, 1], lost[r, 2]) for r in range(len(rows))]
        return [(jointed.lost(self._sparse((row,), response=True, ends=(True, False))),
                 jointed.lost(self._sparse((row,), response=True, ends=(False, True))),
                 jointed.lost(self._sparse((row,), response=True))) for row in rows]

    @functools.cached_property
    def _group_shares(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """With the joints: how many contact ends each contact's end a and end b shares its jointed group with (K,)
        each (a group moves as one under any of them), and which contacts have both ends in one group (K,)."""
        a, b, group = self.a, self.b, self._contact_groups
        shares = np.bincount(np.concatenate([group[a], group[b]]) + 1, minlength=group.max() + 2).astype(float)
        return shares[group[a] + 1], shares[group[b] + 1], (group[a] == group[b]) & (group[a] >= 0)

    def _jointed_weight(self, row: _Direction, lost_a: np.ndarray, lost_b: np.ndarray,
                        lost_both: np.ndarray) -> np.ndarray:
        """Effective mass along a row with the joints: each end's inverse effective mass less what the joints take
        away (``lost_*`` (K,), :meth:`_jointed_losses`), split among the contacts of its whole jointed group
        (:attr:`_group_shares`), or for two ends in one group, the pair's together."""
        own_a = np.einsum("ki,ki->k", row.lin_a, row.d) + np.einsum("ki,ki->k", row.turn_a, row.ang_a)
        own_b = np.einsum("ki,ki->k", row.lin_b, row.d) + np.einsum("ki,ki->k", row.turn_b, row.ang_b)
        share_a, share_b, together = self._group_shares
        inverse = np.where(together, share_a * (own_a + own_b - lost_both),
                           share_a * (own_a - lost_a) + share_b * (own_b - lost_b))
        return 1.0 / np.maximum(inverse, 1e-300)

    def weight(self, direction: np.ndarray) -> np.ndarray:
        """Effective mass of each row along ``direction`` (K, 3), with masses split among contacts."""
        return self._weight(self._direction(direction))

    # -- flat velocity vectors (FlatVelocities): what the solver iterates on -----------------------------------------

    def response_normal_columns(self, chosen: np.ndarray) -> np.ndarray:
        """The velocity change (6 (P + 1), J) per unit normal impulse of the ``chosen`` contacts."""
        response = self._response_normal
        if isinstance(response, np.ndarray):
            return response[:, chosen]
        return sp.csc_matrix(response)[:, chosen].toarray()

    def normal_jacobian_rows(self, chosen: np.ndarray) -> sp.csr_matrix | np.ndarray:
        """The normal rows (J, 6 (P + 1)) of the ``chosen`` contacts."""
        jacobian = self._jacobian_normal
        return jacobian[chosen] if isinstance(jacobian, np.ndarray) else sp.csr_matrix(jacobian)[chosen]

    def normal_velocity(self, velocity: np.ndarray) -> np.ndarray:
        """Relative normal velocities (K,) for the flat velocity ``V``."""
        return self._jacobian_normal @ velocity

    def tangent_velocity(self, velocity: np.ndarray) -> np.ndarray:
        """Relative tangential velocities (K, 2) in the (t1, t2) basis for the flat velocity ``V``."""
        return (self._jacobian_tangent @ velocity).reshape(2, -1).T

    def push_normal(self, velocity: np.ndarray, amount: np.ndarray) -> None:
        """Add normal impulses (K,) to the flat velocity ``V`` in place."""
        velocity += self._response_normal @ amount

    def push_tangent(self, velocity: np.ndarray, amounts: np.ndarray) -> None:
        """Add tangential impulses (K, 2), in the (t1, t2) basis, to the flat velocity ``V`` in place."""
        velocity += self._response_tangent @ amounts.T.ravel()

    # -- the same on (P + 1, 3) arrays, for callers that keep v and ω apart -----------------------------------------

    def _row(self, direction: np.ndarray) -> _Direction:
        for row in (self.normal_row, self.first_row, self.second_row):
            if row.d is direction:
                return row
        return self._direction(direction)

    def relative(self, direction: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        """Relative velocity (or acceleration) of the contact points along ``direction``, (K,)."""
        if direction is self.n:
            return self.normal_velocity(self.flat(v, w))
        v = self.bodies.v if v is None else v
        w = self.bodies.omega if w is None else w
        row = self._row(direction)
        a, b = self.a, self.b
        return (np.einsum("ki,ki->k", v[a] - v[b], row.d) + np.einsum("ki,ki->k", w[a], row.ang_a)
                - np.einsum("ki,ki->k", w[b], row.ang_b))

    def tangential(self, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        """Relative tangential motion (K, 2) in the (t1, t2) basis."""
        return self.tangent_velocity(self.flat(v, w))

    def apply_normal(self, amount: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> None:
        velocity = self.flat(v, w)
        self.push_normal(velocity, amount)
        self.unflat(velocity, v, w)


class JointedNormals:
    """The normal rows of the contacts on jointed bodies, solved together: ``chosen`` (J,) of the K contacts and
    their Delassus matrix ``W = J K Jᵀ`` (J, J) within the joints. Jacobi sweeps, even with each contact's
    articulated effective mass, crawl where a light body carries a heavy one on a lever (a plank under a weight on
    a stalk: its corners mostly tip the plank, together they lift the weight; the matrix's condition number is the
    mass ratio times the lever's); solving these rows directly, with the active set of pushing contacts, takes the
    whole weight in one go. The friction and the other contacts stay with the sweeps."""

    def __init__(self, chosen: np.ndarray, matrix: np.ndarray) -> None:
        self.chosen = chosen
        self.matrix = matrix
        # per pass of the active-set search: the active rows (J,) and the pseudo-inverse (J, J) of their block of
        # the matrix, zero elsewhere; a pass that meets the same rows again (solve after solve) uses it again
        self._inverses: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    @classmethod
    def of(cls, rows: ContactRows, jointed: JointedResponse) -> JointedNormals | None:
        group = jointed.groups(rows.size)
        joined = np.bincount(group, minlength=group.max() + 1)[group] > 1  # bodies some joint holds
        joined[-1] = False
        chosen = np.flatnonzero(joined[rows.a] | joined[rows.b])
        if not len(chosen) or len(chosen) > BLOCK_CONTACTS:
            return None
        response = rows.response_normal_columns(chosen)
        return cls(chosen, rows.normal_jacobian_rows(chosen) @ response)

    def solve(self, normal_impulse: np.ndarray, normal_now: np.ndarray) -> np.ndarray:
        """The normal impulses (K,) with the chosen ones replaced by the solution of their complementarity problem
        (λ ≥ 0, rate ≥ 0, one of them zero) given the others, by active sets: ``normal_now`` (K,) is each row's
        rate less its target at ``normal_impulse``."""
        chosen, matrix = self.chosen, self.matrix
        start = normal_impulse[chosen]
        active = (start > 0) | (normal_now[chosen] < 0)
        result = normal_impulse.copy()
        found = start.copy()
        for step in range(ACTIVE_SET_PASSES):
            found = start.copy()
            if active.any():
                known = self._inverses.get(step)
                if known is None or not np.array_equal(known[0], active):
                    inverse = np.zeros_like(matrix)
                    inverse[np.ix_(active, active)] = np.linalg.pinv(matrix[np.ix_(active, active)], rcond=1e-12)
                    known = self._inverses[step] = (active.copy(), inverse)
                found += known[1] @ np.where(active, -normal_now[chosen], 0.0)
            negative = active & (found < 0)
            if not negative.any():
                break
            active &= ~negative
        result[chosen] = np.maximum(found, 0.0)
        return result


#: Contacts on jointed bodies solved directly (JointedNormals) when there are at most this many; beyond, sweeps.
BLOCK_CONTACTS = 400
#: Passes of the active-set search for the jointed contacts' normal impulses.
ACTIVE_SET_PASSES = 8

#: Resting-contact force solves of at most this many rows (three a contact) sweep on Python floats, larger ones on
#: numpy arrays (see :func:`solve_forces`).
SMALL_FORCE_ROWS = 48
#: Resting-contact forces are converged when every contact's acceleration target is met to this [m/s²].
ACCELERATION_TOLERANCE = 1e-9
#: Impulses are converged when every contact's velocity target is met to this, relative to the approach speeds.
VELOCITY_TOLERANCE = 1e-10
@dataclass
class SolveResult:
    """Accumulated normal impulses (or forces) (K,) and tangential ones (K, 2); for impulse solves, the
    pseudo-velocities (P + 1, 3) that move positions out of overlaps (or None when nothing overlaps)."""

    normal_impulse: np.ndarray
    tangent_impulse: np.ndarray
    pseudo_v: np.ndarray | None = None
    pseudo_omega: np.ndarray | None = None
    # (K,) bool: contacts arriving faster than the rest speed (they bounce)
    impact: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    # (K,) fraction of the step at which each gap closes (straight-line motion)
    arrival: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # (K, 3) the tangential impulses as world vectors (impulse solves)
    tangent_vector: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # how many sweeps numpy made (0 when they ran compiled): what the caller counts to know when compiling pays
    numpy_sweeps: int = 0
    # impulse solves: the largest violation of a contact's target the sweeps left [m/s], and whether that is more
    # than the tolerance (the sweeps ran out: ``iterations`` was not enough)
    residual: float = 0.0
    unconverged: bool = False


#: Impulse solves of at least this many contacts run their sweeps compiled
#: (:mod:`animbatch.sim.kernels.contact_impulses`) unless ``ANIMBATCH_KERNELS=numpy``; fewer finish in numpy before
#: numba has loaded (``numba`` compiles them all).
#: Measured on a pile of 10 000 balls: 1.6 ms per sweep in numpy.
COMPILED_CONTACTS = 1000


def compiled_contacts(count: int, *, long_run: bool = False) -> bool:
    """Whether an impulse solve of ``count`` contacts runs its sweeps compiled: where it pays (many contacts, or a
    ``long_run`` of small solves: a pile of a dozen bodies solves thousands of times), and once the kernels are
    built (:func:`build_contact_kernels`)."""
    from animbatch.sim.kernels import CONTACT_KERNELS, MIN_WORK, kernels_ready

    return kernels_ready(MIN_WORK if count >= COMPILED_CONTACTS or long_run else 0.0, build_contact_kernels,
                         CONTACT_KERNELS, "numpy solves the contacts")


@functools.cache
def build_contact_kernels() -> str | None:
    """Build (or load from numba's disk cache) the contact kernels on one contact, so that a kernel numba cannot
    build is found before it is needed; None, or what failed."""
    from animbatch.sim.kernels import build_failure

    def build() -> None:
        from animbatch.sim.contact.detection import build_probe_kernels
        from animbatch.sim.contact.hulls import build_edge_kernels
        from animbatch.sim.contact.sides import build_side_kernels
        from animbatch.sim.kernels import contact_impulses as kernels
        from animbatch.sim.kernels import resting_forces

        impulses: Any = kernels
        velocity = np.zeros(12)
        one: Any = np.zeros(1, np.int64), np.ones(1, np.int64)
        impulses.solve_contacts(*one, np.array([[0.0, 1.0, 0.0]]), np.zeros((1, 3)), np.full(1, -1.0), np.zeros(1),
                                np.zeros(1), np.zeros(1), np.zeros((2, 3)), np.ones(2), np.zeros((2, 3, 3)), velocity,
                                np.zeros(1), np.zeros((1, 3)), 1e-3, True, 0.01, 1e-4, 1, _COMPILED_SETTINGS)
        # the jointed scenes' sweeps on array rows (one contact, two bodies: 12 velocity columns), with the block
        # of jointed normals and without
        for chosen, block in ((np.zeros(0, np.int64), np.zeros((0, 0))), (np.zeros(1, np.int64), np.ones((1, 1)))):
            impulses.dense_sweeps(velocity, np.zeros((1, 12)), np.zeros((2, 12)), np.zeros((12, 1)),
                                  np.zeros((12, 2)), np.ones((3, 1)), np.zeros(1), np.zeros(1), np.zeros((1, 2)),
                                  np.zeros(1), np.zeros(1), np.zeros(1, np.bool_), chosen, block, BLOCK_EVERY,
                                  ACTIVE_SET_PASSES, 1, 0.0)
        impulses.dense_pushes(velocity, np.zeros((1, 12)), np.zeros((12, 1)), np.ones(1), np.ones(1), 0.0, 1)
        # a small jointed system's rows: one contact of body 0 on the fixed body, one joint row, by the Cholesky
        # factor and by the pseudo-inverse
        flags, one_row = np.array([True, False]), np.zeros((1, 12))
        for cholesky in (True, False):
            impulses.small_jointed_rows(*one, np.zeros((3, 1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), np.ones(2),
                                        np.zeros((2, 3, 3)), flags, flags, flags, flags, np.array([0, -1]), one_row,
                                        one_row.T.copy(), np.ones((1, 1)), cholesky)
        forces: Any = resting_forces.resting_forces  # one resting contact of body 0 on the fixed body
        forces(*one, np.eye(3)[:, None, :], np.array([[0.0, 1.0, 0.0]]), np.zeros((1, 3)), np.zeros((1, 3)),
               np.ones(2), np.zeros((2, 3, 3)), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(3), np.zeros(3),
               np.ones(1, np.bool_), np.ones(1), 1, 0.0)
        build_edge_kernels()
        build_probe_kernels()
        build_side_kernels()

    return build_failure(build)


def solve_impulses(contacts: Contacts, bodies: BodyVelocities, x: np.ndarray, h: float, *, iterations: int,
                   rest_speed: float, slop: float, bounce: bool = True,
                   warm: tuple[np.ndarray, np.ndarray] | None = None,
                   kinematic: np.ndarray | None = None,
                   couple: Callable[[BodyVelocities], None] | None = None,
                   jointed: JointedResponse | None = None, long_run: bool = False) -> SolveResult:
    """Change ``bodies.v`` and ``bodies.omega`` in place so that the contacts hold, over a step of ``h`` [s].

    ``x``: centres of mass (P + 1, 3) [m]. ``bounce``: apply restitution (off when re-projecting velocities that
    were already resolved in this step). ``h = 0`` means an instant: no speculative contacts, no pushing apart.
    ``warm``: normal impulses (K,) and tangential impulse vectors (K, 3) to start from (warm starting: the last
    step's impulses of the same contacts, so that resting contacts converge over steps). ``kinematic`` (K,): the
    slot in ``bodies`` of the moving collider each contact touches (−1: none). ``couple``: the joints on the same
    bodies, applied to their velocities in place before the contacts and after them, and ``jointed`` their rows:
    every contact impulse then moves the bodies within the joints, and the normals of the contacts on jointed
    bodies are solved directly every :data:`BLOCK_EVERY` sweeps (one system, see
    :mod:`~animbatch.sim.contact.jointed` and :class:`JointedNormals`). ``long_run``: the sweeps run compiled
    whatever the count (see :func:`compiled_contacts`).
    """
    count = contacts.count
    result = SolveResult(np.zeros(count), np.zeros((count, 2)))
    if count == 0:
        return result
    if couple is not None:  # start on the joints: with their rows in the response, the contacts keep them
        couple(bodies)
    if jointed is None and couple is None and compiled_contacts(count, long_run=long_run):
        return _solve_compiled(contacts, bodies, x, h, iterations=iterations, rest_speed=rest_speed, slop=slop,
                               bounce=bounce, warm=warm, kinematic=kinematic)
    compiled = compiled_contacts(count, long_run=long_run)
    rows = ContactRows(contacts, bodies, x, kinematic, jointed, compiled=compiled)
    block = JointedNormals.of(rows, jointed) if jointed is not None else None
    n = rows.n
    approach = rows.relative(n)
    sticking = np.linalg.norm(rows.tangential(), axis=1) <= rest_speed
    fast = approach < -rest_speed
    gap = contacts.gap
    bounce_target = -contacts.restitution * approach if bounce else np.zeros(count)
    if h > 0:
        arrives = approach * h < -gap  # reaches the surface within this step
        # without bounce (re-projecting after a step's second half kick), a fast contact still in the air is an
        # impact the next bouncing solve must see at full speed: leave it alone rather than stop it dead
        arriving = bounce_target if bounce else approach
        target = np.where(gap > 0, np.where(arrives & fast, arriving, -gap / h),
                          np.where(fast, bounce_target, 0.0))
        result.impact = fast & ((gap <= 0) | arrives) if bounce else np.zeros(count, bool)
        with np.errstate(divide="ignore", invalid="ignore"):
            result.arrival = np.clip(np.where(approach < 0, gap / (-approach * h), 0.0), 0.0, 1.0)
    else:
        target = np.where(fast, bounce_target, 0.0)
        result.impact, result.arrival = fast & bounce, np.zeros(count)
    normal_impulse = np.zeros(count)
    tangent_impulse = np.zeros((count, 2))
    velocity = rows.flat()
    if warm is not None:
        normal_impulse = np.where(fast, 0.0, warm[0])  # impacts start afresh; resting contacts from last step
        tangent_impulse = np.stack([np.einsum("ki,ki->k", warm[1], rows.t1),
                                    np.einsum("ki,ki->k", warm[1], rows.t2)], axis=1) * (~fast)[:, None]
        rows.push_normal(velocity, normal_impulse)
        rows.push_tangent(velocity, tangent_impulse)
    tolerance = VELOCITY_TOLERANCE * (1.0 + float(np.abs(approach).max(initial=0.0)))
    if compiled and rows.dense:  # small jointed scenes: array rows, compiled
        normal_impulse, tangent_impulse, _, result.residual = _compiled_dense_sweeps(
            rows, contacts, velocity, target, normal_impulse, tangent_impulse, sticking, block, iterations, tolerance)
    else:
        normal_impulse, tangent_impulse, result.numpy_sweeps, result.residual = _sweeps(
            rows, contacts, velocity, target, normal_impulse, tangent_impulse, sticking, block, iterations, tolerance)
    result.unconverged = result.residual > tolerance
    if couple is not None:  # end on the joints
        rows.unflat(velocity)
        couple(bodies)
        velocity = rows.flat()
    rows.unflat(velocity)
    result.normal_impulse[:] = normal_impulse
    result.tangent_impulse[:] = tangent_impulse
    result.tangent_vector = tangent_impulse[:, [0]] * rows.t1 + tangent_impulse[:, [1]] * rows.t2
    # split impulse: push apart through positions only, the overlaps that exceed the slop by more than a trifle
    # (pushing converges geometrically onto the slop; chasing the last nanometre would cost a solve every step)
    overlap = np.maximum(-gap - slop, 0.0)
    overlap[overlap < OVERLAP_TOLERANCE * max(slop, 1e-6)] = 0.0
    if h > 0 and np.any(overlap > 0):
        pseudo = np.zeros_like(velocity)
        push_target = BAUMGARTE * overlap / h
        enough = PUSH_TOLERANCE * float(push_target.max())
        if compiled and rows.dense:  # small jointed scenes: array rows, compiled (as their sweeps)
            _compiled_dense_pushes(rows, pseudo, push_target, enough, min(iterations, PUSH_ITERATIONS))
        else:
            _pushes(rows, pseudo, push_target, enough, min(iterations, PUSH_ITERATIONS))
        pseudo_v, pseudo_w = np.zeros_like(bodies.v), np.zeros_like(bodies.omega)
        rows.unflat(pseudo, pseudo_v, pseudo_w)
        result.pseudo_v, result.pseudo_omega = pseudo_v, pseudo_w
    return result


def _solve_compiled(contacts: Contacts, bodies: BodyVelocities, x: np.ndarray, h: float, *, iterations: int,
                    rest_speed: float, slop: float, bounce: bool, warm: tuple[np.ndarray, np.ndarray] | None,
                    kinematic: np.ndarray | None) -> SolveResult:
    """:func:`solve_impulses` without joints in one compiled call
    (:func:`animbatch.sim.kernels.contact_impulses.solve_contacts`): the same steps in the same order, so the same
    impulses and velocities to round-off (tests compare them); what a step of a long run with contacts pays in
    Python is only this call's arguments."""
    from animbatch.sim.kernels import contact_impulses

    solve: Any = contact_impulses.solve_contacts
    count, size = contacts.count, len(x)
    a, b = (np.asarray(end, np.int64) for end in contact_ends(contacts, size, kinematic))
    velocity = np.concatenate([bodies.v.ravel(), bodies.omega.ravel()])
    warm_normal, warm_tangent = warm if warm is not None else (np.zeros(count), np.zeros((count, 3)))

    def floats(values: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(values, np.float64)

    normal_impulse, tangent_impulse, tangent_vector, impact, arrival, pseudo, residual, tolerance = solve(
        a, b, floats(contacts.normal), floats(contacts.point), floats(contacts.gap), floats(contacts.restitution),
        floats(contacts.static_friction), floats(contacts.kinetic_friction), floats(x), floats(bodies.inverse_mass),
        floats(bodies.inverse_inertia), velocity, floats(warm_normal), floats(warm_tangent), float(h), bool(bounce),
        float(rest_speed), float(slop), int(iterations), _COMPILED_SETTINGS)
    half = 3 * size
    bodies.v[:] = velocity[:half].reshape(-1, 3)
    bodies.omega[:] = velocity[half:].reshape(-1, 3)
    result = SolveResult(normal_impulse, tangent_impulse, impact=impact, arrival=arrival,
                         tangent_vector=tangent_vector, residual=float(residual), unconverged=residual > tolerance)
    if len(pseudo):
        result.pseudo_v, result.pseudo_omega = pseudo[:half].reshape(-1, 3), pseudo[half:].reshape(-1, 3)
    return result


#: The solver's constants as :func:`animbatch.sim.kernels.contact_impulses.solve_contacts` takes them.
_COMPILED_SETTINGS = np.array([VELOCITY_TOLERANCE, BAUMGARTE, OVERLAP_TOLERANCE, PUSH_TOLERANCE, PUSH_ITERATIONS],
                              float)


def _sweeps(rows: ContactRows, contacts: Contacts, velocity: np.ndarray, target: np.ndarray,
            normal_impulse: np.ndarray, tangent_impulse: np.ndarray, sticking: np.ndarray,
            block: JointedNormals | None, iterations: int, tolerance: float
            ) -> tuple[np.ndarray, np.ndarray, int, float]:
    """The impulse solver's sweeps in numpy (changing ``velocity`` in place), normal then friction, until every
    contact does what it must or after ``iterations``: the accumulated normal (K,) and tangential (K, 2) impulses,
    how many sweeps that took, and the largest violation they left [m/s] (above ``tolerance``: they ran out).

    A sweep of a small scene is some twenty numpy calls of a microsecond or two each, so the tangential parts are
    kept as two (K,) arrays (no stacking, reshaping or norms along an axis): the same arithmetic as the compiled
    sweeps (:func:`animbatch.sim.kernels.contact_impulses.impulse_iterations`), in bulk."""
    count = len(target)
    normal_rows, tangent_rows = rows._jacobian_normal, rows._jacobian_tangent
    normal_response, tangent_response = rows._response_normal, rows._response_tangent
    first, second = tangent_impulse[:, 0].copy(), tangent_impulse[:, 1].copy()
    static_limit, kinetic_limit = contacts.static_friction, contacts.kinetic_friction
    no_scale = np.zeros(count)
    gripping = np.zeros(count, bool)  # which contacts hold by friction; set by the first iteration
    watch = [np.inf, np.inf]  # the smallest violations, for stalled()
    for iteration in range(iterations + 1):
        normal_now = normal_rows @ velocity - target
        # Stop when every contact does what it must (not when impulses stop changing: with redundant contacts,
        # a box on four corners, impulses may keep moving among corners after the motion has converged). At least
        # one iteration, so that a warm start that is almost right is still polished, and resting bodies stay put.
        if iteration > 0:
            # a contact pushing must meet its target exactly, one not pushing may only separate faster
            worst = max(-float(normal_now.min()), float(normal_now.max(where=normal_impulse > 0, initial=0.0)))
            if gripping.any():
                slip = tangent_rows @ velocity
                worst = max(worst, float((np.sqrt(slip[:count] ** 2 + slip[count:] ** 2) * gripping).max()))
            if worst <= tolerance or iteration == iterations or stalled(iteration, worst, watch):
                return normal_impulse, np.stack([first, second], axis=1), iteration, worst
        updated = np.maximum(normal_impulse - normal_now * rows.w_n, 0.0)
        if block is not None and iteration % BLOCK_EVERY == 0:  # the jointed contacts' normals at once
            updated = block.solve(normal_impulse, normal_now)
        velocity += normal_response @ (updated - normal_impulse)
        normal_impulse = updated
        # one Coulomb projection: the tangential impulse that stops the sliding if the static cone allows it (for
        # contacts that may stick), else the kinetic limit against it
        current = tangent_rows @ velocity
        wanted_1 = first - current[:count] * rows.w_1
        wanted_2 = second - current[count:] * rows.w_2
        size = np.sqrt(wanted_1 ** 2 + wanted_2 ** 2)
        gripping = sticking & (size <= static_limit * normal_impulse)
        limit = np.where(gripping, size, kinetic_limit * normal_impulse)
        scale = np.divide(np.minimum(size, limit), size, out=no_scale.copy(), where=size > 0)
        wanted_1 *= scale
        wanted_2 *= scale
        velocity += tangent_response @ np.concatenate([wanted_1 - first, wanted_2 - second])
        first, second = wanted_1, wanted_2
    return normal_impulse, np.stack([first, second], axis=1), 1, np.inf  # only with iterations = 0 (the loop returns)


def _compiled_dense_sweeps(rows: ContactRows, contacts: Contacts, velocity: np.ndarray, target: np.ndarray,
                           normal_impulse: np.ndarray, tangent_impulse: np.ndarray, sticking: np.ndarray,
                           block: JointedNormals | None, iterations: int, tolerance: float
                           ) -> tuple[np.ndarray, np.ndarray, int, float]:
    """:func:`_sweeps` in one compiled call (:func:`animbatch.sim.kernels.contact_impulses.dense_sweeps`), for rows
    kept as arrays."""
    from animbatch.sim.kernels import contact_impulses

    sweeps: Any = contact_impulses.dense_sweeps

    def array(matrix: Any) -> np.ndarray:
        return np.ascontiguousarray(matrix, dtype=np.float64)

    chosen = block.chosen.astype(np.int64) if block is not None else np.zeros(0, np.int64)
    matrix = array(block.matrix) if block is not None else np.zeros((0, 0))
    return sweeps(velocity, array(rows._jacobian_normal), array(rows._jacobian_tangent), array(rows._response_normal),
                  array(rows._response_tangent), array(np.stack([rows.w_n, rows.w_1, rows.w_2])),
                  array(target), array(normal_impulse), array(tangent_impulse), array(contacts.static_friction),
                  array(contacts.kinetic_friction), np.asarray(sticking, np.bool_), chosen, matrix, BLOCK_EVERY,
                  ACTIVE_SET_PASSES, int(iterations), float(tolerance))


def _pushes(rows: ContactRows, pseudo: np.ndarray, push_target: np.ndarray, enough: float, iterations: int) -> None:
    """The split impulse's sweeps in numpy on the pseudo-velocities ``pseudo`` (changed in place)."""
    push = np.zeros(len(push_target))
    for _ in range(iterations):
        pushed = rows.normal_velocity(pseudo) - push_target
        violation = np.where(push > 0, np.abs(pushed), np.maximum(-pushed, 0.0))
        if float(violation.max()) <= enough:
            break
        updated = np.maximum(push - pushed * rows.w_n, 0.0)
        rows.push_normal(pseudo, updated - push)
        push = updated


def _compiled_dense_pushes(rows: ContactRows, pseudo: np.ndarray, push_target: np.ndarray, enough: float,
                           iterations: int) -> None:
    """:func:`_pushes` in one compiled call (:func:`animbatch.sim.kernels.contact_impulses.dense_pushes`), for rows
    kept as arrays."""
    from animbatch.sim.kernels import contact_impulses

    pushes: Any = contact_impulses.dense_pushes
    pushes(pseudo, np.ascontiguousarray(rows._jacobian_normal, np.float64),
           np.ascontiguousarray(rows._response_normal, np.float64), np.ascontiguousarray(rows.w_n, np.float64),
           np.ascontiguousarray(push_target, np.float64), float(enough), int(iterations))


def _small_converged(coupling: list[list[float]], constant: list[float], current: list[float], holds: list[bool],
                     cone: list[float], count: int) -> bool:
    """:func:`solve_forces`' test of a small solution, in floats: every pressing normal row (``count``, then the
    two tangential blocks) at zero residual and no free one pulled in, and every sticking contact strictly inside
    its cone with no tangential residual, all to :data:`ACCELERATION_TOLERANCE`."""
    residual = [c + sum(map(operator.mul, row, current)) for row, c in zip(coupling, constant)]
    for k in range(count):
        if (abs(residual[k]) if current[k] > 0 else max(-residual[k], 0.0)) > ACCELERATION_TOLERANCE:
            return False
        j1, j2 = count + k, 2 * count + k
        if (holds[k] and math.hypot(current[j1], current[j2]) < cone[k] * current[k] * (1 - 1e-9)
                and math.hypot(residual[j1], residual[j2]) > ACCELERATION_TOLERANCE):
            return False
    return True


def solve_forces(contacts: Contacts, accelerations: BodyVelocities, x: np.ndarray, *, normal_bias: np.ndarray,
                 tangent_bias: np.ndarray, sticking: np.ndarray, slide_direction: np.ndarray,
                 iterations: int, warm: tuple[np.ndarray, np.ndarray] | None = None,
                 frame: ContactFrame | None = None, compiled: bool = False,
                 jointed: JointedResponse | None = None) -> SolveResult:
    """Forces of resting contacts, changing the accelerations in ``accelerations`` (``v``: linear, ``omega``:
    angular) in place.

    ``normal_bias`` (K,): the part of each gap's second derivative not carried by the accelerations (velocity
    products, stabilisation); the normal rows make ``relative acceleration + normal_bias ≥ 0``. ``tangent_bias``
    (K, 2): the same for the contact points' tangential acceleration. ``sticking`` (K,) bool; ``slide_direction``
    (K, 3): unit slip direction of sliding contacts (friction opposes it). ``warm``: normal (K,) and tangential
    (K, 2) forces to start from. ``frame``: the contacts' frame, when the caller has it already. ``compiled``: in one
    compiled call (:mod:`animbatch.sim.kernels.resting_forces`; the same forces to round-off). ``jointed``: the
    joints on these bodies (over the flat velocity of all of ``accelerations``' slots): each force then moves the
    bodies within their joints (``K Fᵀ`` for ``M⁻¹ Fᵀ``, :mod:`~animbatch.sim.contact.jointed`), so that a body a
    joint holds passes a load on to the joint instead of giving way under it (numpy only).

    Resting contacts are few, so this builds their small contact matrix ``A = J M⁻¹ Fᵀ`` (J: what each row measures,
    F: the force each row applies; a sliding contact's normal row also carries its kinetic friction, ``n - μk d``)
    and solves it by projected Gauss–Seidel, which converges in a few sweeps where Jacobi iteration crawls on
    redundant contacts (a box resting on four corners). ``iterations`` bounds the sweeps.
    """
    count = contacts.count
    result = SolveResult(np.zeros(count), np.zeros((count, 2)))
    if count == 0:
        return result
    rows = frame if frame is not None else ContactFrame.of(contacts, x)
    sliding = ~sticking
    normal_force_direction = rows.n - (contacts.kinetic_friction * sliding)[:, None] * slide_direction
    solution = np.zeros(3 * count)
    if warm is not None:
        solution[:count] = warm[0]
        solution[count:] = np.concatenate([warm[1][:, 0], warm[1][:, 1]]) * np.tile(sticking, 2)
    if compiled and jointed is None:
        _compiled_forces(rows, normal_force_direction, accelerations, normal_bias, tangent_bias, solution, sticking,
                         contacts.static_friction, iterations)
        result.normal_impulse[:] = solution[:count]
        result.tangent_impulse[:] = np.stack([solution[count:2 * count], solution[2 * count:]], axis=1)
        return result
    measure = rows.ends(rows.directions)  # (3K, 2, 6): each row at each of its ends
    force = measure  # the rows push along what they measure, but a sliding contact's normal row (with its friction)
    if sliding.any():
        force = measure.copy()
        force[:count] = rows.ends(normal_force_direction[None])
    body = np.tile(np.stack([rows.a, rows.b], axis=1), (3, 1))  # (3K, 2)
    response = np.concatenate([accelerations.inverse_mass[body][:, :, None] * force[:, :, :3],  # M⁻¹ Fᵀ per end
                               np.einsum("reij,rej->rei", accelerations.inverse_inertia[body], force[:, :, 3:])],
                              axis=2)
    spread = None  # with joints: K Fᵀ (6N, 3K), what each row's force does to every body's acceleration
    if jointed is None:
        # row i's acceleration per unit of force j, through the bodies their ends share (the fixed one responds not)
        shared = body[:, :, None, None] == body[None, None, :, :]
        matrix = np.einsum("iejf,iex,jfx->ij", shared, measure, response)  # (3K, 3K)
    else:
        size = len(accelerations.v)
        corrected = jointed.correct(_flat_columns(response, body, size))
        spread = corrected if isinstance(corrected, np.ndarray) else corrected.toarray()
        matrix = _flat_columns(measure, body, size).T @ spread
    v, w = accelerations.v, accelerations.omega
    free = (rows.along(v, w) + np.stack([normal_bias, tangent_bias[:, 0], tangent_bias[:, 1]])).ravel()
    diagonal = np.diag(matrix).copy()
    diagonal[diagonal <= 0] = np.inf
    limit = contacts.static_friction
    # a row update reads one row of A against the whole solution: for a few resting contacts (a box on its corners)
    # Python floats do that faster than numpy's scalars and views (a microsecond a row against three)
    small = 3 * count <= SMALL_FORCE_ROWS
    coupling: Any = matrix.tolist() if small else matrix
    constant: Any = free.tolist() if small else free
    pivot: Any = diagonal.tolist() if small else diagonal
    holds: Any = sticking.tolist() if small else sticking
    cone: Any = limit.tolist() if small else limit

    def update(row: int, current: Any) -> float:
        """Row ``row``'s value that meets its target with the others at ``current`` (Gauss–Seidel)."""
        along = sum(map(operator.mul, coupling[row], current)) if small else coupling[row] @ current
        return current[row] - (constant[row] + along) / pivot[row]

    current: Any = solution.tolist() if small else solution  # (numpy: the same array, updated in place)
    for _ in range(iterations):
        for k in range(count):
            current[k] = max(update(k, current), 0.0)
            if holds[k]:
                j1, j2 = count + k, 2 * count + k
                t1 = current[j1] = update(j1, current)
                t2 = update(j2, current)
                size_t = math.hypot(t1, t2)  # scalars: math, not numpy (a sweep is many of these)
                cap = cone[k] * current[k]
                scale = 1.0 if size_t <= cap else cap / size_t
                current[j1], current[j2] = t1 * scale, t2 * scale
        if small:  # judged in floats too: a dozen rows cost less than numpy's calls on them
            if _small_converged(coupling, constant, current, holds, cone, count):
                break
            continue
        residual = free + matrix @ solution
        normal_residual = np.where(solution[:count] > 0, np.abs(residual[:count]),
                                   np.maximum(-residual[:count], 0.0))
        tangential = np.hypot(residual[count:2 * count], residual[2 * count:]) * sticking
        inside = np.hypot(solution[count:2 * count], solution[2 * count:]) < limit * solution[:count] * (1 - 1e-9)
        if max(float(normal_residual.max()), float((tangential * inside).max())) <= ACCELERATION_TOLERANCE:
            break
    if small:
        solution = np.array(current, float)
    normal_force = solution[:count]
    tangent_force = np.stack([solution[count:2 * count], solution[2 * count:]], axis=1)
    if spread is not None:
        change = (spread @ solution).reshape(2, -1, 3)  # the flat velocity's linear, then angular, parts
        accelerations.v += change[0]
        accelerations.omega += change[1]
    else:
        change = response * solution[:, None, None]  # (3K, 2, 6): the accelerations the forces add at each end
        np.add.at(accelerations.v, body, change[:, :, :3])
        np.add.at(accelerations.omega, body, change[:, :, 3:])
    result.normal_impulse[:] = normal_force
    result.tangent_impulse[:] = tangent_force
    return result


def _flat_columns(per_end: np.ndarray, body: np.ndarray, size: int) -> np.ndarray:
    """Rows' values at their two ends (R, 2, 6: linear, angular), bodies ``body`` (R, 2), as columns (6 size, R) over
    the flat velocity ``[v.ravel(), ω.ravel()]`` of ``size`` bodies."""
    count = len(body)
    entry = 3 * body[:, :, None] + np.arange(3)  # (R, 2, 3): each end's three components in a part
    column = np.broadcast_to(np.arange(count)[:, None, None], entry.shape)
    flat = np.zeros((2, 3 * size, count))
    np.add.at(flat[0], (entry, column), per_end[:, :, :3])
    np.add.at(flat[1], (entry, column), per_end[:, :, 3:])
    return flat.reshape(6 * size, count)


def _compiled_forces(rows: ContactFrame, pushes: np.ndarray, accelerations: BodyVelocities, normal_bias: np.ndarray,
                     tangent_bias: np.ndarray, solution: np.ndarray, sticking: np.ndarray,
                     static_friction: np.ndarray, iterations: int) -> None:
    """:func:`solve_forces`' matrix, sweeps and accelerations in one compiled call, ``solution`` (3K,) updated in
    place (:func:`animbatch.sim.kernels.resting_forces.resting_forces`)."""
    from animbatch.sim.kernels import resting_forces

    def floats(values: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(values, dtype=np.float64)

    v, w = accelerations.v, accelerations.omega
    if not (v.flags.c_contiguous and w.flags.c_contiguous and v.dtype == w.dtype == np.float64):
        raise ValueError("the compiled resting forces change the accelerations in place: they must be C-contiguous "
                         "float64 arrays")
    solve: Any = resting_forces.resting_forces
    solve(np.asarray(rows.a, np.int64), np.asarray(rows.b, np.int64), floats(rows.directions), floats(pushes),
          floats(rows.r_a), floats(rows.r_b), floats(accelerations.inverse_mass), floats(accelerations.inverse_inertia),
          v, w, np.concatenate([normal_bias, tangent_bias[:, 0], tangent_bias[:, 1]]), solution,
          np.asarray(sticking, np.bool_), floats(static_friction), int(iterations), ACCELERATION_TOLERANCE)
