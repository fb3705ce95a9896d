"""Force fields. Each is compiled into a force term only when declared."""

from __future__ import annotations

from typing import Annotated, Literal, get_args

from pydantic import Field, model_validator

from animbatch.scene.annotations import tag_of
from animbatch.scene.schema.bodies import KeyframeList
from animbatch.scene.schema.keys import Name, NonZeroVec3, SceneModel, Vec3, key, rule_error

BodySelection = list[Name] | None
_BODIES_DESCRIPTION = "Names of the bodies this field acts on (default: all bodies)."


class GravitySpec(SceneModel):
    """Uniform gravity: ``f = m g`` on each selected body."""

    type: Literal["gravity"] = key(description="Field type.")
    g: Vec3 = key([0.0, -9.81, 0.0], "Gravitational acceleration vector.", "m/s²")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class GravitationSpec(SceneModel):
    """Newtonian gravitation between every pair of selected bodies, with Plummer softening.

    ``f_i = Σ_j G m_i m_j (x_j - x_i) / (|x_j - x_i|² + ε²)^(3/2)``.
    """

    type: Literal["gravitation"] = key(description="Field type.")
    G: float = key(6.674e-11, "Gravitational constant (scenes often use G = 1 with scaled masses).",
                   "m³/(kg·s²)", gt=0)
    softening: float = key(0.0, "Plummer softening length ε; keeps close encounters finite.", "m", ge=0)
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


#: Coulomb's constant k = 1 / (4 π ε₀) [N·m²/C²] (CODATA 2018).
COULOMB_CONSTANT = 8.9875517923e9


class CoulombSpec(SceneModel):
    """Coulomb's law between every pair of selected charged bodies, with Plummer softening: like charges repel,
    opposite ones attract.

    ``f_i = -Σ_j k q_i q_j (x_j - x_i) / (|x_j - x_i|² + ε²)^(3/2)``.
    """

    type: Literal["coulomb"] = key(description="Field type.")
    k: float = key(COULOMB_CONSTANT, "Coulomb's constant 1/(4 π ε₀) (scenes may use k = 1 with scaled charges).",
                   "N·m²/C²", gt=0)
    softening: float = key(0.0, "Plummer softening length ε; keeps close encounters finite.", "m", ge=0)
    bodies: BodySelection = key(None, "Names of the bodies this field acts on (default: every body with a charge).")


class FieldKeyframeSpec(SceneModel):
    """The electric and/or magnetic field at a time; each is linear between the keyframes that give it."""

    time: float = key(description="Time of the key.", unit="s", ge=0)
    E: Vec3 | None = key(None, "Electric field at that time (default: this key leaves E to the others).", "V/m")
    B: Vec3 | None = key(None, "Magnetic field at that time (default: this key leaves B to the others).", "T")


class ElectromagneticSpec(SceneModel):
    """Uniform electric and magnetic fields acting on charged bodies: the Lorentz force ``f = q (E + v × B)``.

    With ``keyframes``, E and B change in time: each is linear between the keyframes that give it, and held before
    the first and after the last of them.
    """

    type: Literal["electromagnetic"] = key(description="Field type.")
    E: Vec3 = key([0.0, 0.0, 0.0], "Electric field (unless keyframes give it).", "V/m")
    B: Vec3 = key([0.0, 0.0, 0.0], "Magnetic field (unless keyframes give it).", "T")
    keyframes: KeyframeList[FieldKeyframeSpec] | None = key(
        None, "E and B over time (times increasing).")
    bodies: BodySelection = key(None, "Names of the bodies this field acts on (default: every body with a charge).")


DragModel = Literal["linear", "quadratic", "stokes"]


class _DragLaw(SceneModel):
    """The keys shared by drag and wind, and the rule tying the drag law to its parameters."""

    at: Vec3 | None = key(None, "For rigid bodies: the point (body coordinates, relative to the shape's origin) "
                                "whose velocity the drag opposes and where it acts, giving a torque (default: the "
                                "centre of mass). Particles ignore it.", "m")

    coefficient: float | None = key(None, "C for the linear (N·s/m) or quadratic (kg/m) law; not used by stokes.",
                                    "N·s/m or kg/m", ge=0)
    viscosity: float | None = key(None, "Dynamic viscosity η of the fluid for the stokes law "
                                        "(default 1.81e-5, air at 15 °C).", "Pa·s", gt=0)

    @model_validator(mode="after")
    def _parameters_match_law(self) -> "_DragLaw":
        model = self.model  # type: ignore[attr-defined]  # each law's class declares its own Literal model
        if model in ("linear", "quadratic") and self.coefficient is None:
            unit = "N·s/m" if model == "linear" else "kg/m"
            raise rule_error(f"required key missing: the {model} drag law needs 'coefficient' (C in {unit})",
                             "coefficient")
        if model == "stokes" and self.coefficient is not None:
            raise rule_error("not used by the stokes law (its coefficient is 6 π η r); remove it, or set 'viscosity'",
                             "coefficient")
        if model != "stokes" and self.viscosity is not None:
            raise rule_error(f"only the stokes law uses 'viscosity'; the {model} law uses 'coefficient'",
                             "viscosity")
        return self


