"""Pressure inside closed cloths and lattices: F = P·A on every surface triangle, along its outward normal.

A triangle ``(a, b, c)`` wound counter-clockwise seen from outside has ``N = (b − a) × (c − a)`` = 2 A n, and the
gauge pressure ``p = P − P_outside`` pushes each of its vertices with ``p N / 6`` (a third of ``p A n``). Summed
around a vertex this is ``p ∂V/∂x`` for the enclosed volume ``V = Σ a·(b × c) / 6``: the force is the gradient of
``p V``, so a closed surface feels no net force and no net torque from it.

The gauge ``p`` of each body is held, follows keyframes (linear between them), or comes from a gas at constant
temperature: ``P V = P₀ V₀`` (absolute pressures), ``p = P₀ V₀ / V − P_outside``. Held and gas pressures have a
potential: ``U = −p (V − V₀)`` held, ``U = −P₀ V₀ ln(V / V₀) + P_outside (V − V₀)`` for the gas (its work on the
surroundings included), both 0 at the start.

Implicit methods: Radau and BDF get the exact derivatives of the held part, ``∂f_k/∂x_j = (p/6) [d_j]×`` for each
vertex ``k`` of a triangle and ``d_a = c − b``, ``d_b = a − c``, ``d_c = b − a`` (the gas's ``∂p/∂x`` couples every
vertex of a body with every other, a dense block, and is left to the Newton iterations). Backward Euler's definite
form has no place for them (``p ∂²V/∂x²`` is indefinite), so it treats pressure explicitly: stable while a step is
short next to the gas's breathing (:meth:`Pressure.time_scale`, which the pre-flight and the cost estimate read).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from animbatch.sim.deformable.topology import enclosed_volumes
from animbatch.sim.deformable.vertices import PARTICLE, DeformableSet, triangle_share
from animbatch.sim.forces.term import BodyTable, ForceJacobian, ForceTerm, Kinematics, TimeScale


@dataclass(frozen=True)
class PressureSetting:
    """One body's pressure: ``gauge`` [Pa] held (or the gas's at the start), or along keyframes ``times`` [s] and
    ``values`` [Pa]; ``gas``: P V constant, with ``outside`` [Pa] the absolute pressure around it."""

    gauge: float = 0.0
    times: np.ndarray | None = None
    values: np.ndarray | None = None
    gas: bool = False
    outside: float = 101325.0


@dataclass(frozen=True, eq=False)
class Pressure(ForceTerm):
    """Pressure on the closed surfaces of the bodies ``names`` (B of them)."""

    kind = "pressure"
    has_potential = True

    deformables: DeformableSet
    triangles: np.ndarray  # (T, 3) vertex-map indices, wound counter-clockwise seen from outside
    owner: np.ndarray  # (T,) which of the B bodies each triangle bounds
    names: tuple[str, ...]
    settings: tuple[PressureSetting, ...]  # (B,)
    start_volume: np.ndarray  # (B,) [m³]
    share: sp.csr_matrix  # (V, T): 1/3 at each triangle's three vertices

    @property
    def adds_energy(self) -> bool:
        return any(setting.times is not None for setting in self.settings)  # a pump does work

    def volumes(self, x: np.ndarray) -> np.ndarray:
        """Each body's enclosed volume [m³] (B,) for vertex positions ``x`` (V, 3)."""
        return enclosed_volumes(x, self.triangles, self.owner, len(self.names))

    def gauges(self, t: float, volumes: np.ndarray) -> np.ndarray:
        """Each body's gauge pressure [Pa] (B,) at time ``t`` [s] and ``volumes`` [m³] (B,)."""
        gauge = np.empty(len(self.names))
        for b, setting in enumerate(self.settings):
            if setting.times is not None:
                assert setting.values is not None
                gauge[b] = np.interp(t, setting.times, setting.values)
            elif setting.gas:
                gauge[b] = (setting.outside + setting.gauge) * self.start_volume[b] / volumes[b] - setting.outside
            else:
                gauge[b] = setting.gauge
        return gauge

    def _positions(self, state: Kinematics) -> np.ndarray:
        vertices = self.deformables.vertex_map
        return vertices.place(state.x, state.rotation, self.deformables.anchors.positions(state.t))

    def face_forces(self, x: np.ndarray, t: float) -> np.ndarray:
        """Force on each triangle [N] (T, 3): ``p A n``."""
        a, b, c = (x[self.triangles[:, k]] for k in range(3))
        gauge = self.gauges(t, self.volumes(x))
        return 0.5 * gauge[self.owner, None] * np.cross(b - a, c - a)

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        x = self._positions(state)
        self.deformables.vertex_map.scatter(self.share @ self.face_forces(x, t), state, force, torque)

    def potential_energy(self, state: Kinematics) -> float:
        volumes = self.volumes(self._positions(state))
        total = 0.0
        for b, setting in enumerate(self.settings):
            grown = volumes[b] - self.start_volume[b]
            if setting.gas:
                absolute = (setting.outside + setting.gauge) * self.start_volume[b]
                total += -absolute * np.log(volumes[b] / self.start_volume[b]) + setting.outside * grown
            elif setting.times is None:  # a pump's work has no potential (adds_energy says so)
                total += -setting.gauge * grown
        return float(total)

    def energy_scale(self, size: float) -> float:
        """The work a gauge can do on its volume: |p| V₀ (for a gas, its absolute pressure's)."""
        return float(max((abs(s.outside + s.gauge) if s.gas else abs(s.gauge)) * v
                         for s, v in zip(self.settings, self.start_volume)))

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        if out.definite:  # p ∂²V/∂x² is indefinite: backward Euler treats pressure explicitly
            return False
        x = self._positions(state)
        gauge = self.gauges(t, self.volumes(x))[self.owner]
        a, b, c = (x[self.triangles[:, k]] for k in range(3))
        sides = (c - b, a - c, b - a)  # d_j: ∂N/∂x_j = [d_j]×
        vertices = self.deformables.vertex_map
        kind, index = vertices.kind[self.triangles], vertices.index[self.triangles]
        for j in range(3):
            block = (gauge / 6)[:, None, None] * _cross_matrices(sides[j])
            for k in range(3):
                both = (kind[:, k] == PARTICLE) & (kind[:, j] == PARTICLE)
                out.add(index[both, k], index[both, j], dfdx=block[both])
        return True

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        """A gas's breathing: along the mode ``u = g / |g|`` (``g = ∂V/∂x``, every vertex moving to grow the
        volume) the stiffness is ``−dP/dV |g|² = (P/V) |g|²`` and the mass ``Σ m_k |g_k|² / |g|²``, so
        ``ω² = (P/V) |g|⁴ / Σ m_k |g_k|²`` (P absolute). The fastest body's; None without a gas."""
        if not any(setting.gas for setting in self.settings):
            return None
        x = self._positions(state)
        volumes = self.volumes(x)
        a, b, c = (x[self.triangles[:, k]] for k in range(3))
        gradient = self.share @ (np.cross(b - a, c - a) / 2)  # ∂V/∂x (V, 3) = Σ N / 6 over a vertex's triangles
        vertices = self.deformables.vertex_map
        free = vertices.kind == PARTICLE
        mass = np.zeros(vertices.count)
        mass[free] = bodies.mass[vertices.index[free]]
        fastest, which = 0.0, ""
        for body, setting in enumerate(self.settings):
            if not setting.gas:
                continue
            mine = np.zeros(vertices.count, bool)
            mine[np.unique(self.triangles[self.owner == body])] = True
            mine &= free
            squared = np.einsum("ij,ij->i", gradient[mine], gradient[mine])
            moved = float(np.sum(mass[mine] * squared))
            if moved <= 0:
                continue
            absolute = (setting.outside + setting.gauge) * self.start_volume[body] / volumes[body]
            rate = float(np.sqrt(absolute / volumes[body] * squared.sum() ** 2 / moved))
            if rate > fastest:
                fastest, which = rate, self.names[body]
        if not fastest:
            return None
        return TimeScale(fastest, f"gas in {which!r} breathing (period {2 * np.pi / fastest:.3g} s)", turns=True,
                         explicit=True)

    def describe(self) -> str:
        parts = []
        for name, setting, volume in zip(self.names, self.settings, self.start_volume):
            if setting.times is not None:
                how = f"gauge along {len(setting.times)} keyframes"
            elif setting.gas:
                how = f"gas at {setting.gauge:g} Pa gauge, P V = const (outside {setting.outside:g} Pa)"
            else:
                how = f"gauge {setting.gauge:g} Pa"
            parts.append(f"{name}: {how}, V₀ {volume:.4g} m³")
        return f"{len(self.triangles)} triangles; " + "; ".join(parts)


