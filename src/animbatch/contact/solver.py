"""Contact impulses: restitution, non-penetration and Coulomb friction, solved together for all contacts.

For contact k between bodies a (the probe's) and b (the solid's, or a fixed collider), with normal n and lever arms
``r_a``, ``r_b`` from the centres of mass to the contact point, the relative velocity at the contact is
``u = (v_a + ω_a × r_a) - (v_b + ω_b × r_b)``. An impulse ``λ d`` along a direction d changes it by
``λ / w(d)`` along d, with ``w(d) = 1/m_a + (r_a × d)·I_a⁻¹(r_a × d) + (same for b)``: impulses change both
linear and angular momentum (``ΔP = λ d``, ``ΔL = r × λ d``), so a box landing on an edge tumbles and a sliding
ball starts to roll.

Each contact asks for (Newton's impact law with the lecture notes' coefficient of restitution, and Coulomb friction):

* normal: ``u_n ≥ target``, impulse ``λ_n ≥ 0``, and no impulse where the contact separates by itself. The target is
  ``-e u_n⁻`` (bounce) when the contact approaches faster than ``rest_speed``, 0 (rest) when slower, and, for a
  contact still ``gap`` away, ``-gap / h``: it may close the gap during the step but not pass it (speculative
  contact);
* friction: the tangential impulse makes ``u_t = 0`` if that needs no more than ``μs λ_n`` (sticking: the contact
  holds exactly, and stays stopped once stopped), and is ``μk λ_n`` against the sliding direction otherwise.

Overlapping bodies (depth beyond ``slop``) are pushed apart by a separate *pseudo-velocity* that moves positions only
(split impulse): a velocity bias would turn overlap into kinetic energy and make bodies pop out.

All contacts are solved at once by projected Jacobi iterations with *mass splitting* (each of a body's n contacts
sees it with n times its inverse mass, and the velocity updates are summed), which is fully vectorised and converges
to the simultaneous solution. Contacts that happen one after the other in time (a Newton's cradle with small gaps,
successive bounces) are resolved one after the other by the time stepping itself.

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
    """Velocities and inverse inertias of P bodies plus one fixed "body" at index P (for colliders).

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


@dataclass
class SolveResult:
    """Accumulated normal impulses (K,) and tangential impulses (K, 2), and the pseudo-velocities (P + 1, 3) that move
    positions out of overlaps (or None when nothing overlaps)."""

    normal_impulse: np.ndarray
    tangent_impulse: np.ndarray
    pseudo_v: np.ndarray | None = None
    pseudo_omega: np.ndarray | None = None


