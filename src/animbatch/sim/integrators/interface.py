"""The contract every integrator keeps, and what a run records about its solver.

An integrator takes the equations of motion, an initial state and the frame times, and returns the state at exactly
those times (whatever its internal steps). It raises :class:`~animbatch.errors.SimulationError` as soon as the state
stops being finite or the solver fails, before any frame could be rendered from a broken state.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

#: Called after each frame's state is known: ``on_frame(frame_index, time)``.
FrameCallback = Callable[[int, float], None]


class EquationsOfMotion(Protocol):
    """What integrators need from a system (see :class:`~animbatch.sim.model.dynamics.Dynamics`)."""

    size: int

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray: ...

    def split(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def motion_rate(self, t: float, config: np.ndarray, motion: np.ndarray,
                    out: np.ndarray | None = None) -> np.ndarray: ...

    def drift(self, config: np.ndarray, motion: np.ndarray, h: float) -> None: ...

    def project(self, y: np.ndarray, *, joints: bool = True, t: float = 0.0, start: np.ndarray | None = None,
                step: float = 0.0) -> None: ...


class StepSettings(Protocol):
    """How a run is to be integrated, in numbers: the method's name, a fixed step ``dt`` [s] (None: the default),
    the adaptive methods' ``rtol``, ``atol`` and ``max_step`` [s] (None: no limit). A scene's solver section has
    this shape."""

    @property
    def method(self) -> str: ...

    @property
    def dt(self) -> float | None: ...

    @property
    def rtol(self) -> float: ...

    @property
    def atol(self) -> float: ...

    @property
    def max_step(self) -> float | None: ...


class ImpactRecord(Protocol):
    """The impacts a constraint logged, as (time [s], body index) pairs in time order."""

    def as_list(self) -> list[tuple[float, int]]: ...


@dataclass
class ContactSolves:
    """How a run's contact impulse solves ended: how many there were (``solves``), how many stopped (out of sweeps,
    ``contacts.iterations``, or stalled) before every contact met its target to the solver's tolerance
    (``unconverged``), and
    the largest violation of a target such a solve left (``residual`` [m/s]; 0 when every solve converged)."""

    solves: int = 0
    unconverged: int = 0
    residual: float = 0.0

    def record(self, residual: float, unconverged: bool) -> None:
        """Count one solve that left ``residual`` [m/s]."""
        self.solves += 1
        if unconverged:
            self.unconverged += 1
            self.residual = max(self.residual, residual)

    def add(self, other: ContactSolves) -> None:
        """Count the solves of a later part of the same run."""
        self.solves += other.solves
        self.unconverged += other.unconverged
        self.residual = max(self.residual, other.residual)


class VelocityConstraint(Protocol):
    """Velocity-level constraints a fixed-step scheme applies between its kick and its drift (contacts; next,
    joints): they change the motion so that the constraints hold over the step. Schemes that can take one say so
    with ``takes_constraints``; the integrator is given a factory and never imports the constraint's code."""

    @property
    def impacts(self) -> ImpactRecord: ...  # what it logged

    @property
    def solves(self) -> ContactSolves: ...  # how its solves ended

    def resolve(self, config: np.ndarray, motion: np.ndarray, h: float, *, t: float,
                bounce: bool = True) -> np.ndarray | None:
        """Correct ``motion`` in place for a step of ``h`` [s] from ``t``; return the motion to drift with when it
        differs (overlaps pushed apart), else None. ``bounce`` False: project only (end-of-step velocities)."""
        ...


#: (equations of motion) -> the constraint for them; how a fixed-step integrator is told about contacts.
ConstraintFactory = Callable[[EquationsOfMotion], VelocityConstraint | None]


class StepEvents(Protocol):
    """Events an adaptive method stops at between its steps (for contacts: impacts and changes of contact mode).

    The integrator steps the scipy solver; after each step it asks for the first event inside it, writes the frames
    before it from the step's dense output, lets the events act on the state at that instant, and restarts the
    solver there. How an adaptive integrator is told about contacts, without importing them."""

    #: What the events are about and what to try when they cannot be resolved, for messages ("contacts", …).
    label: str
    advice: str

    @property
    def impacts(self) -> ImpactRecord: ...  # what was logged

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """The right-hand side to integrate between events (with the forces of resting contacts)."""
        ...

    def start(self, t: float, y: np.ndarray, frames: int, method: str) -> None:
        """Act on the initial state ``y`` in place (touching contacts settle) before a run of ``frames`` frames."""
        ...

    def restart(self, t: float, y: np.ndarray) -> float | None:
        """A solver (re)starts from ``y`` at ``t`` [s]: the largest step it may take from there [s], or None."""
        ...

    def first_event(self, solver: Any, before: np.ndarray) -> float | None:
        """The time [s] of the first event within the solver's last step (from ``before``), or None."""
        ...

    def handle(self, t: float, y: np.ndarray) -> None:
        """Act on the state ``y`` in place at the event time ``t`` [s]; raise SimulationError when events stop
        advancing time or never settle."""
        ...


