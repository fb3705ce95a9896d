"""What a study measures about one run: its errors against the reference, and the drift of conserved quantities.

Every error is dimensionless, relative to the scene's scales (:class:`Scales`), so that scenes of marbles and of
planets read alike:

* ``position_error``: the RMS over all frames and bodies (or emitted particles alive in both runs) of how far each
  body is from where the reference puts it, over the length scale L. A rigid body's distance adds its orientation
  error (angle) times its radius, the distance its surface is off: what a viewer sees.
* ``final_error``: at the last frame, the RMS over bodies of ``√(|Δx|²/L² + |Δv|²/V²)`` (the state a continuation
  would start from; ``|Δx|/L`` alone for emitted particles, whose velocities are not recorded).
* drifts, only where the scene conserves the quantity (:func:`conserved`): the largest change from the first frame
  of the total energy over ``M V²``, of the linear momentum over ``M V`` and of the angular momentum over ``M V L``
  (M the total mass).
* ``contact_time_error`` [s]: in scenes with collisions, the largest difference between the run's impact times and
  the reference's (each body's bounces matched in order); the only error here with a unit, since a bounce early by a
  step is the fixed-step methods' characteristic error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.invariants import angular_momentum, linear_momentum, total_energy
from animbatch.sim.ledger import conservation_laws
from animbatch.sim.model.model import Model


@dataclass(frozen=True)
class Scales:
    """The scene's length ``L`` [m] and speed ``V`` [m/s] scales, from its reference motion: L is the diagonal of
    the box the bodies sweep (at least their largest radius), V the largest speed (at least L over the duration)."""

    length: float
    speed: float

    @classmethod
    def of_motion(cls, model: Model, positions: np.ndarray, velocities: np.ndarray) -> Scales:
        """From positions and velocities (F, P, 3) of every body at the frame times."""
        radius = float(np.max(model.bodies.radius)) if model.body_count else 1.0
        extent = float(np.linalg.norm(positions.max(axis=(0, 1)) - positions.min(axis=(0, 1))))
        length = max(extent, radius, 1e-9)
        duration = max(float(model.frame_times[-1]), 1e-9)
        speed = max(float(np.linalg.norm(velocities, axis=-1).max()), length / duration)
        return cls(length, speed)

    def tolerance_scale(self, model: Model) -> np.ndarray:
        """Per state component (n,), what ``atol = rtol × scale`` should be relative to: L for positions, 1 for
        quaternions, V for velocities, M_body V for momenta, I_body V / L for angular momenta and L / V for proper
        times."""
        scale = np.ones(model.layout.size)
        per_block = {"particle_position": lambda b: np.full(b.size, self.length),
                     "rigid_position": lambda b: np.full(b.size, self.length),
                     "rigid_orientation": lambda b: np.ones(b.size),
                     "particle_velocity": lambda b: np.full(b.size, self.speed),
                     "proper_time": lambda b: np.full(b.size, self.length / self.speed)}  # a time: L / V
        if model.rigid is not None:
            mass = model.rigid.mass
            inertia = np.trace(model.rigid.inertia, axis1=1, axis2=2) / 3
            per_block["rigid_momentum"] = lambda b: np.repeat(mass * self.speed, 3)
            per_block["rigid_angular_momentum"] = lambda b: np.repeat(inertia * self.speed / self.length, 3)
        for block in model.layout.blocks:
            scale[block.span] = per_block[block.name](block)
        return scale


@dataclass(frozen=True)
class Motion:
    """What a run (or the reference) says the bodies do at the frame times: positions and velocities (F, P, 3),
    and for rigid bodies orientations (F, P, 4) (identity for particles); ``states`` (F, n) when it came from a run
    (closed forms have none)."""

    positions: np.ndarray
    velocities: np.ndarray
    orientations: np.ndarray
    states: np.ndarray | None = None
    impacts: tuple[tuple[float, int], ...] = ()

    @classmethod
    def of_states(cls, model: Model, states: np.ndarray, impacts: list[tuple[float, int]] | None = None) -> Motion:
        return cls(model.positions(states), model.velocities(states), model.orientations(states), states,
                   tuple(impacts or ()))


def conserved(model: Model) -> dict[str, bool]:
    """Which of energy, linear and angular momentum the scene conserves (see
    :func:`~animbatch.sim.ledger.conservation_laws`, which also says why)."""
    return {name: law.conserved for name, law in conservation_laws(model).items()}


def _rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle [rad] between unit quaternions (..., 4) (q and -q are the same rotation)."""
    dot = np.clip(np.abs(np.einsum("...i,...i->...", a, b)), 0.0, 1.0)
    return 2 * np.arccos(dot)


def position_error(model: Model, run: Motion, reference: Motion, scales: Scales) -> float:
    distance = np.linalg.norm(run.positions - reference.positions, axis=-1)  # (F, P)
    if model.rigid is not None:
        distance = distance + _rotation_angle(run.orientations, reference.orientations) * model.bodies.radius
    alive = np.isfinite(distance)  # emitted particles: only where both runs hold the particle (NaN elsewhere)
    return float(np.sqrt(np.mean(distance[alive]**2)) / scales.length) if alive.any() else 0.0


def final_error(run: Motion, reference: Motion, scales: Scales) -> float:
    dx = np.linalg.norm(run.positions[-1] - reference.positions[-1], axis=-1) / scales.length
    dv = np.linalg.norm(run.velocities[-1] - reference.velocities[-1], axis=-1) / scales.speed
    dv = np.where(np.isnan(dv), 0.0, dv)  # emitted particles' velocities are not recorded: positions alone
    alive = np.isfinite(dx)
    return float(np.sqrt(np.mean(dx[alive]**2 + dv[alive]**2))) if alive.any() else 0.0


def contact_time_error(run: Motion, reference: Motion) -> float | None:
    """The largest difference [s] between a run's impact times and the reference's, matching each body's impacts in
    order (the k-th bounce of a body with its k-th bounce in the reference), over the impacts both have; None when
    neither has any. A run that misses or adds bounces shows in the impact counts (and usually here too: every later
    bounce is then matched with the wrong one)."""
    if not run.impacts and not reference.impacts:
        return None
    worst = 0.0
    for body in {b for _, b in reference.impacts} | {b for _, b in run.impacts}:
        mine = [t for t, b in run.impacts if b == body]
        theirs = [t for t, b in reference.impacts if b == body]
        pairs = min(len(mine), len(theirs))
        if pairs:
            worst = max(worst, float(np.max(np.abs(np.subtract(mine[:pairs], theirs[:pairs])))))
    return worst


def drifts(model: Model, states: np.ndarray, scales: Scales, which: dict[str, bool]) -> dict[str, float | None]:
    """The largest relative change of each conserved quantity over the run (None where it is not conserved)."""
    mass = float(np.sum(model.bodies.mass))
    result: dict[str, float | None] = {"energy": None, "momentum": None, "angular_momentum": None}
    if which["energy"]:
        energy = total_energy(model, states)
        result["energy"] = float(np.max(np.abs(energy - energy[0])) / (mass * scales.speed**2))
    if which["momentum"]:
        momentum = linear_momentum(model, states)
        result["momentum"] = float(np.max(np.linalg.norm(momentum - momentum[0], axis=-1)) / (mass * scales.speed))
    if which["angular_momentum"]:
        spin = angular_momentum(model, states)
        result["angular_momentum"] = float(np.max(np.linalg.norm(spin - spin[0], axis=-1))
                                           / (mass * scales.speed * scales.length))
    return result
