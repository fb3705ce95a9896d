"""A scene's ``solver`` section -> the integrator it asks for."""

from __future__ import annotations

from animbatch.scene.schema import SolverSpec
from animbatch.sim.closed_forms import ClosedFormIntegrator
from animbatch.sim.integrate import integrator_for
from animbatch.sim.integrators import Integrator
from animbatch.sim.model.model import Model


def make_integrator(solver: SolverSpec, model: Model | None = None) -> Integrator:
    """The integrator a scene's ``solver`` section asks for, with contact handling when ``model`` has contacts
    (``analytic``: the closed forms, no integration)."""
    if solver.method == "analytic":
        return ClosedFormIntegrator()
    return integrator_for(model, solver.method, dt=solver.dt, rtol=solver.rtol, atol=solver.atol,
                          max_step=solver.max_step)
