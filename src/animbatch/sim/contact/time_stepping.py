"""Contacts for the fixed-step methods (velocity-level time stepping, as in Box2D, Bullet or MuJoCo).

:class:`ContactResolver` is the velocity constraint the fixed-step schemes apply between their kick and their drift
(:class:`~animbatch.sim.integrators.interface.VelocityConstraint`); :func:`animbatch.sim.integrate.integrator_for` hands
it to them for scenes with contacts.

A step of ``h``: forces change the velocities (kick), the contact solver changes them again so that every contact
holds over the step (see :mod:`animbatch.sim.contact.impulses`), and positions move with the corrected velocities
(drift).
Contacts are looked for up to the distance bodies can travel in the step (speculative contacts), which is the swept
test: a fast body stops at a thin wall instead of passing through it. Positions never move with velocities that would
take them into a collider, so a body resting on the ground stays exactly still.

* ``symplectic_euler``: kick h, contacts, drift h.
* ``verlet``: kick h/2, contacts, drift h, kick h/2, and the end-of-step velocities re-projected onto the contacts
  (without restitution), so that resting bodies end each step with zero velocity too.

Explicit Euler and midpoint move positions with the velocities from before the step, so they cannot keep contacts;
the loader refuses them for scenes with contacts.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from animbatch.sim.contact.clearance import Clearance
from animbatch.sim.contact.contacts import Contacts, contact_codes
from animbatch.sim.contact.detection import body_reach, detect
from animbatch.sim.contact.impacts import ImpactLog
from animbatch.sim.contact.impulses import (
    BodyVelocities,
    compiled_contacts,
    inverse_mass_matrix,
    solve_impulses,
)
from animbatch.sim.contact.jointed import DENSE_COLUMNS, BlockInverse, JointedResponse
from animbatch.sim.forces import Kinematics
from animbatch.sim.forces.gravity import gravity_magnitude
from animbatch.sim.integrators.interface import ContactSolves
from animbatch.sim.kernels import CONTACT_KERNELS, MIN_WORK, compiled_kernels, kernels_loaded
from animbatch.sim.model.dynamics import Dynamics

DEFAULT_REST_SPEED = 0.01  # m/s
NO_CONTACTS = Contacts.concatenate([])

#: What numpy's contact steps cost, to know when compiling them pays: about 2 ms a step with contacts (search, rows,
#: write-back) and 150 µs a sweep of the impulse solver (measured against the compiled path on a ball resting on a
#: slope, a box sliding on a floor, `mixed_pile` and `dominoes`, whose piles take 100-140 sweeps a step: 2.2-2.5 ms
#: a step, 170-260 µs a sweep). A run starts in numpy unless its estimate says it is long
#: (:func:`animbatch.sim.model.compiled.dynamics_for`; the estimate counts a step and a sweep per contact found at
#: the start); once its contact steps have cost :data:`COMPILE_CONTACTS_AFTER` [s] by these counts, the rest of it
#: searches and solves compiled. Counted, not timed, so that a scene switches at the same step on every machine and
#: under any load.
NUMPY_CONTACT_STEP = 2e-3
NUMPY_SWEEP = 150e-6
COMPILE_CONTACTS_AFTER = 0.5  # as COMPILE_AFTER: numpy runs take 2-4x their estimate
#: The same, once this process has loaded the contact kernels (as COMPILE_AFTER_LOADED).
COMPILE_CONTACTS_AFTER_LOADED = 0.05


class NumpyContactCost:
    """What a run's contact work in numpy has cost so far [s], counted by fixed costs per piece of work (not timed),
    and the run's switch to the compiled contact kernels once that passes :data:`COMPILE_CONTACTS_AFTER`
    (:data:`COMPILE_CONTACTS_AFTER_LOADED` once the contact kernels are loaded in this process): shared by the
    fixed-step contact step and the adaptive methods' resting forces."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def add(self, system: Dynamics, seconds: float) -> None:
        """Count ``seconds`` of numpy work; past the threshold, mark ``system`` a long run (once)."""
        if system.long_run or self.seconds < 0:
            return
        self.seconds += seconds
        if self.seconds >= (COMPILE_CONTACTS_AFTER_LOADED if kernels_loaded(CONTACT_KERNELS)
                            else COMPILE_CONTACTS_AFTER):
            system.long_run = compiled_kernels(MIN_WORK)
            self.seconds = -np.inf  # asked once: numba may be unavailable or refused


