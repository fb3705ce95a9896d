"""Joint limits and ropes as events of the adaptive methods: a stop is met at the instant it is reached.

Reaching a limit (or a rope going taut) is an impact, a jump of velocity that no smooth right-hand side can make;
switching the limit's force on inside the right-hand side would make it discontinuous, and an adaptive method then
creeps up to the stop in ever shorter steps. So, as for contacts, the stops have *modes*: between events the set
of engaged rows is fixed (an engaged row is held like an equality, with Baumgarte stabilisation; a free one does
nothing), and the method stops at the instants the modes change:

* a free row reaches its stop (C crosses 0 from above, found on the step's dense output): the state is projected,
  which removes the approaching velocity (an inelastic stop, as fixed-step methods do after every step), and the
  row is engaged;
* an engaged row would pull (its multiplier λ crosses 0 from above): it is released.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import brentq

from animbatch.errors import SimulationError

#: Mode changes at one instant (a few ulps apart) more often than this in a row: the stops cannot be resolved.
MAX_STALLED_EVENTS = 50
#: At an engaging event, unilateral rows this close to their stops (times the joints' scale) count as reached.
REACH = 1e-9


class JointStops:
    """The :class:`~animbatch.sim.integrators.interface.StepEvents` of joints with limits or ropes, for a model's
    Dynamics ``system`` (whose ``engaged_stops`` they set)."""

    label = "joint limits and ropes"
    advice = "use a fixed-step method (solver.method: verlet), or tighter solver.rtol and solver.atol"

    def __init__(self, system: Any) -> None:
        self.system = system
        self.joints = system.joints
        self._unilateral = np.flatnonzero(self.joints.row_is_unilateral)
        self._engaged = np.zeros(len(self.joints.row_is_unilateral), bool)
        self._log: list[tuple[float, int]] = []
        self._last_event = -np.inf
        self._stalled = 0
        self._pending: tuple[str, int] | None = None
        self.events = 0

    @property
    def impacts(self) -> JointStops:
        return self

    def as_list(self) -> list[tuple[float, int]]:
        """The stops met, as (time [s], model point of the joint's first body)."""
        return list(self._log)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        return self.system.rhs(t, y)

    def start(self, t: float, y: np.ndarray, frames: int, method: str) -> None:
        """Engage the rows at or past their stops that push at the start."""
        self.system.engaged_stops = None
        engaged = self._measure(y, t)[1] > 0
        self._engaged[self._unilateral] = engaged & (self._measure(y, t)[0] <= REACH * self.joints.scale)
        self.system.engaged_stops = self._engaged

    def restart(self, t: float, y: np.ndarray) -> float | None:
        return None

    def _measure(self, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """C and λ of the unilateral rows at state ``y`` (C > 0: free; λ > 0: pushing), in the present modes."""
        system, joints = self.system, self.joints
        state = system.kinematics(*system.split(y), t=t)
        gaps = joints.rows(joints.motion(state)).violation[self._unilateral]
        force, torque = system.loads(t, state)
        loads = joints.loads(state, force, torque, system.engaged_stops)
        return gaps, loads.multipliers[self._unilateral]

    def first_event(self, solver: Any, before: np.ndarray) -> float | None:
        """The first instant in the solver's last step at which a free row reaches its stop or an engaged one
        starts to pull."""
        start, end = float(solver.t_old), float(solver.t)
        (gap_before, pull_before), (gap_after, pull_after) = self._measure(before, start), self._measure(solver.y, end)
        engaged = self._engaged[self._unilateral]
        candidates = [(k, "reach", 0) for k in np.flatnonzero(~engaged & (gap_before > 0) & (gap_after <= 0))]
        candidates += [(k, "release", 1) for k in np.flatnonzero(engaged & (pull_before > 0) & (pull_after <= 0))]
        if not candidates:
            self._pending = None
            return None
        dense = solver.dense_output()
        first = np.inf
        for k, kind, which in candidates:
            found = brentq(lambda t: self._measure(dense(t), t)[which][k], start, end, xtol=1e-14,
                           rtol=4 * np.finfo(float).eps)
            if found < first:
                first, self._pending = found, (kind, int(self._unilateral[k]))
        return float(first)

    def handle(self, t: float, y: np.ndarray) -> None:
        """Change the pending row's mode at ``t`` [s]: a row reaching its stop is engaged and the state projected
        (its approaching velocity removed); a row that would pull is released."""
        last = self._last_event
        self._stalled = self._stalled + 1 if t <= last + 1e-12 * max(1.0, abs(last)) else 0
        if self._stalled > MAX_STALLED_EVENTS:
            raise SimulationError(f"joint stops stopped advancing at t = {last:.9g} s ({self._stalled} events at that "
                                  f"time): {self.advice}.", time=last)
        self._last_event = t
        assert self._pending is not None
        kind, row = self._pending
        if kind == "reach":
            self._engaged[row] = True
            self.system.project(y, reach=REACH * self.joints.scale, t=t)
            joints = self.joints
            self._log.append((float(t), int(joints.points[joints.first_body[joints.row_joint[row]]])))
        else:
            self._engaged[row] = False
        self.events += 1
