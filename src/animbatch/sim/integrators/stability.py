"""Before a fixed-step run: will this step size hold the scene's springs? If not, stop and say which spring.

An explicit method is stable on a spring only while ``ω h`` is small enough, ω being the spring's angular frequency.
A mesh of springs vibrates faster than any one of its springs: its highest mode is bounded (Gershgorin's theorem on
``M⁻¹ K``, with each spring's stiffness ``ks`` along its axis) by::

    ω_max² ≤ max over particles i of  Σ_springs at i  ks (1 + [other end is a particle]) / m_i

(exact for a chain of equal masses, ``2 √(k/m)``), and damped at a rate ``α`` bounded the same way by the dampers.
For that mode each method multiplies the amplitude per step by the spectral radius ρ of its one-step matrix on
``x'' = -ω² x - 2 α x'``. If ``ρ`` to the power of the run's steps exceeds ``GROWTH_LIMIT``, the run would blow up
(or fill the frames with garbage long before), so it is refused before it starts, naming the stiffest spring and a
step or method that works. Backward Euler is stable for any step and is never refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.errors import SimulationError
from animbatch.sim.bodies import Kinematics
from animbatch.sim.forces.controllers import Controllers
from animbatch.sim.forces.gravity import gravity_magnitude
from animbatch.sim.forces.term import TimeScale
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.model.model import Model

#: Largest amplitude growth of the stiffest mode tolerated over a whole run.
GROWTH_LIMIT = 1e6


@dataclass(frozen=True)
class StiffestMode:
    """The bound on the fastest spring vibration: ``omega`` [rad/s] and its damping rate ``decay`` [1/s], at the
    particle ``body``; and the single stiffest spring or controller (a virtual spring to its target), the one with
    the highest ``√(ks (1/m1 + 1/m2))``: its ``spring_kind`` ("spring" or "controller") and name."""

    omega: float
    decay: float
    body: str
    spring: str
    spring_omega: float
    spring_stiffness: float
    spring_masses: tuple[float, float]
    spring_kind: str = "spring"

    def stiffest(self) -> str:
        """``spring 'name' (ks = … N/m, between … kg and …)`` for messages."""
        first, second = self.spring_masses
        other = ("its target" if self.spring_kind == "controller" else "an anchor") if np.isinf(second) else \
            f"{second:.3g} kg"
        return (f"{self.spring_kind} {self.spring!r} (ks = {self.spring_stiffness:g} N/m, between {first:.3g} kg "
                f"and {other})")


def stiffest_mode(model: Model) -> StiffestMode | None:
    """The stiffest spring vibration of a model, counting PD controllers as springs to their targets (None without
    either)."""
    springs = model.springs
    controllers = next((term for term in model.force_terms if isinstance(term, Controllers)), None)
    if (springs is None or springs.count == 0) and controllers is None:
        return None
    bodies = model.bodies
    mass = np.asarray(bodies.mass, float)
    stiffness_sum = np.zeros(len(mass))
    damping_sum = np.zeros(len(mass))
    candidates = []  # (ω, name, ks, masses, kind) of the stiffest spring and of the stiffest controller
    if springs is not None and springs.count > 0:
        first, second, anchored = springs.first, springs.second, springs.second_is_anchor
        mass_first = mass[first]
        mass_second = np.where(anchored, np.inf, mass[np.where(anchored, 0, second)])
        spring_omega = np.sqrt(springs.stiffness * (1 / mass_first + 1 / mass_second))
        k = int(np.argmax(spring_omega))
        candidates.append((float(spring_omega[k]), springs.names[k], float(springs.stiffness[k]),
                           (float(mass_first[k]), float(mass_second[k])), "spring"))
        both = ~anchored
        share = np.where(both, 2.0, 1.0)  # a spring to another body adds its coupling to the row sum too
        stiffness_sum += np.bincount(first, springs.stiffness * share, minlength=len(mass))
        damping_sum += np.bincount(first, springs.damping * share, minlength=len(mass))
        stiffness_sum += np.bincount(second[both], (springs.stiffness * share)[both], minlength=len(mass))
        damping_sum += np.bincount(second[both], (springs.damping * share)[both], minlength=len(mass))
    if controllers is not None:
        points = np.asarray(controllers.point, np.intp)
        np.add.at(stiffness_sum, points, controllers.stiffness)
        np.add.at(damping_sum, points, controllers.damping)
        controller_omega = np.sqrt(controllers.stiffness / mass[points])
        k = int(np.argmax(controller_omega))
        candidates.append((float(controller_omega[k]), controllers.names[k], float(controllers.stiffness[k]),
                           (float(mass[points[k]]), np.inf), "controller"))
    omega2 = stiffness_sum / mass
    fastest = int(np.argmax(omega2))
    spring_omega_max, name, stiffness, masses, kind = max(candidates, key=lambda candidate: candidate[0])
    return StiffestMode(float(np.sqrt(omega2[fastest])), float(damping_sum[fastest] / (2 * mass[fastest])),
                        bodies.names[fastest], name, spring_omega_max, stiffness, masses, kind)


def step_matrix(method: str, h: float, omega: float, decay: float) -> np.ndarray:
    """The matrix taking (x, v) over one step of ``method`` on ``x'' = -ω² x - 2 α x'`` (its ``step_matrix`` in
    :data:`~animbatch.sim.integrators.methods.METHODS`); for Verlet (3, 3), taking (x, v, a)."""
    model = METHODS[method].step_matrix if method in METHODS else None
    if model is None:
        raise ValueError(f"no stability model for {method!r}")
    return model(h, omega, decay)


def amplification(method: str, h: float, omega: float, decay: float) -> float:
    """Spectral radius of one step: how much the mode's amplitude grows per step (≤ 1: stable)."""
    return float(np.max(np.abs(np.linalg.eigvals(step_matrix(method, h, omega, decay)))))