class DragSpec(_DragLaw):
    """Fluid drag against the body's velocity, at its centre of mass or at a point ``at`` of rigid bodies.

    ``linear``: ``f = -C v``; ``quadratic``: ``f = -C |v| v``; ``stokes``: ``f = -6 π η r v`` (r: the particle's
    radius, or for a rigid body the radius of the sphere of equal volume).
    """

    type: Literal["drag"] = key(description="Field type.")
    model: DragModel = key(description="Drag law: linear, quadratic or stokes.", example="quadratic")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class WindSpec(_DragLaw):
    """Drag relative to moving air: the drag law applied to ``v - wind velocity``."""

    type: Literal["wind"] = key(description="Field type.")
    velocity: Vec3 = key(description="Wind velocity.", unit="m/s")
    model: DragModel = key("quadratic", "Drag law: linear, quadratic or stokes.")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


Frame = Literal["world", "body"]


class ForceSpec(SceneModel):
    """A constant force, applied at a point of each selected body; off the centre of mass it gives torque r × f."""

    type: Literal["force"] = key(description="Field type.")
    force: Vec3 = key(description="The force vector.", unit="N")
    at: Vec3 | None = key(None, "Point of application in body coordinates (relative to the shape's origin; default: "
                                "the centre of mass). Particles ignore it.", "m")
    frame: Frame = key("world", "Axes of 'force': world (fixed direction) or body (turns with the body, like a "
                                "thruster).")
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class TorqueSpec(SceneModel):
    """A constant torque on each selected rigid body."""

    type: Literal["torque"] = key(description="Field type.")
    torque: Vec3 = key(description="The torque vector.", unit="N·m")
    frame: Frame = key("world", "Axes of 'torque': world or body.")
    bodies: BodySelection = key(None, "Names of the rigid bodies it acts on (default: all rigid bodies).")


class AngularDragSpec(SceneModel):
    """Rotational damping ``τ = -c ω`` on each selected rigid body (air resistance to spinning, bearing friction)."""

    type: Literal["angular_drag"] = key(description="Field type.")
    coefficient: float = key(description="Rotational damping coefficient c.", unit="N·m·s", ge=0)
    bodies: BodySelection = key(None, "Names of the rigid bodies it acts on (default: all rigid bodies).")


class BuoyancySpec(SceneModel):
    """A fluid filling the half-space below a surface: each selected body is pushed up by ``ρ g V_submerged`` at the
    centre of the submerged volume (so floating bodies right themselves), and optionally damped in proportion to how
    much of it is submerged.

    Submerged volumes are exact for spheres, particles (spheres of their radius), boxes and meshes (clipped exactly
    at the surface); cylinders and rods use a 96-sided prism, within 0.1 % of their volume.
    """

    type: Literal["buoyancy"] = key(description="Field type.")
    density: float = key(1000.0, "Density ρ of the fluid (water 1000, sea water 1025, air 1.2).", "kg/m³", gt=0)
    level: float = key(0.0, "Height of the fluid surface along 'up'.", "m")
    up: NonZeroVec3 = key([0.0, 1.0, 0.0], "Upward direction (opposite to gravity).", "1")
    g: float = key(9.81, "Gravitational acceleration used for the buoyant force.", "m/s²", gt=0)
    linear_damping: float = key(0.0, "Viscous damping of the fluid, -c v, at full submersion (scaled by the "
                                     "submerged fraction).", "N·s/m", ge=0)
    angular_damping: float = key(0.0, "Rotational damping -c ω at full submersion (scaled likewise).", "N·m·s", ge=0)
    bodies: BodySelection = key(None, _BODIES_DESCRIPTION)


class GustSpec(SceneModel):
    """Gusts on top of the steady wind: ``w(t) = wind + amplitude · g(t)``, with g a smooth, repeatable signal in
    [-1, 1] (three sine waves at incommensurate frequencies, the slowest of period ``period``)."""

    amplitude: Vec3 = key(description="Largest change of the wind velocity.", unit="m/s")
    period: float = key(2.0, "Period of the slowest gust component.", "s", gt=0)


class AerodynamicsSpec(SceneModel):
    """Air acting on each triangle of a cloth, through its face normal n: with ``u = v_face - w`` the face's velocity
    relative to the wind, the face feels ``f = -½ ρ A |u| (C_n (u·n) n + C_t (u - (u·n) n))``, shared equally by its
    three vertices. A sheet facing the wind catches it; one edge-on barely does, so a flag billows and flutters."""

    type: Literal["aerodynamics"] = key(description="Field type.")
    wind: Vec3 = key([0.0, 0.0, 0.0], "Steady wind velocity w.", "m/s")
    gust: GustSpec | None = key(None, "Gusts added to the steady wind.")
    density: float = key(1.2, "Density ρ of the air.", "kg/m³", gt=0)
    drag: float = key(1.0, "Coefficient C_n of the force along the face normal.", "1", ge=0)
    friction: float = key(0.02, "Coefficient C_t of the force along the face (skin friction).", "1", ge=0)
    bodies: BodySelection = key(None, "Names of the cloths it acts on (default: all cloths).")


#: Field types that act on charged bodies only.
CHARGED_FIELD_TYPES = ("electromagnetic", "coulomb")
#: Field types that act on emitted particles too (the others act on bodies only).
PARTICLE_FIELD_TYPES = ("gravity", "drag", "wind", "buoyancy")
FieldSpec = Annotated[GravitySpec | GravitationSpec | DragSpec | WindSpec | ForceSpec | TorqueSpec |
    AngularDragSpec | BuoyancySpec | AerodynamicsSpec | ElectromagneticSpec | CoulombSpec, Field(discriminator="type")]
#: The members of FieldSpec, in order.
FIELD_SPECS: tuple[type[SceneModel], ...] = get_args(get_args(FieldSpec)[0])


def field_type_names() -> tuple[str, ...]:
    """The ``type`` values of all field kinds, in declaration order."""

    return tuple(str(tag_of(spec)) for spec in FIELD_SPECS)
