"""Adaptive (solve_ivp) integration with contacts: impacts at their exact time, resting contacts as forces.

The scipy solver integrates free motion. After each accepted step, the step is searched for

* **impacts**: a probe, a round's side (a rod's, cylinder's or capsule's, against another's side or an edge:
  :func:`~animbatch.sim.contact.sides.side_pairs`) or an edge crossing an edge (of boxes and hulls:
  :func:`~animbatch.sim.contact.hulls.edge_pairs`), reaching a solid it was not resting on. The pairs that the
  step's travel could bring into touch, named at the step's start and at its end, are evaluated along the solver's
  dense output; between samples a probe's gap along the straight segment is minimised too, so that a thin wall
  cannot hide between two samples (a side or an edge is a body's length, no thin wall). The first crossing is
  refined by Brent's method to the exact contact time;
* **mode changes** of resting contacts (root finding on the dense output as well): a contact whose normal force
  would turn into a pull separates; a sliding contact whose slip reverses starts to stick; a sticking one whose
  friction would exceed ``μs f_n`` starts to slide.

At the first such event the integration stops exactly there, impulses are applied (restitution and friction,
:func:`~animbatch.sim.contact.impulses.solve_impulses`) or the contact's mode changes, and the solver restarts. Frames
before the event come from the old dense output, frames after it from the new one: both sides of a contact are right.

An impact slower than ``rest_speed`` does not bounce: the contact becomes *resting*, and from then on it exerts
forces (:func:`~animbatch.sim.contact.impulses.solve_forces`) instead of impulses. So a bouncing ball comes to rest
after finitely many bounces instead of stalling the solver on ever shorter ones (the Zeno problem), and a resting body
stays exactly still.

For stacks, piles and many simultaneous contacts, the fixed-step methods (:mod:`animbatch.sim.contact.time_stepping`)
are the robust choice; this path suits scenes with few contacts where exact impact times matter.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq

from animbatch.errors import SimulationError
from animbatch.quaternion import cross, from_rotation_vector, to_matrix
from animbatch.sim.contact.contacts import (
    BODY_BOX_FACE,
    PLANE_RIM,
    SIDE_ROUND,
    STATIC_BOX_FACE,
    Contacts,
    contact_codes,
)
from animbatch.sim.contact.detection import (
    FOLLOWED_KINDS,
    SIDE_KINDS,
    body_box_poses,
    body_reach,
    closing_margin,
    detect,
    evaluate_pairs,
    pair_gaps,
    probe_centres,
    rim_index,
    turn_angle,
)
from animbatch.sim.contact.hulls import edge_contacts
from animbatch.sim.contact.impacts import ImpactLog
from animbatch.sim.contact.impulses import (
    BodyVelocities,
    ContactFrame,
    ContactRows,
    compiled_contacts,
    solve_forces,
    solve_impulses,
)
from animbatch.sim.contact.jointed import JointedResponse
from animbatch.sim.contact.time_stepping import DEFAULT_REST_SPEED, NumpyContactCost, joints_on
from animbatch.sim.forces import Kinematics
from animbatch.sim.model.dynamics import Dynamics

SAMPLES = 24  # points per step at which impact candidates are evaluated
TOUCH = 1e-6  # m: contacts this close count as touching at an event
HOP_RESOLUTION = 1e-12  # m: a hop must rise this far above its starting depth to be followed (rounding is far below)
STIFFNESS = 2500.0  # 1/s²: pulls a resting contact's gap back to zero (ω0 = 50 rad/s, critically damped)
DAMPING = 100.0  # 1/s
#: Longest step [s] while contacts rest: the gap's stabilisation (rate √STIFFNESS) must stay within an explicit
#: method's stability region. Unbounded, a loose tolerance let resting balls sink 8 mm and jump out of rest.
RESTING_MAX_STEP = 2.0 / np.sqrt(STIFFNESS)
#: Safety factor on a body's travel over a step (:meth:`ContactEvents._travel`), for paths that bend more than a
#: parabola's within one step.
PATH_ALLOWANCE = 1.25
#: Arcs between two samples are longer than their chords (by π/2 at most for a half turn).
ARC_ALLOWANCE = 1.6
MAX_EVENTS_PER_FRAME = 10_000
#: Time step [s] of the second difference that gives a side contact's velocity terms (:meth:`ContactEvents.
#: _side_curvature`).
CURVATURE_STEP = 1e-4
#: Consecutive events at one instant after which the event loop gives up (it would otherwise spin forever).
MAX_STALLED_EVENTS = 100
SLIP_ONSET = 1e-6  # m/s²: tangential acceleration of a sticking contact point at which it starts to slide
#: What one resting-force solve costs in numpy [s] (a few contacts; measured 0.4-0.5 ms): counted as the stepping
#: path counts its steps, so that a long adaptive run solves its resting forces compiled from the
#: :class:`~animbatch.sim.contact.time_stepping.NumpyContactCost` threshold on, at the same evaluation on every machine.
NUMPY_FORCE_SOLVE = 0.5e-3


@dataclass
class Resting:
    """Resting contacts, by the features that touch: ``probe``, ``kind``, ``index`` (R,); ``sticking`` (R,);
    ``slide_direction`` (R, 3), the unit slip direction of sliding contacts."""

    probe: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    sticking: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    slide_direction: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def count(self) -> int:
        return len(self.probe)

    def keys(self) -> set[tuple[int, int, int]]:
        return set(zip(self.probe.tolist(), self.kind.tolist(), self.index.tolist()))

    def holds(self, contacts: Contacts) -> np.ndarray:
        """Which of the contacts (K,) bool are among these resting ones (same probe and solid)."""
        keys = self.keys()
        return np.array([key in keys for key in zip(contacts.probe.tolist(), contacts.solid_kind.tolist(),
                                                     contacts.solid_index.tolist())], dtype=bool)

    def keep(self, chosen: np.ndarray) -> Resting:
        return Resting(self.probe[chosen], self.kind[chosen], self.index[chosen], self.sticking[chosen],
                       self.slide_direction[chosen])


_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0  # 0.618…: the fraction of the bracket a golden-section step keeps


def _golden_section(function: Callable[[float], float], low: float, high: float, fraction: float) -> float:
    """Where ``function`` (unimodal on [low, high]) is least, to ``fraction`` of the interval: golden-section search,
    one evaluation per step (a ternary search takes two for a smaller cut; the event search calls the gaps
    hundreds of times per step)."""
    left, right = high - _GOLDEN * (high - low), low + _GOLDEN * (high - low)
    at_left, at_right = function(left), function(right)
    # a count of steps, not a width: near a large t the bracket cannot shrink below its rounding
    for _ in range(math.ceil(math.log(fraction) / math.log(_GOLDEN))):
        if at_left > at_right:  # the least value lies right of left
            low, left, at_left = left, right, at_right
            right = low + _GOLDEN * (high - low)
            at_right = function(right)
        else:
            high, right, at_right = right, left, at_left
            left = high - _GOLDEN * (high - low)
            at_left = function(left)
    return 0.5 * (low + high)


class ContactEvents:
    """The event-driven contact handling of one run."""

    def __init__(self, system: Dynamics) -> None:
        model = system.model
        self.system = system
        assert model.contact_world is not None and model.contact_settings is not None, "no contacts were compiled"
        self.world = model.contact_world
        self.settings = model.contact_settings
        self.rest_speed = self.settings.rest_speed or DEFAULT_REST_SPEED
        self.resting = Resting()
        self._warm_forces: tuple[np.ndarray, np.ndarray] | None = None  # last forces of the current resting set
        self.reach = body_reach(self.world, model.body_count)
        self.events = 0
        self.impacts = ImpactLog()
        #: Probe–solid pairs whose rebound was too small for the solver to follow; the next settle lands them.
        self.landing: Contacts | None = None
        self._modes: np.ndarray | None = None  # mode functions at the end of the last step (resting contacts)
        self._impact_first = False  # whether the pending event is an impact (else a change of contact modes)
        self._last_event = 0.0  # s
        self._stalled = 0  # consecutive events that did not move time forward
        self._budget = 0
        self._method = ""
        # the last right-hand side's contact forces: (t, y, the resting set, what _contact_forces returned). The
        # explicit pairs end a step with the right-hand side at its end (first same as last), where the mode
        # functions are asked for next: the same forces, not solved again
        self._last_forces: tuple[float, np.ndarray, Resting, Any] | None = None
        self._numpy_cost = NumpyContactCost()  # what the numpy resting-force solves have cost, by NUMPY_FORCE_SOLVE

    # ------------------------------------------------------------------------------------- as StepEvents

    label = "contacts"
    advice = "A fixed-step method (symplectic_euler) is more robust for scenes with many contacts."

    def start(self, t: float, y: np.ndarray, frames: int, method: str) -> None:
        """Settle the contacts touching at the start: impacts, and which contacts rest."""
        self._budget, self._method, self._last_event = MAX_EVENTS_PER_FRAME * frames, method, t
        self.settle(y, t)

    def restart(self, t: float, y: np.ndarray) -> float | None:
        """With resting contacts, steps stay below :data:`RESTING_MAX_STEP` and their modes are watched."""
        self._modes = self._mode_functions(t, y) if self.resting.count else None
        return RESTING_MAX_STEP if self.resting.count else None

    def first_event(self, solver: Any, before: np.ndarray) -> float | None:
        """The first impact or change of a resting contact's mode within the solver's last step, or None."""
        impact = self._first_impact(solver, *self._impact_candidates(before, solver.y, solver.t - solver.t_old,
                                                                     solver.t))
        change = None
        if self._modes is not None:
            after = self._mode_functions(solver.t, solver.y)
            change = self._first_mode_change(solver, self._modes, after)
            self._modes = after
        self._impact_first = impact is not None and (change is None or impact <= change)
        return min((e for e in (impact, change) if e is not None), default=None)

    def handle(self, t: float, y: np.ndarray) -> None:
        """Apply the pending event at ``t`` [s]: impacts (settle) or a change of modes; stop when events no longer
        advance time (a safety net) or never settle."""
        # events a few ulps apart are the same instant: count them as no progress
        last = self._last_event
        self._stalled = self._stalled + 1 if t <= last + 1e-12 * max(1.0, abs(last)) else 0
        if self._stalled > MAX_STALLED_EVENTS:
            raise SimulationError(
                f"contact events stopped advancing at t = {last:.9g} s ({self._stalled} events at that time): "
                f"{self._method} cannot resolve these contacts. Use a fixed-step method (solver.method: "
                "symplectic_euler), or tighter solver.rtol and solver.atol.", time=last)
        self._last_event = t
        if self._impact_first:
            self.settle(y, t)
        else:
            self.change_modes(t, y)
        self.events += 1
        if self.events > self._budget:
            raise SimulationError(f"more than {self._budget} contact events: the contacts do not settle. Use a "
                                  "fixed-step method (symplectic_euler) for this scene.", time=t)

    # ------------------------------------------------------------------------------------- bodies

    def _state(self, y: np.ndarray, t: float = 0.0) -> Kinematics:
        """The kinematics of a state at time ``t`` [s], in arrays of its own (events compare several states)."""
        return self.system.kinematics(*self.system.split(y), t=t, copy=True)

    def _inertia(self, state: Kinematics) -> BodyVelocities:
        """Inverse masses and world inverse inertias, with zeros for velocities (filled by callers)."""
        model = self.system.model
        count, n = model.body_count, model.particle_count
        inverse_mass = np.zeros(count + 1)
        inverse_mass[:count] = 1.0 / model.bodies.mass
        inverse_inertia = np.zeros((count + 1, 3, 3))
        if state.rotation is not None and model.rigid is not None:
            r = state.rotation
            inverse_inertia[n:count] = r @ model.rigid.inverse_inertia @ np.transpose(r, (0, 2, 1))
        return BodyVelocities(np.zeros((count + 1, 3)), np.zeros((count + 1, 3)), inverse_mass, inverse_inertia)

    def _write_velocities(self, y: np.ndarray, state: Kinematics, bodies: BodyVelocities) -> None:
        """Store velocities (v, ω) back into a state's motion (P = M v, L = I ω for rigid bodies)."""
        model = self.system.model
        n, b = model.particle_count, model.rigid_count
        _, motion = self.system.split(y)
        motion[: 3 * n] = bodies.v[:n].ravel()
        rigid, r = model.rigid, state.rotation
        if rigid is not None and r is not None:
            motion[3 * n: 3 * n + 3 * b] = (bodies.v[n:n + b] * rigid.mass[:, None]).ravel()
            inertia_world = r @ rigid.inertia @ np.transpose(r, (0, 2, 1))
            motion[3 * n + 3 * b:] = np.einsum("bij,bj->bi", inertia_world, bodies.omega[n:n + b]).ravel()

    # ------------------------------------------------------------------------------------- resting forces

    def _resting_contacts(self, state: Kinematics) -> Contacts:
        r = self.resting
        return evaluate_pairs(self.world, state, r.probe, r.kind, r.index)

    def _contact_forces(self, t: float, y: np.ndarray, dydt: np.ndarray
                        ) -> tuple[Contacts, Any, BodyVelocities, np.ndarray]:
        """Add the resting contacts' forces to ``dydt``; return the contacts, the force solution, the accelerations
        and the tangential biases (K, 2)."""
        model, system = self.system.model, self.system
        n, b = model.particle_count, model.rigid_count
        config, motion = system.split(y)
        state = system.kinematics(config, motion)
        contacts = self._resting_contacts(state)
        bodies = self._inertia(state)
        _, rate = system.split(dydt)
        bodies.v[:n] = rate[: 3 * n].reshape(n, 3)
        rigid, r, omega = model.rigid, state.rotation, state.omega
        spin = np.zeros((b, 3))
        if rigid is not None and r is not None and omega is not None:
            force = rate[3 * n: 3 * n + 3 * b].reshape(b, 3)
            torque = rate[3 * n + 3 * b:].reshape(b, 3)
            angular = motion[3 * n + 3 * b:].reshape(b, 3)
            bodies.v[n:n + b] = force / rigid.mass[:, None]
            spin = cross(omega, angular)  # dL/dt = I ω̇ + ω × L
            bodies.omega[n:n + b] = np.einsum("bij,bj->bi", bodies.inverse_inertia[n:n + b], torque - spin)
        velocities = self._velocities(state, masses=bodies)
        x = np.vstack([state.x, np.zeros((1, 3))])
        frame = ContactFrame.of(contacts, x)
        normal_bias, tangent_bias = self._biases(contacts, state, velocities, x, frame)
        warm = self._warm_forces
        if warm is not None and len(warm[0]) != contacts.count:
            warm = None
        _, jointed = joints_on(self.system, state, bodies, contacts)  # a load on a jointed body passes to its joints
        result = solve_forces(contacts, bodies, x, normal_bias=normal_bias, tangent_bias=tangent_bias,
                              sticking=self.resting.sticking, slide_direction=self.resting.slide_direction,
                              iterations=self.settings.iterations, warm=warm, frame=frame,
                              compiled=self._compiled_forces(), jointed=jointed)
        # consecutive evaluations see nearly the same contacts: start the next solve from this one
        self._warm_forces = (result.normal_impulse.copy(), result.tangent_impulse.copy())
        rate[: 3 * n] = bodies.v[:n].ravel()
        if rigid is not None and r is not None:
            rate[3 * n: 3 * n + 3 * b] = (bodies.v[n:n + b] * rigid.mass[:, None]).ravel()
            inertia_world = r @ rigid.inertia @ np.transpose(r, (0, 2, 1))
            rate[3 * n + 3 * b:] = (np.einsum("bij,bj->bi", inertia_world, bodies.omega[n:n + b]) + spin).ravel()
        return contacts, result, bodies, tangent_bias

    def _compiled_forces(self) -> bool:
        """Whether this resting-force solve runs compiled: in a long run, or once this run's numpy solves have cost
        :class:`~animbatch.sim.contact.time_stepping.NumpyContactCost`'s threshold at :data:`NUMPY_FORCE_SOLVE` each."""
        self._numpy_cost.add(self.system, NUMPY_FORCE_SOLVE)
        return compiled_contacts(0, long_run=self.system.long_run)

    def _velocities(self, state: Kinematics, *, masses: BodyVelocities | None = None) -> BodyVelocities:
        """The bodies' velocities at ``state``, with their inverse masses and inertias (those of ``masses`` where
        given, for the same state: read, never written, so both may share them)."""
        bodies = self._inertia(state) if masses is None else BodyVelocities(
            np.zeros_like(masses.v), np.zeros_like(masses.omega), masses.inverse_mass, masses.inverse_inertia)
        count, n = self.system.model.body_count, self.system.model.particle_count
        bodies.v[:count] = state.v
        if state.omega is not None:
            bodies.omega[n:count] = state.omega
        return bodies

    def _biases(self, contacts: Contacts, state: Kinematics, velocities: BodyVelocities, x: np.ndarray,
                rows: ContactFrame) -> tuple[np.ndarray, np.ndarray]:
        """Velocity products and stabilisation terms of the resting contacts' gaps and tangential motion."""
        v, w = velocities.v, velocities.omega
        a, b = rows.a, rows.b
        # The gap and the slip follow the probe's centre, a point of the body: a sphere's contact point slides over
        # its surface and has no centripetal term of its own (a corner's centre is the corner itself).
        centre = contacts.point.copy()  # a side's contact point (followed along it, as a point of its body)
        probes = contacts.probe < self.world.probes.count
        centre[probes] = probe_centres(self.world, state)[contacts.probe[probes]]
        centre -= x[a]
        centripetal = cross(w[a], cross(w[a], centre)) - cross(w[b], cross(w[b], rows.r_b))
        velocity = rows.along(v, w)  # (3, K): normal, first and second tangent
        inward = np.einsum("ki,dki->dk", centripetal, rows.directions)
        sides = np.flatnonzero(contacts.probe >= self.world.probes.count)
        if len(sides):
            inward[0, sides] = self._side_curvature(state, contacts.select(sides))
        normal_bias = inward[0] + STIFFNESS * contacts.gap + DAMPING * velocity[0]
        tangent_bias = (inward[1:] + DAMPING * velocity[1:]).T
        return normal_bias, tangent_bias

    def _side_curvature(self, state: Kinematics, contacts: Contacts) -> np.ndarray:
        """The part of side contacts' gap accelerations (K,) [m/s²] that the bodies' velocities make with no
        acceleration (points moving straight on, bodies turning steadily): the gaps' second difference along that
        motion. A probe's centre is a point of its body, and the centripetal terms give its part; a side's contact
        point runs along both bodies, and the distance of two turning lines bends as no point's path does."""
        gaps = [pair_gaps(self.world, self._coasting(state, tau), contacts.probe, contacts.solid_kind,
                          contacts.solid_index) for tau in (-CURVATURE_STEP, 0.0, CURVATURE_STEP)]
        return (gaps[0] - 2 * gaps[1] + gaps[2]) / CURVATURE_STEP**2

    @staticmethod
    def _coasting(state: Kinematics, tau: float) -> Kinematics:
        """``state`` moved on by ``tau`` [s] at its velocities: positions by v τ, rotations by exp(τ ω)."""
        rotation = state.rotation
        if rotation is not None and state.omega is not None:
            rotation = to_matrix(from_rotation_vector(tau * state.omega)) @ rotation
        return Kinematics(state.x + tau * state.v, state.v, rotation, state.omega, state.first_rigid, state.t)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        dydt = self.system.rhs(t, y)
        if self.resting.count:
            self._last_forces = (t, y.copy(), self.resting, self._contact_forces(t, y, dydt))
        return dydt

    def _forces_at(self, t: float, y: np.ndarray) -> tuple[Contacts, Any, BodyVelocities, np.ndarray]:
        """:meth:`_contact_forces` at a state, taken from the last right-hand side when that was at this state
        with these resting contacts."""
        last = self._last_forces
        if last is not None and last[0] == t and last[2] is self.resting and np.array_equal(last[1], y):
            return last[3]
        return self._contact_forces(t, y, self.system.rhs(t, y))

    # ------------------------------------------------------------------------------------- events

    def _mode_functions(self, t: float, y: np.ndarray) -> np.ndarray:
        """For each resting contact, a value that changes sign when its mode must change (R,)."""
        contacts, result, accelerations, tangent_bias = self._forces_at(t, y)
        state = self._state(y)
        velocities = self._velocities(state, masses=accelerations)  # the same state: the same inertias

        x = np.vstack([state.x, np.zeros((1, 3))])
        rows = ContactRows(contacts, velocities, x)
        separating = rows.relative(rows.n, accelerations.v, accelerations.omega)
        sides = np.flatnonzero(contacts.probe >= self.world.probes.count)
        if len(sides):  # and, for sides, what the velocities alone do to the gap
            separating[sides] += self._side_curvature(self._state(y, t), contacts.select(sides))
        # normal force per unit effective mass minus the separating acceleration: + pressing, - pulling apart
        values = result.normal_impulse / rows.w_n - np.maximum(separating, 0.0)
        slip = rows.tangential()
        sticking = self.resting.sticking
        direction = self.resting.slide_direction
        along = slip[:, 0] * np.einsum("ki,ki->k", direction, rows.t1) + slip[:, 1] * np.einsum(
            "ki,ki->k", direction, rows.t2)
        # A sticking contact starts to slide when static friction, even at its limit, no longer stops the contact
        # point: its tangential acceleration leaves zero. (Friction at the limit of the cone alone is not slipping:
        # with several contacts, some may sit at their limit while the body is held.)
        slipping = np.linalg.norm(rows.tangential(accelerations.v, accelerations.omega) + tangent_bias, axis=1)
        grip = SLIP_ONSET - slipping
        mode = np.where(sticking, grip, along)  # stick: no slip acceleration; slide: slip along its direction
        return np.concatenate([values, mode])

    def _travel(self, s0: Kinematics, s1: Kinematics, h: float) -> np.ndarray:
        """How far any point of each body (P,) [m] can have moved during a step of ``h`` [s] from ``s0`` to ``s1``.

        The chord alone misses curved paths (a ball thrown up and caught again in one long step has a chord of
        zero), so the path is taken as at least ``h`` times the larger end speed: exact for a parabola, whose speed
        is largest at an end. Rotation moves a point by at most its reach times the angle turned, likewise bounded
        by ``h`` times the larger end spin."""
        chord = np.linalg.norm(s1.x - s0.x, axis=1)
        speed = np.maximum(np.linalg.norm(s0.v, axis=1), np.linalg.norm(s1.v, axis=1))
        travel = np.maximum(chord, h * speed)
        if s0.rotation is not None:
            assert s1.rotation is not None and s0.omega is not None and s1.omega is not None
            travel[s0.first_rigid:] += self.reach[s0.first_rigid:] * np.maximum(
                turn_angle(s0.rotation, s1.rotation),
                h * np.maximum(np.linalg.norm(s0.omega, axis=1), np.linalg.norm(s1.omega, axis=1)))
        return PATH_ALLOWANCE * travel

    def _impact_candidates(self, y0: np.ndarray, y1: np.ndarray, h: float, t1: float = 0.0
                           ) -> tuple[Contacts, np.ndarray]:
        """Pairs that the step of ``h`` [s] could bring into touch (excluding resting ones): every probe–solid pair
        whose gap at the step's end is less than what its two sides travelled (:meth:`_travel`; a fixed solid
        travels nothing), and that travel (K,) [m]."""
        s0, s1 = self._state(y0, t1 - h), self._state(y1, t1)
        travel = self._travel(s0, s1, h)
        found = self._detect(s1, TOUCH, travel, start=s0)
        if self.resting.count and found.count:
            found = found.select(~self.resting.holds(found))
        return found, closing_margin(found.probe_body, found.solid_body, 0.0, travel)

    def _detect(self, state: Kinematics, margin: float, travel: np.ndarray | None = None, *,
                start: Kinematics | None = None) -> Contacts:
        """:func:`detect`'s contacts of probes and, where there are rounds, boxes or hulls, of the features that
        probes miss (rounds' sides against other sides and edges, edges crossing edges: the contacts that
        :func:`evaluate_pairs` follows from state to state), one per pair, as :func:`evaluate_pairs` follows it
        (for sides, at the nearest point: the search's stretch ends, two for rounds lying along each other, are
        the fixed-step methods'; for rims on planes, the rim of each end that is near).

        With ``start``, the state a step began at, the pairs within reach there whose name fixes what their gap is
        measured to (a box's face, two edges) are named too, once each: a body that passed through another within
        one long step of free flight is measured at the step's end to the far face, or to no edge at all; named as
        it came, its gap crosses zero where it struck. (A probe's distance to a sphere, plane, round or hull, and a
        side's, are signed and named the same from either side: the step's end finds those.)"""
        found = self._named(state, margin, travel)
        world = self.world
        if start is None or not (world.boxes.count or world.hulls or len(world.statics.box_centre)):
            return found
        named = detect(world, start, margin, travel=travel)
        named = named.select(np.isin(named.solid_kind, (STATIC_BOX_FACE, BODY_BOX_FACE)))
        if world.boxes.count or world.hulls:
            named = Contacts.concatenate([named, edge_contacts(world, start, world.statics_at(start.t),
                                                               *body_box_poses(world, start), margin, travel)])
        found = Contacts.concatenate([found, named])
        _, first = np.unique(contact_codes(found), return_index=True)
        return found.select(np.sort(first))

    def _named(self, state: Kinematics, margin: float, travel: np.ndarray | None) -> Contacts:
        """:meth:`_detect` at one state."""
        world = self.world
        if world.cylinders is None and not world.boxes.count and not world.hulls:
            return detect(world, state, margin, travel=travel)
        found = detect(world, state, margin, travel=travel, edges=True)
        probes = found.probe < world.probes.count
        followed = ~probes & np.isin(found.solid_kind, FOLLOWED_KINDS)
        if not followed.any():
            return found.select(probes)
        # one name per pair, whichever end or way the search found it by: a side's near end's, and two rounds'
        # sides as the lower-numbered round's against the other's (an edge pair has one name already)
        probe, kind, index = found.probe[followed], found.solid_kind[followed], found.solid_index[followed]
        sides = np.isin(kind, SIDE_KINDS)
        index[sides] = 2 * (index[sides] // 2)
        rounds = kind == SIDE_ROUND
        if rounds.any():
            assert world.cylinders is not None
            first = world.probes.count + 12 * world.boxes.count + world.cylinders.count
            own, other = probe[rounds] - first, index[rounds] // 2
            probe[rounds], index[rounds] = first + np.minimum(own, other), 2 * np.maximum(own, other)
        rims = kind == PLANE_RIM  # a cylinder's rims on a plane: each end's rim, followed on its own
        if rims.any():
            probe = np.concatenate([probe, probe[rims]])
            kind = np.concatenate([kind, kind[rims]])
            index = np.concatenate([index, rim_index(world, index[rims], 1)])
            index[np.flatnonzero(rims)] = rim_index(world, index[np.flatnonzero(rims)], 0)
        named = np.unique(np.stack([probe, kind, index]), axis=1)
        pairs = evaluate_pairs(world, state, *named)
        near = pairs.gap < closing_margin(pairs.probe_body, pairs.solid_body, margin, travel)
        return Contacts.concatenate([found.select(probes), pairs.select(near)])

    def _first_impact(self, solver: Any, candidates: Contacts, closing: np.ndarray) -> float | None:
        """Time of the first impact among the candidates during the solver's last step, or None; ``closing`` (K,)
        [m] bounds how far each candidate's gap can change over the step."""
        if not candidates.count:
            return None
        t0, t1 = solver.t_old, solver.t
        interpolant = solver.dense_output()
        # Quick exclusion: a gap that changes by at most ``closing`` and is positive at both ends, with the two
        # ends' gaps together larger than ``closing``, stays positive in between (triangle inequality).
        ends = [self._state(solver.y_start if hasattr(solver, "y_start") else interpolant(t0)), self._state(solver.y)]
        end_gaps = [pair_gaps(self.world, state, candidates.probe, candidates.solid_kind, candidates.solid_index)
                    for state in ends]
        if np.all(end_gaps[1] > 0) and np.all(closing < end_gaps[0] + end_gaps[1]):
            return None
        times = np.linspace(t0, t1, SAMPLES + 1)

        def gaps(t: float, chosen: Any = slice(None)) -> np.ndarray:
            return pair_gaps(self.world, self._state(interpolant(t)), candidates.probe[chosen],
                             candidates.solid_kind[chosen], candidates.solid_index[chosen])

        sampled = [self._state(interpolant(t)) for t in times]
        probes = candidates.probe < self.world.probes.count
        values = np.array([pair_gaps(self.world, state, candidates.probe, candidates.solid_kind,
                                     candidates.solid_index) for state in sampled])  # (S + 1, C)
        travel = self._sample_travel(sampled, candidates)  # (S, C)
        # A probe that starts the step touching the solid (it bounced off at the event that began the step, or left
        # rest a hair inside the solid at a loose tolerance) impacts when it comes back to its starting depth, not
        # to zero depth, which it may never reach again. A short hop can rise and come back within the first
        # sample interval: then the impact lies between the hop's apex and the first sample.
        level = np.minimum(values[0], 0.0)
        first = None
        hops = np.flatnonzero((values[0] <= TOUCH) & (values[1] <= level))
        unresolved = []
        for pair in hops.tolist():
            apex = self._apex(gaps, t0, times[1], int(pair))
            if gaps(apex, [pair])[0] > level[pair] + HOP_RESOLUTION:
                hop = brentq(lambda t, k=int(pair): gaps(t, [k])[0] - level[k], apex, times[1], xtol=1e-12,
                             rtol=4 * np.finfo(float).eps)
                first = hop if first is None else min(first, hop)
            else:
                unresolved.append(int(pair))
        if unresolved:
            # The probe touched the solid at the step's start (it had just bounced) yet never rises above its
            # depth on the solver's path: a hop too small for the step (a slow rebound under a low-order or loose
            # solver; its first step after a restart is often of order one) that would otherwise sink into the
            # solid unnoticed, or bounce again and again at the same instant. It lands where it is.
            self.landing = candidates.select(np.array(unresolved))
            return t0
        if first is not None:
            return first
        for k in range(SAMPLES):
            # Several pairs can reach their solids within one sample interval (a long step of free flight carries
            # every ball to the floor): the impact is the earliest of their crossings, not the first pair's.
            brackets = [(times[k], times[k + 1], int(pair))
                        for pair in np.flatnonzero((values[k] > level) & (values[k + 1] <= level))]
            # a thin solid may hide between samples: look for a dip below zero inside the interval (a probe's: a
            # side against a round or an edge is a body's length, not a thin solid, and its search costs a
            # hundred times a probe's)
            could = (values[k] > 0) & (values[k + 1] > 0) & (travel[k] > values[k] + values[k + 1]) & probes
            brackets += self._dips(gaps, times[k], times[k + 1], could, level)
            for lower, upper, pair in brackets:
                crossing = brentq(lambda t, p=pair: gaps(t, [p])[0] - level[p], lower, upper, xtol=1e-12,
                                  rtol=4 * np.finfo(float).eps)
                first = crossing if first is None else min(first, crossing)
            if first is not None:
                break
        return first

    def _sample_travel(self, sampled: list[Kinematics], candidates: Contacts) -> np.ndarray:
        """For each interval between consecutive samples (S) and candidate (C), a bound [m] on how much its gap can
        change: the probe's move plus, for a solid that is a body, that body's (translation plus reach times the
        angle turned). A straight piece of path shorter than the gaps at its two ends cannot reach the solid
        (triangle inequality); probes and solids move on arcs, hence the allowance."""
        def body_travel(bodies: np.ndarray) -> np.ndarray:
            """(S, M): how far any point of each body moves between samples (translation plus reach × turn)."""
            x = np.array([state.x[bodies] for state in sampled])  # (S+1, M, 3)
            moved = np.linalg.norm(np.diff(x, axis=0), axis=2)
            first = sampled[0].first_rigid
            rigid = bodies >= first
            if rigid.any():
                rotations = np.array([state.rotation[bodies[rigid] - first] for state in sampled
                                      if state.rotation is not None])  # (every state: it has rigid bodies)
                moved[:, rigid] += self.reach[bodies[rigid]] * turn_angle(rotations[:-1], rotations[1:])
            return moved

        travel = np.zeros((len(sampled) - 1, candidates.count))
        probes = candidates.probe < self.world.probes.count
        centres = np.array([probe_centres(self.world, state)[candidates.probe[probes]] for state in sampled])
        travel[:, probes] = np.linalg.norm(np.diff(centres, axis=0), axis=2)
        if not probes.all():  # a side's contact point runs along it: bound it by its body's points
            travel[:, ~probes] = body_travel(candidates.probe_body[~probes])
        moving = candidates.solid_body >= 0
        if moving.any():
            travel[:, moving] += body_travel(candidates.solid_body[moving])
        return ARC_ALLOWANCE * travel

    @staticmethod
    def _apex(gaps: Any, start: float, stop: float, pair: int) -> float:
        """Where one candidate's gap is largest in [start, stop] (a hop's gap is concave), to 1e-11 of the
        interval."""
        return _golden_section(lambda t: -gaps(t, [pair])[0], start, stop, 1e-11)

    @staticmethod
    def _dips(gaps: Any, start: float, stop: float, candidates: np.ndarray, level: np.ndarray
              ) -> list[tuple[float, float, int]]:
        """For each candidate whose gap dips below its ``level`` inside [start, stop], a sub-interval that brackets
        its first crossing (the gap's least value, found to 1e-7 of the interval: it is close to convex over so
        short a piece of path)."""
        found = []
        for pair in np.flatnonzero(candidates).tolist():
            def gap(t: float, chosen: list[int] = [pair]) -> float:  # (this candidate's, bound now)
                return float(gaps(t, chosen)[0])

            middle = _golden_section(gap, start, stop, 1e-7)
            if gap(middle) <= level[pair]:
                found.append((start, middle, pair))
        return found

    def _first_mode_change(self, solver: Any, before: np.ndarray, after: np.ndarray) -> float | None:
        """Time of the first sign change of a resting contact's mode function in the last step, or None."""
        changed = (before > 0) & (after <= 0)
        if not changed.any():
            return None
        interpolant = solver.dense_output()
        # Each is evaluated again at the step's two ends before the root search: a contact whose force is shared with
        # others (a rim probe just where the exact rim touches too) can take any share of it, and the solve's warm
        # start gives it another at the same state. On the other side at the start already, its change is there;
        # back on the first side at the end, it has none.
        times = []
        for k in np.flatnonzero(changed).tolist():
            def mode(t: float, k: int = k) -> float:
                return float(self._mode_functions(t, interpolant(t))[k])

            if mode(solver.t_old) <= 0:
                times.append(float(solver.t_old))
            elif mode(solver.t) <= 0:
                times.append(brentq(mode, solver.t_old, solver.t, xtol=1e-12))
        return min(times, default=None)

    # ------------------------------------------------------------------------------------- handling events

    def settle(self, y: np.ndarray, t: float) -> None:
        """At an event (or the start) at time ``t`` [s]: apply impacts at touching contacts (and log them) and decide
        which contacts rest."""
        state = self._state(y, t)
        touching = self._detect(state, TOUCH + self.settings.slop)
        if touching.count:
            bodies = self._velocities(state)
            x = np.vstack([state.x, np.zeros((1, 3))])
            couple, jointed = joints_on(self.system, state, bodies, touching)
            result = solve_impulses(touching, bodies, x, 0.0, iterations=self.settings.iterations,
                                    rest_speed=self.rest_speed, slop=self.settings.slop, couple=couple,
                                    jointed=jointed)
            self.impacts.record(np.full(touching.count, t), touching.probe_body, result.impact)
            if self.landing is not None:
                self._land(touching, bodies, x, jointed)
            self._write_velocities(y, state, bodies)
            state = self._state(y)
        self.landing = None
        self._choose_resting(y, state, touching)

    def _land(self, touching: Contacts, bodies: BodyVelocities, x: np.ndarray,
              jointed: JointedResponse | None) -> None:
        """Take away the separating normal velocity of the landing contacts among ``touching``, so that they rest
        (the kinetic energy of a hop the solver could not resolve, ½ m v² for v below what its step can show)."""

        landing = self.landing
        assert landing is not None
        keys = set(zip(landing.probe.tolist(), landing.solid_kind.tolist(), landing.solid_index.tolist()))
        chosen = np.array([key in keys for key in zip(touching.probe.tolist(), touching.solid_kind.tolist(),
                                                       touching.solid_index.tolist())], dtype=bool)
        if not chosen.any():
            return
        rows = ContactRows(touching.select(chosen), bodies, x, jointed=jointed)
        for _ in range(self.settings.iterations):  # contacts on one body share it: a few sweeps
            separating = np.maximum(rows.relative(rows.n), 0.0)
            if separating.max(initial=0.0) <= 1e-12:
                break
            rows.apply_normal(-separating / rows.w_n)

    def _choose_resting(self, y: np.ndarray, state: Kinematics, touching: Contacts) -> None:
        """Touching contacts that the impulses left at rest become resting contacts; those that bounced fly free
        until their next, slower impact.

        A contact that was already resting before this event (another body's impact, say) stays resting unless it
        separates at the rest speed or faster: its normal velocity carries the integration's error (1e-8 m/s at a
        loose tolerance, either sign), and let fly it would start its flight touching or a hair inside the solid,
        where no gap can cross zero to report its next impact: it would sink through. (Lift-off from rest is a mode
        change, found by the mode functions.)
        """
        if not touching.count:
            self.resting = Resting()
            self._warm_forces = None
            return

        velocities = self._velocities(state)
        x = np.vstack([state.x, np.zeros((1, 3))])
        rows = ContactRows(touching, velocities, x)
        normal = rows.relative(rows.n)
        keep = normal < 1e-9 + 1e-9 * np.abs(normal).max(initial=0.0)
        if self.resting.count:
            keep |= self.resting.holds(touching) & (normal < self.rest_speed)
        slip = rows.tangential()[keep]
        speed = np.linalg.norm(slip, axis=1)
        chosen = touching.select(keep)
        t1, t2 = rows.t1[keep], rows.t2[keep]
        direction = slip[:, [0]] * t1 + slip[:, [1]] * t2
        direction = np.divide(direction, speed[:, None], out=np.zeros_like(direction), where=speed[:, None] > 0)
        self.resting = Resting(chosen.probe, chosen.solid_kind, chosen.solid_index, speed <= self.rest_speed,
                               direction)
        self._warm_forces = None
        if self.resting.count:  # a contact may only stick where static friction can hold it
            self.change_modes(0.0, y)

    def change_modes(self, t: float, y: np.ndarray) -> None:
        """After a mode event: drop separating contacts, and switch sticking and sliding where their functions
        changed sign."""
        values = self._mode_functions(t, y)
        count = self.resting.count
        pressing, mode = values[:count], values[count:]
        state = self._state(y)
        keep = pressing > 1e-9
        resting = self.resting
        switch = (mode <= 1e-9) & keep
        if switch.any():
            contacts = evaluate_pairs(self.world, state, resting.probe, resting.kind, resting.index)

            bodies = self._velocities(state)
            x = np.vstack([state.x, np.zeros((1, 3))])
            rows = ContactRows(contacts, bodies, x)
            to_stick = switch & ~resting.sticking
            to_slide = switch & resting.sticking
            if to_stick.any():  # the slip has just reversed: stop it exactly
                couple, jointed = joints_on(self.system, state, bodies, contacts.select(to_stick))
                solve_impulses(contacts.select(to_stick), bodies, x, 0.0, iterations=self.settings.iterations,
                               rest_speed=np.inf, slop=self.settings.slop, bounce=False, couple=couple,
                               jointed=jointed)
                self._write_velocities(y, state, bodies)
            sticking = resting.sticking.copy()
            sticking[to_stick] = True
            sticking[to_slide] = False
            direction = resting.slide_direction.copy()
            if to_slide.any():  # slip starts along the tangential acceleration friction could no longer cancel
                dydt = self.system.rhs(t, y)
                _, rate = self.system.split(dydt)
                free = self._inertia(state)
                n, b = self.system.model.particle_count, self.system.model.rigid_count
                free.v[:n] = rate[: 3 * n].reshape(n, 3)
                rigid = self.system.model.rigid
                if rigid is not None:
                    free.v[n:n + b] = rate[3 * n: 3 * n + 3 * b].reshape(b, 3) / rigid.mass[:, None]
                tangential = rows.tangential(free.v, free.omega)[to_slide]
                vector = tangential[:, [0]] * rows.t1[to_slide] + tangential[:, [1]] * rows.t2[to_slide]
                direction[to_slide] = vector / np.maximum(np.linalg.norm(vector, axis=1, keepdims=True), 1e-300)
            self.resting = Resting(resting.probe, resting.kind, resting.index, sticking, direction)
        self.resting = self.resting.keep(keep)
        self._warm_forces = None
