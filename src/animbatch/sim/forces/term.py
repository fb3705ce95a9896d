"""What every force term provides, and what it is given.

Force terms see every body as a *point* at its centre of mass: particles first (indices ``0 … N-1``), then rigid
bodies (``N … N+B-1``). A term adds forces [N] on those points to ``force`` (P, 3); terms that act off the centre
of mass (springs attached to a body point, forces ``at`` a point, buoyancy) also add torques [N·m] about each rigid
body's centre of mass to ``torque`` (B, 3). Terms are immutable and built only for effects the scene declares (see
:mod:`animbatch.sim.model.builder`), so the right-hand side loops over exactly the declared terms.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from animbatch.sim.bodies import BodyTable, Kinematics
from animbatch.sim.forces.jacobian import BlockPattern, ForceJacobian

__all__ = ["BlockPattern", "BodyTable", "ForceJacobian", "ForceTerm", "Kinematics", "TermFactory", "add_at",
           "TimeScale", "fastest_spin_decay", "rigid_selection", "selection_text", "vector_text"]


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

    @property
    def adds_energy(self) -> bool:
        """True when the term can put mechanical energy in (applied forces, wind, moving anchors and targets, forces
        whose potential is not tracked); False when its energy is accounted for by ``potential_energy`` or it only
        ever removes energy (drag, dampers). Backward Euler keeps a scene without inputs from gaining energy."""
        return not self.has_potential

    @property
    def steps_lose_energy(self) -> bool:
        """True when a backward Euler step linearised with this term's definite derivatives loses energy unless the
        step is too long (so halving a step that gained energy cures it); False when those derivatives leave out a
        part of the force's change that makes every step's energy error O(h²) of either sign, so that halving
        shrinks a gain but does not end it (backward Euler then halves only a few times)."""
        return True

    @abstractmethod
    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        """Add this term's forces [N] (P, 3) and, for rigid bodies, torques [N·m] (B, 3) at time ``t`` [s]."""

    @abstractmethod
    def describe(self) -> str:
        """One line for ``animbatch info``: the parameters and the bodies acted on."""

    def potential_energy(self, state: Kinematics) -> float:
        """Potential energy [J]; only for terms with ``has_potential``."""
        raise NotImplementedError(f"{self.kind} has no potential energy")

    def energy_scale(self, size: float) -> float:
        """The energy [J] this term can trade over a distance ``size`` [m] (the scene's size), when its potential
        can start at zero (as ``-q E · x`` does); 0 when the scene's other scales cover it."""
        return 0.0

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """Add this term's ``∂f/∂x`` and ``∂f/∂v`` on particles to ``out``; return False when the term gives none
        (implicit methods then treat its force explicitly, as evaluated at the start of the step)."""
        return False

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        """The fastest motion this term sets from ``state`` on ``bodies`` (their masses, inertias) under a gravity of
        ``gravity`` [m/s²] (how fast a body can come to fall): what a step must resolve (the pre-flight's and the
        cost estimate's); None for a term that sets none of its own."""
        return None


@dataclass(frozen=True)
class TimeScale:
    """How fast a term makes something change: a turn at ``rate`` [rad/s] (``turns``: a gyration or an
    oscillation, which a method must follow for accuracy as well as stability) or a decay at ``rate`` [1/s] (drag:
    stability alone), and on what, in words. ``explicit``: every fixed-step method takes this force explicitly,
    backward Euler too (it has no definite derivatives of it), so its stability limit binds them all."""

    rate: float
    what: str
    turns: bool
    explicit: bool = False


#: How a model builder makes a force term once the bodies are known: (bodies, selected point indices or None for
#: all) -> term. The compiler makes one from each scene field (:mod:`animbatch.compile.forces`).
TermFactory = Callable[[BodyTable, "np.ndarray | None"], ForceTerm]


def fastest_spin_decay(coefficient: float, rigid: np.ndarray, bodies: BodyTable, what: str) -> TimeScale | None:
    """The fastest relaxation of a spin under a torque ``-c ω`` on the rigid bodies ``rigid`` (K,): c / I about the
    axis of least inertia [1/s], named ``what`` on that body; None without rigid bodies or c."""
    if not coefficient or not len(rigid) or bodies.rigid is None:
        return None
    least = np.linalg.eigvalsh(bodies.rigid.inertia[rigid])[:, 0]
    k = int(np.argmax(coefficient / least))
    name = bodies.names[bodies.first_rigid + rigid[k]]
    return TimeScale(float(coefficient / least[k]),
                     f"{what} on {name!r} (its spin relaxes in {least[k] / coefficient:.3g} s)", turns=False)


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
