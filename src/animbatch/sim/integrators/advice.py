"""What to change when an integration fails: advice that fits what happened, not one remedy for everything.

When a solver gives up ("step size too small") or its state stops being finite, the culprit is looked for in this
order, and the first one found is named with its numbers and its fix:

1. **a close gravitational encounter**: two bodies of a gravitation field without softening closer than their radii
   together, where the 1/r² force grows without bound. Fix: ``softening`` on the field, a collision (a ``contacts``
   section so that they bounce off each other), or larger radii;
2. **a stiff spring or controller** (the pre-flight's bound on the fastest vibration, :func:`stiffest_mode`), named
   with its stiffness, masses and frequency. Fix: an implicit method for an explicit one; for an implicit one that
   still failed, ``backward_euler`` (stable at any step) or a softer or better damped spring;
3. otherwise **the body changing fastest** relative to the tolerances. An explicit method is pointed to Radau or
   BDF (the system may be stiff); an implicit one is not (it already is one), but to the body's parameters and to a
   fixed step that steps through a discontinuity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.forces.gravitation import InverseSquarePairs
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.integrators.stability import stiffest_mode
from animbatch.sim.model.model import Model

#: Methods that are implicit (or switch to an implicit method when the problem is stiff, as LSODA does).
IMPLICIT = tuple(name for name, method in METHODS.items() if method.implicit)


@dataclass(frozen=True)
class Encounter:
    """Two gravitating (or charged) bodies ``first`` and ``second`` ``distance`` [m] apart, with radii summing to
    ``touching`` [m], under a field without softening; at ``time`` [s] when known."""

    first: str
    second: str
    distance: float
    touching: float
    time: float | None = None
    collide: str = "a 'contacts: {}' section"  # what makes them collide in this scene
    field: str = "gravitation"  # the field type: gravitation or coulomb

    def advice(self) -> str:
        when = f" at t ≈ {self.time:.4g} s" if self.time is not None else ""
        return (f"Bodies {self.first!r} and {self.second!r} come {self.distance:.3g} m apart{when}, closer than "
                f"their radii together ({self.touching:.3g} m), and the {self.field} field has no softening, so the "
                f"1/r² force between them grows without bound. Give the {self.field} field a softening length "
                f"(softening: {max(0.5 * self.touching, 1e-12):.3g}), let the bodies collide ({self.collide}), or "
                "make their radii match their closest approach")


def _collide_hint(model: Model) -> str:
    """What to change in the scene so that bodies collide."""
    world = getattr(model, "contact_world", None)
    if world is None:
        return "a 'contacts: {}' section"
    if not world.bodies_collide:
        return "contacts.bodies: true"
    return "remove 'collide: false' from them"


def closest_encounter(model: Model, positions: np.ndarray, times: np.ndarray | None = None) -> Encounter | None:
    """The gravitating or charged pair without softening that comes closest to touching in ``positions`` (P, 3) or
    (F, P, 3) [m] (at the frames ``times`` [s] and on the straight paths between them), if any pair is closer than
    its radii together."""

    worst = None
    frames = positions.reshape(-1, *positions.shape[-2:])
    for term in model.force_terms:
        if not isinstance(term, InverseSquarePairs) or term.softening > 0:
            continue
        index = np.arange(model.body_count) if term.index is None else term.index
        if len(index) < 2:
            continue
        radius = model.bodies.radius[index]
        touching = radius[:, None] + radius[None, :]
        upper = np.triu(np.ones((len(index), len(index)), bool), 1)
        for k in range(len(frames)):
            offset = frames[k][index][None, :, :] - frames[k][index][:, None, :]
            if k:  # between frames, the closest approach of the straight relative path (a fast flyby)
                start = frames[k - 1][index][None, :, :] - frames[k - 1][index][:, None, :]
                move = offset - start
                along = np.einsum("ijk,ijk->ij", start, move) / np.maximum(np.einsum("ijk,ijk->ij", move, move),
                                                                           1e-300)
                fraction = np.clip(-along, 0.0, 1.0)
                offset = start + fraction[:, :, None] * move
            distance = np.linalg.norm(offset, axis=2)
            ratio = np.where(upper, distance / touching, np.inf)
            i, j = np.unravel_index(int(np.argmin(ratio)), ratio.shape)
            if ratio[i, j] < 1 and (worst is None or ratio[i, j] < worst[0]):
                names = model.bodies.names
                when = None if times is None else float(times[k] if not k else times[k - 1] + fraction[i, j] * (
                    times[k] - times[k - 1]))
                worst = (ratio[i, j], Encounter(names[index[i]], names[index[j]], float(distance[i, j]),
                                                float(touching[i, j]), when, _collide_hint(model), term.kind))
    return None if worst is None else worst[1]


def failure_advice(model: Model | None, method: str, y: np.ndarray, t: float, fastest: str | None) -> str:
    """What to change after ``method`` failed at time ``t`` [s] in state ``y`` (see the module notes); ``fastest``:
    the body changing fastest, if known."""
    implicit = method in IMPLICIT
    if model is not None:
        encounter = closest_encounter(model, model.positions(y), np.array([t]))
        if encounter is not None:
            return encounter.advice()

        mode = stiffest_mode(model)
        if mode is not None:
            stiffest = (f"The stiffest part is the {mode.stiffest()}, ω = {mode.spring_omega:.4g} rad/s (up to "
                        f"{mode.omega:.4g} rad/s around {mode.body!r})")
            if implicit:
                return (f"{stiffest}. {method} is already implicit: try backward_euler (stable at any step, it damps "
                        "the fastest vibrations), or a softer spring (lower ks), heavier bodies or more damping")
            return f"{stiffest}: use an implicit method (solver.method: Radau or BDF) or backward_euler"
    who = f"The fastest-changing body is {fastest!r}: check its masses, springs and fields for extreme values" \
        if fastest else "Check the bodies' masses, springs and fields for extreme values"
    if implicit:
        return (f"{who}. {method} is already implicit, so stiffness is not the cause: a force that jumps or "
                "becomes singular near this time is; a fixed-step method (solver.method: verlet with a small "
                "solver.dt) steps through it")
    return f"{who}; if the scene is stiff, an implicit method (solver.method: Radau or BDF) takes far fewer steps"
