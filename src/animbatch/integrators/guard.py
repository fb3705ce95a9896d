"""Turning a non-finite state or a solver failure into an error that names the time, the body and the fix."""

from __future__ import annotations

import numpy as np

from animbatch.errors import SimulationError
from animbatch.model.layout import StateLayout


def first_non_finite(y: np.ndarray) -> int | None:
    """Index of the first NaN or infinite component of ``y``, or None."""
    if np.isfinite(y).all():  # the common case: one fast pass
        return None
    return int(np.flatnonzero(~np.isfinite(y))[0])


def divergence_error(layout: StateLayout | None, y: np.ndarray, index: int, t: float, *, method: str,
                     dt: float | None = None, step: int | None = None) -> SimulationError:
    """The error for state component ``index`` of ``y`` having become non-finite at time ``t`` [s]."""
    body, quantity = layout.describe_index(index) if layout is not None else (None, f"component {index}")
    who = f"body {body!r} {quantity}" if body is not None else quantity
    when = f"t = {t:.6g} s" + (f" (step {step})" if step is not None else "")
    value = "NaN" if np.isnan(y[index]) else "infinite"
    if dt is not None:
        advice = (f"{method} is unstable at dt = {dt:.3g} s for this scene: reduce solver.dt (try {dt / 10:.3g}), "
                  "or use an adaptive method (solver.method: RK45, or Radau for stiff springs)")
    else:
        advice = "tighten solver.rtol/atol, or try a stiff method (solver.method: Radau or BDF)"
    return SimulationError(f"the simulation diverged at {when}: {who} became {value} ({method}). {advice}.",
                           time=t, body=body, details={"quantity": quantity, "method": method, "dt": dt})


def fastest_body(layout: StateLayout | None, rate: np.ndarray, y: np.ndarray, atol: float, rtol: float) -> str:
    """The body whose state changes fastest relative to the tolerances: usually the culprit of a stalled solver."""
    if layout is None:
        return "?"
    with np.errstate(all="ignore"):
        scaled = np.abs(rate) / (atol + rtol * np.abs(y))
    scaled = np.where(np.isfinite(scaled), scaled, np.inf)
    body, _ = layout.describe_index(int(np.argmax(scaled)))
    return body
