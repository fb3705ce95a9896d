"""The integrator for a model: where contacts plug into the integration methods.

The methods (:mod:`animbatch.sim.integrators`) know nothing of contacts: a fixed-step scheme applies whatever
velocity constraint it is given between its kick and its drift, and an adaptive method hands its stepping to an
event integration when given one. This module gives them the contact ones when the model has contacts, so that
``integrators`` never imports ``contact`` (contact code imports the integrators, one way).
"""

from __future__ import annotations

import numpy as np

from animbatch.sim.contact.events import integrate_with_events
from animbatch.sim.contact.stepping import ContactResolver
from animbatch.sim.integrators import DEFAULT_DT, SCIPY_METHODS, FixedStepIntegrator, Integrator, ScipyIntegrator
from animbatch.sim.model.model import Model


def integrator_for(model: Model | None, method: str, *, dt: float | None = None, rtol: float = 1e-6,
                   atol: float | np.ndarray = 1e-9, max_step: float | None = None) -> Integrator:
    """The integrator of ``method`` (an adaptive scipy method with ``rtol``, ``atol``, ``max_step`` [s], or a
    fixed-step one with step at most ``dt`` [s]) for ``model``, with contact handling when the model has contacts."""
    contacts = model is not None and model.contact_world is not None
    if method in SCIPY_METHODS:
        return ScipyIntegrator(method, rtol=rtol, atol=atol, max_step=max_step,
                               events=integrate_with_events if contacts else None)
    return FixedStepIntegrator(method, dt=dt if dt is not None else DEFAULT_DT,
                               constraint=ContactResolver if contacts else None)  # type: ignore[arg-type]
