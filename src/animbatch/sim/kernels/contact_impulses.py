"""Compiled iterations of the contact impulse solver: the loops of :func:`animbatch.sim.contact.impulses.solve_impulses`
(projected Jacobi with mass splitting), in one pass over the contacts per half iteration instead of five sparse
products and a dozen temporary arrays.

On a pile of 10 000 balls the iterations were 93 % of a step and contact detection 5 %, so the iterations are what is
compiled. For small jointed systems (a ragdoll) the rows themselves are built here too (:func:`small_jointed_rows`):
their response within the joints took some twenty numpy calls a step. Every operation is the numpy code's, in the
same order per contact, so the two agree to round-off (the tests compare them): a row's rate
``(v_a − v_b)·d + ω_a·(r_a × d) − ω_b·(r_b × d)`` is :meth:`ContactRows.relative`, and an impulse λ along a row
adds ``λ lin_a`` and ``λ turn_a`` to body a's linear and angular velocity and takes ``λ lin_b``, ``λ turn_b`` from
body b's, as the response matrices do.

Arrays (K contacts, B bodies with the fixed one last): ``velocity`` (6 B,) flat, ``[v.ravel(), ω.ravel()]``, changed in
place; ``a``, ``b`` (K,) body indices; per row r (0: normal, 1 and 2: tangents) ``direction``, ``arm_a``, ``arm_b``
(``r × d``), ``lin_a``, ``lin_b``, ``turn_a``, ``turn_b``: (3, K, 3); ``weight`` (3, K): effective masses.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from animbatch.sim.kernels.stall import stalled

#: The numpy sweeps' rule for a stall (:mod:`animbatch.sim.kernels.stall`), compiled as it is.
_stalled = njit(cache=True, inline="always")(stalled)


@njit(cache=True, inline="always")
def _rate(velocity: np.ndarray, bodies: int, row: int, k: int, a: np.ndarray, b: np.ndarray, direction: np.ndarray,
          arm_a: np.ndarray, arm_b: np.ndarray) -> float:
    """The relative velocity of contact k along row ``row``."""
    i, j = 3 * a[k], 3 * b[k]
    wi, wj = 3 * (bodies + a[k]), 3 * (bodies + b[k])
    linear = 0.0
    angular_a = 0.0
    angular_b = 0.0
    for c in range(3):
        linear += (velocity[i + c] - velocity[j + c]) * direction[row, k, c]
        angular_a += velocity[wi + c] * arm_a[row, k, c]
        angular_b += velocity[wj + c] * arm_b[row, k, c]
    return linear + angular_a - angular_b


@njit(cache=True, inline="always")
def _apply(velocity: np.ndarray, bodies: int, row: int, k: int, amount: float, a: np.ndarray, b: np.ndarray,
           lin_a: np.ndarray, lin_b: np.ndarray, turn_a: np.ndarray, turn_b: np.ndarray) -> None:
    """An impulse ``amount`` along row ``row`` of contact k, into the velocities."""
    i, j = 3 * a[k], 3 * b[k]
    wi, wj = 3 * (bodies + a[k]), 3 * (bodies + b[k])
    for c in range(3):
        velocity[i + c] += amount * lin_a[row, k, c]
        velocity[wi + c] += amount * turn_a[row, k, c]
        velocity[j + c] -= amount * lin_b[row, k, c]
        velocity[wj + c] -= amount * turn_b[row, k, c]


@njit(cache=True)
def apply_impulses(velocity: np.ndarray, normal: np.ndarray, tangent: np.ndarray, a: np.ndarray, b: np.ndarray,
                   lin_a: np.ndarray, lin_b: np.ndarray, turn_a: np.ndarray, turn_b: np.ndarray) -> None:
    """Normal impulses (K,) and tangential ones (K, 2) into the velocities, all at once."""
    bodies = len(velocity) // 6
    for k in range(len(a)):
        _apply(velocity, bodies, 0, k, normal[k], a, b, lin_a, lin_b, turn_a, turn_b)
    for k in range(len(a)):
        _apply(velocity, bodies, 1, k, tangent[k, 0], a, b, lin_a, lin_b, turn_a, turn_b)
    for k in range(len(a)):
        _apply(velocity, bodies, 2, k, tangent[k, 1], a, b, lin_a, lin_b, turn_a, turn_b)


@njit(cache=True)
def impulse_iterations(velocity: np.ndarray, a: np.ndarray, b: np.ndarray, direction: np.ndarray, arm_a: np.ndarray,
                       arm_b: np.ndarray, lin_a: np.ndarray, lin_b: np.ndarray, turn_a: np.ndarray,
                       turn_b: np.ndarray, weight: np.ndarray, target: np.ndarray, normal_impulse: np.ndarray,
                       tangent_impulse: np.ndarray, static: np.ndarray, kinetic: np.ndarray, sticking: np.ndarray,
                       iterations: int, tolerance: float) -> tuple[int, float]:
    """The solver's sweeps, normal then friction, until every contact does what it must (to ``tolerance``) or after
    ``iterations``; ``normal_impulse`` (K,) and ``tangent_impulse`` (K, 2) are updated in place. Returns the sweeps
    made and the largest violation left [m/s] (above ``tolerance``: the sweeps ran out)."""
    count = len(a)
    bodies = len(velocity) // 6
    normal_now = np.empty(count)
    change = np.empty(count)
    updated = np.empty((count, 2))
    gripping = np.zeros(count, np.bool_)
    watch = np.full(2, np.inf)
    for iteration in range(iterations + 1):
        for k in range(count):
            normal_now[k] = _rate(velocity, bodies, 0, k, a, b, direction, arm_a, arm_b) - target[k]
        if iteration > 0:
            worst = 0.0
            for k in range(count):
                violation = abs(normal_now[k]) if normal_impulse[k] > 0 else max(-normal_now[k], 0.0)
                worst = max(worst, violation)
                if gripping[k]:
                    first = _rate(velocity, bodies, 1, k, a, b, direction, arm_a, arm_b)
                    second = _rate(velocity, bodies, 2, k, a, b, direction, arm_a, arm_b)
                    worst = max(worst, math.sqrt(first * first + second * second))
            if worst <= tolerance or iteration == iterations or _stalled(iteration, worst, watch):
                return iteration, worst
        for k in range(count):
            new = max(normal_impulse[k] - normal_now[k] * weight[0, k], 0.0)
            change[k] = new - normal_impulse[k]
            normal_impulse[k] = new
        for k in range(count):
            _apply(velocity, bodies, 0, k, change[k], a, b, lin_a, lin_b, turn_a, turn_b)
        # Coulomb: the impulse that stops the tangential motion if the static cone allows, else the kinetic limit
        for k in range(count):
            first = _rate(velocity, bodies, 1, k, a, b, direction, arm_a, arm_b)
            second = _rate(velocity, bodies, 2, k, a, b, direction, arm_a, arm_b)
            wanted_1 = tangent_impulse[k, 0] - first * weight[1, k]
            wanted_2 = tangent_impulse[k, 1] - second * weight[2, k]
            size = math.sqrt(wanted_1 * wanted_1 + wanted_2 * wanted_2)
            holds = sticking[k] and size <= static[k] * normal_impulse[k]
            limit = size if holds else kinetic[k] * normal_impulse[k]
            scale = min(size, limit) / size if size > 0 else 0.0
            updated[k, 0], updated[k, 1] = wanted_1 * scale, wanted_2 * scale
            gripping[k] = holds
        for k in range(count):
            _apply(velocity, bodies, 1, k, updated[k, 0] - tangent_impulse[k, 0], a, b, lin_a, lin_b, turn_a, turn_b)
            _apply(velocity, bodies, 2, k, updated[k, 1] - tangent_impulse[k, 1], a, b, lin_a, lin_b, turn_a, turn_b)
            tangent_impulse[k, 0], tangent_impulse[k, 1] = updated[k, 0], updated[k, 1]
    return iterations, np.inf  # only with iterations = 0 (the loop returns)


@njit(cache=True)
def push_iterations(pseudo: np.ndarray, a: np.ndarray, b: np.ndarray, direction: np.ndarray, arm_a: np.ndarray,
                    arm_b: np.ndarray, lin_a: np.ndarray, lin_b: np.ndarray, turn_a: np.ndarray, turn_b: np.ndarray,
                    weight: np.ndarray, push_target: np.ndarray, enough: float, iterations: int) -> None:
    """The split impulse's sweeps on the pseudo-velocities ``pseudo`` (6 B,), normals only, until every push meets
    its target to ``enough`` or after ``iterations``."""
    count = len(a)
    bodies = len(pseudo) // 6
    push = np.zeros(count)
    pushed = np.empty(count)
    for _ in range(iterations):
        worst = 0.0
        for k in range(count):
            pushed[k] = _rate(pseudo, bodies, 0, k, a, b, direction, arm_a, arm_b) - push_target[k]
            worst = max(worst, abs(pushed[k]) if push[k] > 0 else max(-pushed[k], 0.0))
        if worst <= enough:
            return
        for k in range(count):
            new = max(push[k] - pushed[k] * weight[0, k], 0.0)
            _apply(pseudo, bodies, 0, k, new - push[k], a, b, lin_a, lin_b, turn_a, turn_b)
            push[k] = new


@njit(cache=True, error_model="numpy")
def dense_pushes(pseudo: np.ndarray, jacobian_normal: np.ndarray, response_normal: np.ndarray, weight: np.ndarray,
                 push_target: np.ndarray, enough: float, iterations: int) -> None:
    """The numpy split impulse's sweeps (:func:`animbatch.sim.contact.impulses._pushes`) on the normal rows as arrays
    (small jointed scenes): ``jacobian_normal`` (K, V), ``response_normal`` (V, K), ``weight`` (K,) the normals'
    effective masses; ``pseudo`` (V,) changes in place until every push meets its target ``push_target`` (K,)
    [m/s] to ``enough`` or after ``iterations``. The same operations in the same order (Jacobi: every push from the
    same rates), so the same pseudo-velocities to round-off."""
    count = len(push_target)
    push = np.zeros(count)
    change = np.empty(count)
    for _ in range(iterations):
        pushed = jacobian_normal @ pseudo - push_target
        worst = 0.0
        for k in range(count):
            worst = max(worst, abs(pushed[k]) if push[k] > 0 else max(-pushed[k], 0.0))
        if worst <= enough:
            return
        for k in range(count):
            updated = max(push[k] - pushed[k] * weight[k], 0.0)
            change[k] = updated - push[k]
            push[k] = updated
        pseudo += response_normal @ change


@njit(cache=True, error_model="numpy")
def contact_rows(a: np.ndarray, b: np.ndarray, normal: np.ndarray, point: np.ndarray, x: np.ndarray,
                 inverse_mass: np.ndarray, inverse_inertia: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                            np.ndarray]:
    """The rows of K contacts as :class:`animbatch.sim.contact.impulses.ContactRows` builds them, in one pass:
    ``direction`` (normal, then the tangent basis of ``tangent_basis``), ``arm_a``, ``arm_b`` (``r × d``),
    ``lin_a``, ``lin_b`` (``d / m``), ``turn_a``, ``turn_b`` (``I⁻¹ (r × d)``), all (3, K, 3), and the effective
    masses ``weight`` (3, K) with each body's inverse mass and inertia times its number of contacts (mass
    splitting; the fixed body, last, counts once). ``x`` (B, 3) [m] centres of mass, ``inverse_mass`` (B,),
    ``inverse_inertia`` (B, 3, 3) world axes."""
    count, bodies = len(a), len(x)
    shares = np.zeros(bodies)
    for k in range(count):
        shares[a[k]] += 1.0
        shares[b[k]] += 1.0
    shares[bodies - 1] = 1.0
    direction = np.empty((3, count, 3))
    arm_a, arm_b = np.empty((3, count, 3)), np.empty((3, count, 3))
    lin_a, lin_b = np.empty((3, count, 3)), np.empty((3, count, 3))
    turn_a, turn_b = np.empty((3, count, 3)), np.empty((3, count, 3))
    weight = np.empty((3, count))
    for k in range(count):
        n0, n1, n2 = normal[k, 0], normal[k, 1], normal[k, 2]
        h0, h1, h2 = (1.0, 0.0, 0.0) if abs(n0) < 0.6 else (0.0, 1.0, 0.0)
        f0, f1, f2 = n1 * h2 - n2 * h1, n2 * h0 - n0 * h2, n0 * h1 - n1 * h0
        size = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        f0, f1, f2 = f0 / size, f1 / size, f2 / size
        direction[0, k, 0], direction[0, k, 1], direction[0, k, 2] = n0, n1, n2
        direction[1, k, 0], direction[1, k, 1], direction[1, k, 2] = f0, f1, f2
        direction[2, k, 0], direction[2, k, 1] = n1 * f2 - n2 * f1, n2 * f0 - n0 * f2
        direction[2, k, 2] = n0 * f1 - n1 * f0
        i, j = a[k], b[k]
        for row in range(3):
            inverse = 0.0
            for end in range(2):
                body = i if end == 0 else j
                arm, lin, turn = (arm_a, lin_a, turn_a) if end == 0 else (arm_b, lin_b, turn_b)
                r0, r1, r2 = point[k, 0] - x[body, 0], point[k, 1] - x[body, 1], point[k, 2] - x[body, 2]
                d0, d1, d2 = direction[row, k, 0], direction[row, k, 1], direction[row, k, 2]
                arm[row, k, 0], arm[row, k, 1] = r1 * d2 - r2 * d1, r2 * d0 - r0 * d2
                arm[row, k, 2] = r0 * d1 - r1 * d0
                for c in range(3):
                    lin[row, k, c] = inverse_mass[body] * direction[row, k, c]
                    turn[row, k, c] = (inverse_inertia[body, c, 0] * arm[row, k, 0]
                                       + inverse_inertia[body, c, 1] * arm[row, k, 1]
                                       + inverse_inertia[body, c, 2] * arm[row, k, 2])
                own = 0.0
                for c in range(3):
                    own += lin[row, k, c] * direction[row, k, c]
                turned = 0.0
                for c in range(3):
                    turned += turn[row, k, c] * arm[row, k, c]
                inverse += shares[body] * (own + turned)
            weight[row, k] = 1.0 / inverse
    return direction, arm_a, arm_b, lin_a, lin_b, turn_a, turn_b, weight


@njit(cache=True, error_model="numpy")
def _block_solve(normal_impulse: np.ndarray, normal_now: np.ndarray, chosen: np.ndarray, matrix: np.ndarray,
                 passes: int, patterns: np.ndarray, inverses: np.ndarray, stored: np.ndarray) -> np.ndarray:
    """:meth:`animbatch.sim.contact.impulses.JointedNormals.solve`: the chosen rows' normal impulses by active sets,
    the others as they were. Each pass's pseudo-inverse is kept (``patterns`` (P, J): the active rows it was made
    for, ``inverses`` (P, J, J): it, on those rows and zero elsewhere, ``stored`` (P,): whether there is one) and
    used again while that pass meets the same active rows, as it does solve after solve of one sweep loop."""
    start = normal_impulse[chosen]
    active = (start > 0) | (normal_now[chosen] < 0)
    result = normal_impulse.copy()
    found = start.copy()
    size = len(chosen)
    right = np.empty(size)
    for p in range(passes):
        found = start.copy()
        if active.any():
            if not (stored[p] and np.array_equal(patterns[p], active)):
                where = np.flatnonzero(active)
                system = np.empty((len(where), len(where)))
                for i in range(len(where)):
                    for j in range(len(where)):
                        system[i, j] = matrix[where[i], where[j]]
                inverse = np.linalg.pinv(system, rcond=1e-12)
                inverses[p] = 0.0
                for i in range(len(where)):
                    for j in range(len(where)):
                        inverses[p, where[i], where[j]] = inverse[i, j]
                patterns[p] = active
                stored[p] = True
            for i in range(size):
                right[i] = -normal_now[chosen[i]] if active[i] else 0.0
            found += inverses[p] @ right
        negative = active & (found < 0)
        if not negative.any():
            break
        active &= ~negative
    for i in range(size):
        result[chosen[i]] = max(found[i], 0.0)
    return result


@njit(cache=True, error_model="numpy")
def dense_sweeps(velocity: np.ndarray, jacobian_normal: np.ndarray, jacobian_tangent: np.ndarray,
                 response_normal: np.ndarray, response_tangent: np.ndarray, weight: np.ndarray,
                 target: np.ndarray, normal_impulse: np.ndarray, tangent_impulse: np.ndarray,
                 static_friction: np.ndarray, kinetic_friction: np.ndarray, sticking: np.ndarray,
                 block_chosen: np.ndarray, block_matrix: np.ndarray, block_every: int, block_passes: int,
                 iterations: int, tolerance: float) -> tuple[np.ndarray, np.ndarray, int, float]:
    """The numpy sweeps of :func:`animbatch.sim.contact.impulses._sweeps` on the row matrices as arrays (what small
    jointed scenes use: the responses are the joints' ``K Jᵀ``): ``jacobian_normal`` (K, V), ``jacobian_tangent``
    (2K, V), ``response_normal`` (V, K), ``response_tangent`` (V, 2K), ``weight`` (3, K); the jointed contacts'
    normals (``block_chosen``, none: empty) solved at once every ``block_every`` sweeps. ``velocity`` (V,) changes
    in place; returns the normal (K,) and tangential (K, 2) impulses, the sweeps made and the largest violation
    left [m/s].

    The sweeps read the body velocities only through the rows' rates ``J v`` (3K,) and change them only by
    ``R Δλ``. A solve that goes on past :func:`_contact_space_after` sweeps therefore carries on in contact space:
    the rates updated by the Delassus matrix ``J R`` (3K, 3K), built once, and the velocities moved once at the end
    by the impulses' total change. A sweep then costs (3K)² instead of some 8 K V (V = 6 per body: a ragdoll's
    four contacts on 72 velocities, twelve times less); the same operations on the same numbers, so the same
    impulses to round-off."""
    count = len(target)
    gripping = np.zeros(count, np.bool_)
    worst, sweeps = np.inf, iterations
    switch = _contact_space_after(count, len(velocity))
    chosen_count = len(block_chosen)  # the block's pseudo-inverses, pass by pass (_block_solve)
    patterns = np.zeros((block_passes, chosen_count), np.bool_)
    inverses = np.zeros((block_passes, chosen_count, chosen_count))
    stored = np.zeros(block_passes, np.bool_)
    delassus = np.zeros((0, 0))
    rates = np.zeros(0)  # J v (3K,) while in contact space: normals, first tangents, second tangents
    from_normal, from_tangent = normal_impulse.copy(), tangent_impulse.copy()  # the impulses at the switch
    watch = np.full(2, np.inf)
    for iteration in range(iterations + 1):
        in_rates = len(rates) > 0
        if in_rates:
            normal_now = rates[:count] - target
            tangential = rates[count:]
        else:
            normal_now = jacobian_normal @ velocity - target
            tangential = np.zeros(0)
        if iteration > 0:
            worst = 0.0
            for k in range(count):
                worst = max(worst, abs(normal_now[k]) if normal_impulse[k] > 0 else max(-normal_now[k], 0.0))
            if not in_rates:
                tangential = jacobian_tangent @ velocity
            for k in range(count):
                if gripping[k]:
                    worst = max(worst, math.sqrt(tangential[k] ** 2 + tangential[count + k] ** 2))
            if worst <= tolerance or iteration == iterations or _stalled(iteration, worst, watch):
                sweeps = iteration
                break
        if not in_rates and iteration == switch:
            if iteration == 0:
                tangential = jacobian_tangent @ velocity
            rates = np.concatenate((normal_now + target, tangential))
            delassus = np.vstack((jacobian_normal, jacobian_tangent)) @ np.hstack((response_normal,
                                                                                   response_tangent))
            from_normal, from_tangent = normal_impulse.copy(), tangent_impulse.copy()
            in_rates = True
        updated = np.maximum(normal_impulse - normal_now * weight[0], 0.0)
        if len(block_chosen) and iteration % block_every == 0:
            updated = _block_solve(normal_impulse, normal_now, block_chosen, block_matrix, block_passes, patterns,
                                   inverses, stored)
        if in_rates:
            _delassus_push(rates, delassus, updated - normal_impulse, 0)
            current = rates[count:]
        else:
            velocity += response_normal @ (updated - normal_impulse)
            current = jacobian_tangent @ velocity
        normal_impulse = updated
        # one Coulomb projection: stop the sliding if the static cone allows it, else the kinetic limit against it
        change = np.empty(2 * count)
        fresh = np.empty((count, 2))
        for k in range(count):
            wanted0 = tangent_impulse[k, 0] - current[k] * weight[1, k]
            wanted1 = tangent_impulse[k, 1] - current[count + k] * weight[2, k]
            size = math.sqrt(wanted0 * wanted0 + wanted1 * wanted1)
            holds = sticking[k] and size <= static_friction[k] * normal_impulse[k]
            limit = size if holds else kinetic_friction[k] * normal_impulse[k]
            scale = min(size, limit) / size if size > 0 else 0.0
            fresh[k, 0], fresh[k, 1] = wanted0 * scale, wanted1 * scale
            change[k], change[count + k] = fresh[k, 0] - tangent_impulse[k, 0], fresh[k, 1] - tangent_impulse[k, 1]
            gripping[k] = holds
        if in_rates:
            _delassus_push(rates, delassus, change, count)
        else:
            velocity += response_tangent @ change
        tangent_impulse = fresh
    if len(rates):  # the velocities take the impulses' change since the switch at once
        change = np.empty(2 * count)
        for k in range(count):
            change[k] = tangent_impulse[k, 0] - from_tangent[k, 0]
            change[count + k] = tangent_impulse[k, 1] - from_tangent[k, 1]
        velocity += response_normal @ (normal_impulse - from_normal) + response_tangent @ change
    return normal_impulse, tangent_impulse, sweeps, worst


@njit(cache=True, inline="always")
def _contact_space_after(count: int, velocities: int) -> int:
    """The sweep from which :func:`dense_sweeps` works in contact space: once the sweeps already made cost about
    what building the Delassus matrix does (9 K² V flops against some 8 K V a sweep), so that a solve done in a
    sweep or two never pays for it and a long one gains from its first sweeps."""
    return 1 + (9 * count * velocities) // max(8 * velocities - 9 * count, velocities)


@njit(cache=True, inline="always")
def _delassus_push(rates: np.ndarray, delassus: np.ndarray, change: np.ndarray, first: int) -> None:
    """``rates += delassus[:, first:first + len(change)] @ change``: the rows' rates after impulses ``change`` on the
    rows from ``first``."""
    for r in range(len(rates)):
        total = 0.0
        for c in range(len(change)):
            total += delassus[r, first + c] * change[c]
        rates[r] += total


@njit(cache=True, error_model="numpy")
def solve_contacts(a: np.ndarray, b: np.ndarray, normal: np.ndarray, point: np.ndarray, gap: np.ndarray,
                   restitution: np.ndarray, static: np.ndarray, kinetic: np.ndarray, x: np.ndarray,
                   inverse_mass: np.ndarray, inverse_inertia: np.ndarray, velocity: np.ndarray,
                   warm_normal: np.ndarray, warm_tangent: np.ndarray, h: float, bounce: bool, rest_speed: float,
                   slop: float, iterations: int, settings: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float]:
    """A whole impulse solve of :func:`animbatch.sim.contact.impulses.solve_impulses` (without joints) in one call:
    the rows (:func:`contact_rows`), each contact's approach and whether it sticks, its velocity target (bounce,
    speculative gap, rest), the warm start, the sweeps (:func:`impulse_iterations`) and the split impulse's push
    (:func:`push_iterations`), in the numpy code's order.

    Contacts (K,): ``a``, ``b`` body slots, ``normal``, ``point`` (K, 3), ``gap`` [m], ``restitution``, ``static``
    and ``kinetic`` friction; bodies (B, the fixed one last): ``x`` (B, 3), ``inverse_mass`` (B,),
    ``inverse_inertia`` (B, 3, 3), ``velocity`` (6 B,) flat, changed in place; the warm start's normal impulses (K,)
    and tangential impulse vectors (K, 3). ``settings``: the solver's constants ``[VELOCITY_TOLERANCE, BAUMGARTE,
    OVERLAP_TOLERANCE, PUSH_TOLERANCE, PUSH_ITERATIONS]``.

    Returns the normal (K,) and tangential (K, 2) impulses, the tangential ones as world vectors (K, 3), which
    contacts are impacts (K,) and where in the step their gaps close (K,), the push's pseudo-velocities (6 B,)
    (empty when nothing overlaps beyond the slop), and the largest violation the sweeps left [m/s]
    (:func:`impulse_iterations`) with the tolerance it is held to (above it, the sweeps ran out)."""
    count = len(a)
    bodies = len(velocity) // 6
    direction, arm_a, arm_b, lin_a, lin_b, turn_a, turn_b, weight = contact_rows(a, b, normal, point, x,
                                                                               inverse_mass, inverse_inertia)
    approach = np.empty(count)
    sticking = np.empty(count, np.bool_)
    largest = 0.0
    for k in range(count):
        approach[k] = _rate(velocity, bodies, 0, k, a, b, direction, arm_a, arm_b)
        first = _rate(velocity, bodies, 1, k, a, b, direction, arm_a, arm_b)
        second = _rate(velocity, bodies, 2, k, a, b, direction, arm_a, arm_b)
        sticking[k] = np.hypot(first, second) <= rest_speed
        largest = max(largest, abs(approach[k]))
    target = np.empty(count)
    impact = np.zeros(count, np.bool_)
    arrival = np.zeros(count)
    normal_impulse = np.empty(count)
    tangent_impulse = np.empty((count, 2))
    for k in range(count):
        fast = approach[k] < -rest_speed
        bounce_target = -restitution[k] * approach[k] if bounce else 0.0
        if h > 0:
            arrives = approach[k] * h < -gap[k]  # reaches the surface within this step
            arriving = bounce_target if bounce else approach[k]
            if gap[k] > 0:
                target[k] = arriving if arrives and fast else -gap[k] / h
            else:
                target[k] = bounce_target if fast else 0.0
            impact[k] = bounce and fast and (gap[k] <= 0 or arrives)
            if approach[k] < 0:
                arrival[k] = min(max(gap[k] / (-approach[k] * h), 0.0), 1.0)
        else:
            target[k] = bounce_target if fast else 0.0
            impact[k] = fast and bounce
        # impacts start afresh; resting contacts from last step's impulses
        normal_impulse[k] = 0.0 if fast else warm_normal[k]
        for row in range(2):
            along = (warm_tangent[k, 0] * direction[row + 1, k, 0] + warm_tangent[k, 1] * direction[row + 1, k, 1]
                     + warm_tangent[k, 2] * direction[row + 1, k, 2])
            tangent_impulse[k, row] = 0.0 if fast else along
    apply_impulses(velocity, normal_impulse, tangent_impulse, a, b, lin_a, lin_b, turn_a, turn_b)
    tolerance = settings[0] * (1.0 + largest)
    _, residual = impulse_iterations(velocity, a, b, direction, arm_a, arm_b, lin_a, lin_b, turn_a, turn_b,
                                          weight, target, normal_impulse, tangent_impulse, static, kinetic, sticking,
                                          iterations, tolerance)
    tangent_vector = np.empty((count, 3))
    for k in range(count):
        for c in range(3):
            tangent_vector[k, c] = (tangent_impulse[k, 0] * direction[1, k, c]
                                    + tangent_impulse[k, 1] * direction[2, k, c])
    # split impulse: push apart through positions only, the overlaps that exceed the slop by more than a trifle
    push_target = np.zeros(count)
    strongest = 0.0
    for k in range(count):
        overlap = max(-gap[k] - slop, 0.0)
        if overlap < settings[2] * max(slop, 1e-6):
            overlap = 0.0
        push_target[k] = settings[1] * overlap / h if h > 0 else 0.0
        strongest = max(strongest, push_target[k])
    if strongest <= 0:
        return normal_impulse, tangent_impulse, tangent_vector, impact, arrival, np.zeros(0), residual, tolerance
    pseudo = np.zeros(len(velocity))
    push_iterations(pseudo, a, b, direction, arm_a, arm_b, lin_a, lin_b, turn_a, turn_b, weight, push_target,
                    settings[3] * strongest, min(iterations, int(settings[4])))
    return normal_impulse, tangent_impulse, tangent_vector, impact, arrival, pseudo, residual, tolerance


@njit(cache=True, error_model="numpy")
def _solve_rows(factor: np.ndarray, cholesky: bool, right: np.ndarray) -> np.ndarray:
    """``(G M⁻¹ Gᵀ)⁺ right`` for right (R, m): by the lower Cholesky factor ``factor`` (R, R) (forward and back
    substitution, row by row over all columns; a tree of joints leaves most of the factor zero, skipped), or with
    ``cholesky`` False, ``factor`` is the pseudo-inverse."""
    rows, width = right.shape
    if not cholesky:
        return factor @ right
    out = right.copy()
    for i in range(rows):  # L y = right
        for j in range(i):
            f = factor[i, j]
            if f != 0.0:
                for c in range(width):
                    out[i, c] -= f * out[j, c]
        pivot = factor[i, i]
        for c in range(width):
            out[i, c] /= pivot
    for i in range(rows - 1, -1, -1):  # Lᵀ x = y
        for j in range(i + 1, rows):
            f = factor[j, i]
            if f != 0.0:
                for c in range(width):
                    out[i, c] -= f * out[j, c]
        pivot = factor[i, i]
        for c in range(width):
            out[i, c] /= pivot
    return out


@njit(cache=True, error_model="numpy")
def small_jointed_rows(a: np.ndarray, b: np.ndarray, directions: np.ndarray, r_a: np.ndarray, r_b: np.ndarray,
                       inverse_mass: np.ndarray, inverse_inertia: np.ndarray, read_moving: np.ndarray,
                       read_turning: np.ndarray, moving: np.ndarray, turning: np.ndarray, group: np.ndarray,
                       rows: np.ndarray, push: np.ndarray, factor: np.ndarray, cholesky: bool
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`animbatch.sim.contact.impulses.ContactRows._small_jointed` in one call: the Jacobian ``J`` (3K, 6S) of K
    contacts' rows along ``directions`` (3, K, 3) (normals, first and second tangents) at lever arms ``r_a``, ``r_b``
    (K, 3) on bodies ``a``, ``b`` (K,) of S (the fixed one last; ``inverse_mass`` (S,), world ``inverse_inertia``
    (S, 3, 3)); each end's response ``M⁻¹ Jᵀ``, corrected within the joints (rows ``rows`` G (R, 6S), ``push``
    M⁻¹ Gᵀ (6S, R), ``factor`` of G M⁻¹ Gᵀ: its lower Cholesky factor, or with ``cholesky`` False its
    pseudo-inverse), summed into the response (6S, 3K); and the effective masses (3, K), each end's inverse
    effective mass less what the joints take, split among the contact ends of its jointed ``group`` (S,; −1: none),
    or a pair's together when both ends are in one group. Entries of bodies that cannot take them are left 0:
    ``read_moving``, ``read_turning`` (S,) for the Jacobian (moving colliders are read), ``moving``, ``turning`` for
    the responses. The same arithmetic as numpy's, to round-off (the tests compare them)."""
    count, size = len(a), len(inverse_mass)
    columns = 6 * size
    jacobian = np.zeros((3 * count, columns))
    ends = np.zeros((columns, 6 * count))
    own = np.zeros((2, 3 * count))  # each end's own inverse effective mass per row
    for r in range(3):
        for k in range(count):
            line = r * count + k
            for end in range(2):
                body = a[k] if end == 0 else b[k]
                sign = 1.0 if end == 0 else -1.0
                lever = r_a if end == 0 else r_b
                d0, d1, d2 = directions[r, k, 0], directions[r, k, 1], directions[r, k, 2]
                l0, l1, l2 = lever[k, 0], lever[k, 1], lever[k, 2]
                arm = np.empty(3)
                arm[0] = l1 * d2 - l2 * d1
                arm[1] = l2 * d0 - l0 * d2
                arm[2] = l0 * d1 - l1 * d0
                linear_column, angular_column = 3 * body, 3 * (size + body)
                turn = np.empty(3)
                for i in range(3):
                    turn[i] = (inverse_inertia[body, i, 0] * arm[0] + inverse_inertia[body, i, 1] * arm[1]
                               + inverse_inertia[body, i, 2] * arm[2])
                mass = inverse_mass[body]
                total = 0.0
                for i in range(3):
                    if read_moving[body]:
                        jacobian[line, linear_column + i] = sign * directions[r, k, i]
                    if read_turning[body]:
                        jacobian[line, angular_column + i] = sign * arm[i]
                    if moving[body]:
                        ends[linear_column + i, end * 3 * count + line] = sign * mass * directions[r, k, i]
                    if turning[body]:
                        ends[angular_column + i, end * 3 * count + line] = sign * turn[i]
                for i in range(3):
                    total += mass * directions[r, k, i] * directions[r, k, i]
                turned = 0.0
                for i in range(3):
                    turned += turn[i] * arm[i]
                own[end, line] = total + turned
    rates = rows @ ends  # (R, 6K): what each end's unit impulse does to the joints
    answers = _solve_rows(factor, cholesky, rates)
    response = np.empty((columns, 3 * count))
    both = answers[:, :3 * count] + answers[:, 3 * count:]
    correction = push @ both
    for i in range(columns):
        for line in range(3 * count):
            response[i, line] = ends[i, line] + ends[i, 3 * count + line] - correction[i, line]
    shares = np.zeros(size + 1)
    for k in range(count):
        shares[group[a[k]] + 1] += 1.0
        shares[group[b[k]] + 1] += 1.0
    weight = np.empty((3, count))
    for r in range(3):
        for k in range(count):
            line = r * count + k
            lost_a = lost_b = lost_both = 0.0
            for j in range(rates.shape[0]):
                ra, rb = rates[j, line], rates[j, 3 * count + line]
                za, zb = answers[j, line], answers[j, 3 * count + line]
                lost_a += ra * za
                lost_b += rb * zb
                lost_both += (ra + rb) * (za + zb)
            ga, gb = group[a[k]], group[b[k]]
            share_a, share_b = shares[ga + 1], shares[gb + 1]
            if ga == gb and ga >= 0:
                inverse = share_a * (own[0, line] + own[1, line] - lost_both)
            else:
                inverse = share_a * (own[0, line] - lost_a) + share_b * (own[1, line] - lost_b)
            weight[r, k] = 1.0 / max(inverse, 1e-300)
    return jacobian, response, weight
