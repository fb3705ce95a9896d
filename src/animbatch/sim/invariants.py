"""Quantities that physics conserves, for tests, reports and (later) stability guards.

Each takes the model and states ``y`` of shape (n,) or (F, n) (see :meth:`Model.states_from` to get them from a
trajectory) and returns one value, or one per frame.

* kinetic energy: ``Σ ½ m v²`` over particles, ``Σ (½ M v² + ½ ω·L)`` over rigid bodies;
* linear momentum: ``Σ m v + Σ P``;
* angular momentum about a point o: ``Σ (x - o) × m v`` over particles, ``Σ [(x - o) × P + L]`` over rigid bodies
  (orbital plus spin, as in the notes);
* potential energy: the sum of the potentials of the force terms that have one.
"""

from __future__ import annotations

import numpy as np

from animbatch.sim.model.dynamics import Dynamics
from animbatch.sim.model.model import Model


def _frames(model: Model, y: np.ndarray) -> tuple[np.ndarray, ...]:
    x, v = model.positions(y), model.velocities(y)
    omega = model.angular_velocities(y)
    return x, v, omega


def _spin(model: Model, y: np.ndarray) -> np.ndarray:
    """Spin angular momentum L of every body [kg·m²/s] (zero for particles), (..., P, 3)."""
    result = np.zeros((*y.shape[:-1], model.body_count, 3))
    if model.rigid is not None:
        result[..., model.particle_count:, :] = model.layout.view(y, "rigid_angular_momentum")
    return result


def kinetic_energy(model: Model, y: np.ndarray) -> np.ndarray:
    """Translational plus rotational kinetic energy [J]."""
    x, v, omega = _frames(model, y)
    translational = 0.5 * np.einsum("p,...pi,...pi->...", model.bodies.mass, v, v)
    return translational + 0.5 * np.einsum("...pi,...pi->...", omega, _spin(model, y))


def linear_momentum(model: Model, y: np.ndarray) -> np.ndarray:
    """Total linear momentum [kg·m/s], (..., 3)."""
    return np.einsum("p,...pi->...i", model.bodies.mass, model.velocities(y))


def angular_momentum(model: Model, y: np.ndarray, origin: np.ndarray | None = None) -> np.ndarray:
    """Total angular momentum about ``origin`` (default the world origin) [kg·m²/s], (..., 3)."""
    x, v = model.positions(y), model.velocities(y)
    r = x if origin is None else x - origin
    orbital = np.einsum("p,...pi->...i", model.bodies.mass, np.cross(r, v))
    return orbital + _spin(model, y).sum(axis=-2)


def centre_of_mass(model: Model, y: np.ndarray) -> np.ndarray:
    """``Σ m x / Σ m`` [m], (..., 3) (the lecture notes' discrete centre of mass)."""
    return np.einsum("p,...pi->...i", model.bodies.mass, model.positions(y)) / np.sum(model.bodies.mass)


def potential_energy(model: Model, y: np.ndarray) -> np.ndarray:
    """Sum of the potentials of the model's force terms that have one [J], per frame."""
    dynamics = Dynamics(model)
    terms = [term for term in model.force_terms if term.has_potential]
    frames = y.reshape(-1, y.shape[-1])
    energy = np.array([sum(term.potential_energy(dynamics.kinematics(*dynamics.split(frame))) for term in terms)
                       for frame in frames])
    return energy.reshape(y.shape[:-1])


def total_energy(model: Model, y: np.ndarray) -> np.ndarray:
    """Kinetic plus potential energy [J], per frame."""
    return kinetic_energy(model, y) + potential_energy(model, y)
