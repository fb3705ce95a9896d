"""A pool of particle slots: fixed capacity, dead slots reused (the lecture notes' "if dead, reallocate").

Memory is allocated once, for ``capacity`` particles, and never grows: births take the lowest free slots, deaths
free them. Every per-particle quantity is one numpy array over the slots, so that a step is a handful of vectorised
operations whatever the number of particles.
"""

from __future__ import annotations

import numpy as np


class ParticlePool:
    """The slots of one emitter.

    Per slot (C = capacity): ``x``, ``v`` (C, 3) [m], [m/s]; ``acceleration`` (C, 3) [m/s²], kept by methods that
    reuse it (Verlet); ``alive``, ``stuck`` (C,) bool; a stuck particle's ``stuck_to`` (C,) body (−1: a fixed
    collider; ``-2 - m``: the m-th collider on keyframes) and, on a body, its place ``stuck_at`` (C, 3) in the
    body's axes from its centre of mass [m]; ``serial`` (C,) int64 (-1 when the slot was never used);
    ``birth``, ``lifetime`` [s], ``mass`` [kg], ``radius`` [m] (C,). ``dropped``: births that found no free slot.
    ``first_death`` [s]: no live particle dies before it (a lower bound of birth + lifetime over the live slots,
    lowered at every birth, raised by whoever reads every age), so that steps before it need not read the ages.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.x = np.zeros((capacity, 3))
        self.v = np.zeros((capacity, 3))
        self.acceleration = np.zeros((capacity, 3))
        self.alive = np.zeros(capacity, bool)
        self.stuck = np.zeros(capacity, bool)
        self.stuck_to = np.full(capacity, -1, np.intp)
        self.stuck_at = np.zeros((capacity, 3))
        self.serial = np.full(capacity, -1, np.int64)
        self.birth = np.zeros(capacity)
        self.lifetime = np.zeros(capacity)
        self.mass = np.ones(capacity)  # never zero, so dead slots divide safely
        self.radius = np.zeros(capacity)
        self.dropped = 0
        self.born = 0
        self.died = 0
        self.first_death = np.inf

    @property
    def live_count(self) -> int:
        return int(np.count_nonzero(self.alive))

    def allocate(self, count: int) -> np.ndarray:
        """The lowest ``count`` free slots (fewer when the pool is full; the rest are counted as dropped)."""
        free = np.flatnonzero(~self.alive)[:count]
        self.dropped += count - len(free)
        self.born += len(free)
        return free

    def start_lives(self, slots: np.ndarray, birth: np.ndarray, lifetime: np.ndarray) -> None:
        """Set the birth instants and lifetimes [s] of the particles born into ``slots``."""
        self.birth[slots] = birth
        self.lifetime[slots] = lifetime
        if len(slots):
            self.first_death = min(self.first_death, float(np.min(birth + lifetime)))

    def may_die_by(self, now: float) -> bool:
        """Whether a live particle may have reached its lifetime at ``now`` [s]: ``now - birth >= lifetime``, which
        cannot hold while ``now`` is clearly (by more than round-off) before :attr:`first_death`."""
        return now >= self.first_death - 1e-9 * (1.0 + abs(self.first_death))

    def age(self, now: float) -> None:
        """Particles whose age at ``now`` [s] reached their lifetime (``now - birth >= lifetime``) die, and
        :attr:`first_death` becomes the survivors' earliest; nothing is read while no particle may die."""
        if not self.may_die_by(now):
            return
        aged = self.alive & (now - self.birth >= self.lifetime)
        if aged.any():
            self.kill(aged)
        alive = self.alive
        self.first_death = float(np.min(self.birth[alive] + self.lifetime[alive])) if alive.any() else np.inf

    def kill(self, slots: np.ndarray) -> None:
        """Free ``slots`` (indices or a boolean mask)."""
        self.died += int(np.count_nonzero(self.alive[slots]))
        self.alive[slots] = False
        self.stuck[slots] = False
        self.stuck_to[slots] = -1
        self.v[slots] = 0.0

    def moving(self) -> np.ndarray:
        """Indices of the slots that move: alive and not stuck."""
        return np.flatnonzero(self.alive & ~self.stuck)
