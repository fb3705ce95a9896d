"""Fluid drag, optionally relative to a moving medium (wind), optionally at a point of rigid bodies.

With relative velocity ``u = v - w`` (``w``: wind velocity, zero for plain drag):

* linear:    ``f = -C u``            (C in N·s/m)
* quadratic: ``f = -C |u| u``        (C in kg/m; ``C = ½ ρ C_d A`` for a body of area A)
* stokes:    ``f = -6 π η r u``      (η: dynamic viscosity in Pa·s, r: particle radius, or for a rigid body the
  radius of the sphere of equal volume)

At a point ``at`` of a rigid body, ``v`` is that point's velocity ``v_cm + ω × r`` and the force there also gives a
torque ``r × f``; particles and bodies without ``at`` feel the drag at their centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType
from typing import Any, Literal

import numpy as np

from animbatch.quaternion import cross
from animbatch.sim.forces.on_particles import ParticleLaw, Slots
from animbatch.sim.forces.term import (
    BodyTable,
    ForceJacobian,
    ForceTerm,
    Kinematics,
    TimeScale,
    add_at,
    rigid_selection,
    selection_text,
    vector_text,
)

AIR_VISCOSITY = 1.81e-5  # Pa·s, dry air at 15 °C
DragLaw = Literal["linear", "quadratic", "stokes"]


def drag_force(law: DragLaw, coefficient: float | np.ndarray, relative: np.ndarray) -> np.ndarray:
    """The drag force [N] (K, 3) for relative velocities (K, 3); ``coefficient`` scalar or (K, 1)."""
    if law == "quadratic":
        scale = np.sqrt(np.einsum("ij,ij->i", relative, relative))  # |u|, shape (K,)
        scale *= np.ravel(coefficient) if np.ndim(coefficient) else coefficient
        return scale[:, None] * -relative
    return -(coefficient * relative)


def quadratic_drag_rate(coefficient: Any, mass: Any, relative_speed: Any, gravity: float) -> Any:
    """The fastest a velocity relaxes under quadratic drag ``-C |u| u`` [1/s]: 2 C |u| / m (the largest eigenvalue
    of C |u| (I + û ûᵀ) / m), with |u| the faster of ``relative_speed`` [m/s] (through the air, at a launch or at
    the start) and the terminal fall √(m g / C) that a body under ``gravity`` [m/s²] tends to. Numbers or arrays."""
    terminal = np.sqrt(mass * gravity / np.maximum(coefficient, 1e-300))
    return 2 * coefficient * np.maximum(relative_speed, terminal) / mass


@dataclass(frozen=True, eq=False)
class Drag(ForceTerm):
    """Drag at centres of mass for points ``index`` (None: all), and at body points for rigid bodies.

    ``coefficient``: C, a number when it is the same for every body (linear, quadratic), else per centre-of-mass point
    with shape (S, 1) (stokes: 6 π η r). Bodies dragged at a point: ``at_points`` (K,) point indices, ``at_rigid`` (K,)
    rigid indices, ``at_offset`` (K, 3) the point in body axes from the centre of mass, ``at_coefficient`` like
    ``coefficient``. ``wind``: (3,) or None.
    """

    kind = "drag"

    law: DragLaw
    coefficient: float | np.ndarray
    wind: np.ndarray | None
    index: np.ndarray | None
    names: tuple[str, ...]
    viscosity: float | None = None
    at_points: np.ndarray | None = None
    at_rigid: np.ndarray | None = None
    at_offset: np.ndarray | None = None
    at_coefficient: float | np.ndarray = 0.0
    at: np.ndarray | None = None  # the point as given (shape coordinates), for messages

    @classmethod
    def build(cls, law: DragLaw, *, coefficient: float | None, viscosity: float | None, wind: np.ndarray | None,
              bodies: BodyTable, index: np.ndarray | None, at: list[float] | None = None) -> Drag:
        if law == "stokes":
            viscosity = AIR_VISCOSITY if viscosity is None else viscosity
        elif coefficient is None:
            raise ValueError(f"the {law} drag law needs a coefficient")

        given = float(coefficient) if coefficient is not None else 0.0  # linear and quadratic laws have one

        def law_coefficient(points: np.ndarray | None) -> float | np.ndarray:
            if law != "stokes":
                return given
            assert viscosity is not None  # set above for stokes
            radius = bodies.radius if points is None else bodies.radius[points]
            return (6.0 * np.pi * viscosity * radius)[:, None]  # Stokes' law for a sphere

        wind_vector = None if wind is None or not np.any(wind) else np.asarray(wind, float)
        if at is None or bodies.rigid is None:
            return cls(law, law_coefficient(index), wind_vector, index, bodies.names, viscosity)
        rigid = rigid_selection(bodies, index)
        points = np.arange(bodies.count) if index is None else np.asarray(index)
        centre_points = points[points < bodies.first_rigid]
        at_points = rigid + bodies.first_rigid
        offset = np.asarray(at, float)[None, :] - bodies.rigid.centre[rigid]  # shape frame -> from the centre of mass
        return cls(law, law_coefficient(centre_points), wind_vector, centre_points, bodies.names, viscosity,
                   at_points, rigid, offset, law_coefficient(at_points), np.asarray(at, float))

    @property
    def label(self) -> str:
        return "wind" if self.wind is not None else "drag"

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        """The fastest decay of a velocity relative to the air: c / m (linear; Stokes with c = 6 π η r), and for the
        quadratic law :func:`quadratic_drag_rate` at the faster of the start's speed and the terminal fall."""
        points = np.arange(len(bodies.mass)) if self.index is None else np.asarray(self.index)
        coefficient = np.broadcast_to(np.ravel(np.asarray(self.coefficient, float)), (len(points),))
        if self.at_points is not None:  # dragged at a body point: the same law on that body's mass
            points = np.concatenate([points, self.at_points])
            coefficient = np.concatenate([coefficient, np.broadcast_to(
                np.ravel(np.asarray(self.at_coefficient, float)), (len(self.at_points),))])
        if not len(points):
            return None
        mass = bodies.mass[points]
        if self.law == "quadratic":
            relative = state.v[points] - (self.wind if self.wind is not None else 0.0)
            rates = quadratic_drag_rate(coefficient, mass, np.linalg.norm(relative, axis=1), gravity)
        else:
            rates = coefficient / mass
        k = int(np.argmax(rates))
        if not rates[k] > 0:
            return None
        rate, point = float(rates[k]), int(points[k])
        return TimeScale(rate, f"{self.law} drag on {self.names[point]!r} (its velocity relaxes in "
                               f"{1 / rate:.3g} s)", turns=False)

    @property
    def dissipative(self) -> bool:
        return True

    @property
    def adds_energy(self) -> bool:
        return self.wind is not None  # still air only takes energy; wind can give it

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        if self.index is None or len(self.index):
            relative = state.v if self.index is None else state.v[self.index]
            if self.wind is not None:
                relative = relative - self.wind
            add_at(force, self.index, drag_force(self.law, self.coefficient, relative))
        if self.at_points is not None and len(self.at_points):
            assert torque is not None and state.omega is not None
            assert self.at_rigid is not None and self.at_offset is not None  # set with at_points
            lever = state.lever(self.at_rigid, self.at_offset)
            relative = state.v[self.at_points] + cross(state.omega[self.at_rigid], lever)
            if self.wind is not None:
                relative = relative - self.wind
            pulled = drag_force(self.law, self.at_coefficient, relative)
            force[self.at_points] += pulled
            torque[self.at_rigid] += cross(lever, pulled)

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """``∂f/∂v`` on particles: ``-C I`` (linear, stokes), ``-C (|u| I + u uᵀ / |u|)`` (quadratic)."""
        points = np.arange(len(state.x)) if self.index is None else np.asarray(self.index)
        coefficient = np.broadcast_to(np.ravel(self.coefficient), (len(points),)) if np.ndim(self.coefficient) \
            else np.full(len(points), float(self.coefficient))
        particles = points < state.first_rigid
        points, coefficient = points[particles], coefficient[particles]
        if not len(points):
            return True
        if self.law != "quadratic":
            blocks = -coefficient[:, None, None] * np.eye(3)
        else:
            relative = state.v[points] - (self.wind if self.wind is not None else 0.0)
            speed = np.sqrt(np.einsum("ij,ij->i", relative, relative))
            unit = np.divide(relative, speed[:, None], out=np.zeros_like(relative), where=speed[:, None] > 0)
            # ∂(|u| u)/∂u = |u| (I + û ûᵀ)
            blocks = -(coefficient * speed)[:, None, None] * (np.eye(3) + unit[:, :, None] * unit[:, None, :])
        out.add(points, points, dfdv=blocks)
        return True

    def describe(self) -> str:
        if self.law == "stokes":
            law = f"stokes 6πηr with η = {self.viscosity:g} Pa·s"
        else:
            unit = "N·s/m" if self.law == "linear" else "kg/m"
            law = f"{self.law}, C = {self.coefficient:g} {unit}"
        wind = f", wind {vector_text(self.wind)} m/s" if self.wind is not None else ""
        if self.at_points is None:
            return f"{law}{wind} on {selection_text(self.index, self.names)}"
        assert self.index is not None and self.at is not None  # both set with at_points
        selected = np.sort(np.concatenate([self.index, self.at_points]))
        return (f"{law}{wind} on {selection_text(selected, self.names)}; rigid bodies at their point "
                f"{vector_text(self.at)} m")


