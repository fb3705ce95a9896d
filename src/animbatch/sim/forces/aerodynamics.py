"""Air on cloth faces: drag along each triangle's normal, and a little skin friction along it.

For a triangle with area A, unit normal n and velocity (the mean of its vertices') relative to the wind
``u = v_face - w(t)``::

    f = -½ ρ A |u| (C_n (u·n) n + C_t (u - (u·n) n))

shared equally by its three vertices. The normal part is the pressure drag of a flat plate, proportional to the
area the face shows the wind (``A |u·n| / |u|``) times the dynamic pressure ``½ ρ |u|²``; it is what makes a flag
billow. Wind may gust: ``w(t) = wind + amplitude · g(t)``, g a smooth, repeatable signal in [-1, 1].

Vertices pinned to anchors pass their share to the anchor; vertices attached to a rigid body pass it to the body, as
a force at that point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from animbatch.sim.deformable.vertices import PARTICLE, DeformableSet, triangle_share
from animbatch.sim.forces.term import BodyTable, ForceTerm, Kinematics, vector_text

#: Relative frequencies, weights and phases of the three sine waves of a gust (incommensurate, so the pattern does
#: not visibly repeat within a few periods).
GUST_WAVES = ((1.0, 1.0, 0.0), (2.31, 0.5, 1.1), (5.37, 0.25, 2.3))


def gust_signal(t: float, period: float) -> float:
    """A smooth signal in [-1, 1] whose slowest component has period ``period`` [s]."""
    total = sum(weight for _, weight, _ in GUST_WAVES)
    return sum(weight * np.sin(2 * np.pi * frequency * t / period + phase)
               for frequency, weight, phase in GUST_WAVES) / total


@dataclass(frozen=True, eq=False)
class Aerodynamics(ForceTerm):
    """The aerodynamics term: per-triangle drag on the selected cloths."""

    kind = "aerodynamics"

    deformables: DeformableSet
    triangles: np.ndarray  # (T, 3) vertex indices
    wind: np.ndarray  # (3,) [m/s]
    gust_amplitude: np.ndarray  # (3,) [m/s]
    gust_period: float  # [s]
    density: float  # [kg/m³]
    normal_coefficient: float
    tangential_coefficient: float
    share: sp.csr_matrix  # (V, T): 1/3 at each triangle's three vertices
    cloth_names: tuple[str, ...]

    @property
    def dissipative(self) -> bool:
        return True

    @property
    def adds_energy(self) -> bool:
        return bool(self.wind.any() or self.gust_amplitude.any())  # in still air it only takes energy

    def wind_at(self, t: float) -> np.ndarray:
        """Wind velocity [m/s] at time ``t`` [s]."""
        if not self.gust_amplitude.any():
            return self.wind
        return self.wind + self.gust_amplitude * gust_signal(t, self.gust_period)

    def face_forces(self, x: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Force on each triangle (T, 3) [N] for vertex positions and velocities (V, 3)."""
        tri = self.triangles
        a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
        normal = np.cross(b - a, c - a)
        twice_area = np.sqrt(np.einsum("ij,ij->i", normal, normal))
        unit = np.divide(normal, twice_area[:, None], out=np.zeros_like(normal), where=twice_area[:, None] > 0)
        relative = (v[tri[:, 0]] + v[tri[:, 1]] + v[tri[:, 2]]) / 3 - self.wind_at(t)
        speed = np.sqrt(np.einsum("ij,ij->i", relative, relative))
        along = np.einsum("ij,ij->i", relative, unit)
        normal_part = along[:, None] * unit
        scale = -0.25 * self.density * twice_area * speed  # ½ ρ A |u|, A = twice_area / 2
        return scale[:, None] * (self.normal_coefficient * normal_part
                                 + self.tangential_coefficient * (relative - normal_part))

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        vertices = self.deformables.vertex_map
        x, v = vertices.positions_velocities(state, self.deformables.anchors)
        vertices.scatter(self.share @ self.face_forces(x, v, t), state, force, torque)

    def describe(self) -> str:
        gust = (f", gusts ±{vector_text(self.gust_amplitude)} m/s (period {self.gust_period:g} s)"
                if self.gust_amplitude.any() else "")
        return (f"wind {vector_text(self.wind)} m/s{gust}, ρ {self.density:g} kg/m³, C_n {self.normal_coefficient:g}, "
                f"C_t {self.tangential_coefficient:g} on {len(self.triangles)} triangles of "
                f"{', '.join(self.cloth_names)}")


def build_aerodynamics(bodies: BodyTable, index: np.ndarray | None, *, wind: np.ndarray, gust_amplitude: np.ndarray,
                       gust_period: float, density: float, drag: float, friction: float) -> Aerodynamics:
    """Wind pressure on the triangles of the cloths among the selected points (all cloths when ``index`` is None);
    ``wind`` [m/s] (3,), gusts of ``gust_amplitude`` [m/s] (3,) over ``gust_period`` [s], air ``density`` [kg/m³],
    normal ``drag`` and tangential ``friction`` coefficients."""

    deformables = bodies.deformables
    assert deformables is not None, "wind pressure acts on cloth: the compiler builds it only for scenes with cloth"
    vertex_map = deformables.vertex_map
    selected = set(range(bodies.count)) if index is None else set(np.asarray(index).tolist())
    cloths = []
    for body in deformables.bodies:
        kinds = vertex_map.kind[body.vertices]
        points = vertex_map.index[body.vertices][kinds == PARTICLE]
        if body.kind == "cloth" and (index is None or selected.intersection(points.tolist())):
            cloths.append(body)
    triangles = np.concatenate([body.triangles for body in cloths]) if cloths else np.zeros((0, 3), np.intp)
    share = triangle_share(triangles, vertex_map.count)
    return Aerodynamics(deformables, triangles, np.asarray(wind, float), np.asarray(gust_amplitude, float),
                        gust_period, density, drag, friction, share, tuple(body.name for body in cloths))
