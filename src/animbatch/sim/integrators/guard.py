"""Turning a non-finite state or a solver failure into an error that names the time, the body and the fix."""

from __future__ import annotations

import numpy as np

from animbatch.errors import SimulationError
from animbatch.sim.forces.gravitation import InverseSquarePairs
from animbatch.sim.forces.gravity import gravity_magnitude
from animbatch.sim.integrators.advice import closest_encounter, failure_advice
from animbatch.sim.integrators.interface import EquationsOfMotion
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.integrators.stability import largest_stable_step, stiffest_mode
from animbatch.sim.invariants import kinetic_energy, total_energy
from animbatch.sim.model.layout import StateLayout
from animbatch.sim.model.model import Model


def first_non_finite(y: np.ndarray) -> int | None:
    """Index of the first NaN or infinite component of ``y``, or None."""
    if np.isfinite(y).all():  # the common case: one fast pass
        return None
    return int(np.flatnonzero(~np.isfinite(y))[0])


def project_start(system: EquationsOfMotion, y: np.ndarray, t: float) -> None:
    """Put a start that breaks its joints on them (:meth:`EquationsOfMotion.project`, in place), and stop with the
    body and its joints named when that start cannot be placed: a state that is not finite after the projection
    (a position so far out, 1e18 m say, that the joint's geometry overflows) would otherwise reach the method as
    NaN, or pass for a divergence of the step."""
    before = y.copy()
    with np.errstate(all="ignore"):  # a start that overflows is reported below, not warned about
        system.project(y, t=t)
    index = first_non_finite(y)
    if index is None:
        return
    model: Model | None = getattr(system, "model", None)
    body: str | None = None
    quantity = f"component {index}"
    holding: tuple[str, ...] = ()
    if model is not None and model.body_count:
        quantity = model.layout.describe_index(index)[1]
        # the culprit is the body that started farthest out (the projection spreads NaN to the bodies it couples)
        reach = np.linalg.norm(model.positions(before[None])[0], axis=1)
        body = model.body_names[int(np.argmax(np.where(np.isnan(reach), np.inf, reach)))]
        if model.joints is not None:
            holding = model.joints.names_joining(model.body_names.index(body))
    held = f" by joint{'s' if len(holding) > 1 else ''} {', '.join(repr(n) for n in holding)}" if holding else ""
    raise SimulationError(
        f"the start cannot be put on its joints: body {body!r}, held{held}, starts too far from where they allow "
        f"(its state is {'NaN' if np.isnan(y[index]) else 'infinite'} once moved onto them). Give it a start within "
        "the joint's reach of the other end", time=t, body=body,
        details={"quantity": quantity, "joints": list(holding)})


def divergence_error(layout: StateLayout | None, y: np.ndarray, index: int, t: float, *, method: str,
                     dt: float | None = None, step: int | None = None, model: Model | None = None,
                     last_finite: np.ndarray | None = None) -> SimulationError:
    """The error for state component ``index`` of ``y`` having become non-finite at time ``t`` [s]; with the
    ``model`` and the ``last_finite`` state before it, an adaptive method's advice fits the cause
    (:func:`~animbatch.sim.integrators.advice.failure_advice`)."""
    body, quantity = layout.describe_index(index) if layout is not None else (None, f"component {index}")
    who = f"body {body!r} {quantity}" if body is not None else quantity
    when = f"t = {t:.6g} s" + (f" (step {step})" if step is not None else "")
    value = "NaN" if np.isnan(y[index]) else "infinite"
    if dt is not None:
        advice = (f"{method} is unstable at dt = {dt:.3g} s for this scene: reduce solver.dt (try {dt / 10:.3g}), "
                  "or use an adaptive method (solver.method: RK45, or Radau for stiff springs)")
    else:

        advice = failure_advice(model, method, last_finite if last_finite is not None else y, t, body)
    return SimulationError(f"the simulation diverged at {when}: {who} became {value} ({method}). {advice}.",
                           time=t, body=body, details={"quantity": quantity, "method": method, "dt": dt})


def fastest_body(layout: StateLayout | None, rate: np.ndarray, y: np.ndarray, atol: float | np.ndarray,
                 rtol: float) -> str:
    """The body whose state changes fastest relative to the tolerances: usually the culprit of a stalled solver."""
    if layout is None:
        return "?"
    with np.errstate(all="ignore"):
        scaled = np.abs(rate) / (atol + rtol * np.abs(y))
    scaled = np.where(np.isfinite(scaled), scaled, np.inf)
    body, _ = layout.describe_index(int(np.argmax(scaled)))
    return body


#: Largest sustained rise of the total energy tolerated in a scene without energy input, as a multiple of its
#: energy scale (see :func:`check_energy_growth`): far above what any stable method's error gives, and reached soon
#: by an unstable one, whose energy grows geometrically.
ENERGY_GROWTH_LIMIT = 1.0
#: The same for a fixed implicit step (backward Euler), which damps every mode it integrates: any lasting rise is
#: the work of something else (contacts resolved a whole long step at a time: a cloth landing on a box at one step
#: per frame stored 0.45 of its scale in its springs, where a fine step loses energy), so a fifth is enough.
DISSIPATIVE_STEP_GROWTH_LIMIT = 0.2
#: The rise must hold over this long [s] (every frame in it), so that a stable symplectic method, whose energy
#: oscillates (widely near its step limit) but always comes back, is never stopped.
ENERGY_WINDOW = 0.5


