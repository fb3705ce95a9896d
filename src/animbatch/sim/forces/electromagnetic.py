"""The Lorentz force of uniform electric and magnetic fields on charged bodies: ``f = q (E(t) + v × B(t))``.

The fields are the same everywhere and may change in time, piecewise linearly between keyframes (held before the
first and after the last). A rigid body feels the force at its centre of mass, as a point charge. The magnetic part
does no work (it is perpendicular to v); the electric part has the potential ``-q E · x`` while E is constant, so a
scene in constant fields conserves ``KE - Σ q E · x``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.term import (
    BodyTable,
    ForceJacobian,
    ForceTerm,
    Kinematics,
    TimeScale,
    add_at,
    selection_text,
    vector_text,
)


@dataclass(frozen=True, eq=False)
class FieldHistory:
    """A uniform vector field over time: values (K, 3) at increasing ``times`` (K,) [s], linear between them."""

    times: np.ndarray
    values: np.ndarray

    @property
    def varies(self) -> bool:
        return len(self.values) > 1 and bool(np.ptp(self.values, axis=0).any())

    def at(self, t: float) -> np.ndarray:
        if len(self.times) == 1:
            return self.values[0]
        return np.array([np.interp(t, self.times, self.values[:, axis]) for axis in range(3)])


@dataclass(frozen=True, eq=False)
class LorentzForce(ForceTerm):
    """``charge`` (S,) [C] of the selected points ``index`` (None: all); ``electric`` [V/m] and ``magnetic`` [T]."""

    kind = "electromagnetic"
    has_potential = True

    charge: np.ndarray
    electric: FieldHistory
    magnetic: FieldHistory
    index: np.ndarray | None
    names: tuple[str, ...]

    @property
    def adds_energy(self) -> bool:
        # a changing E field does work no potential accounts for; B never does work
        return self.electric.varies

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        v = state.v if self.index is None else state.v[self.index]
        field = self.electric.at(t) + np.cross(v, self.magnetic.at(t))
        add_at(force, self.index, self.charge[:, None] * field)

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """``∂f/∂v = -q [B]×`` (``v × B = -[B]× v``), nothing on position; in the definite form too. Being
        antisymmetric, it leaves the symmetric part of backward Euler's ``M - h ∂f/∂v`` equal to M, so the matrix
        stays positive definite (LU factors it without pivoting) and each step turns the charge on a circle that
        shrinks by ``1/√(1 + (ωh)²)``, never grows, where treating it explicitly would spiral outwards."""
        b = self.magnetic.at(t)
        skew = np.array([[0.0, -b[2], b[1]], [b[2], 0.0, -b[0]], [-b[1], b[0], 0.0]])
        points = np.arange(len(state.v)) if self.index is None else self.index
        particles = points < out.particles
        blocks = -self.charge[particles, None, None] * skew[None]
        out.add(points[particles], points[particles], dfdv=blocks)
        return True

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        """The fastest gyration: a charge q of mass m turns about the strongest B at ω = |q| B / m."""
        mass = bodies.mass
        strongest = float(np.max(np.linalg.norm(self.magnetic.values, axis=1)))
        points = np.arange(len(mass)) if self.index is None else self.index
        omega = np.abs(self.charge) * strongest / mass[points]
        if not omega.size or not omega.max() > 0:
            return None
        k = int(np.argmax(omega))
        return TimeScale(float(omega[k]), f"gyration of {self.names[points[k]]!r} in B = {strongest:.3g} T "
                                          f"(ω = |q| B / m)", turns=True)

    def energy_scale(self, size: float) -> float:
        strongest = float(np.max(np.linalg.norm(self.electric.values, axis=1)))
        return float(np.sum(np.abs(self.charge))) * strongest * size

    def potential_energy(self, state: Kinematics) -> float:
        x = state.x if self.index is None else state.x[self.index]
        return -float(self.charge @ (x @ self.electric.at(state.t)))

    def describe(self) -> str:
        def shown(history: FieldHistory, unit: str) -> str:
            if len(history.times) == 1:
                return f"{vector_text(history.values[0])} {unit}"
            return f"keyframed over {history.times[0]:g}–{history.times[-1]:g} s ({len(history.times)} keys) {unit}"

        return (f"E = {shown(self.electric, 'V/m')}, B = {shown(self.magnetic, 'T')} on charged "
                f"{selection_text(self.index, self.names)}")


def build_lorentz(bodies: BodyTable, index: np.ndarray | None, *, charge: np.ndarray, electric: FieldHistory,
                  magnetic: FieldHistory) -> LorentzForce:
    """The Lorentz force on the selected points, of charges ``charge`` (S,) [C] in the order of ``index`` (all
    points when None)."""
    return LorentzForce(np.asarray(charge, float), electric, magnetic, index, bodies.names)
