"""What a particle simulation hands to rendering: each emitter's slots at the frame times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ParticleFrames:
    """One emitter's particles at the frame times (F frames, C slots): ``positions`` (F, C, 3) float32 [m];
    ``serials`` (F, C) int32, the serial of the particle in each slot, -1 where the slot is free; ``ages`` (F, C)
    float32 [s]. ``radius`` is not stored: it follows from the serial like every attribute."""

    name: str
    positions: np.ndarray
    serials: np.ndarray
    ages: np.ndarray

    @property
    def live_counts(self) -> np.ndarray:
        return np.count_nonzero(self.serials >= 0, axis=1)
