"""A run's step plan -> the integrator it asks for."""

from __future__ import annotations

from animbatch.sim.closed_forms import ClosedFormIntegrator
from animbatch.sim.integrate import integrator_for
from animbatch.sim.integrators import Integrator
from animbatch.sim.integrators.interface import StepSettings
from animbatch.sim.model.model import Model


def make_integrator(steps: StepSettings, model: Model | None = None) -> Integrator:
    """The integrator a run's ``steps`` ask for, with contact handling when ``model`` has contacts
    (``analytic``: the closed forms, no integration)."""
    if steps.method == "analytic":
        return ClosedFormIntegrator()
    return integrator_for(model, steps.method, dt=steps.dt, rtol=steps.rtol, atol=steps.atol,
                          max_step=steps.max_step)
