"""Checks before a run that warn, with numbers, about settings that are risky but not certain to fail.

What certainly fails is refused earlier (:func:`~animbatch.sim.integrators.stability.check_fixed_step`). Here:

* a fixed step above the stable step of the stiffest spring mode, whose growth over the run is more than
  ``WARN_GROWTH`` but below the refusal limit (a slow, visible wobble that grows);
* an explicit adaptive method (RK23, RK45, DOP853) on springs so stiff that stability alone will force more than
  ``STIFF_STEPS`` steps: Radau, BDF or LSODA would take far fewer;
* LSODA on a large spring system: it takes no analytic Jacobian, so once it turns to its stiff mode each Jacobian
  costs one right-hand side per state variable and a dense factorisation;
* fixed-step contact where a body may move further in one step than the thinnest box or sphere collider is thick:
  speculative contacts catch it, but only to the accuracy of one step;
* a fixed step that turns a gyration in a magnetic field by more than ``MOST_TURN_PER_STEP`` (the circle is drawn
  as a coarse polygon, and explicit methods spiral it outwards, implicit ones inwards).

Each warning is a :class:`StabilityWarning` (shown on stderr by the command line) and is kept in the run's solver
statistics.
"""

from __future__ import annotations

import warnings

import numpy as np

from animbatch.errors import AnimbatchWarning
from animbatch.sim.contact.contacts import STATIC_BOX, STATIC_SPHERE
from animbatch.sim.contact.detection import ContactWorld
from animbatch.sim.forces.gravity import gravity_magnitude
from animbatch.sim.integrators.methods import EXPLICIT_LIMITS, METHODS
from animbatch.sim.integrators.stability import (
    GROWTH_LIMIT,
    amplification,
    largest_stable_step,
    stiffest_mode,
    time_scales,
)
from animbatch.sim.integrators.step_plan import resolve_dt, substeps
from animbatch.sim.model.model import Model

#: Steps an explicit adaptive method may be forced to take by stability before we suggest an implicit one.
STIFF_STEPS = 1e6
#: Growth of the stiffest spring vibration over a run above which a fixed step gets a warning.
WARN_GROWTH = 2.0
#: The most a fixed step may turn a gyration [rad] without a warning (about 12 steps per turn).
MOST_TURN_PER_STEP = 0.5
#: State variables above which LSODA's finite-difference, dense Jacobians make it slow on springs (a 10×10 cloth).
LSODA_DENSE_STATES = 600


class StabilityWarning(AnimbatchWarning):
    """A setting likely to give a wrong or slow run, found before it starts."""


def _spring_warnings(model: Model, method: str, steps: int, h: float | None) -> list[str]:
    mode = stiffest_mode(model)
    if mode is None:
        return []
    zeta = mode.decay / mode.omega if mode.omega > 0 else 0.0
    duration = float(model.frame_times[-1])
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
    states = int(np.size(model.y0))
    if method == "LSODA" and states > LSODA_DENSE_STATES:
        return [f"LSODA gets no analytic Jacobian: when the springs around {mode.body!r} (ω = {mode.omega:.4g} rad/s) "
                f"make it switch to its stiff mode, each Jacobian costs {states} right-hand sides (finite "
                f"differences) and a dense {states}×{states} factorisation. Use BDF or Radau (analytic sparse "
                "Jacobian in scenes of particles and cloth), backward_euler, or DOP853."]
    return []


def _thinnest_collider(world: ContactWorld) -> tuple[str, float] | None:
    """The thinnest box or sphere collider, named as the scene numbers it, and its thickness [m]; planes are
    infinitely thick and meshes are surfaces (caught by the swept test alone)."""
    statics = world.statics
    sources = world.collider_source or {}
    found = [(STATIC_SPHERE, "sphere", k, 2 * float(radius)) for k, radius in enumerate(statics.sphere_radius)]
    found += [(STATIC_BOX, "box", k, 2 * float(half.min())) for k, half in enumerate(statics.box_half)]
    if not found:
        return None
    kind, label, k, thickness = min(found, key=lambda item: item[3])
    return (f"colliders[{sources[kind][k]}] ({label})" if kind in sources else f"a {label} collider"), thickness


def _contact_warnings(model: Model, world: ContactWorld, h: float) -> list[str]:
    thinnest = _thinnest_collider(world)
    if thinnest is None or model.body_count == 0:
        return []
    velocities = model.velocities(model.y0[None])[0]
    duration = float(model.frame_times[-1])
    speed = np.linalg.norm(velocities, axis=1) + gravity_magnitude(model.force_terms) * duration  # free flight bound
    fastest = int(np.argmax(speed))
    reach = float(speed[fastest]) * h
    name, thickness = thinnest
    if reach <= thickness:
        return []
    body = model.bodies.names[fastest]
    return [f"body {body!r} may reach {speed[fastest]:.3g} m/s and so move {reach:.3g} m "
            f"in one step of {h:.3g} s, more than the {thickness:.3g} m thickness of {name}. Speculative contacts "
            f"still stop it, to the accuracy of one step; solver.dt ≤ {0.9 * thickness / speed[fastest]:.3g} s "
            "resolves the wall."]


def _turn_warnings(model: Model, method: str, h: float) -> list[str]:
    messages = []
    for scale in time_scales(model):
        if not scale.turns or scale.rate * h <= MOST_TURN_PER_STEP:
            continue
        if scale.explicit and METHODS[method].implicit:
            # a gas's breathing under backward Euler: damped like the stiff springs it steps, and refused before
            # the run where its explicit part could not hold it (stability.check_fixed_step)
            continue
        drift = "shrinks" if METHODS[method].implicit else "grows"
        messages.append(f"{method} at dt = {h:.3g} s turns the {scale.what}, ω = {scale.rate:.4g} rad/s, by "
                        f"{scale.rate * h:.3g} rad a step ({2 * np.pi / (scale.rate * h):.3g} steps a turn): its "
                        f"circle is a coarse polygon and its radius {drift} step by step. Use solver.dt ≤ "
                        f"{MOST_TURN_PER_STEP / scale.rate:.3g} s, or an adaptive method (DOP853).")
    return messages


def preflight(model: Model, method: str, dt: float | None = None) -> list[str]:
    """Warnings for running ``model`` with ``method`` (at step ``dt`` [s] for a fixed-step method; None: its
    default); each is also issued as a StabilityWarning."""
    times = model.frame_times
    h = steps = None
    if METHODS[method].fixed_step and len(times) > 1:
        interval = float(times[1] - times[0])
        count = substeps(interval, resolve_dt(dt, method, interval))
        h, steps = interval / count, count * (len(times) - 1)
    messages = _spring_warnings(model, method, steps or 0, h)
    if h is not None and model.contact_world is not None:
        messages += _contact_warnings(model, model.contact_world, h)
    if h is not None:
        messages += _turn_warnings(model, method, h)
    for message in messages:
        warnings.warn(message, StabilityWarning, stacklevel=2)
    return messages