def energy_scale(model: Model) -> float:
    """The energy a scene has to play with [J], from its initial state: the largest of |E₀|, the kinetic energy,
    ``M |g| L`` (total mass, strongest uniform gravity, size of the initial configuration or the largest body) and
    what a term can trade over ``L`` (``Σ|q| |E| L`` in an electric field)."""

    y0 = model.y0
    x0 = model.positions(y0[None])[0]
    size = max(float(np.linalg.norm(np.ptp(x0, axis=0))) if len(x0) else 0.0,
               float(np.max(model.bodies.radius, initial=0.0)))
    gravity = gravity_magnitude(model.force_terms)
    return max(abs(float(total_energy(model, y0))), float(kinetic_energy(model, y0)),
               float(np.sum(model.bodies.mass)) * gravity * size,
               max((term.energy_scale(size) for term in model.force_terms), default=0.0), 1e-12)


def check_energy_growth(model: Model, states: np.ndarray, method: str, dt: float | None,
                        limit: float = ENERGY_GROWTH_LIMIT) -> None:
    """Raise SimulationError when the total energy of a scene that has no energy input (no wind, applied forces,
    moving anchors or targets) stays above ``E₀ + limit × scale`` (:func:`energy_scale`) at every frame of a window
    of :data:`ENERGY_WINDOW` seconds, or of the last half window or more of the run, in ``states`` (F, n).

    Such a rise can only be numerical: an unstable step, or a near collision under gravitation resolved too coarsely.
    The error names the frame time, the body that gained the most kinetic energy, the stiffest spring and the largest
    stable step, and what to change.
    """

    if len(states) < 2 or model.adds_energy:
        return
    if getattr(model.anchors, "moving", False):
        return
    times = model.frame_times
    energy = total_energy(model, states)
    scale = energy_scale(model)
    # A run shorter than the window is judged on all its frames after the first. In a longer one, windows near the
    # end are cut short by it: a rise in the last half window must stay high to the end, over half a window at least
    # (a plunge through a singularity 0.45 s before the end went unnoticed otherwise).
    interval = float(times[1] - times[0])
    window = min(max(2, int(round(ENERGY_WINDOW / interval))), len(energy) - 1)
    shortest = window if window == len(energy) - 1 else max(2, -(-window // 2))
    padded = np.concatenate([energy[1:], np.full(window - 1, np.inf)])
    sustained = np.lib.stride_tricks.sliding_window_view(padded, window).min(axis=1)[: len(energy) - shortest]
    mode = stiffest_mode(model)
    if dt and METHODS[method].implicit:
        limit = min(limit, DISSIPATIVE_STEP_GROWTH_LIMIT)
    if dt and mode is not None and METHODS[method].symplectic and mode.omega * dt < 2:
        # a stable symplectic step keeps a modified energy; the true one swings within 1 / (1 - (ω h / 2)²) of it
        limit = max(limit, 2 / (1 - (mode.omega * dt / 2) ** 2))
    over = np.flatnonzero(sustained - energy[0] > limit * scale)
    if not len(over):
        return
    first = int(over[0]) + 1  # the first frame of the first window that stayed high
    frame = min(first + window - 1, len(energy) - 1)  # and its last
    t = float(times[frame])
    velocities = model.velocities(states[[0, frame]])
    speed2 = np.sum(velocities**2, axis=2)  # (2, P)
    gained = 0.5 * model.bodies.mass * (speed2[1] - speed2[0])
    body = model.bodies.names[int(np.argmax(gained))]
    rise = energy[frame] - energy[0]
    message = (f"the total energy rose by {rise:.4g} J ({rise / scale:.3g} × its scale {scale:.4g} J, and stayed "
               f"that high for {(frame - first + 1) * interval:.3g} s"
               + (", to the end of the run" if frame - first + 1 < window else "")
               + f") by t = {t:.4g} s, in a scene that has "
               f"no energy input: the integration ({method}"
               + (f" at dt = {dt:.3g} s" if dt else "") + f") is adding energy. Body {body!r} gained the most "
               f"kinetic energy ({gained.max():.4g} J).")
    remedies = []
    if dt and METHODS[method].implicit:
        # stable at any step: the stiffest spring is not the culprit, the long steps around contacts are
        message += (f" {method} damps every motion it integrates, so the rise comes from what it resolves a whole step "
                    f"at a time: contacts and collisions at {dt:.3g} s a step.")
        raise SimulationError(message + f" Try a smaller solver.dt (≤ {dt / 8:.2g} s). No frame was written.",
                              time=t, body=body, details={"energy_rise": float(rise), "method": method, "dt": dt,
                                                          "spring": None})
    if mode is not None:
        stable = largest_stable_step(method, mode.omega, mode.decay) if dt else None
        message += (f" The stiffest is the {mode.stiffest()}, ω = {mode.spring_omega:.4g} rad/s "
                    f"(up to {mode.omega:.4g} rad/s around {mode.body!r})"
                    + (f"; the largest stable step of {method} for it is {stable:.3g} s" if stable else "") + ".")
        remedies.append(f"a smaller solver.dt (≤ {0.9 * stable:.3g} s)" if stable else "a smaller solver.dt")
    else:
        remedies.append("a smaller solver.dt" if dt else "tighter solver.rtol and solver.atol")
    remedies += ["solver.method Radau or BDF", "backward_euler"]
    terms = model.force_terms
    unsoftened = [term.kind for term in terms if isinstance(term, InverseSquarePairs) and term.softening == 0]
    if unsoftened:

        encounter = closest_encounter(model, model.positions(states[: frame + 1]),
                                      times[: frame + 1])
        if encounter is not None:
            message += " " + encounter.advice() + "."
        else:
            remedies.append(f"softening on the {unsoftened[0]} field (bodies pass very close)")
    raise SimulationError(message + " Try " + ", ".join(remedies) + ". No frame was written.", time=t, body=body,
                          details={"energy_rise": float(rise), "method": method, "dt": dt,
                                   "spring": mode.spring if mode else None})
