"""Quantities that physics conserves, for tests, reports and (later) stability guards.

All take positions ``x`` [m] and velocities ``v`` [m/s] of shape (N, 3) or (F, N, 3) and masses ``m`` [kg] (N,).
"""

from __future__ import annotations

import numpy as np

from animbatch.model.model import Model


def kinetic_energy(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Σ ½ m |v|²`` [J], per frame."""
    return 0.5 * np.einsum("n,...ni,...ni->...", m, v, v)


def linear_momentum(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``P = Σ m v`` [kg·m/s], shape (..., 3)."""
    return np.einsum("n,...ni->...i", m, v)


def angular_momentum(m: np.ndarray, x: np.ndarray, v: np.ndarray, origin: np.ndarray | None = None) -> np.ndarray:
    """``L = Σ (x - origin) × m v`` [kg·m²/s], shape (..., 3)."""
    r = x if origin is None else x - origin
    return np.einsum("n,...ni->...i", m, np.cross(r, v))


def centre_of_mass(m: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``Σ m x / Σ m`` [m], shape (..., 3) (the lecture notes' discrete centre of mass)."""
    return np.einsum("n,...ni->...i", m, x) / np.sum(m)


def potential_energy(model: Model, x: np.ndarray) -> np.ndarray:
    """Sum of the potentials of the model's force terms that have one [J], per frame."""
    frames = x.reshape(-1, *x.shape[-2:])
    terms = [term for term in model.force_terms if term.has_potential]
    energy = np.array([sum(term.potential_energy(frame) for term in terms) for frame in frames])
    return energy.reshape(x.shape[:-2])


def total_energy(model: Model, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Kinetic plus potential energy [J], per frame."""
    return kinetic_energy(model.particles.mass, v) + potential_energy(model, x)