#: The drag laws the compiled pool kernel evaluates, by its codes.
_KERNEL_LAWS = ("linear", "quadratic", "stokes")


@dataclass(frozen=True, eq=False)
class DragOnParticles(ParticleLaw):
    """Drag (or wind: ``wind`` (3,) [m/s], None for still air) on emitted particles: ``a = f(u) / m`` with
    ``u = v - w`` and ``f`` of :func:`drag_force` (``law``, ``coefficient``; Stokes' ``6 π η r`` from ``viscosity``
    [Pa·s] and each particle's radius). ``kind``: the field it came from, ``drag`` or ``wind``."""

    law: DragLaw
    coefficient: float
    viscosity: float
    wind: np.ndarray | None
    kind: str = "drag"

    def describe(self) -> str:
        if self.law == "stokes":
            law = f"stokes 6πηr, η = {self.viscosity:g} Pa·s"
        else:
            law = f"{self.law}, C = {self.coefficient:g} {'N·s/m' if self.law == 'linear' else 'kg/m'}"
        wind = "" if self.kind != "wind" else \
            f", wind {vector_text(self.wind if self.wind is not None else np.zeros(3))} m/s"
        return f"{self.kind} {law}{wind}"

    def _relative(self, v: np.ndarray) -> np.ndarray:
        return v - self.wind if self.wind is not None else v

    def drag_coefficient(self, slots: Slots) -> float | np.ndarray:
        """C of the law: a number, or per slot (K, 1) for Stokes' 6 π η r."""
        if self.law == "stokes":
            return (6.0 * np.pi * self.viscosity * slots.radius)[:, None]
        return self.coefficient

    def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
        out += drag_force(self.law, self.drag_coefficient(slots), self._relative(slots.v)) / slots.mass[:, None]

    def rates(self, slots: Slots) -> np.ndarray:
        rates = np.zeros((len(slots.mass), 2))
        coefficient = np.ravel(np.broadcast_to(self.drag_coefficient(slots), (len(slots.mass), 1)))
        if self.law == "quadratic":
            relative = self._relative(slots.v)
            speed = np.sqrt(np.einsum("ij,ij->i", relative, relative))
            rates[:, 0] = rates[:, 1] = coefficient * speed / slots.mass  # ∂(|u| u)/∂u = |u| (I + û ûᵀ)
        else:
            rates[:, 0] = coefficient / slots.mass
        return rates

    def quadratic_relative(self, v: np.ndarray) -> np.ndarray | None:
        return self._relative(v) if self.law == "quadratic" else None

    def largest_rate(self, mass: float, radius: float, speed: float, gravity: float) -> float | None:
        if self.law == "quadratic":
            # launched at up to ``speed`` into the wind: at most speed + |w| through the air
            wind = float(np.linalg.norm(self.wind)) if self.wind is not None else 0.0
            return float(quadratic_drag_rate(self.coefficient, mass, speed + wind, gravity))
        return (6.0 * np.pi * self.viscosity * radius if self.law == "stokes" else self.coefficient) / mass

    @property
    def compiled(self) -> bool:
        return self.law in _KERNEL_LAWS

    def kernel_row(self, row: np.ndarray, kernel: ModuleType) -> None:
        row[kernel.KIND] = kernel.FIELD_DRAG
        row[kernel.LAW] = (kernel.LAW_LINEAR, kernel.LAW_QUADRATIC, kernel.LAW_STOKES)[_KERNEL_LAWS.index(self.law)]
        row[kernel.COEFFICIENT], row[kernel.VISCOSITY] = self.coefficient, self.viscosity
        row[kernel.HAS_WIND] = self.wind is not None
        row[kernel.VECTOR:kernel.VECTOR + 3] = self.wind if self.wind is not None else 0.0
