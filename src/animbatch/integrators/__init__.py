"""Integrators behind one interface: adaptive scipy methods and fixed-step schemes, looked up by name."""

from __future__ import annotations

from animbatch.integrators.base import CountingRhs, IntegrationResult, Integrator, SolverStats
from animbatch.integrators.fixed_step import DEFAULT_DT, FIXED_STEP_SCHEMES, FixedStepIntegrator
from animbatch.integrators.scipy_ivp import SCIPY_METHODS, ScipyIntegrator
from animbatch.scene.schema import SolverSpec

#: Every method name a scene may use, and whether it is adaptive.
METHODS: dict[str, str] = {**{name: "adaptive" for name in SCIPY_METHODS},
                           **{name: "fixed-step" for name in FIXED_STEP_SCHEMES}}


def make_integrator(solver: SolverSpec) -> Integrator:
    """The integrator a scene's ``solver`` section asks for."""
    if solver.method in SCIPY_METHODS:
        return ScipyIntegrator(solver.method, rtol=solver.rtol, atol=solver.atol, max_step=solver.max_step)
    return FixedStepIntegrator(solver.method, dt=solver.dt if solver.dt is not None else DEFAULT_DT)


__all__ = ["DEFAULT_DT", "FIXED_STEP_SCHEMES", "METHODS", "SCIPY_METHODS", "CountingRhs", "FixedStepIntegrator",
           "IntegrationResult", "Integrator", "ScipyIntegrator", "SolverStats", "make_integrator"]