def _cross_matrices(vectors: np.ndarray) -> np.ndarray:
    """``[d]×`` (K, 3, 3) with ``[d]× u = d × u`` for each row ``d`` of ``vectors`` (K, 3)."""
    out = np.zeros((len(vectors), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -vectors[:, 2], vectors[:, 1]
    out[:, 1, 0], out[:, 1, 2] = vectors[:, 2], -vectors[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -vectors[:, 1], vectors[:, 0]
    return out


def build_pressure(deformables: DeformableSet, settings: dict[str, PressureSetting]) -> Pressure:
    """The pressure term of the bodies named in ``settings``; their surfaces must be closed (the compiler checks),
    and are wound outward here (a surface enclosing a negative volume is turned over)."""
    names = tuple(body.name for body in deformables.bodies if body.name in settings)
    chosen = [deformables.body(name) for name in names]
    owner = np.concatenate([np.full(len(body.triangles), b) for b, body in enumerate(chosen)])
    triangles = np.concatenate([body.triangles for body in chosen]).copy()
    x = deformables.initial_positions
    inward = enclosed_volumes(x, triangles, owner, len(names)) < 0
    flip = inward[owner]
    triangles[flip] = triangles[flip][:, [0, 2, 1]]
    volumes = enclosed_volumes(x, triangles, owner, len(names))
    share = triangle_share(triangles, deformables.vertex_map.count)
    return Pressure(deformables, triangles, owner, names, tuple(settings[name] for name in names), volumes, share)
