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

from dataclasses import dataclass

import numpy as np

from animbatch.contact.detection import Contacts
from animbatch.rigid.quaternion import cross

#: Fraction of an overlap (beyond the slop) removed per step.
BAUMGARTE = 0.2


@dataclass
class BodyVelocities:
    """Velocities (or accelerations) and inverse inertias of P bodies plus one fixed "body" at index P (colliders).

    ``v``, ``omega``: (P + 1, 3); ``inverse_mass``: (P + 1,); ``inverse_inertia``: (P + 1, 3, 3), world axes
    (zero for particles, which do not turn, and for the fixed body).
    """

    v: np.ndarray
    omega: np.ndarray
    inverse_mass: np.ndarray
    inverse_inertia: np.ndarray


def tangent_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (K, 3) spanning the plane perpendicular to each normal."""
    helper = np.where(np.abs(normal[:, [0]]) < 0.6, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = cross(normal, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return first, cross(normal, first)


class ContactRows:
    """The rows of K contacts on the bodies of ``bodies``: directions, lever arms, effective masses, and how to read
    relative motion along a row and apply impulses (or forces) to the bodies."""

    def __init__(self, contacts: Contacts, bodies: BodyVelocities, x: np.ndarray) -> None:
        self.bodies = bodies
        self.count = contacts.count
        self.size = len(x)
        self.a = contacts.probe_body
        self.b = np.where(contacts.solid_body < 0, len(x) - 1, contacts.solid_body)
        self.n = contacts.normal
        self.t1, self.t2 = tangent_basis(self.n)
        self.r_a, self.r_b = contacts.point - x[self.a], contacts.point - x[self.b]
        # mass splitting: each body is shared by the contacts touching it
        shares = np.bincount(np.concatenate([self.a, self.b]), minlength=len(x)).astype(float)
        shares[-1] = 1.0
        self._split_mass = bodies.inverse_mass * shares
        self._split_inertia = bodies.inverse_inertia * shares[:, None, None]
        self.w_n, self.w_1, self.w_2 = self.weight(self.n), self.weight(self.t1), self.weight(self.t2)

    def weight(self, direction: np.ndarray) -> np.ndarray:
        """Effective mass of each row along ``direction`` (K, 3), with masses split among contacts."""
        a, b = self.a, self.b
        ra, rb = cross(self.r_a, direction), cross(self.r_b, direction)
        angular = (np.einsum("ki,kij,kj->k", ra, self._split_inertia[a], ra)
                   + np.einsum("ki,kij,kj->k", rb, self._split_inertia[b], rb))
        return 1.0 / (self._split_mass[a] + self._split_mass[b] + angular)

    def relative(self, direction: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        """Relative velocity (or acceleration) of the contact points along ``direction``, (K,)."""
        v = self.bodies.v if v is None else v
        w = self.bodies.omega if w is None else w
        a, b = self.a, self.b
        return np.einsum("ki,ki->k", v[a] + cross(w[a], self.r_a) - v[b] - cross(w[b], self.r_b), direction)

    def apply(self, impulse: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> None:
        """Add impulses (or forces) (K, 3) at the contacts: +impulse on a, -impulse on b."""
        v = self.bodies.v if v is None else v
        w = self.bodies.omega if w is None else w
        for body, lever, sign in ((self.a, self.r_a, 1.0), (self.b, self.r_b, -1.0)):
            linear = self.bodies.inverse_mass[body][:, None] * impulse * sign
            angular = np.einsum("kij,kj->ki", self.bodies.inverse_inertia[body], cross(lever, impulse)) * sign
            for axis in range(3):
                v[:, axis] += np.bincount(body, weights=linear[:, axis], minlength=self.size)
                w[:, axis] += np.bincount(body, weights=angular[:, axis], minlength=self.size)
        v[-1] = 0.0  # the fixed body never moves
        w[-1] = 0.0

    def tangential(self, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        """Relative tangential motion (K, 2) in the (t1, t2) basis."""
        return np.stack([self.relative(self.t1, v, w), self.relative(self.t2, v, w)], axis=1)

    def friction_step(self, tangent_impulse: np.ndarray, normal_impulse: np.ndarray, static: np.ndarray,
                      sticking: np.ndarray, kinetic: np.ndarray) -> np.ndarray:
        """One Coulomb projection: the tangential impulse that stops the relative tangential motion if the static
        cone allows it (for contacts that may stick), else the kinetic limit against it. Returns the new total."""
        current = self.tangential()
        wanted = tangent_impulse - np.stack([current[:, 0] * self.w_1, current[:, 1] * self.w_2], axis=1)
        size = np.linalg.norm(wanted, axis=1)
        holds = sticking & (size <= static * normal_impulse)
        limit = np.where(holds, size, kinetic * normal_impulse)
        scale = np.divide(np.minimum(size, limit), size, out=np.zeros(self.count), where=size > 0)
        updated = wanted * scale[:, None]
        change = updated - tangent_impulse
        self.apply(change[:, [0]] * self.t1 + change[:, [1]] * self.t2)
        return updated


@dataclass
class SolveResult:
    """Accumulated normal impulses (or forces) (K,) and tangential ones (K, 2); for impulse solves, the
    pseudo-velocities (P + 1, 3) that move positions out of overlaps (or None when nothing overlaps)."""

    normal_impulse: np.ndarray
    tangent_impulse: np.ndarray
    pseudo_v: np.ndarray | None = None
    pseudo_omega: np.ndarray | None = None


def solve_impulses(contacts: Contacts, bodies: BodyVelocities, x: np.ndarray, h: float, *, iterations: int,
                   rest_speed: float, slop: float, bounce: bool = True) -> SolveResult:
    """Change ``bodies.v`` and ``bodies.omega`` in place so that the contacts hold, over a step of ``h`` [s].

    ``x``: centres of mass (P + 1, 3) [m]. ``bounce``: apply restitution (off when re-projecting velocities that
    were already resolved in this step). ``h = 0`` means an instant: no speculative contacts, no pushing apart.
    """
    count = contacts.count
    result = SolveResult(np.zeros(count), np.zeros((count, 2)))
    if count == 0:
        return result
    rows = ContactRows(contacts, bodies, x)
    n = rows.n
    approach = rows.relative(n)
    sticking = np.linalg.norm(rows.tangential(), axis=1) <= rest_speed
    fast = approach < -rest_speed
    gap = contacts.gap
    bounce_target = -contacts.restitution * approach if bounce else np.zeros(count)
    if h > 0:
        arrives = approach * h < -gap  # reaches the surface within this step
        target = np.where(gap > 0, np.where(arrives & fast, bounce_target, -gap / h),
                          np.where(fast, bounce_target, 0.0))
    else:
        target = np.where(fast, bounce_target, 0.0)
    normal_impulse = np.zeros(count)
    tangent_impulse = np.zeros((count, 2))
    for _ in range(iterations):
        updated = np.maximum(normal_impulse + (target - rows.relative(n)) * rows.w_n, 0.0)
        rows.apply((updated - normal_impulse)[:, None] * n)
        normal_impulse = updated
        tangent_impulse = rows.friction_step(tangent_impulse, normal_impulse, contacts.static_friction, sticking,
                                             contacts.kinetic_friction)
    result.normal_impulse[:] = normal_impulse
    result.tangent_impulse[:] = tangent_impulse
    overlap = np.maximum(-gap - slop, 0.0)
    if h > 0 and np.any(overlap > 0):  # split impulse: push apart through positions only
        pseudo_v, pseudo_w = np.zeros_like(bodies.v), np.zeros_like(bodies.omega)
        push_target = BAUMGARTE * overlap / h
        push = np.zeros(count)
        for _ in range(iterations):
            updated = np.maximum(push + (push_target - rows.relative(n, pseudo_v, pseudo_w)) * rows.w_n, 0.0)
            rows.apply((updated - push)[:, None] * n, pseudo_v, pseudo_w)
            push = updated
        result.pseudo_v, result.pseudo_omega = pseudo_v, pseudo_w
    return result


def solve_forces(contacts: Contacts, accelerations: BodyVelocities, x: np.ndarray, *, normal_bias: np.ndarray,
                 tangent_bias: np.ndarray, sticking: np.ndarray, slide_direction: np.ndarray,
                 iterations: int) -> SolveResult:
    """Forces of resting contacts, changing the accelerations in ``accelerations`` (``v``: linear, ``omega``:
    angular) in place.

    ``normal_bias`` (K,): the part of each gap's second derivative not carried by the accelerations (velocity
    products, stabilisation); the normal rows make ``relative acceleration + normal_bias ≥ 0``. ``tangent_bias``
    (K, 2): the same for the contact points' tangential acceleration. ``sticking`` (K,) bool; ``slide_direction``
    (K, 3): unit slip direction of sliding contacts (friction opposes it).
    """
    count = contacts.count
    result = SolveResult(np.zeros(count), np.zeros((count, 2)))
    if count == 0:
        return result
    rows = ContactRows(contacts, accelerations, x)
    n = rows.n
    normal_force = np.zeros(count)
    tangent_force = np.zeros((count, 2))
    sliding = ~sticking
    kinetic_direction = -slide_direction
    mu_k = contacts.kinetic_friction
    for _ in range(iterations):
        updated = np.maximum(normal_force - (rows.relative(n) + normal_bias) * rows.w_n, 0.0)
        change = updated - normal_force
        rows.apply(change[:, None] * n)
        if sliding.any():  # kinetic friction follows the normal force, against the slip
            rows.apply((change * mu_k * sliding)[:, None] * kinetic_direction)
        normal_force = updated
        if sticking.any():
            current = rows.tangential() + tangent_bias
            wanted = tangent_force - np.stack([current[:, 0] * rows.w_1, current[:, 1] * rows.w_2], axis=1)
            size = np.linalg.norm(wanted, axis=1)
            limit = contacts.static_friction * normal_force
            scale = np.divide(np.minimum(size, limit), size, out=np.zeros(count), where=size > 0)
            updated_t = np.where(sticking[:, None], wanted * scale[:, None], 0.0)
            delta = updated_t - tangent_force
            rows.apply(delta[:, [0]] * rows.t1 + delta[:, [1]] * rows.t2)
            tangent_force = updated_t
    result.normal_impulse[:] = normal_force
    result.tangent_impulse[:] = tangent_force
    return result
