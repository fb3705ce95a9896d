"""A record of impacts (bounces), for the contact-time errors of ``animbatch study`` and the run's statistics."""

from __future__ import annotations

import numpy as np

#: Impacts kept per run; a pile of many bodies can bounce millions of times, and only the first ones are compared.
MAX_RECORDED_IMPACTS = 10_000


class ImpactLog:
    """Times [s] and body indices of impacts: contacts that arrive faster than the rest speed and bounce. One entry
    per body per solve (a box landing on four corners is one impact)."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self.bodies: list[int] = []
        self.count = 0  # every impact, recorded or not

    def record(self, times: np.ndarray, bodies: np.ndarray, impacting: np.ndarray) -> None:
        """Add the impacts among K contacts: their times (K,) [s], probe body indices (K,), and which (K,) bool
        are impacts; a body that hits at several contacts at once counts once, at its earliest time."""
        if not impacting.any():
            return
        hit, first = np.unique(bodies[impacting], return_inverse=True)
        earliest = np.full(len(hit), np.inf)
        np.minimum.at(earliest, first, times[impacting])
        order = np.argsort(earliest, kind="stable")
        self.count += len(hit)
        room = MAX_RECORDED_IMPACTS - len(self.times)
        self.times += [float(t) for t in earliest[order][:room]]
        self.bodies += [int(b) for b in hit[order][:room]]

    def as_list(self) -> list[tuple[float, int]]:
        return list(zip(self.times, self.bodies))
