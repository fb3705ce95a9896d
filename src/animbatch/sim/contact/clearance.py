"""Skipping the contact search while nothing can be near anything (conservative advancement).

A body in free flight costs the fixed-step contact path a whole search every step, only to find nothing. Instead,
now and then the search looks further than the step needs: ``D`` [m] further on each side of every pair, so by
``2 D`` on the margin. When even that finds nothing, no pair can come within the step's search distance until some
body has moved, or turned, by ``D`` less its coming step's travel, and the search is skipped until then. How far a
body has moved is measured on the state itself, not predicted: a point at ``r`` from the centre of mass moves by at
most ``|Δx| + |r| θ``, with ``Δx`` the move of the body's centre and θ the angle it turned since the search that
looked further (:func:`~animbatch.sim.contact.detection.points_moved`, as the overlap audit measures it). So the
contacts found are exactly those the search of every step would find (none), whatever the method, the joints or the
forces do in between.

A search that looks further and finds something was wasted: the next try waits twice as many steps (at most
:data:`LONGEST_WAIT`), so that bodies resting on the ground pay almost nothing for it.

Colliders on keyframes move by themselves: their surfaces' moves since that search count as well (``|Δc| + θ``
times how far the solid reaches from its path's centre). A plane reaches without end, so a plane that has turned
since then brings the search back.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from animbatch.sim.bodies import Kinematics
from animbatch.sim.contact.detection import points_moved, turn_angle
from animbatch.sim.contact.moving import MovingColliders

#: How far ahead the search looks, in steps of the fastest body's travel, and at least this many margins.
AHEAD_STEPS = 8.0
AHEAD_MARGINS = 4.0
#: The most steps between two tries of a search that looks further.
LONGEST_WAIT = 64


class Clearance:
    """Whether the contact search of a step can be skipped, for bodies reaching ``reach`` (P,) [m] from their
    centres of mass, among the colliders on keyframes ``moving`` (None: none)."""

    def __init__(self, reach: np.ndarray, moving: MovingColliders | None = None) -> None:
        self.reach = np.asarray(reach, float)
        self.moving = moving
        self._poses: list[tuple[np.ndarray, np.ndarray]] = []  # each moving collider's centre and turn then
        self.ahead = 0.0  # D [m] of the last search that looked further and found nothing (0: none holds)
        self._then: Kinematics | None = None  # the bodies at that search (their own copies)
        self._wait = 0  # steps until the next try
        self._next_wait = 1

    def clear(self, state: Kinematics, travel: np.ndarray) -> bool:
        """Whether no pair can be within the search distance of this step: every body has moved since the last
        search that looked further, plus its ``travel`` (P,) [m] in this step, by less than that search looked."""
        if self.ahead <= 0.0 or self._then is None:
            return False
        moved = points_moved(self.reach, self._then, state)
        if float(np.max(moved + travel, initial=0.0)) <= self.ahead and self._colliders_within(state.t):
            return True  # (NaN compares False: search)
        self.ahead = 0.0
        return False

    def _colliders_within(self, t: float) -> bool:
        """Whether no moving collider's surface has moved by more than the search looked further, by time t [s]."""
        if self.moving is None:
            return True
        for path, reach, (centre, turn) in zip(self.moving.paths, self.moving.reach, self._poses):
            now, turned = path.pose(t)
            shift = float(np.linalg.norm(now - centre))
            if not np.array_equal(turned, turn):
                if not np.isfinite(reach):  # a turned plane: its far points moved without bound
                    return False
                shift += float(reach * turn_angle(turn, turned))
            if not shift <= self.ahead:
                return False
        return True

    def look_ahead(self, travel: np.ndarray, margin: float) -> float:
        """How much further [m] (D) this step's search should look on each side of every pair, or 0 to search as
        usual (waiting after a wasted try)."""
        if self._wait > 0:
            self._wait -= 1
            return 0.0
        largest = float(np.max(travel, initial=0.0))
        if not np.isfinite(largest):
            return 0.0
        return AHEAD_STEPS * largest + AHEAD_MARGINS * margin

    def found_nothing(self, state: Kinematics, ahead: float) -> None:
        """The search that looked ``ahead`` [m] further found no contact: skip until the bodies have moved that far."""
        self.ahead = ahead
        self._then = replace(state, x=state.x.copy(), v=state.v.copy(),
                             rotation=None if state.rotation is None else state.rotation.copy(),
                             omega=None if state.omega is None else state.omega.copy())
        if self.moving is not None:
            self._poses = [(np.array(centre, float), np.array(turn, float))
                           for centre, turn in (path.pose(state.t) for path in self.moving.paths)]
        self._next_wait = 1

    def found_something(self) -> None:
        """The search that looked further found contacts: wait longer before the next try."""
        self._wait = self._next_wait
        self._next_wait = min(2 * self._next_wait, LONGEST_WAIT)
