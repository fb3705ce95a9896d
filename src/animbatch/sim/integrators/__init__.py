"""Integrators behind one interface: adaptive scipy methods and fixed-step schemes, each described once in
:data:`~animbatch.sim.integrators.methods.METHODS`."""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from animbatch.sim.integrators.step_plan import DEFAULT_DT

if TYPE_CHECKING:
    from animbatch.sim.integrators.fixed_step_loop import FixedStepIntegrator
    from animbatch.sim.integrators.interface import CountingRhs, IntegrationResult, Integrator, SolverStats
    from animbatch.sim.integrators.methods import FIXED_STEP_SCHEMES, METHODS, SCIPY_METHODS, Method
    from animbatch.sim.integrators.scipy_ivp import ScipyIntegrator

#: Where each name lives: the package loads a module (and SciPy with the schemes) only when a name is asked for,
#: so that importing one light module of it (the method descriptions, for validate) costs nothing more.
_HOMES = {"CountingRhs": "interface", "IntegrationResult": "interface", "Integrator": "interface",
          "SolverStats": "interface",
          "FIXED_STEP_SCHEMES": "methods", "METHODS": "methods", "SCIPY_METHODS": "methods", "Method": "methods",
          "ScipyIntegrator": "scipy_ivp", "FixedStepIntegrator": "fixed_step_loop"}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(import_module(f"{__name__}.{_HOMES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["DEFAULT_DT", "FIXED_STEP_SCHEMES", "METHODS", "SCIPY_METHODS", "CountingRhs", "FixedStepIntegrator",
           "IntegrationResult", "Integrator", "Method", "ScipyIntegrator", "SolverStats"]
