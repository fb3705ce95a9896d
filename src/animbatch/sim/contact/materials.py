"""Materials and the coefficients of a pair of them: restitution e, static friction μs, kinetic friction μk.

Built-in friction coefficients are the lecture notes' table of well-known surfaces (each measured on the same
material, except rubber on pavement and oiled steel on steel). The notes give no restitution; the built-in values
are typical ones for balls of these materials and are marked as such in the docs.

Combining two materials A and B (in this order of precedence):

1. a pair listed in the scene's ``material_pairs`` (or the built-in pairs below) uses its own coefficients;
2. otherwise friction is the geometric mean, ``μ = sqrt(μ_A μ_B)``, which gives back the table's value for two
   surfaces of the same material, and restitution is the smaller of the two, ``e = min(e_A, e_B)``: an impact is only
   as elastic as its softer side (a steel ball does not bounce on wood as it does on steel).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.materials import BUILT_IN, BUILT_IN_PAIRS, Coefficients, combine

__all__ = ["BUILT_IN", "BUILT_IN_PAIRS", "Coefficients", "MaterialTable", "combine"]


@dataclass(frozen=True, eq=False)
class MaterialTable:
    """All materials of a scene, numbered, with the pair coefficients precomputed as (M, M) arrays."""

    names: tuple[str, ...]
    restitution: np.ndarray
    static_friction: np.ndarray
    kinetic_friction: np.ndarray

    def index(self, name: str) -> int:
        return self.names.index(name)

    def pair(self, a: str, b: str) -> Coefficients:
        i, j = self.index(a), self.index(b)
        return Coefficients(float(self.restitution[i, j]), float(self.static_friction[i, j]),
                            float(self.kinetic_friction[i, j]))

    @classmethod
    def build(cls, custom: dict[str, Coefficients] | None = None,
              pairs: dict[frozenset[str], dict[str, float | None]] | None = None) -> MaterialTable:
        """Built-ins plus ``custom`` materials; ``pairs`` override individual coefficients of pairs."""
        materials = {**BUILT_IN, **(custom or {})}
        names = tuple(materials)
        size = len(names)
        tables = np.zeros((3, size, size))
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                coefficients = BUILT_IN_PAIRS.get(frozenset({a, b})) or combine(materials[a], materials[b])
                tables[:, i, j] = (coefficients.restitution, coefficients.static_friction,
                                   coefficients.kinetic_friction)
        for members, values in (pairs or {}).items():
            a, b = (tuple(members) * 2)[:2]
            i, j = names.index(a), names.index(b)
            for k, key in enumerate(("restitution", "static_friction", "kinetic_friction")):
                if values.get(key) is not None:
                    tables[k, i, j] = tables[k, j, i] = values[key]
        return cls(names, *tables)
