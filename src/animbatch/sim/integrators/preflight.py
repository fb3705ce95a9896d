"""Checks before a run that warn, with numbers, about settings that are risky but not certain to fail.

What certainly fails is refused earlier (:func:`~animbatch.sim.integrators.stability.check_fixed_step`). Here:

* a fixed step above the stable step of the stiffest spring mode, whose growth over the run is more than
  ``WARN_GROWTH`` but below the refusal limit (a slow, visible wobble that grows);
* an explicit adaptive method (RK23, RK45, DOP853) on springs so stiff that stability alone will force more than
  ``STIFF_STEPS`` steps: Radau, BDF or LSODA would take far fewer;
* LSODA on a large spring system: it takes no analytic Jacobian, so once it turns to its stiff mode each Jacobian
  costs one right-hand side per state variable and a dense factorisation;
* fixed-step contact where a body may move further in one step than the thinnest box or sphere collider is thick:
  speculative contacts catch it, but only to the accuracy of one step.

Each warning is a :class:`StabilityWarning` (shown on stderr by the command line) and is kept in the run's solver
statistics.
"""

from __future__ import annotations

import warnings

import numpy as np

from animbatch.errors import AnimbatchWarning
from animbatch.sim.integrators.fixed_step import DEFAULT_DT, substeps
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.integrators.stability import GROWTH_LIMIT, amplification, largest_stable_step, stiffest_mode

#: Steps an explicit adaptive method may be forced to take by stability before we suggest an implicit one.
STIFF_STEPS = 1e6
#: Growth of the stiffest spring vibration over a run above which a fixed step gets a warning.
WARN_GROWTH = 2.0
#: State variables above which LSODA's finite-difference, dense Jacobians make it slow on springs (a 10×10 cloth).
LSODA_DENSE_STATES = 600
#: Stability limit ``|h λ|`` along the negative real axis of each explicit Runge–Kutta pair.
EXPLICIT_LIMITS = {name: m.stability_limit for name, m in METHODS.items() if m.stability_limit is not None}


class StabilityWarning(AnimbatchWarning):
    """A setting likely to give a wrong or slow run, found before it starts."""


def _spring_warnings(model: object, solver: object, steps: int, h: float | None) -> list[str]:
    mode = stiffest_mode(model)
    if mode is None:
        return []
    method = solver.method  # type: ignore[attr-defined]
    zeta = mode.decay / mode.omega if mode.omega > 0 else 0.0
    duration = float(model.frame_times[-1])  # type: ignore[attr-defined]
    if h is not None and not METHODS[method].implicit:  # implicit fixed-step methods are stable at any step
        growth = amplification(method, h, mode.omega, mode.decay)
        if growth > 1 + 1e-9 and steps * np.log(growth) > np.log(GROWTH_LIMIT):
            return []  # certain to blow up: refused with its own error when the run starts
        if steps * np.log(max(growth, 1.0)) > np.log(WARN_GROWTH):
            limit = largest_stable_step(method, mode.omega, mode.decay)
            fix = f"solver.dt ≤ {0.9 * limit:.3g} s" if limit is not None else "backward_euler"
            return [f"{method} at dt = {h:.3g} s is above the stable step of the stiffest spring mode (around "
                    f"{mode.body!r}: ω = {mode.omega:.4g} rad/s, damping ratio ζ = {zeta:.3g}, ω dt = "
                    f"{mode.omega * h:.3g}); that vibration grows ×{growth:.4g} per step, ×"
                    f"{growth ** steps:.3g} over the run. Use {fix}, or backward_euler."]
    if method in EXPLICIT_LIMITS:
        forced = mode.omega * duration / EXPLICIT_LIMITS[method]  # |h λ| ≤ limit, |λ| ≈ ω
        if forced > STIFF_STEPS:
            return [f"{method} will need about {forced:.2g} steps for stability alone: the springs around "
                    f"{mode.body!r} vibrate at ω = {mode.omega:.4g} rad/s (ζ = {zeta:.3g}) over {duration:g} s. "
                    "Radau or BDF (with the analytic Jacobian) or backward_euler take far fewer."]
    states = int(np.size(model.y0))  # type: ignore[attr-defined]
    if method == "LSODA" and states > LSODA_DENSE_STATES:
        return [f"LSODA gets no analytic Jacobian: when the springs around {mode.body!r} (ω = {mode.omega:.4g} rad/s) "
                f"make it switch to its stiff mode, each Jacobian costs {states} right-hand sides (finite "
                f"differences) and a dense {states}×{states} factorisation. Use BDF or Radau (analytic sparse "
                "Jacobian in scenes of particles and cloth), backward_euler, or DOP853."]
    return []


def _thinnest_collider(spec: object) -> tuple[str, float] | None:
    thinnest = None
    for number, collider in enumerate(spec.colliders):  # type: ignore[attr-defined]
        if collider.type == "box":
            thickness = float(min(collider.size))
        elif collider.type == "sphere":
            thickness = 2 * float(collider.radius)
        else:
            continue  # planes are infinitely thick; meshes are surfaces, caught by the swept test alone
        if thinnest is None or thickness < thinnest[1]:
            thinnest = (f"colliders[{number}] ({collider.type})", thickness)
    return thinnest


def _contact_warnings(spec: object, model: object, h: float) -> list[str]:
    thinnest = _thinnest_collider(spec)
    if thinnest is None or model.body_count == 0:  # type: ignore[attr-defined]
        return []
    velocities = model.velocities(model.y0[None])[0]  # type: ignore[attr-defined]
    gravity = max((float(np.linalg.norm(term.g)) for term in model.force_terms  # type: ignore[attr-defined]
                   if term.kind == "gravity"), default=0.0)
    duration = float(model.frame_times[-1])  # type: ignore[attr-defined]
    speed = np.linalg.norm(velocities, axis=1) + gravity * duration  # a bound for free flight under gravity
    fastest = int(np.argmax(speed))
    reach = float(speed[fastest]) * h
    name, thickness = thinnest
    if reach <= thickness:
        return []
    body = model.bodies.names[fastest]  # type: ignore[attr-defined]
    return [f"body {body!r} may reach {speed[fastest]:.3g} m/s and so move {reach:.3g} m "
            f"in one step of {h:.3g} s, more than the {thickness:.3g} m thickness of {name}. Speculative contacts "
            f"still stop it, to the accuracy of one step; solver.dt ≤ {0.9 * thickness / speed[fastest]:.3g} s "
            "resolves the wall."]


def preflight(spec: object, model: object) -> list[str]:
    """Warnings for running ``model`` with ``spec.solver``; each is also issued as a StabilityWarning."""

    solver = spec.solver  # type: ignore[attr-defined]
    times = model.frame_times  # type: ignore[attr-defined]
    h = steps = None
    if not solver.is_adaptive and len(times) > 1:
        interval = float(times[1] - times[0])
        count = substeps(interval, solver.dt if solver.dt is not None else DEFAULT_DT)
        h, steps = interval / count, count * (len(times) - 1)
    messages = _spring_warnings(model, solver, steps or 0, h)
    if h is not None and model.contact_world is not None:  # type: ignore[attr-defined]
        messages += _contact_warnings(spec, model, h)
    for message in messages:
        warnings.warn(message, StabilityWarning, stacklevel=2)
    return messages
