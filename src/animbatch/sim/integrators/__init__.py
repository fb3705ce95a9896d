"""Integrators behind one interface: adaptive scipy methods and fixed-step schemes, each described once in
:data:`~animbatch.sim.integrators.methods.METHODS`."""

from __future__ import annotations

from animbatch.sim.integrators.base import CountingRhs, IntegrationResult, Integrator, SolverStats
from animbatch.sim.integrators.fixed_step import DEFAULT_DT
from animbatch.sim.integrators.methods import FIXED_STEP_SCHEMES, METHODS, SCIPY_METHODS, Method
from animbatch.sim.integrators.scipy_ivp import ScipyIntegrator
from animbatch.sim.integrators.stepping import FixedStepIntegrator

__all__ = ["DEFAULT_DT", "FIXED_STEP_SCHEMES", "METHODS", "SCIPY_METHODS", "CountingRhs", "FixedStepIntegrator",
           "IntegrationResult", "Integrator", "Method", "ScipyIntegrator", "SolverStats"]