def solve(contacts: Contacts, bodies: BodyVelocities, x: np.ndarray, h: float, *, iterations: int,
          rest_speed: float, slop: float, bounce: bool = True) -> SolveResult:
    """Change ``bodies.v`` and ``bodies.omega`` in place so that the contacts hold, over a step of ``h`` [s].

    ``x``: centres of mass (P + 1, 3) [m]. ``bounce``: apply restitution (off when re-projecting velocities that
    were already resolved in this step).
    """
    count = contacts.count
    result = SolveResult(np.zeros(count), np.zeros((count, 2)))
    if count == 0:
        return result
    a = contacts.probe_body
    b = np.where(contacts.solid_body < 0, len(x) - 1, contacts.solid_body)
    n = contacts.normal
    t1, t2 = tangent_basis(n)
    r_a, r_b = contacts.point - x[a], contacts.point - x[b]
    # mass splitting: each body is shared by the contacts touching it
    shares = np.bincount(np.concatenate([a, b]), minlength=len(x)).astype(float)
    shares[-1] = 1.0
    inverse_mass = bodies.inverse_mass * shares
    inverse_inertia = bodies.inverse_inertia * shares[:, None, None]

    def weight(direction: np.ndarray) -> np.ndarray:
        ra, rb = cross(r_a, direction), cross(r_b, direction)
        angular = (np.einsum("ki,kij,kj->k", ra, inverse_inertia[a], ra)
                   + np.einsum("ki,kij,kj->k", rb, inverse_inertia[b], rb))
        return 1.0 / (inverse_mass[a] + inverse_mass[b] + angular)

    def relative(direction: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> np.ndarray:
        v = bodies.v if v is None else v
        w = bodies.omega if w is None else w
        return np.einsum("ki,ki->k", v[a] + cross(w[a], r_a) - v[b] - cross(w[b], r_b), direction)

    def apply(impulse: np.ndarray, v: np.ndarray | None = None, w: np.ndarray | None = None) -> None:
        """Add impulses (K, 3) at the contacts: +impulse on a, -impulse on b."""
        v = bodies.v if v is None else v
        w = bodies.omega if w is None else w
        for body, lever, sign in ((a, r_a, 1.0), (b, r_b, -1.0)):
            linear = bodies.inverse_mass[body][:, None] * impulse * sign
            angular = np.einsum("kij,kj->ki", bodies.inverse_inertia[body], cross(lever, impulse)) * sign
            for axis in range(3):
                v[:, axis] += np.bincount(body, weights=linear[:, axis], minlength=len(x))
                w[:, axis] += np.bincount(body, weights=angular[:, axis], minlength=len(x))
        v[-1] = 0.0  # the fixed body never moves
        w[-1] = 0.0

    w_n, w_1, w_2 = weight(n), weight(t1), weight(t2)
    approach = relative(n)
    tangential = np.stack([relative(t1), relative(t2)], axis=1)
    fast = approach < -rest_speed
    gap = contacts.gap
    bounce_target = -contacts.restitution * approach if bounce else np.zeros(count)
    arrives = approach * h < -gap  # reaches the surface within this step
    target = np.where(gap > 0, np.where(arrives & fast, bounce_target, -gap / h), np.where(fast, bounce_target, 0.0))
    sticking = np.linalg.norm(tangential, axis=1) <= rest_speed
    mu_static, mu_kinetic = contacts.static_friction, contacts.kinetic_friction
    normal_impulse = np.zeros(count)
    tangent_impulse = np.zeros((count, 2))
    for _ in range(iterations):
        delta = (target - relative(n)) * w_n
        updated = np.maximum(normal_impulse + delta, 0.0)
        apply((updated - normal_impulse)[:, None] * n)
        normal_impulse = updated
        wanted = tangent_impulse - np.stack([relative(t1) * w_1, relative(t2) * w_2], axis=1)
        size = np.linalg.norm(wanted, axis=1)
        # Coulomb: stick if the static cone allows it, otherwise slide at the kinetic limit
        holds = sticking & (size <= mu_static * normal_impulse)
        limit = np.where(holds, size, mu_kinetic * normal_impulse)
        scale = np.divide(np.minimum(size, limit), size, out=np.zeros(count), where=size > 0)
        updated_t = wanted * scale[:, None]
        change = updated_t - tangent_impulse
        apply(change[:, [0]] * t1 + change[:, [1]] * t2)
        tangent_impulse = updated_t
    result.normal_impulse[:] = normal_impulse
    result.tangent_impulse[:] = tangent_impulse
    overlap = np.maximum(-gap - slop, 0.0)
    if np.any(overlap > 0):  # split impulse: push apart through positions only
        pseudo_v, pseudo_w = np.zeros_like(bodies.v), np.zeros_like(bodies.omega)
        push_target = BAUMGARTE * overlap / h
        push = np.zeros(count)
        for _ in range(iterations):
            updated = np.maximum(push + (push_target - relative(n, pseudo_v, pseudo_w)) * w_n, 0.0)
            apply((updated - push)[:, None] * n, pseudo_v, pseudo_w)
            push = updated
        result.pseudo_v, result.pseudo_omega = pseudo_v, pseudo_w
    return result