def largest_stable_step(method: str, omega: float, decay: float) -> float | None:
    """The largest h with amplification ≤ 1 + 1e-9 (found by bisection), or None when no step is stable."""
    tolerance = 1e-9
    rate = max(omega, 2 * decay, 1e-12)  # without a spring (ω = 0) the decay alone sets the scale
    high = 10.0 / rate
    # ω h = 1e-4 is small enough for every method with a stable range, and large enough that undamped explicit
    # Euler's growth √(1 + (ω h)²) shows above the tolerance
    low = 1e-4 / rate
    if amplification(method, low, omega, decay) > 1 + tolerance:
        return None
    for _ in range(100):
        middle = 0.5 * (low + high)
        if amplification(method, middle, omega, decay) <= 1 + tolerance:
            low = middle
        else:
            high = middle
    return low


def start_kinematics(model: Model) -> Kinematics:
    """Where the bodies are and how they move at the start."""
    return Kinematics(np.asarray(model.positions(model.y0[None])[0]), np.asarray(model.velocities(model.y0[None])[0]),
                      None, None, model.particle_count)


def time_scales(model: Model) -> list[TimeScale]:
    """Each force term's own fastest motion from the start (:meth:`ForceTerm.time_scale`): gyrations, drag and
    damping."""
    start = start_kinematics(model)
    gravity = gravity_magnitude(model.force_terms)
    found = (term.time_scale(start, model.bodies, gravity) for term in model.force_terms)
    return [scale for scale in found if scale is not None]


def _check_drag_step(scales: list[TimeScale], method: str, h: float, steps: int) -> None:
    """Raise SimulationError when an explicit step ``h`` [s] is too long for the fastest drag: a velocity relaxing
    at rate λ is multiplied by |1 − h λ| per explicit Euler step (the method's own factor for the others), which
    overshoots and grows once h λ passes the method's limit (2 for Euler)."""
    for scale in scales:
        if scale.turns:
            continue
        growth = amplification(method, h, 0.0, scale.rate / 2)  # x'' = −λ x': the mode model without a spring
        if growth <= 1.0 or steps * np.log(growth) <= np.log(GROWTH_LIMIT):
            continue
        limit = largest_stable_step(method, 0.0, scale.rate / 2)
        fix = f"solver.dt ≤ {0.9 * limit:.3g} s" if limit is not None else "backward_euler"
        raise SimulationError(
            f"{method} at dt = {h:.3g} s cannot hold the {scale.what}: its rate λ = {scale.rate:.4g} 1/s gives "
            f"h λ = {h * scale.rate:.3g}, and each step multiplies the velocity by {growth:.4g} instead of damping "
            f"it. Use {fix}, or backward_euler (stable at any dt). Nothing was simulated.",
            time=0.0, details={"rate": scale.rate, "dt": h, "method": method})


