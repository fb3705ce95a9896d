"""What every force term provides, and what it is given.

Force terms see every body as a *point* at its centre of mass: particles first (indices ``0 … N-1``), then rigid
bodies (``N … N+B-1``). A term adds forces [N] on those points to ``force`` (P, 3); terms that act off the centre
of mass (springs attached to a body point, forces ``at`` a point, buoyancy) also add torques [N·m] about each rigid
body's centre of mass to ``torque`` (B, 3). Terms are immutable and built only for effects the scene declares (see
:mod:`animbatch.model.builder`), so the right-hand side loops over exactly the declared terms.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np


@dataclass(frozen=True, eq=False)
class BodyTable:
    """The bodies as force terms see them (immutable).

    ``names``, ``mass`` [kg], ``radius`` [m]: per point, shape (P,); a rigid body's radius is that of the sphere of its
    volume. ``first_rigid``: index of the first rigid body (= number of particles). ``rigid``: the rigid bodies'
    inertia and geometry (a :class:`~animbatch.model.rigid_set.RigidBodySet`), or None.
    """

    names: tuple[str, ...]
    mass: np.ndarray
    radius: np.ndarray
    first_rigid: int
    rigid: Any = None

    @property
    def count(self) -> int:
        return len(self.names)

    @property
    def rigid_count(self) -> int:
        return self.count - self.first_rigid

    def is_rigid(self, index: np.ndarray) -> np.ndarray:
        return np.asarray(index) >= self.first_rigid


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Where the bodies are and how they move, at one instant.

    ``x``, ``v``: centre-of-mass positions [m] and velocities [m/s] of all points, shape (P, 3). For the B rigid bodies
    (points ``first_rigid …``): ``rotation`` (B, 3, 3) body-to-world matrices and ``omega`` (B, 3) angular velocities
    [rad/s], world axes; both None when there are no rigid bodies.
    """

    x: np.ndarray
    v: np.ndarray
    rotation: np.ndarray | None
    omega: np.ndarray | None
    first_rigid: int

    def lever(self, rigid_index: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """World vectors from the centres of mass of rigid bodies ``rigid_index`` (K,) to their body points
        ``offset`` (K, 3), given in body axes relative to the centre of mass."""
        assert self.rotation is not None
        return np.einsum("kij,kj->ki", self.rotation[rigid_index], offset)


class ForceTerm(ABC):
    """One force law acting on some or all bodies."""

    #: Registry name, shown by ``animbatch info``.
    kind: ClassVar[str]
    #: True when part of the force derives from a potential, returned by ``potential_energy``.
    has_potential: ClassVar[bool] = False

    @property
    def label(self) -> str:
        """Name shown to users (a term kind may have variants, e.g. drag and wind)."""
        return self.kind

    @property
    def dissipative(self) -> bool:
        """True when the term can change the total mechanical energy (drag, dampers, applied forces)."""
        return False

    @abstractmethod
    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        """Add this term's forces [N] (P, 3) and, for rigid bodies, torques [N·m] (B, 3) at time ``t`` [s]."""

    @abstractmethod
    def describe(self) -> str:
        """One line for ``animbatch info``: the parameters and the bodies acted on."""

    def potential_energy(self, state: Kinematics) -> float:
        """Potential energy [J]; only for terms with ``has_potential``."""
        raise NotImplementedError(f"{self.kind} has no potential energy")


#: Field ``type`` (as in the scene file) -> function building its term from (spec, bodies, selection index).
FIELD_TERMS: dict[str, Callable[[Any, BodyTable, np.ndarray | None], ForceTerm]] = {}


def field_term(type_name: str) -> Callable[[Callable[..., ForceTerm]], Callable[..., ForceTerm]]:
    """Register the builder of the force term for scene fields of ``type: type_name``."""

    def register(builder: Callable[..., ForceTerm]) -> Callable[..., ForceTerm]:
        if type_name in FIELD_TERMS:
            raise ValueError(f"field type {type_name!r} is registered twice")
        FIELD_TERMS[type_name] = builder
        return builder

    return register


def selection_text(index: np.ndarray | None, names: tuple[str, ...]) -> str:
    """'all 5 bodies' or 'bodies a, b' for a selection of points."""
    if index is None:
        return f"all {len(names)} bod{'y' if len(names) == 1 else 'ies'}"
    chosen = [names[i] for i in index]
    shown = ", ".join(chosen[:6]) + (f", … ({len(chosen)} in all)" if len(chosen) > 6 else "")
    return f"bod{'y' if len(chosen) == 1 else 'ies'} {shown}"


def vector_text(vector: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:g}" for c in vector) + ")"


def add_at(target: np.ndarray, index: np.ndarray | None, values: np.ndarray, sign: float = 1.0) -> None:
    """``target[index] += sign * values`` for unique indices (or all rows when index is None)."""
    if index is None:
        if sign > 0:
            target += values
        else:
            target -= values
    elif sign > 0:
        target[index] += values
    else:
        target[index] -= values


def rigid_selection(bodies: BodyTable, index: np.ndarray | None) -> np.ndarray:
    """The rigid bodies (as indices 0 … B-1) among a selection of points."""
    points = np.arange(bodies.count) if index is None else np.asarray(index)
    return points[points >= bodies.first_rigid] - bodies.first_rigid
