"""Scene fields -> force terms: the one table that says which field ``type`` builds which term.

Each entry reads a validated field spec and calls the term's numeric constructor in :mod:`animbatch.sim.forces`,
which never sees the scene format. A new force law adds its spec (``scene/schema``), its module (``sim/forces``) and
one line here; a test checks that this table and the schema's field types are the same set.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from animbatch.scene.schema import (
    CHARGED_FIELD_TYPES,
    AerodynamicsSpec,
    AngularDragSpec,
    BuoyancySpec,
    CoulombSpec,
    DragSpec,
    ElectromagneticSpec,
    FieldSpec,
    ForceSpec,
    GravitationSpec,
    GravitySpec,
    TorqueSpec,
    WindSpec,
)
from animbatch.sim.forces.aerodynamics import build_aerodynamics
from animbatch.sim.forces.applied import build_angular_drag, build_force, build_torque
from animbatch.sim.forces.buoyancy import build_buoyancy
from animbatch.sim.forces.drag import Drag
from animbatch.sim.forces.electromagnetic import FieldHistory, build_lorentz
from animbatch.sim.forces.gravitation import build_coulomb, build_gravitation
from animbatch.sim.forces.gravity import build_gravity
from animbatch.sim.forces.term import BodyTable, ForceTerm, TermFactory

Index = np.ndarray | None


def _gravity(spec: GravitySpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_gravity(bodies, index, g=np.asarray(spec.g, float))


def _gravitation(spec: GravitationSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_gravitation(bodies, index, G=spec.G, softening=spec.softening)


def _drag(spec: DragSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return Drag.build(spec.model, coefficient=spec.coefficient, viscosity=spec.viscosity, wind=None, bodies=bodies,
                      index=index, at=spec.at)


def _wind(spec: WindSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return Drag.build(spec.model, coefficient=spec.coefficient, viscosity=spec.viscosity,
                      wind=np.asarray(spec.velocity, float), bodies=bodies, index=index, at=spec.at)


def _force(spec: ForceSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_force(bodies, index, force=np.asarray(spec.force, float), frame=spec.frame,
                       at=None if spec.at is None else np.asarray(spec.at, float))


def _torque(spec: TorqueSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_torque(bodies, index, torque=np.asarray(spec.torque, float), frame=spec.frame)


def _angular_drag(spec: AngularDragSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_angular_drag(bodies, index, coefficient=spec.coefficient)


def _buoyancy(spec: BuoyancySpec, bodies: BodyTable, index: Index) -> ForceTerm:
    return build_buoyancy(bodies, index, density=spec.density, g=spec.g, level=spec.level,
                          up=np.asarray(spec.up, float), linear_damping=spec.linear_damping,
                          angular_damping=spec.angular_damping)


def _charges(charges: dict[str, float], bodies: BodyTable, index: Index) -> np.ndarray:
    """The charge [C] of each selected point (all points when ``index`` is None), from the scene's bodies."""
    points = range(bodies.count) if index is None else index
    return np.array([charges.get(bodies.names[i], 0.0) for i in points], float)  # once, at compile time


def _history(spec: ElectromagneticSpec, which: str) -> FieldHistory:
    """E or B over time: from the keyframes that give it, else the field's constant value."""
    keys = [(k.time, getattr(k, which)) for k in spec.keyframes or () if getattr(k, which) is not None]
    if not keys:
        return FieldHistory(np.zeros(1), np.asarray([getattr(spec, which)], float))
    return FieldHistory(np.array([t for t, _ in keys], float), np.array([v for _, v in keys], float))


def _electromagnetic(spec: ElectromagneticSpec, bodies: BodyTable, index: Index, *,
                     charges: dict[str, float]) -> ForceTerm:
    return build_lorentz(bodies, index, charge=_charges(charges, bodies, index), electric=_history(spec, "E"),
                         magnetic=_history(spec, "B"))


def _coulomb(spec: CoulombSpec, bodies: BodyTable, index: Index, *, charges: dict[str, float]) -> ForceTerm:
    return build_coulomb(bodies, index, k=spec.k, softening=spec.softening, charge=_charges(charges, bodies, index))


def _aerodynamics(spec: AerodynamicsSpec, bodies: BodyTable, index: Index) -> ForceTerm:
    gust = spec.gust
    return build_aerodynamics(bodies, index, wind=np.asarray(spec.wind, float),
                              gust_amplitude=np.asarray(gust.amplitude, float) if gust else np.zeros(3),
                              gust_period=gust.period if gust else 1.0, density=spec.density, drag=spec.drag,
                              friction=spec.friction)


#: Field ``type`` (as in the scene file) -> builder of its term from (spec, bodies, selected points or None); the
#: fields on charges (CHARGED_FIELD_TYPES) also take ``charges=`` (body name -> charge [C]).
FIELD_TERMS: dict[str, Callable[..., ForceTerm]] = {
    "aerodynamics": _aerodynamics,
    "force": _force,
    "torque": _torque,
    "angular_drag": _angular_drag,
    "buoyancy": _buoyancy,
    "drag": _drag,
    "wind": _wind,
    "gravitation": _gravitation,
    "gravity": _gravity,
    "electromagnetic": _electromagnetic,
    "coulomb": _coulomb,
}

_FIELD_ADAPTER: TypeAdapter[Any] = TypeAdapter(FieldSpec)


def field_term(spec: Any, charges: dict[str, float] | None = None) -> TermFactory:
    """The term factory of a field spec (a dict is validated first, with the scene's rules and messages).
    ``charges``: body name -> charge [C], for the fields that act on charges (electromagnetic, coulomb)."""
    if isinstance(spec, dict):
        spec = _FIELD_ADAPTER.validate_python(spec)
    if spec.type in CHARGED_FIELD_TYPES:
        return partial(FIELD_TERMS[spec.type], spec, charges=charges or {})
    return partial(FIELD_TERMS[spec.type], spec)
