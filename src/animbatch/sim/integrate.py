"""The integrator for a model: where contacts plug into the integration methods.

The methods (:mod:`animbatch.sim.integrators`) know nothing of contacts: a fixed-step scheme applies whatever
velocity constraint it is given between its kick and its drift, and an adaptive method stops at the events it is
given (:class:`~animbatch.sim.integrators.interface.StepEvents`: it asks for the first event in each step, and lets the
events act there before it restarts). This module gives them the contact ones when the model has contacts, so that
``integrators`` never imports ``contact`` (contact code imports the integrators, one way). Cloth that collides
with itself gets its self-collision filter as a constraint too, after the contacts with solids.
"""

from __future__ import annotations

import numpy as np

from animbatch.sim.contact.impact_events import ContactEvents
from animbatch.sim.contact.self_collision_step import self_contact_constraint
from animbatch.sim.contact.time_stepping import ContactResolver
from animbatch.sim.integrators import SCIPY_METHODS, FixedStepIntegrator, Integrator, ScipyIntegrator
from animbatch.sim.integrators.interface import EquationsOfMotion, VelocityConstraint
from animbatch.sim.joints.stops import JointStops
from animbatch.sim.model.dynamics import Dynamics
from animbatch.sim.model.model import Model


def _dynamics(system: EquationsOfMotion) -> Dynamics:
    """Contacts act on a model's bodies: the system integrated is the model's Dynamics whenever it has contacts."""
    assert isinstance(system, Dynamics), f"contacts need a model's Dynamics, not {type(system).__name__}"
    return system


def contact_constraint(system: EquationsOfMotion) -> ContactResolver:
    """The velocity constraint of a fixed-step scheme: contacts resolved between its kick and its drift."""
    return ContactResolver(_dynamics(system))


def contact_events(system: EquationsOfMotion) -> ContactEvents:
    """The events of an adaptive method: it stops at every impact and change of contact mode."""
    return ContactEvents(_dynamics(system))


def joint_stops(system: EquationsOfMotion) -> JointStops:
    """The events of an adaptive method: it stops where joint limits and ropes are reached."""
    return JointStops(_dynamics(system))


def integrator_for(model: Model | None, method: str, *, dt: float | None = None, rtol: float = 1e-6,
                   atol: float | np.ndarray = 1e-9, max_step: float | None = None) -> Integrator:
    """The integrator of ``method`` (an adaptive scipy method with ``rtol``, ``atol``, ``max_step`` [s], or a
    fixed-step one with step at most ``dt`` [s]) for ``model``, with contact handling when the model has contacts."""
    contacts = model is not None and model.contact_world is not None
    if method in SCIPY_METHODS:
        # joint limits and ropes meet their stops as events too; beside contacts they are left to the Baumgarte
        # stabilisation (one set of events per run)
        stops = model is not None and model.joints is not None and model.joints.stopping and not contacts
        return ScipyIntegrator(method, rtol=rtol, atol=atol, max_step=max_step,
                               events=contact_events if contacts else joint_stops if stops else None)
    folds = (model is not None and model.deformables is not None
             and any(body.self_collision for body in model.deformables.bodies))
    if folds:
        return FixedStepIntegrator(method, dt=dt, constraint=contacts_and_self_contact if contacts
                                   else self_contact_alone)
    return FixedStepIntegrator(method, dt=dt,
                               constraint=contact_constraint if contacts else None)


def self_contact_alone(system: EquationsOfMotion) -> VelocityConstraint | None:
    """The velocity constraint of a model whose cloth collides with itself but meets no solid."""
    return self_contact_constraint(_dynamics(system), None)


def contacts_and_self_contact(system: EquationsOfMotion) -> VelocityConstraint | None:
    """Contacts with solids first, then self-collision on the velocities they leave."""
    return self_contact_constraint(_dynamics(system), contact_constraint(system))