def _check_explicit_oscillations(scales: list[TimeScale], method: str, h: float, steps: int) -> None:
    """Raise SimulationError when a step ``h`` [s] is too long for an oscillation that every fixed-step method
    follows explicitly (a gas's breathing): an implicit method then steps it as symplectic Euler does (the force
    from the start of the step, the positions from the new velocities), stable up to ω h = 2."""
    for scale in scales:
        if not scale.explicit:
            continue
        scheme = "symplectic_euler" if METHODS[method].implicit else method
        growth = amplification(scheme, h, scale.rate, 0.0)
        if growth <= 1.0 or steps * np.log(growth) <= np.log(GROWTH_LIMIT):
            continue
        limit = largest_stable_step(scheme, scale.rate, 0.0)
        fix = f"solver.dt ≤ {0.9 * limit:.3g} s, or " if limit is not None else ""
        raise SimulationError(
            f"{method} at dt = {h:.3g} s cannot follow the {scale.what}: every fixed-step method takes this force "
            f"from the start of each step, and at ω = {scale.rate:.4g} rad/s (ω dt = {scale.rate * h:.3g}) each step "
            f"multiplies the motion by {growth:.4g}. Use {fix}an adaptive method (DOP853), which follows it at its "
            "own steps. Nothing was simulated.", time=0.0, details={"rate": scale.rate, "dt": h, "method": method})


def check_fixed_step(model: Model, method: str, h: float, steps: int) -> None:
    """Raise SimulationError before the run when ``method`` at step ``h`` [s] would let the stiffest spring
    vibration, a velocity under the fastest drag, or an oscillation every method takes explicitly, grow by more
    than GROWTH_LIMIT over ``steps`` steps."""
    scales = time_scales(model)  # each term's, gathered once
    _check_explicit_oscillations(scales, method, h, steps)
    if METHODS[method].implicit:  # stable at any step
        return
    _check_drag_step(scales, method, h, steps)
    mode = stiffest_mode(model)
    if mode is None:
        return
    growth_per_step = amplification(method, h, mode.omega, mode.decay)
    if growth_per_step <= 1.0 or steps * np.log(growth_per_step) <= np.log(GROWTH_LIMIT):
        return
    limit = largest_stable_step(method, mode.omega, mode.decay)
    fix = (f"reduce solver.dt to at most {0.9 * limit:.3g} s" if limit is not None
           else f"{method} is unstable at any step for these springs (too little damping)")
    other = largest_stable_step("symplectic_euler", mode.omega, mode.decay)
    undamped = largest_stable_step(method, mode.omega, 0.0)
    # an explicit damper term is limited by its rate as a spring by its frequency: say so when dampers set the step
    damper_note = (f" The dampers set this limit (without them it would be {0.9 * undamped:.3g} s)."
                   if limit is not None and undamped is not None and limit < 0.8 * undamped else "")
    raise SimulationError(
        f"{method} at dt = {h:.3g} s cannot hold this scene's springs: the stiffest {mode.stiffest()} vibrates at "
        f"ω = {mode.spring_omega:.4g} rad/s, and "
        f"the springs around {mode.body!r} at up to {mode.omega:.4g} rad/s (damping ratio ζ = "
        f"{mode.decay / mode.omega:.2g}, ω dt = {mode.omega * h:.3g}). "
        f"{method} multiplies that vibration by {growth_per_step:.4g} per step, so it would blow up within the first "
        f"{int(np.log(GROWTH_LIMIT) / np.log(growth_per_step)) + 1} of the run's {steps} steps. Use solver.method: "
        f"backward_euler (stable at any dt), or {fix}"
        + (f" (symplectic_euler: dt ≤ {0.9 * other:.3g} s)" if other is not None and method != "symplectic_euler"
           else "") + f".{damper_note} Nothing was simulated.",
        time=0.0, body=mode.body, details={"spring": mode.spring, "omega": mode.omega, "dt": h, "method": method})
