"""How a run steps, resolved once: the default step, how a fixed step divides the frame interval, and the frozen
:class:`StepPlan` every stage reads (the compiler makes it from the scene's ``solver`` section). Light: nothing but
numpy, so that ``animbatch validate`` and the method descriptions can use it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The step explicit fixed-step methods take when the scene names none [s].
DEFAULT_DT = 1e-3
#: Fixed-step methods stable at any step (implicit): without ``solver.dt`` they take one step per frame, as the
#: docs recommend for cloth (a test checks this is every implicit fixed-step method of the method table).
ONE_STEP_PER_FRAME = ("backward_euler",)


def resolve_dt(dt: float | None, method: str = "", interval: float | None = None) -> float:
    """The step bound [s] a fixed-step ``method`` uses over frames ``interval`` [s] apart: the scene's ``solver.dt``;
    without one, the frame interval for the implicit methods (:data:`ONE_STEP_PER_FRAME`) and :data:`DEFAULT_DT`
    for the others. This is the one place the default is applied."""
    if dt is not None:
        return float(dt)
    if method in ONE_STEP_PER_FRAME and interval is not None:
        return float(interval)
    return DEFAULT_DT


def substeps(interval: float, dt: float) -> int:
    """Number of equal steps of at most ``dt`` that cover ``interval``. A relative tolerance of 1e-6 absorbs a dt
    written to a few digits: ``dt: 0.008333333`` means 1/120 s, four steps per frame at 30 fps, not five."""
    return max(1, math.ceil(interval / dt * (1 - 1e-6)))


@dataclass(frozen=True)
class StepPlan:
    """A run's step settings in numbers, resolved once.

    ``method``: the integration method's name; ``adaptive``: whether it chooses its own steps (scipy's methods;
    ``analytic`` counts as neither); ``dt``: the step bound of fixed-step methods [s], the default applied
    (``dt_given``: the scene set it); ``rtol``, ``atol``, ``max_step`` [s]: the adaptive methods' settings;
    ``interval``: the frame interval 1/fps [s] (None with a single frame). It has the shape of
    :class:`~animbatch.sim.integrators.interface.StepSettings`."""

    method: str
    adaptive: bool
    dt: float
    dt_given: bool
    rtol: float
    atol: float
    max_step: float | None
    interval: float | None

    @property
    def is_adaptive(self) -> bool:
        return self.adaptive

    @property
    def frame_substeps(self) -> int:
        """Steps per frame interval: a fixed-step method's equal steps of at most ``dt``; 1 for the others (an
        adaptive method integrates each frame interval as one segment)."""
        if self.adaptive or self.method == "analytic" or self.interval is None:
            return 1
        return substeps(self.interval, self.dt)

    @property
    def step(self) -> float | None:
        """The fixed step actually taken [s] (the frame interval over :attr:`frame_substeps`); None for adaptive
        methods and single frames."""
        if self.adaptive or self.method == "analytic" or self.interval is None:
            return None
        return self.interval / self.frame_substeps


def plan_steps(method: str, *, adaptive: bool, dt: float | None, rtol: float, atol: float,
               max_step: float | None, frame_times: np.ndarray) -> StepPlan:
    """The :class:`StepPlan` of a run over ``frame_times`` (F,) [s] with these settings (``dt`` None: the
    default)."""
    interval = float(frame_times[1] - frame_times[0]) if len(frame_times) > 1 else None
    return StepPlan(method, adaptive, resolve_dt(dt, method, interval), dt is not None, float(rtol), float(atol),
                    None if max_step is None else float(max_step), interval)
