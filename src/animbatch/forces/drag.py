"""Fluid drag, optionally relative to a moving medium (wind).

With relative velocity ``u = v - w`` (``w``: wind velocity, zero for plain drag):

* linear:    ``f = -C u``            (C in N·s/m)
* quadratic: ``f = -C |u| u``        (C in kg/m; ``C = ½ ρ C_d A`` for a body of area A)
* stokes:    ``f = -6 π η r u``      (η: dynamic viscosity in Pa·s, r: particle radius in m)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from animbatch.scene.schema import DragSpec, WindSpec
from animbatch.forces.base import ForceTerm, ParticleProperties, field_term, selection_text, vector_text

AIR_VISCOSITY = 1.81e-5  # Pa·s, dry air at 15 °C


@dataclass(frozen=True, eq=False)
class Drag(ForceTerm):
    """``coefficient``: C, a number when it is the same for every particle (linear, quadratic), else per selected
    particle with shape (S, 1) (stokes: 6 π η r); ``wind``: (3,) or None."""

    kind = "drag"

    @property
    def dissipative(self) -> bool:
        return True

    law: Literal["linear", "quadratic", "stokes"]
    coefficient: float | np.ndarray
    wind: np.ndarray | None
    index: np.ndarray | None
    names: tuple[str, ...]
    viscosity: float | None = None

    @classmethod
    def build(cls, law: Literal["linear", "quadratic", "stokes"], *, coefficient: float | None,
              viscosity: float | None, wind: np.ndarray | None, radius: np.ndarray, index: np.ndarray | None,
              names: tuple[str, ...]) -> Drag:
        selected_radius = radius if index is None else radius[index]
        if law == "stokes":
            viscosity = AIR_VISCOSITY if viscosity is None else viscosity
            value: float | np.ndarray = (6.0 * np.pi * viscosity * selected_radius)[:, None]  # Stokes, per sphere
        else:
            if coefficient is None:
                raise ValueError(f"the {law} drag law needs a coefficient")
            value = float(coefficient)
        wind_vector = None if wind is None or not np.any(wind) else np.asarray(wind, float)
        return cls(law, value, wind_vector, index, names, viscosity)

    @property
    def label(self) -> str:
        return "wind" if self.wind is not None else "drag"

    def accumulate(self, t: float, x: np.ndarray, v: np.ndarray, force: np.ndarray) -> None:
        relative = v if self.index is None else v[self.index]
        if self.wind is not None:
            relative = relative - self.wind
        if self.law == "quadratic":
            scale = np.sqrt(np.einsum("ij,ij->i", relative, relative))  # |u|, shape (S,)
            scale *= self.coefficient
            term = scale[:, None] * relative
        else:
            term = self.coefficient * relative
        if self.index is None:
            force -= term
        else:
            force[self.index] -= term

    def describe(self) -> str:
        if self.law == "stokes":
            law = f"stokes 6πηr with η = {self.viscosity:g} Pa·s"
        else:
            unit = "N·s/m" if self.law == "linear" else "kg/m"
            law = f"{self.law}, C = {self.coefficient:g} {unit}"
        wind = f", wind {vector_text(self.wind)} m/s" if self.wind is not None else ""
        return f"{law}{wind} on {selection_text(self.index, self.names)}"


@field_term("drag")
def _drag(spec: DragSpec, particles: ParticleProperties, index: np.ndarray | None) -> Drag:
    return Drag.build(spec.model, coefficient=spec.coefficient, viscosity=spec.viscosity, wind=None,
                      radius=particles.radius, index=index, names=particles.names)


@field_term("wind")
def _wind(spec: WindSpec, particles: ParticleProperties, index: np.ndarray | None) -> Drag:
    return Drag.build(spec.model, coefficient=spec.coefficient, viscosity=spec.viscosity,
                      wind=np.asarray(spec.velocity), radius=particles.radius, index=index, names=particles.names)
