"""The arrows a render draws (``render.arrows``): velocity, acceleration and each kind of force on chosen bodies at
every frame, computed once from the trajectory so that any frame range draws the same arrows.

Forces come from the model's own force terms evaluated at the frame states, summed by kind. Contacts and
constraints act through impulses and velocity corrections, not force terms, so their share is what is left of
Newton's second law: ``F_contact = m a − Σ F_terms``, with ``a`` the central difference of the frame velocities (an
impact shows as its mean force over the frames around it). The acceleration is ``Σ F_terms / m`` exactly when the
scene has no contacts, and that difference quotient when it has.
"""

from __future__ import annotations

import numpy as np

from animbatch.render.frame_geometry import ArrowSeries
from animbatch.scene.schema import FORCE_ARROW_KINDS, SceneSpec
from animbatch.sim.model import Dynamics, Model

#: Arrow colours: the kinematic quantities, then each kind of force.
ARROW_COLORS = {"velocity": "#2b7bba", "acceleration": "#e66101", "gravity": "#6a3d9a", "gravitation": "#7570b3",
                "drag": "#1b9e77", "wind": "#66a61e", "aerodynamics": "#d95f02", "buoyancy": "#1f78b4",
                "spring": "#e7298a", "dihedral": "#b15928", "controller": "#a6761d", "force": "#c9a100",
                "electromagnetic": "#0096c7", "coulomb": "#e63946", "joint": "#3d4451", "contact": "#404040"}
assert set(FORCE_ARROW_KINDS) <= set(ARROW_COLORS)


def arrow_series(spec: SceneSpec, model: Model, states: np.ndarray, times: np.ndarray, velocities: np.ndarray,
                 bounds: np.ndarray) -> ArrowSeries | None:
    """The arrows of ``render.arrows`` at the frames: ``states`` (F, n) the model's flat states, ``velocities``
    (F, P, 3) [m/s] at ``times`` (F,) [s]; ``bounds`` (2, 3) [m] of the motion sets the default length."""
    arrows = spec.render.arrows
    if arrows is None or not model.body_count:
        return None
    own = {name: k for k, (name, owner) in enumerate(zip(model.body_names, model.owners)) if name == owner}
    bodies = np.array([own[name] for name in arrows.bodies] if arrows.bodies else list(own.values()), np.intp)
    mass = body_masses(model)[bodies, None]
    quantities: dict[str, tuple[str, np.ndarray]] = {}  # name -> (unit, vectors (F, A, 3))
    need_forces = "forces" in arrows.show or "acceleration" in arrows.show
    forces = forces_at_frames(model, states, times, bodies) if need_forces else {}
    total = sum(forces.values(), np.zeros((len(times), len(bodies), 3)))
    if model.contact_world is not None and need_forces:  # contacts: the rest of m a
        observed = np.gradient(velocities[:, bodies], times, axis=0) if len(times) > 1 else np.zeros_like(total)
        forces["contact"] = mass * observed - total
        total = mass * observed
    if "velocity" in arrows.show:
        quantities["velocity"] = ("m/s", velocities[:, bodies])
    if "acceleration" in arrows.show:
        quantities["acceleration"] = ("m/s²", total / mass)
    if "forces" in arrows.show:
        wanted = arrows.forces if arrows.forces is not None else FORCE_ARROW_KINDS
        for kind in wanted:
            if kind in forces:
                quantities[kind] = ("N", forces[kind])
    length = arrows.length or 0.2 * float(np.linalg.norm(bounds[1] - bounds[0]))
    forces_only = [vectors for unit, vectors in quantities.values() if unit == "N"]
    force_peak = _peak(np.concatenate(forces_only, axis=1)) if forces_only else 0.0

    def scale(unit: str, vectors: np.ndarray) -> float:
        """Metres per unit: the quantity's typical longest arrow (of all forces together) is ``length`` long."""
        peak = force_peak if unit == "N" else _peak(vectors)
        return length / peak if peak > 0 else 0.0

    scales = tuple(scale(unit, vectors) for unit, vectors in quantities.values())
    return ArrowSeries(np.asarray(times), bodies, tuple(quantities), tuple(ARROW_COLORS[name] for name in quantities),
                       tuple(unit for unit, _ in quantities.values()),
                       tuple(vectors for _, vectors in quantities.values()), scales, length, arrows.legend)


#: Arrows are scaled so that this percentile of a quantity's lengths over the run (bodies × frames) is drawn
#: ``length`` long: a brief peak (an impact's mean force over a frame) then does not shrink every other arrow.
TYPICAL_PERCENTILE = 90


def _peak(vectors: np.ndarray) -> float:
    """The typical largest length of the vectors (…, 3): their 90th percentile, ignoring non-finite ones and zeros
    (frames where the quantity is off)."""
    lengths = np.linalg.norm(vectors, axis=-1)
    lengths = lengths[np.isfinite(lengths) & (lengths > 0)]
    return float(np.percentile(lengths, TYPICAL_PERCENTILE)) if lengths.size else 0.0


def body_masses(model: Model) -> np.ndarray:
    """Mass [kg] of every body (P,): particles, then rigid bodies."""
    particles = np.asarray(model.bodies.mass[: model.particle_count], float)
    return np.concatenate([particles, model.rigid.mass]) if model.rigid is not None else particles


def forces_at_frames(model: Model, states: np.ndarray, times: np.ndarray, bodies: np.ndarray
                     ) -> dict[str, np.ndarray]:
    """The force [N] (F, A, 3) of each kind of force term on ``bodies`` (A,) at each frame state."""
    dynamics = Dynamics(model)
    result: dict[str, np.ndarray] = {}
    for frame, (t, y) in enumerate(zip(times, states)):
        for label, force in dynamics.loads_by_term(float(t), y).items():
            result.setdefault(label, np.zeros((len(times), len(bodies), 3)))[frame] = force[bodies]
    return result
