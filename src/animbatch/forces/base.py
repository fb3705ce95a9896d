"""What every force term provides.

A force term adds its force to an accumulator: ``accumulate(t, x, v, force)`` with particle positions ``x`` [m],
velocities ``v`` [m/s] and ``force`` [N], all of shape ``(N, 3)``. Terms are immutable and built only for effects the
scene declares (see :mod:`animbatch.model.compile`), so the right-hand side loops over exactly the declared terms.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np


class ForceTerm(ABC):
    """One force law acting on some or all particles."""

    #: Registry name, shown by ``animbatch info``.
    kind: ClassVar[str]
    #: True when part of the force derives from a potential, returned by ``potential_energy``.
    has_potential: ClassVar[bool] = False

    @property
    def dissipative(self) -> bool:
        """True when the term can change the total mechanical energy (drag, dampers)."""
        return False

    @property
    def label(self) -> str:
        """Name shown to users (a term kind may have variants, e.g. drag and wind)."""
        return self.kind

    @abstractmethod
    def accumulate(self, t: float, x: np.ndarray, v: np.ndarray, force: np.ndarray) -> None:
        """Add this term's force [N] at time ``t`` [s] to ``force`` (shape (N, 3)) in place."""

    @abstractmethod
    def describe(self) -> str:
        """One line for ``animbatch info``: the parameters and the bodies acted on."""

    def potential_energy(self, x: np.ndarray) -> float:
        """Potential energy [J] at positions ``x`` (N, 3); only for terms with ``has_potential``."""
        raise NotImplementedError(f"{self.kind} has no potential energy")


@dataclass(frozen=True, eq=False)
class ParticleProperties:
    """What force terms may need to know about the particles: names, masses [kg] and radii [m], shape (N,)."""

    names: tuple[str, ...]
    mass: np.ndarray
    radius: np.ndarray


#: Field ``type`` (as in the scene file) -> function building its term from (spec, particles, selection index).
FIELD_TERMS: dict[str, Callable[[Any, ParticleProperties, np.ndarray | None], ForceTerm]] = {}


def field_term(type_name: str) -> Callable[[Callable[..., ForceTerm]], Callable[..., ForceTerm]]:
    """Register the builder of the force term for scene fields of ``type: type_name``."""

    def register(builder: Callable[..., ForceTerm]) -> Callable[..., ForceTerm]:
        if type_name in FIELD_TERMS:
            raise ValueError(f"field type {type_name!r} is registered twice")
        FIELD_TERMS[type_name] = builder
        return builder

    return register


def selection_text(index: np.ndarray | None, names: tuple[str, ...]) -> str:
    """'all 5 bodies' or 'bodies a, b' for a particle selection."""
    if index is None:
        return f"all {len(names)} bod{'y' if len(names) == 1 else 'ies'}"
    chosen = [names[i] for i in index]
    shown = ", ".join(chosen[:6]) + (f", … ({len(chosen)} in all)" if len(chosen) > 6 else "")
    return f"bod{'y' if len(chosen) == 1 else 'ies'} {shown}"


def vector_text(vector: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:g}" for c in vector) + ")"
