"""Scene stopwatches -> their readings on a run: when each started and stopped (see :mod:`animbatch.sim.events`)."""

from __future__ import annotations

import numpy as np

from animbatch.render.frame_geometry import StopwatchReading, stopwatch_line
from animbatch.scene.schema import EventSpec, StopwatchSpec
from animbatch.sim.events import plane_crossings
from animbatch.trajectory import Trajectory

__all__ = ["StopwatchReading", "stopwatch_line", "stopwatch_readings"]


def _event_time(event: EventSpec, trajectory: Trajectory, after: float) -> float | None:
    """The time of ``event``'s occurrence strictly after ``after`` [s] (the count-th one), or None."""
    if event.time is not None:
        happens = (event.time > after or after == -np.inf) and event.time <= trajectory.times[-1]
        return event.time if happens else None
    body = trajectory.body_names.index(event.body)
    times = np.asarray(trajectory.times)
    crossings = plane_crossings(times, trajectory.positions[:, body], trajectory.velocities[:, body],
                                np.asarray(event.point, float), np.asarray(event.normal, float), event.direction,
                                impacts=event.impacts)
    crossings = crossings[crossings > after]
    return float(crossings[event.count - 1]) if len(crossings) >= event.count else None


def stopwatch_readings(stopwatches: list[StopwatchSpec], trajectory: Trajectory) -> list[StopwatchReading]:
    """The readings of the scene's stopwatches on ``trajectory``."""
    readings = []
    for watch in stopwatches:
        start = _event_time(watch.start, trajectory, -np.inf)
        stop = None if start is None or watch.stop is None else _event_time(watch.stop, trajectory, start)
        readings.append(StopwatchReading(watch.name, start, stop, watch.expected))
    return readings
