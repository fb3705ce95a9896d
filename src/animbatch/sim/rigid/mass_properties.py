"""Mass, centre of mass and inertia tensor: the formulas of the lecture notes, and how they combine.

The inertia tensor about a point is ``I = Σ m (|r|² E - r rᵀ)`` (continuous: ``∫ (|r|² E - r rᵀ) dm``), so its
diagonal holds the moments ``I_xx = ∫ (y² + z²) dm`` … and its off-diagonal entries the negated products
``I_xy = -∫ x y dm`` …, as in the notes. All tensors here are about the centre of mass, in body coordinates.

* Translation (parallel-axis theorem): about a point displaced by ``d`` from the centre of mass,
  ``I_d = I + M (|d|² E - d dᵀ)``.
* Rotation: in a frame rotated by ``R``, ``I' = R I Rᵀ`` (the notes' ``R I R⁻¹`` for orthonormal R).
* Compound bodies: ``M = Σ mᵢ``, ``c = Σ mᵢ cᵢ / M``, ``I = Σ [Rᵢ Iᵢ Rᵢᵀ + mᵢ (|dᵢ|² E - dᵢ dᵢᵀ)]`` with
  ``dᵢ = cᵢ - c``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MassProperties:
    """Mass [kg], volume [m³], centre of mass [m] (in the shape's frame) and inertia tensor [kg·m²] about it."""

    mass: float
    volume: float
    centre: np.ndarray  # (3,)
    inertia: np.ndarray  # (3, 3), about ``centre``, axes of the shape's frame

    @property
    def principal_moments(self) -> np.ndarray:
        """Eigenvalues of the inertia tensor, ascending [kg·m²]."""
        return np.linalg.eigvalsh(self.inertia)

    def with_mass(self, mass: float) -> MassProperties:
        """Same shape and mass distribution, scaled to ``mass`` (inertia scales linearly)."""
        factor = mass / self.mass
        return MassProperties(mass, self.volume, self.centre, self.inertia * factor)

    def transformed(self, rotation: np.ndarray, offset: np.ndarray) -> MassProperties:
        """The same body rotated by ``rotation`` (3, 3) and then moved by ``offset`` (3,) in the parent frame."""
        return MassProperties(self.mass, self.volume, rotation @ self.centre + offset,
                              rotation @ self.inertia @ rotation.T)


def parallel_axis(inertia: np.ndarray, mass: float, displacement: np.ndarray) -> np.ndarray:
    """Inertia about a point displaced by ``d`` from the centre of mass: ``I + M (|d|² E - d dᵀ)``."""
    d = np.asarray(displacement, float)
    return inertia + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))


def combine(parts: list[MassProperties]) -> MassProperties:
    """Mass properties of rigidly joined parts, each given in the common frame."""
    mass = sum(p.mass for p in parts)
    centre = np.sum([p.mass * p.centre for p in parts], axis=0) / mass
    inertia = np.sum([parallel_axis(p.inertia, p.mass, p.centre - centre) for p in parts], axis=0)
    return MassProperties(mass, sum(p.volume for p in parts), centre, inertia)


def solid_sphere(mass: float, radius: float) -> MassProperties:
    """``I = 2/5 m r²`` about every axis."""
    return MassProperties(mass, 4 / 3 * np.pi * radius**3, np.zeros(3), 0.4 * mass * radius**2 * np.eye(3))


def spherical_shell(mass: float, radius: float, thickness: float | None = None) -> MassProperties:
    """Thin shell ``I = 2/3 m r²`` (no volume); with a thickness, the hollow sphere
    ``I = 2/5 m (R⁵ - r⁵)/(R³ - r³)`` with R the outer and r = R - thickness the inner radius."""
    if thickness is None or thickness <= 0:
        return MassProperties(mass, 0.0, np.zeros(3), 2 / 3 * mass * radius**2 * np.eye(3))
    inner = max(radius - thickness, 0.0)
    moment = 0.4 * mass * (radius**5 - inner**5) / (radius**3 - inner**3)
    return MassProperties(mass, 4 / 3 * np.pi * (radius**3 - inner**3), np.zeros(3), moment * np.eye(3))


def cuboid(mass: float, size: np.ndarray) -> MassProperties:
    """Box with side lengths (a, b, c) along x, y, z: ``I = m/12 diag(b² + c², a² + c², a² + b²)``."""
    a, b, c = np.asarray(size, float)
    inertia = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return MassProperties(mass, a * b * c, np.zeros(3), inertia)


def cylinder(mass: float, radius: float, length: float) -> MassProperties:
    """Solid cylinder along z: ``I_xx = I_yy = ¼ m r² + 1/12 m l²``, ``I_zz = ½ m r²`` (notes: rod/cylinder)."""
    side = 0.25 * mass * radius**2 + mass * length**2 / 12
    return MassProperties(mass, np.pi * radius**2 * length, np.zeros(3), np.diag([side, side, 0.5 * mass * radius**2]))


def capsule(mass: float, radius: float, length: float) -> MassProperties:
    """Solid capsule along z, ``length`` tip to tip: a cylinder of length ``l = length - 2r`` and two hemispherical
    caps of mass ``m_h`` each, at one density. ``I_zz = ½ m_c r² + ⅘ m_h r²``; about x, each cap contributes
    ``m_h (⅖ r² + l²/4 + ⅜ l r)`` (its own ``83/320 m_h r²`` about its centroid, ``⅜ r`` from the flat face, moved
    to the centre by parallel axes)."""
    straight = length - 2 * radius
    cylinder_volume, cap_volume = np.pi * radius**2 * straight, 2 / 3 * np.pi * radius**3
    volume = cylinder_volume + 2 * cap_volume
    m_c, m_h = mass * cylinder_volume / volume, mass * cap_volume / volume
    side = m_c * (straight**2 / 12 + radius**2 / 4) + 2 * m_h * (0.4 * radius**2 + straight**2 / 4
                                                                 + 0.375 * straight * radius)
    axial = 0.5 * m_c * radius**2 + 0.8 * m_h * radius**2
    return MassProperties(mass, volume, np.zeros(3), np.diag([side, side, axial]))