#: (equations of motion) -> their events; how an adaptive integrator is told about contacts.
EventsFactory = Callable[[EquationsOfMotion], StepEvents]


@dataclass
class SolverStats:
    """Work done by a solver during one run.

    ``rhs_evaluations`` is counted by our own wrapper and includes the evaluations made for finite-difference
    Jacobians, which scipy's ``nfev`` leaves out (it is kept as ``scipy_nfev`` for comparison).
    """

    method: str
    rhs_evaluations: int = 0
    steps: int = 0
    jacobian_evaluations: int = 0
    lu_decompositions: int = 0
    scipy_nfev: int | None = None
    dt: float | None = None  # fixed-step methods: the step actually used [s]
    substeps_per_frame: int | None = None
    smallest_step: float | None = None  # adaptive methods: the shortest and longest accepted steps [s]
    largest_step: float | None = None
    wall_time: float = 0.0  # [s]
    impacts: list[tuple[float, int]] = field(default_factory=list)  # (time [s], body index) of bounces, in order
    contact_solves: ContactSolves | None = None  # fixed-step methods with contacts: how their impulse solves ended
    #: cloth's self-collision: repulsions, collisions, passes, impact zones, the largest zone [vertices], and the
    #: steps that could not part every pair (animbatch.sim.deformable.self_collision.COUNTERS)
    self_contact: dict[str, int] | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, saved: dict[str, Any]) -> SolverStats:
        """The statistics :meth:`as_dict` gave (a checkpoint's)."""
        solves = saved.get("contact_solves")
        return cls(**{**saved, "contact_solves": ContactSolves(**solves) if solves is not None else None})

    def add(self, part: SolverStats) -> None:
        """Add the work of a later part of the same run (a checkpointed segment)."""
        for name in ("rhs_evaluations", "steps", "jacobian_evaluations", "lu_decompositions", "wall_time"):
            setattr(self, name, getattr(self, name) + getattr(part, name))
        self.dt = max(self.dt or 0.0, part.dt or 0.0) or None
        self.substeps_per_frame = part.substeps_per_frame
        for name, pick in (("smallest_step", min), ("largest_step", max)):
            values = [v for v in (getattr(self, name), getattr(part, name)) if v is not None]
            setattr(self, name, pick(values) if values else None)
        self.impacts = list(self.impacts) + list(part.impacts)
        if part.self_contact is not None:
            mine = self.self_contact or dict.fromkeys(part.self_contact, 0)
            self.self_contact = {name: max(mine[name], count) if name == "largest_zone" else mine[name] + count
                                 for name, count in part.self_contact.items()}
        if part.contact_solves is not None:
            if self.contact_solves is None:
                self.contact_solves = ContactSolves()
            self.contact_solves.add(part.contact_solves)

    def count_step(self, h: float) -> None:
        """Count an accepted step of ``h`` [s] (adaptive methods)."""
        self.steps += 1
        self.smallest_step = h if self.smallest_step is None else min(self.smallest_step, h)
        self.largest_step = h if self.largest_step is None else max(self.largest_step, h)


@dataclass
class IntegrationResult:
    """States at the frame times, shape (F, n), and the solver's statistics."""

    states: np.ndarray
    stats: SolverStats


class CountingRhs:
    """Wraps a right-hand side, counts its calls and remembers the first non-finite derivative it returned.

    Adaptive methods never accept a step whose error estimate is not finite, so a non-finite force shows up as a
    solver failure ("step size too small") a few rejections later; ``first_non_finite`` (time, component) then says
    where it came from.
    """

    def __init__(self, fun: Callable[[float, np.ndarray], np.ndarray]) -> None:
        self.fun = fun
        self.count = 0
        self.first_non_finite: tuple[float, int] | None = None

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.count += 1
        dydt = self.fun(t, y)
        if self.first_non_finite is None and not np.isfinite(dydt).all():
            self.first_non_finite = (t, int(np.flatnonzero(~np.isfinite(dydt))[0]))
        return dydt


class Integrator(ABC):
    """Integrates equations of motion and samples the state at given times."""

    method: str

    @abstractmethod
    def integrate(self, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray, *,
                  on_frame: FrameCallback | None = None) -> IntegrationResult:
        """States at ``times`` (increasing, ``times[0]`` is the time of ``y0``), shape (len(times), len(y0))."""

    @abstractmethod
    def describe(self) -> str:
        """One line: the method and its settings."""
