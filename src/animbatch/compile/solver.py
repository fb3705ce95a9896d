"""A scene's ``solver`` section -> the integrator it asks for."""

from __future__ import annotations

from animbatch.scene.schema import SolverSpec
from animbatch.sim.integrators import (DEFAULT_DT, SCIPY_METHODS, FixedStepIntegrator, Integrator,
                                       ScipyIntegrator)


def make_integrator(solver: SolverSpec) -> Integrator:
    """The integrator a scene's ``solver`` section asks for."""
    if solver.method in SCIPY_METHODS:
        return ScipyIntegrator(solver.method, rtol=solver.rtol, atol=solver.atol, max_step=solver.max_step)
    return FixedStepIntegrator(solver.method, dt=solver.dt if solver.dt is not None else DEFAULT_DT)
