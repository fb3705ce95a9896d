"""What a force law provides to act on emitted particles, beside its term on bodies: its acceleration on the live
slots of a pool, its rates for implicit steps, and its row in the compiled pool kernel's field table.

Each law's particle form lives in the law's own module, next to its body term (``GravityOnParticles`` in
``gravity.py``, ``DragOnParticles`` in ``drag.py``, ``BuoyancyOnParticles`` in ``buoyancy.py``), so that a law is
written once and read by bodies, particles and the kernel alike; the compiler's table of laws
(:data:`animbatch.compile.forces.LAWS`) says which laws have a particle form. The particles' code never asks which
law it has.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from types import ModuleType

import numpy as np


@dataclass(frozen=True)
class Slots:
    """The live particles of a pool as the laws see them: positions [m] (K, 3), velocities [m/s] (K, 3), masses
    [kg] (K,), radii [m] (K,)."""

    x: np.ndarray
    v: np.ndarray
    mass: np.ndarray
    radius: np.ndarray


class ParticleLaw(ABC):
    """One declared field acting on particles (subclasses are frozen dataclasses of the law's parameters)."""

    @abstractmethod
    def describe(self) -> str:
        """The law and its parameters in words, for ``animbatch info`` and messages."""

    @abstractmethod
    def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
        """Add this law's acceleration [m/s²] on each slot to ``out`` (K, 3)."""

    def rates(self, slots: Slots) -> np.ndarray | None:
        """For implicit steps: ``-∂a/∂v = α I + β û ûᵀ`` as (α, β) per slot, shape (K, 2); None when the
        acceleration does not depend on velocity."""
        return None

    def largest_rate(self, mass: float, radius: float, speed: float, gravity: float) -> float | None:
        """The largest eigenvalue of ``-∂a/∂v`` [1/s] (``α + β`` of :meth:`rates`) on a particle of ``mass`` [kg] and
        ``radius`` [m], wherever it is, launched at up to ``speed`` [m/s] under a gravity of ``gravity`` [m/s²]
        (which bounds how fast it can come to fall); None when it does not depend on velocity. An explicit step h
        is stable only while that rate times h < 2."""
        return None

    def quadratic_relative(self, v: np.ndarray) -> np.ndarray | None:
        """The velocity (K, 3) [m/s] a quadratic law acts on (``û`` of :meth:`rates`), None for other laws."""
        return None

    @property
    def gravity(self) -> np.ndarray:
        """The uniform acceleration this law adds regardless of the particle's state (3,) [m/s²] (zero for most)."""
        return np.zeros(3)

    @property
    def compiled(self) -> bool:
        """Whether the compiled pool kernel has a form of this law (else the numpy code steps the pool). Known without
        loading numba."""
        return False

    def kernel_row(self, row: np.ndarray, kernel: ModuleType) -> None:
        """Write this law's row of the compiled pool kernel's field table (``kernel``:
        :mod:`animbatch.sim.kernels.particle_pool`); only when :attr:`compiled`."""
        raise NotImplementedError(f"no compiled form of {self.describe()}")