def measure_contact_search(system: Dynamics, repeats: int = 2) -> tuple[float, int]:
    """Wall time [s] of one step's contact search at the model's start (the fastest of a few), and the contacts it
    found, for the cost estimate; (0, 0) without contacts."""
    model = system.model
    if model.contact_world is None or model.contact_settings is None:
        return 0.0, 0
    state = system.kinematics(*system.split(np.array(model.y0, float)), t=float(model.frame_times[0]), copy=True)
    margin = 2 * model.contact_settings.slop + 1e-9
    best, found = np.inf, 0
    for _ in range(repeats + 1):  # the first builds what is built once (mesh trees) and is not counted
        started = time.perf_counter()
        found = detect(model.contact_world, state, margin, edges=True).count
        best = min(best, time.perf_counter() - started)
    return float(best), int(found)


def numpy_contact_solve(contacts: int) -> float:
    """What a numpy contact step that finds ``contacts`` costs besides its search [s], by the counts above: its rows
    and write-back, and a sweep per contact at least (none without contacts: the search alone)."""
    return NUMPY_CONTACT_STEP + NUMPY_SWEEP * contacts if contacts else 0.0


def joints_on(system: Dynamics, state: Kinematics, bodies: BodyVelocities, touching: Contacts | None = None
              ) -> tuple[Callable[[BodyVelocities], None] | None, JointedResponse | None]:
    """How contacts move jointed bodies at ``state`` (``bodies``: the velocity slots the contacts act on, the
    fixed body's among them): ``couple``, the joints applied to velocities in place, and the joints' rows as a
    :class:`~animbatch.sim.contact.jointed.JointedResponse`, with which every contact impulse or force moves the
    bodies within their joints; (None, None) for a model without joints, or when none of the contacts
    ``touching`` (where given) is on a jointed body (they move free bodies only: nothing to build)."""
    if system.joints is None:
        return None, None
    if touching is not None and not np.isin(np.concatenate([touching.probe_body, touching.solid_body]),
                                            system.joints.points).any():
        return None, None
    count, n = system.model.body_count, system.model.particle_count

    def couple(velocities: BodyVelocities) -> None:  # joints and contacts solved together
        system.project_velocities(state, velocities.v[:count], velocities.omega[n:count]
                                  if state.omega is not None else None)

    size = len(bodies.v)
    if 6 * size <= DENSE_COLUMNS:  # a ragdoll's few dozen columns: arrays, no sparse construction a step
        return couple, JointedResponse(system.velocity_rows(state, size, dense=True),
                                       BlockInverse(bodies.inverse_mass, bodies.inverse_inertia))
    return couple, JointedResponse(system.velocity_rows(state, size), inverse_mass_matrix(bodies))


