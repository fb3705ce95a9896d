"""The one-line description of an integration method and its settings, light enough for ``animbatch validate``
(no solver is built, nothing but this module is imported)."""

from __future__ import annotations

from typing import Any

import numpy as np

from animbatch.sim.integrators.step_plan import ONE_STEP_PER_FRAME, resolve_dt


def describe_method(method: str, *, adaptive: bool, dt: float | None = None, rtol: float = 1e-6, atol: Any = 1e-9,
                    max_step: float | None = None) -> str:
    """``RK45 (adaptive, rtol 1e-06, atol 1e-09)``, ``verlet (fixed step, dt <= 0.001 s)`` or the analytic method's
    line; ``atol`` is a number or one per state component."""
    if method == "analytic":
        return "analytic (closed forms of the motion: no integration)"
    if not adaptive:
        if dt is None and method in ONE_STEP_PER_FRAME:
            return f"{method} (fixed step, one step per frame)"
        return f"{method} (fixed step, dt <= {resolve_dt(dt, method):g} s)"
    limit = f", max_step {max_step:g} s" if max_step else ""
    tolerance = f"{float(atol):g}" if np.ndim(atol) == 0 else "per component"
    return f"{method} (adaptive, rtol {rtol:g}, atol {tolerance}{limit})"
