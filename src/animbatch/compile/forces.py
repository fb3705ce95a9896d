"""Scene fields -> force laws: the one table (:data:`LAWS`) that says which field ``type`` builds which term on
bodies, and which form on emitted particles.

Each entry reads a validated field spec and calls the law's numeric constructors in :mod:`animbatch.sim.forces`,
which never see the scene format: the term on bodies (a ``ForceTerm``) and, for the laws that act on particles, the
particle form (a :class:`~animbatch.sim.forces.on_particles.ParticleLaw`, which also writes the compiled pool
kernel's row). A new force law adds its spec (``scene/schema``), its module (``sim/forces``, both forms) and one row
here; tests check that this table and the schema's field types are the same set, and that the laws with a particle
form are the ones the scene format lets fields name emitters for.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
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
from animbatch.sim.forces.buoyancy import BuoyancyOnParticles, build_buoyancy
from animbatch.sim.forces.drag import AIR_VISCOSITY, Drag, DragOnParticles
from animbatch.sim.forces.electromagnetic import FieldHistory, build_lorentz
from animbatch.sim.forces.gravitation import build_coulomb, build_gravitation
from animbatch.sim.forces.gravity import GravityOnParticles, build_gravity
from animbatch.sim.forces.on_particles import ParticleLaw
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


def _gravity_on_particles(spec: GravitySpec) -> ParticleLaw:
    return GravityOnParticles(np.asarray(spec.g, float))


def _drag_on_particles(spec: DragSpec | WindSpec) -> ParticleLaw:
    wind = np.asarray(spec.velocity, float) if isinstance(spec, WindSpec) else None
    viscosity = spec.viscosity if spec.viscosity is not None else AIR_VISCOSITY
    return DragOnParticles(spec.model, float(spec.coefficient or 0.0), viscosity,
                           wind if wind is not None and np.any(wind) else None, spec.type)


def _buoyancy_on_particles(spec: BuoyancySpec) -> ParticleLaw:
    up = np.asarray(spec.up, float)
    return BuoyancyOnParticles(spec.density, spec.g, spec.level, up / np.linalg.norm(up), spec.linear_damping)


@dataclass(frozen=True)
class Law:
    """One field type: the builder of its term on bodies from (spec, bodies, selected points or None), and of its
    form on emitted particles from the spec (None: it acts on bodies only)."""

    bodies: Callable[..., ForceTerm]
    particles: Callable[[Any], ParticleLaw] | None = None


#: Field ``type`` (as in the scene file) -> its law. The fields on charges (CHARGED_FIELD_TYPES) also take
#: ``charges=`` (body name -> charge [C]) in their body builder.
LAWS: dict[str, Law] = {
    "aerodynamics": Law(_aerodynamics),
    "force": Law(_force),
    "torque": Law(_torque),
    "angular_drag": Law(_angular_drag),
    "buoyancy": Law(_buoyancy, _buoyancy_on_particles),
    "drag": Law(_drag, _drag_on_particles),
    "wind": Law(_wind, _drag_on_particles),
    "gravitation": Law(_gravitation),
    "gravity": Law(_gravity, _gravity_on_particles),
    "electromagnetic": Law(_electromagnetic),
    "coulomb": Law(_coulomb),
}
#: The body builders of :data:`LAWS`, by field type.
FIELD_TERMS: dict[str, Callable[..., ForceTerm]] = {name: law.bodies for name, law in LAWS.items()}

_FIELD_ADAPTER: TypeAdapter[Any] = TypeAdapter(FieldSpec)


def field_term(spec: Any, charges: dict[str, float] | None = None) -> TermFactory:
    """The term factory of a field spec (a dict is validated first, with the scene's rules and messages).
    ``charges``: body name -> charge [C], for the fields that act on charges (electromagnetic, coulomb)."""
    if isinstance(spec, dict):
        spec = _FIELD_ADAPTER.validate_python(spec)
    if spec.type in CHARGED_FIELD_TYPES:
        return partial(LAWS[spec.type].bodies, spec, charges=charges or {})
    return partial(LAWS[spec.type].bodies, spec)


def particle_law(spec: Any) -> ParticleLaw | None:
    """The form on emitted particles of a field spec, or None for a field that acts on bodies only."""
    build = LAWS[spec.type].particles
    return build(spec) if build is not None else None
