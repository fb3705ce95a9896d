"""The reference a study measures errors against, and how accurate that reference itself is.

* With ``study.closed_form``, the exact motion (:mod:`animbatch.sim.closed_forms`); its accuracy is that of
  floating point (:data:`ROUND_OFF`).
* Otherwise two tight runs: DOP853 at the tightest tolerance that succeeds (1e-12, else 1e-11, 1e-10), checked
  against DOP853 one decade looser, or, for a stiff scene (springs faster than ten radians per frame), against
  Radau at 1e-9 (an independent, implicit method; tighter Radau runs take minutes on a long stiff scene). Their
  difference, measured like any run's error, is the reference's accuracy ``floor``: a run
  whose error is not clearly above it (below twice the floor) is marked as limited by the reference.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from animbatch.errors import StudyError
from animbatch.sim.closed_forms import exact_motion
from animbatch.sim.integrators.stability import stiffest_mode
from animbatch.sim.model import Model
from animbatch.study.measure import Motion, Scales, final_error, position_error
from animbatch.study.runs import RunOutcome, RunSetting, execute

#: Tolerances tried, tightest first, for the DOP853 reference run.
REFERENCE_RTOLS = (1e-12, 1e-11, 1e-10)
#: A run's error below this many times the reference's own accuracy is not trusted.
REFERENCE_MARGIN = 2.0
#: The accuracy of a closed form as evaluated in floating point, relative to the scene's scales: errors below it are
#: round-off, not the method's.
ROUND_OFF = 1e-13


@dataclass(frozen=True)
class Reference:
    """The reference motion, what it is (``description``), the scene's scales taken from it, and its accuracy
    (``floor`` of the position error and ``final_floor`` of the final-state error)."""

    motion: Motion
    description: str
    scales: Scales
    floor: float
    final_floor: float

    def limits(self, error: float, final: float) -> bool:
        """Whether a run's errors are too close to the reference's own accuracy to be measured."""
        return error <= REFERENCE_MARGIN * self.floor and final <= REFERENCE_MARGIN * max(self.final_floor, 0.0)


def is_stiff(model: Model) -> bool:
    """Springs vibrating faster than ten radians per frame interval: explicit methods need many steps per frame."""
    mode = stiffest_mode(model)
    interval = float(model.frame_times[1] - model.frame_times[0]) if len(model.frame_times) > 1 else 1.0
    return mode is not None and mode.omega * interval > 10


def _first_scales(model: Model) -> np.ndarray:
    """A rough per-component scale before any motion is known: from the initial state alone."""
    x = model.positions(model.y0[None])[0]
    v = model.velocities(model.y0[None])[0]
    guess = Scales.of_motion(model, np.stack([x, x + v * float(model.frame_times[-1])])[:, :, :],
                             np.stack([v, v]))
    return guess.tolerance_scale(model)


def find_reference(model: Model, *, closed_form: bool, timeout: float, progress: Callable[[str], None] = print,
                   fixed: tuple[str, float] | None = None) -> Reference:
    """The study's reference for ``model``; ``timeout`` [s] per reference run (raises StudyError, naming every run
    tried and why it failed, when no tight run succeeds in time). ``fixed``: (method, dt [s]) of a fixed-step
    reference instead of the tight adaptive one, checked against the same method at twice the step."""
    if closed_form:
        exact = exact_motion(model)
        orientations = np.zeros((*exact.positions.shape[:2], 4))
        orientations[..., 0] = 1.0
        motion = Motion(exact.positions, exact.velocities, orientations)
        forms = ", ".join(f"{name}: {form}" for name, form in exact.forms.items())
        return Reference(motion, f"closed form ({forms})", Scales.of_motion(model, motion.positions,
                                                                             motion.velocities), ROUND_OFF, ROUND_OFF)
    scale = _first_scales(model)
    if fixed is not None:
        method, dt = fixed
        progress(f"reference: {method} at dt {dt:.3g} s …")
        primary = execute(model, RunSetting(method, dt=dt), scale, repeats=0, timeout=timeout)
        if primary.status != "ok":
            raise StudyError(f"no reference for the study: {method} at dt {dt:.3g} s (study.reference) "
                             f"{primary.status}: {primary.reason}. Give it more time (--timeout T: reference runs get "
                             "10 T, at least 120 s) or shorten the scene (--set duration=…).")
        return _checked(model, primary, RunSetting(method, dt=2 * dt), scale, timeout, progress)
    stiff = is_stiff(model)
    attempts: list[RunOutcome] = []
    for rtol in REFERENCE_RTOLS:
        if attempts and attempts[-1].status == "timeout" and rtol != REFERENCE_RTOLS[-1]:
            continue  # a decade looser saves only a quarter of DOP853's steps: after a timeout try the loosest
        progress(f"reference: DOP853 at rtol {rtol:.0e} …")
        attempts.append(execute(model, RunSetting("DOP853", rtol=rtol), scale, repeats=0, timeout=timeout))
        if attempts[-1].status == "ok":
            break
    if attempts[-1].status != "ok" and stiff:
        progress("reference: Radau at rtol 1e-11 …")
        attempts.append(execute(model, RunSetting("Radau", rtol=1e-11), scale, repeats=0, timeout=timeout))
    primary = attempts[-1]
    if primary.status != "ok":
        tried = "; ".join(f"{run.setting.method} at {run.setting.label}: {run.reason}" for run in attempts)
        raise StudyError(
            f"no reference for the study: every tight run failed ({tried}). Errors are measured against a tight "
            f"run, so it has to succeed: shorten the scene (--set duration=…), give it more time (--timeout T: "
            f"reference runs get 10 T, at least 120 s), or use --closed-form where every body has one.")
    assert primary.setting.rtol is not None
    check_setting = (RunSetting("Radau", rtol=max(1e-9, 10 * primary.setting.rtol)) if stiff or
                     primary.setting.method == "Radau" else RunSetting("DOP853", rtol=10 * primary.setting.rtol))
    return _checked(model, primary, check_setting, scale, timeout, progress)


def _checked(model: Model, primary: RunOutcome, check_setting: RunSetting, scale: np.ndarray, timeout: float,
             progress: Callable[[str], None]) -> Reference:
    """The reference ``primary``, its accuracy measured by a second run with ``check_setting``."""
    assert primary.states is not None
    progress(f"reference check: {check_setting.method} at {check_setting.label} …")
    check = execute(model, check_setting, scale, repeats=0, timeout=timeout)
    motion = Motion.of_states(model, primary.states, primary.impacts)
    scales = Scales.of_motion(model, motion.positions, motion.velocities)
    description = f"{primary.setting.method} at {primary.setting.label}"
    if check.status != "ok" or check.states is None:
        return Reference(motion, f"{description} (unchecked: {check.setting.method} {check.status})", scales,
                         np.inf, np.inf)
    checked = Motion.of_states(model, check.states, check.impacts)
    return Reference(motion, f"{description}, checked against {check_setting.method} at {check_setting.label}",
                     scales, position_error(model, checked, motion, scales), final_error(checked, motion, scales))
