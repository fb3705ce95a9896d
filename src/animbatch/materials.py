"""The lecture notes' materials table: restitution e, static friction μs, kinetic friction μk of well-known surfaces,
and how each looks (colour, metallic, roughness) when a body made of it gives no look of its own.

Built-in friction coefficients are the notes' table (each measured on the same material, except rubber on pavement
and oiled steel on steel). The notes give no restitution; the built-in values are typical ones for balls of these
materials and are marked as such in the docs. This is data that both the scene checks (which names exist) and the
contact solver (:mod:`animbatch.sim.contact.materials`, the coefficients) read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Coefficients:
    restitution: float
    static_friction: float
    kinetic_friction: float


#: name -> (restitution [typical], μs, μk [lecture notes' table])
BUILT_IN: dict[str, Coefficients] = {
    "glass": Coefficients(0.7, 0.94, 0.40),
    "iron": Coefficients(0.5, 1.10, 0.15),
    "rubber": Coefficients(0.8, 0.55, 0.40),  # table: rubber on pavement
    "pavement": Coefficients(0.6, 0.55, 0.40),
    "steel": Coefficients(0.6, 0.78, 0.42),
    "teflon": Coefficients(0.5, 0.04, 0.04),
    "wood": Coefficients(0.5, 0.38, 0.20),
    "ice": Coefficients(0.3, 0.10, 0.03),
    "oiled_steel": Coefficients(0.6, 0.10, 0.08),  # table: oiled steel on steel
    "default": Coefficients(0.5, 0.50, 0.30),
}

#: Pairs measured together in the notes' table (order does not matter).
BUILT_IN_PAIRS: dict[frozenset[str], Coefficients] = {
    frozenset({"rubber", "pavement"}): Coefficients(0.6, 0.55, 0.40),
    frozenset({"oiled_steel", "steel"}): Coefficients(0.6, 0.10, 0.08),
}


def combine(a: Coefficients, b: Coefficients) -> Coefficients:
    """The rule for two materials without a pair entry."""
    return Coefficients(min(a.restitution, b.restitution), float(np.sqrt(a.static_friction * b.static_friction)),
                        float(np.sqrt(a.kinetic_friction * b.kinetic_friction)))


@dataclass(frozen=True)
class Look:
    """How a surface looks under physically based shading: base colour '#rrggbb', metallic and roughness in 0…1."""

    color: str
    metallic: float
    roughness: float


#: name -> look of the built-in materials ('default' has none: bodies get palette colours and plain shading).
BUILT_IN_LOOKS: dict[str, Look] = {
    "glass": Look("#cfe3ea", 0.0, 0.05),
    "iron": Look("#6b6e73", 1.0, 0.55),
    "rubber": Look("#2e2e30", 0.0, 0.85),
    "pavement": Look("#7d7a74", 0.0, 0.95),
    "steel": Look("#b9bdc4", 1.0, 0.3),
    "teflon": Look("#f0f0ea", 0.0, 0.4),
    "wood": Look("#a8743f", 0.0, 0.7),
    "ice": Look("#dcecf7", 0.0, 0.1),
    "oiled_steel": Look("#a3a8b0", 1.0, 0.15),
}
