"""The fields that act on emitted particles, as accelerations on the live slots of a pool.

Only the fields a scene declares are built, and only those whose selection takes in the emitter (a field without
``bodies`` acts on every body and emitter; one with ``bodies`` acts on the emitters it names). Four kinds act on
particles, with the same laws as on bodies (:mod:`animbatch.sim.forces`):

* ``gravity``: ``a = g``;
* ``drag`` and ``wind``: ``a = f(u) / m`` with ``u = v - w``, linear, quadratic or Stokes (``6 π η r``, r the
  particle's radius);
* ``buoyancy``: ``a = ρ g V_sub up / m`` (V_sub the submerged cap of the particle's sphere), with the fluid's damping
  ``-c v V_sub / V``.

Gravitation between bodies, applied forces and torques, angular drag and cloth aerodynamics act on bodies only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.buoyancy import spherical_caps
from animbatch.sim.forces.drag import AIR_VISCOSITY, drag_force


@dataclass(frozen=True)
class Slots:
    """The live particles of a pool as the fields see them: positions [m] (K, 3), velocities [m/s] (K, 3), masses
    [kg] (K,), radii [m] (K,)."""

    x: np.ndarray
    v: np.ndarray
    mass: np.ndarray
    radius: np.ndarray


@dataclass(frozen=True)
class ParticleField:
    """One declared field, acting on particles. ``kind``: gravity, drag, wind or buoyancy; the other attributes are
    the field's parameters (those of its kind)."""

    kind: str
    label: str
    g: np.ndarray | None = None
    law: str = "linear"
    coefficient: float = 0.0
    viscosity: float = AIR_VISCOSITY
    wind: np.ndarray | None = None
    density: float = 0.0
    level: float = 0.0
    up: np.ndarray | None = None
    buoyancy_g: float = 9.81
    damping: float = 0.0

    @property
    def velocity_dependent(self) -> bool:
        return self.kind in ("drag", "wind") or (self.kind == "buoyancy" and self.damping > 0)

    def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
        """Add this field's acceleration [m/s²] on each slot to ``out`` (K, 3)."""
        if self.kind == "gravity":
            out += self.g
        elif self.kind in ("drag", "wind"):
            relative = slots.v - self.wind if self.wind is not None else slots.v
            out += drag_force(self.law, self.drag_coefficient(slots), relative) / slots.mass[:, None]  # type: ignore[arg-type]  # drag has a law
        elif self.kind == "buoyancy":
            volume, _ = spherical_caps(slots.x, slots.radius, self.level, self.up)  # type: ignore[arg-type]  # buoyancy has both
            out += (self.density * self.buoyancy_g * volume / slots.mass)[:, None] * self.up
            if self.damping:
                fraction = volume / (4.0 / 3.0 * np.pi * slots.radius ** 3)
                out -= (self.damping * fraction / slots.mass)[:, None] * slots.v

    def drag_coefficient(self, slots: Slots) -> float | np.ndarray:
        """C of the drag law: a number, or per slot (K, 1) for Stokes' 6 π η r."""
        if self.law == "stokes":
            return (6.0 * np.pi * self.viscosity * slots.radius)[:, None]
        return self.coefficient

    def drag_rate(self, slots: Slots) -> np.ndarray:
        """For implicit steps: ``∂a/∂v`` of drag as ``-(α I + β û ûᵀ)``, returned as (α, β) per slot, shape (K, 2)."""
        rates = np.zeros((len(slots.mass), 2))
        if self.kind in ("drag", "wind"):
            coefficient = np.ravel(np.broadcast_to(self.drag_coefficient(slots), (len(slots.mass), 1)))
            if self.law == "quadratic":
                relative = slots.v - self.wind if self.wind is not None else slots.v
                speed = np.sqrt(np.einsum("ij,ij->i", relative, relative))
                rates[:, 0] = rates[:, 1] = coefficient * speed / slots.mass  # ∂(|u| u)/∂u = |u| (I + û ûᵀ)
            else:
                rates[:, 0] = coefficient / slots.mass
        elif self.kind == "buoyancy" and self.damping:
            volume, _ = spherical_caps(slots.x, slots.radius, self.level, self.up)  # type: ignore[arg-type]  # buoyancy has both
            rates[:, 0] = self.damping * volume / (4.0 / 3.0 * np.pi * slots.radius ** 3) / slots.mass
        return rates

    def describe(self) -> str:
        return self.label


