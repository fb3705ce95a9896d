"""The rigid bodies of a model: mass, inertia, where the centre of mass sits in the shape, and its geometry."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.rigid.shapes import BodyGeometry


@dataclass(frozen=True, eq=False)
class RigidBodySet:
    """B rigid bodies (immutable).

    Attributes:
        names: body names, shape (B,).
        mass: masses M [kg], (B,).
        inertia: inertia tensors about the centre of mass in body axes, I_body [kg·m²], (B, 3, 3).
        inverse_inertia: I_body⁻¹, (B, 3, 3); ``ω = R I_body⁻¹ Rᵀ L``.
        centre: centre of mass in the shape frame [m], (B, 3): a point p given in shape coordinates is at
            ``p - centre`` from the centre of mass, in body axes.
        geometry: mass properties and buoyancy geometry per body, in the shape frame.
    """

    names: tuple[str, ...]
    mass: np.ndarray
    inertia: np.ndarray
    inverse_inertia: np.ndarray
    centre: np.ndarray
    geometry: tuple[BodyGeometry, ...]

    @property
    def count(self) -> int:
        return len(self.names)

    @property
    def volume(self) -> np.ndarray:
        return np.array([g.properties.volume for g in self.geometry])
