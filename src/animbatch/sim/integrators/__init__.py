"""Integrators behind one interface: adaptive scipy methods and fixed-step schemes, looked up by name."""

from __future__ import annotations

from animbatch.sim.integrators.base import CountingRhs, IntegrationResult, Integrator, SolverStats
from animbatch.sim.integrators.fixed_step import DEFAULT_DT, FIXED_STEP_SCHEMES, FixedStepIntegrator
from animbatch.sim.integrators.scipy_ivp import SCIPY_METHODS, ScipyIntegrator

#: Every method name a scene may use, and whether it is adaptive.
METHODS: dict[str, str] = {**{name: "adaptive" for name in SCIPY_METHODS},
                           **{name: "fixed-step" for name in FIXED_STEP_SCHEMES}}


__all__ = ["DEFAULT_DT", "FIXED_STEP_SCHEMES", "METHODS", "SCIPY_METHODS", "CountingRhs", "FixedStepIntegrator",
           "IntegrationResult", "Integrator", "ScipyIntegrator", "SolverStats"]
