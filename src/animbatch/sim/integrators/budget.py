"""The wall-time budget of one simulation (``solver.max_cost``), checked by every integration loop.

The cost pre-flight (:mod:`animbatch.sim.integrators.cost`) refuses a run it *predicts* to be too expensive. Predictions
miss what cannot be foreseen from the initial state: two bodies plunging into each other under gravitation, a pile
that jams, an adaptive method driven to tiny steps. So the budget is also enforced while the run goes:
:func:`wall_budget` (entered by ``api.simulate`` around bodies and emitted particles) starts the clock, and each loop
calls :func:`budget_spent` once per step (one clock read, ~50 ns). When the budget is spent the loop stops with a
SimulationError (exit code 3) that says where it got to, what the rest would cost at its pace, and how to raise the
budget; adaptive loops add their own advice (the closest gravitational encounter, the stiffest spring).

The budget lives in a context variable, so loops need no extra argument and runs in other threads (Dask workers)
each keep their own.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass


@dataclass(frozen=True)
class _Budget:
    seconds: float  # wall time allowed [s]
    started: float  # time.perf_counter() at the start
    t0: float  # simulated time span [s] of the run
    t1: float


_CURRENT: ContextVar[_Budget | None] = ContextVar("animbatch_wall_budget", default=None)


@contextmanager
def wall_budget(seconds: float | None, t0: float, t1: float) -> Iterator[None]:
    """Enforce a budget of ``seconds`` of wall time [s] on the loops run inside; ``None`` or 0 for none.
    ``t0``, ``t1``: the simulated time span [s], to say how far the run got."""
    token = _CURRENT.set(_Budget(float(seconds), time.perf_counter(), t0, t1) if seconds else None)
    try:
        yield
    finally:
        _CURRENT.reset(token)


def budget_spent(t: float, what: str = "the simulation") -> str | None:
    """None while the budget lasts; once it is spent, a message saying so, for a run that has reached time ``t``."""
    budget = _CURRENT.get()
    if budget is None:
        return None
    elapsed = time.perf_counter() - budget.started
    if elapsed <= budget.seconds:
        return None
    done = (t - budget.t0) / (budget.t1 - budget.t0) if budget.t1 > budget.t0 else 0.0
    pace = (f"; at its pace so far the whole run needs about {format_seconds(elapsed / done)}" if done > 1e-6
            else "; it has barely started, so the whole run could take far longer")
    return (f"{what} used up its wall-time budget of {format_seconds(budget.seconds)} (solver.max_cost) at "
            f"t = {t:.6g} s, {100 * done:.3g} % of the way{pace}. Raise it with --max-cost or solver.max_cost if "
            "the run is worth it (0 = no limit)")


def format_seconds(seconds: float) -> str:
    """``42 s``, ``3.5 min``, ``2.1 h``, ``4.2 days``."""
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    if seconds < 172800:
        return f"{seconds / 3600:.3g} h"
    return f"{seconds / 86400:.3g} days"
