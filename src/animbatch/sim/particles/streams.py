"""Counter-based random streams: the random numbers of particle ``k`` of an emitter depend only on the scene's seed,
the emitter and ``k``.

A global generator would hand out numbers in the order particles are born, so that stepping differently (a smaller
dt, another method, frames simulated in chunks) would give different particles. Here each emitter has its own key,
and particle ``k`` reads the fixed block of ``DRAWS_PER_PARTICLE`` numbers that the Philox bit generator produces at
counter ``k · DRAWS_PER_PARTICLE / 4`` (Philox4x64 gives 4 numbers per counter value; Salmon et al. 2011). Any batch
of consecutive particles is one call.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

#: Uniform numbers reserved per particle; see ``DRAW`` for what each one decides.
DRAWS_PER_PARTICLE = 16
_COUNTERS_PER_PARTICLE = DRAWS_PER_PARTICLE // 4

#: Which of a particle's numbers decides what (fixed, so adding an attribute never changes the others).
DRAW = {"lifetime": 0, "speed": 1, "cone": 2, "turn": 3, "place": 4, "place2": 5, "place3": 6, "radius": 7,
        "mass": 8, "red": 9, "green": 10, "blue": 11, "choice": 12}


class ParticleStreams:
    """The random numbers of one emitter's particles."""

    def __init__(self, seed: int, emitter_index: int) -> None:
        state = np.random.SeedSequence([int(seed), int(emitter_index)]).generate_state(2, np.uint64)
        self.key = state

    def uniforms(self, first: int, count: int) -> np.ndarray:
        """Uniform numbers in [0, 1) of particles ``first … first + count - 1``: shape (count, DRAWS_PER_PARTICLE)."""
        if count == 0:
            return np.zeros((0, DRAWS_PER_PARTICLE))
        counter = np.array([first * _COUNTERS_PER_PARTICLE, 0, 0, 0], dtype=np.uint64)
        generator = np.random.Philox(key=self.key, counter=counter)
        raw = generator.random_raw(count * DRAWS_PER_PARTICLE)
        # 53 random bits -> a double in [0, 1), the same conversion numpy uses, written out so it never changes
        return ((raw >> np.uint64(11)).astype(np.float64) * 2.0 ** -53).reshape(count, DRAWS_PER_PARTICLE)


def spread_values(uniform: np.ndarray, mean: float, spread: float, distribution: str) -> np.ndarray:
    """Values ``mean ± spread`` from uniforms (K,): uniform, or normal with σ = spread / 2 clipped to the bounds."""
    if spread == 0:
        return np.full(uniform.shape, float(mean))
    if distribution == "uniform":
        return mean + spread * (2.0 * uniform - 1.0)
    tiny = 2.0 ** -53
    return np.clip(mean + 0.5 * spread * ndtri(np.clip(uniform, tiny, 1 - tiny)), mean - spread, mean + spread)
