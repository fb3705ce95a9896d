"""Clocks of a run: stopwatches that time the interval between two events (a body crossing a plane, or a given
time), shown on the frame and reported beside the value a closed form predicts; and proper-time clocks that bodies
carry (special relativity's time dilation)."""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from animbatch.scene.schema.keys import Name, NonZeroVec3, SceneModel, Vec3, key, rule_error


class EventSpec(SceneModel):
    """When a stopwatch starts or stops: at a ``time``, or when a ``body``'s centre of mass crosses the plane through
    ``point`` with normal ``normal`` (the ``count``-th such crossing, moving in ``direction``)."""

    time: float | None = key(None, "At this time (instead of a crossing).", "s", ge=0)
    body: Name | None = key(None, "The particle or rigid body whose centre of mass crosses the plane.")
    point: Vec3 = key([0.0, 0.0, 0.0], "A point of the plane.", "m")
    normal: NonZeroVec3 = key([0.0, 1.0, 0.0], "The plane's normal.", "1")
    direction: Literal["any", "along", "against"] = key(
        "any", "Which crossings count: along the normal (e.g. upwards through a floor-like plane), against it "
               "(downwards), or any.")
    count: int = key(1, "Which crossing: the first, second, … (for a stop: counted after the start).", "1", ge=1)
    impacts: bool = key(True, "Count reaching the plane and bouncing back as a crossing, at the time of contact "
                              "(a ball's centre one radius above the floor it hits).")

    @model_validator(mode="after")
    def _time_or_body(self) -> EventSpec:
        if (self.time is None) == (self.body is None):
            raise rule_error("give either time (an instant) or body (a crossing of a plane), not "
                             + ("both" if self.time is not None else "neither"), "body")
        return self


class StopwatchSpec(SceneModel):
    """A stopwatch: it runs from its ``start`` event to its ``stop`` event (or the end of the run). The text overlay
    shows it as ``{stopwatch[NAME]}``; the run reports it, beside ``expected`` when given."""

    name: Name = key(description="Name, used by the text overlay's {stopwatch[NAME]}.", example="fall")
    start: EventSpec = key(EventSpec(time=0.0), "When it starts (default: at t = 0).")
    stop: EventSpec | None = key(None, "When it stops (default: it runs to the end).")
    expected: float | None = key(None, "What a closed form predicts for the time between start and stop; the run "
                                        "reports the difference.", "s")


#: The speed of light in vacuum [m/s] (exact, by the definition of the metre).
SPEED_OF_LIGHT = 299_792_458.0


class ClocksSpec(SceneModel):
    """Proper-time clocks carried by bodies: each ticks at dτ/dt = √(1 − v²/c²) of its body's speed v, integrated
    with the motion (which stays Newtonian). The text overlay shows one as ``{proper_time[NAME]}``."""

    c: float = key(SPEED_OF_LIGHT, "The speed of light (lower it so that dilation shows at the scene's speeds).",
                   "m/s", gt=0)
    bodies: list[Name] | None = key(None, "The particles and rigid bodies that carry a clock (default: all of them).")