class ContactResolver:
    """Applies the contact solver to a state's velocities, for steps of a given length."""

    def __init__(self, system: Dynamics) -> None:
        model = system.model
        assert model.contact_world is not None and model.contact_settings is not None
        self.system = system
        self.world = model.contact_world
        self.settings = model.contact_settings
        self.gravity = gravity_magnitude(system.terms)
        self.reach = body_reach(self.world, model.body_count)
        self.contacts_last_step = 0
        #: Bodies of the last step's contacts (resting on a solid, or reaching it within the step) and the contacts'
        #: normals (from the solid): the cloth's self-collision does not push these vertices into the solid.
        self.resting = np.zeros(0, np.intp)
        self.resting_normal = np.zeros((0, 3))
        self.impacts = ImpactLog()
        self.solves = ContactSolves()  # how the impulse solves ended (the run's ledger reports it)
        # warm starting: last step's impulses per unit time, normal (K,) and tangential vectors (K, 3), for the
        # contacts identified by sorted codes (K,) (see contact_codes)
        self._warm_codes = np.zeros(0, np.int64)
        self._warm_normal = np.zeros(0)
        self._warm_tangent = np.zeros((0, 3))
        self._numpy_cost = NumpyContactCost()  # what numpy's contact steps have cost so far, by the counts above
        self.clearance = Clearance(self.reach, self.world.moving)  # the search is skipped while nothing can be near

    def _count_numpy_work(self, sweeps: int) -> None:
        """Count a contact step's numpy work (``sweeps`` of the impulse solver): past :class:`NumpyContactCost`'s
        threshold the run is a long one and its contacts go compiled from the next step."""
        self._numpy_cost.add(self.system, NUMPY_CONTACT_STEP + NUMPY_SWEEP * sweeps)

    def _search(self, state: Kinematics, travel: np.ndarray) -> Contacts:
        """The contacts within the step's reach (``travel`` (P,) [m] per body): none without a search while the
        last search that looked further still vouches for it (:class:`~animbatch.sim.contact.clearance.Clearance`)."""
        margin = 2 * self.settings.slop + 1e-9
        compiled = compiled_contacts(0, long_run=self.system.long_run)
        clearance = self.clearance
        if clearance.clear(state, travel):
            return NO_CONTACTS
        ahead = clearance.look_ahead(travel, margin)
        if ahead > 0:
            contacts = detect(self.world, state, margin + 2 * ahead, travel=travel, edges=True, compiled=compiled)
            if not contacts.count:
                clearance.found_nothing(state, ahead)
                return contacts
            clearance.found_something()
        return detect(self.world, state, margin, travel=travel, edges=True, compiled=compiled)

    def rest_speed(self, h: float) -> float:
        """Impacts slower than this do not bounce; sticking is allowed below it (at least 3 g h)."""
        if self.settings.rest_speed is not None:
            return self.settings.rest_speed
        return max(DEFAULT_REST_SPEED, 3 * self.gravity * h)

    def _bodies(self, state: Kinematics) -> tuple[BodyVelocities, np.ndarray]:
        """Velocities and inverse inertias, then the moving colliders' (at ``state.t``), then the fixed body; and
        the centres of mass of them all (P + M + 1, 3) [m]."""
        model = self.system.model
        count, n = model.body_count, model.particle_count
        moving = self.world.moving
        extra = moving.count if moving is not None else 0
        v = np.zeros((count + extra + 1, 3))
        omega = np.zeros((count + extra + 1, 3))
        x = np.zeros((count + extra + 1, 3))
        inverse_mass = np.zeros(count + extra + 1)
        inverse_inertia = np.zeros((count + extra + 1, 3, 3))
        v[:count], x[:count] = state.v, state.x
        inverse_mass[:count] = 1.0 / model.bodies.mass
        if state.rotation is not None and state.omega is not None and model.rigid is not None:
            omega[n:count] = state.omega
            rotation = state.rotation
            inverse_inertia[n:count] = rotation @ model.rigid.inverse_inertia @ np.transpose(rotation, (0, 2, 1))
        driven = np.zeros(count + extra + 1, bool)  # bodies whose motion is prescribed
        if moving is not None:  # prescribed motion, no inverse mass: nothing pushes a moving collider back
            x[count:count + extra], v[count:count + extra], omega[count:count + extra] = moving.motion(state.t)
            driven[count:count + extra] = True
        if model.kinematic is not None:  # rigid bodies on keyframes, likewise
            bodies = n + model.kinematic.rigid
            inverse_mass[bodies], inverse_inertia[bodies] = 0.0, 0.0
            driven[bodies] = True
        return BodyVelocities(v, omega, inverse_mass, inverse_inertia, driven if driven.any() else None), x

    def _write_back(self, motion: np.ndarray, state: Kinematics, bodies: BodyVelocities) -> None:
        model = self.system.model
        n, b = model.particle_count, model.rigid_count
        motion[: 3 * n] = bodies.v[:n].ravel()
        rigid, rotation = model.rigid, state.rotation
        if rigid is not None and rotation is not None:
            momentum = motion[3 * n: 3 * n + 3 * b].reshape(b, 3)
            angular = motion[3 * n + 3 * b:].reshape(b, 3)
            momentum[...] = bodies.v[n:n + b] * rigid.mass[:, None]
            inertia_world = rotation @ rigid.inertia @ np.transpose(rotation, (0, 2, 1))
            angular[...] = np.einsum("bij,bj->bi", inertia_world, bodies.omega[n:n + b])

    def _warm_start(self, codes: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Impulses to start from: last step's, for contacts that persist (zero for new ones)."""
        known = self._warm_codes
        if not len(known):
            return np.zeros(len(codes)), np.zeros((len(codes), 3))
        where = np.minimum(np.searchsorted(known, codes), len(known) - 1)
        found = known[where] == codes
        return (np.where(found, self._warm_normal[where] * h, 0.0),
                np.where(found[:, None], self._warm_tangent[where] * h, 0.0))

    def _remember(self, codes: np.ndarray, normal: np.ndarray, tangent: np.ndarray, h: float) -> None:
        order = np.argsort(codes)
        self._warm_codes, self._warm_normal, self._warm_tangent = codes[order], normal[order] / h, tangent[order] / h

    def resolve(self, config: np.ndarray, motion: np.ndarray, h: float, *, t: float,
                bounce: bool = True) -> np.ndarray | None:
        """Change the motion so that all contacts hold over the step of ``h`` [s] from time ``t`` (required: it places
        the colliders on keyframes; an end-of-step re-projection passes the step's end); impacts are logged at the
        time within the step where their gap closes.

        Returns the motion to drift with when overlaps must also be pushed apart (the corrected motion plus the
        split-impulse pseudo-velocities), or None to drift with the motion itself.
        """
        state = self.system.kinematics(config, motion, t=t)
        speed = np.linalg.norm(state.v, axis=1)
        if state.omega is not None:
            speed[state.first_rigid:] += np.linalg.norm(state.omega, axis=1) * self.reach[state.first_rigid:]
        # each body's reach in the step, with room for the velocity to grow; a pair closes the sum of its two (and
        # a moving collider closes on everything at its own speed)
        if self.world.moving is not None:
            speed = speed + self.world.moving.largest_speed(t, state.x, self.reach)
        contacts = self._search(state, travel=1.5 * h * speed)
        self.contacts_last_step = contacts.count
        if bounce:
            self.resting, self.resting_normal = contacts.probe_body, contacts.normal
        if not contacts.count:
            return None
        bodies, x = self._bodies(state)
        kinematic = self.world.kinematic_slots(contacts)
        if kinematic is not None:
            kinematic = np.where(kinematic >= 0, self.system.model.body_count + kinematic, -1)
        codes = contact_codes(contacts)
        warm = self._warm_start(codes, h)
        couple, jointed = joints_on(self.system, state, bodies)
        result = solve_impulses(contacts, bodies, x, h, iterations=self.settings.iterations,
                                rest_speed=self.rest_speed(h), slop=self.settings.slop, bounce=bounce, warm=warm,
                                kinematic=kinematic, couple=couple, jointed=jointed, long_run=self.system.long_run)
        self._count_numpy_work(result.numpy_sweeps)
        self.solves.record(result.residual, result.unconverged)
        if bounce:  # remember the impulses of the main solve (not of end-of-step re-projections)
            self.impacts.record(t + result.arrival * h, contacts.probe_body, result.impact)

            self._remember(codes, result.normal_impulse, result.tangent_vector, h)
        self._write_back(motion, state, bodies)
        if result.pseudo_v is None:
            return None
        bodies.v += result.pseudo_v
        bodies.omega += result.pseudo_omega
        drifting = motion.copy()
        self._write_back(drifting, state, bodies)
        return drifting
