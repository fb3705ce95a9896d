"""Dihedral angle springs: bending resistance of cloth, one angular spring per interior edge (lecture notes).

For an interior edge ``a → b`` with the vertex ``c`` opposite it in the first triangle and ``d`` in the second, θ is
the signed angle between the triangles' normals ``n1 = (b - a) × (c - a)`` and ``n2 = (a - b) × (d - b)`` (zero when
the two triangles are flat). The spring's energy is ``½ k (θ - θ₀)²``, with θ₀ the angle at the start, and a damper
opposes ``θ̇``; each vertex feels

    f_i = -(k (θ - θ₀) + c θ̇) ∂θ/∂x_i,       θ̇ = Σ_i ∂θ/∂x_i · v_i

with the gradients (Bridson, Marino & Fedkiw 2003; checked against finite differences in the tests)::

    ∂θ/∂c = -|e| n1 / |n1|²,   ∂θ/∂d = -|e| n2 / |n2|²,   e = b - a,
    ∂θ/∂a = ((c - b)·ê / |e|) ∂θ/∂c + ((d - b)·ê / |e|) ∂θ/∂d,   ∂θ/∂b = -(∂θ/∂a + ∂θ/∂c + ∂θ/∂d).

The forces sum to zero and exert no net torque, so bending never pushes a cloth around.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from animbatch.quaternion import cross
from animbatch.sim.deformable.vertices import PARTICLE, DeformableSet
from animbatch.sim.forces.term import ForceJacobian, ForceTerm, Kinematics


def hinge_angles(x: np.ndarray) -> np.ndarray:
    """Signed dihedral angles θ (H,) [rad] of hinges with vertex positions ``x`` (H, 4, 3) ordered a, b, c, d."""
    a, b, c, d = x[:, 0], x[:, 1], x[:, 2], x[:, 3]
    edge = b - a
    n1, n2 = cross(edge, c - a), cross(a - b, d - b)
    length = np.sqrt(np.einsum("ij,ij->i", edge, edge))
    sine = np.einsum("ij,ij->i", cross(n1, n2), edge) / length
    return np.arctan2(sine, np.einsum("ij,ij->i", n1, n2))


def hinge_gradients(x: np.ndarray) -> np.ndarray:
    """∂θ/∂x of each hinge's four vertices, (H, 4, 3) [rad/m]."""
    a, b, c, d = x[:, 0], x[:, 1], x[:, 2], x[:, 3]
    edge = b - a
    length = np.sqrt(np.einsum("ij,ij->i", edge, edge))
    unit = edge / length[:, None]
    n1, n2 = cross(edge, c - a), cross(a - b, d - b)
    grad_c = -(length / np.einsum("ij,ij->i", n1, n1))[:, None] * n1
    grad_d = -(length / np.einsum("ij,ij->i", n2, n2))[:, None] * n2
    grad_a = ((np.einsum("ij,ij->i", c - b, unit) / length)[:, None] * grad_c
              + (np.einsum("ij,ij->i", d - b, unit) / length)[:, None] * grad_d)
    grad_b = -(grad_a + grad_c + grad_d)
    return np.stack([grad_a, grad_b, grad_c, grad_d], axis=1)


def wrapped(angle: np.ndarray) -> np.ndarray:
    """An angle difference brought into (-π, π] (a hinge folding through ±π is the same fold)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True, eq=False)
class DihedralSprings(ForceTerm):
    """All dihedral angle springs of the model's cloths."""

    kind = "dihedral"
    has_potential = True

    deformables: DeformableSet
    hinges: np.ndarray  # (H, 4) vertex indices a, b, c, d
    stiffness: np.ndarray  # (H,) [N·m/rad]
    damping: np.ndarray  # (H,) [N·m·s/rad]
    rest_angle: np.ndarray  # (H,) [rad]
    gather: sp.csr_matrix  # (V, 4H): scatters per-hinge-vertex forces onto vertices

    @classmethod
    def build(cls, deformables: DeformableSet, settings: list[tuple[float, float] | None]) -> DihedralSprings:
        """The term for the deformables whose ``settings`` (per body: (k, c) or None) ask for dihedral springs;
        rest angles are the angles at the start."""
        hinges, stiffness, damping = [], [], []
        for body, setting in zip(deformables.bodies, settings):
            if setting is None or not len(body.hinges):
                continue
            hinges.append(body.hinges)
            stiffness.append(np.full(len(body.hinges), setting[0]))
            damping.append(np.full(len(body.hinges), setting[1]))
        hinge_array = np.concatenate(hinges) if hinges else np.zeros((0, 4), np.intp)
        vertex_map = deformables.vertex_map
        count = len(hinge_array)
        gather = sp.csr_matrix((np.ones(4 * count), (hinge_array.ravel(), np.arange(4 * count))),
                               shape=(vertex_map.count, 4 * count))
        start = cls._initial_positions(deformables)[hinge_array]
        return cls(deformables, hinge_array, np.concatenate(stiffness) if stiffness else np.zeros(0),
                   np.concatenate(damping) if damping else np.zeros(0), hinge_angles(start), gather)

    @staticmethod
    def _initial_positions(deformables: DeformableSet) -> np.ndarray:
        """Vertex positions at the start, from the rest data the vertex map was built from."""
        return deformables.initial_positions

    def hinge_forces(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Forces (H, 4, 3) [N] on each hinge's vertices for their positions and velocities (H, 4, 3)."""
        gradient = hinge_gradients(x)
        rate = np.einsum("hki,hki->h", gradient, v)
        magnitude = self.stiffness * wrapped(hinge_angles(x) - self.rest_angle) + self.damping * rate
        return -magnitude[:, None, None] * gradient

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        vertices = self.deformables.vertex_map
        x, v = vertices.positions_velocities(state, self.deformables.anchors)
        forces = self.hinge_forces(x[self.hinges], v[self.hinges])
        vertices.scatter(self.gather @ forces.reshape(-1, 3), state, force, torque)

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """Derivatives on particle vertices. ``∂f_i/∂v_k = -c ∂θ/∂x_i ∂θ/∂x_kᵀ`` exactly; ``∂f/∂x`` by central
        differences within each hinge (12 × 12 per hinge, 24 vectorised evaluations of the hinge forces, step
        1e-6 of the edge length): the exact form needs the Hessian of θ, and these blocks agree with it to about
        1e-8 relative.

        Definite form (``out.definite``): the Gauss–Newton part ``∂f_i/∂x_k = -k ∂θ/∂x_i ∂θ/∂x_kᵀ`` only (the
        part with ``(θ - θ₀)`` times the Hessian of θ is indefinite)."""
        vertices = self.deformables.vertex_map
        x, v = vertices.positions_velocities(state, self.deformables.anchors)
        hinge_x, hinge_v = x[self.hinges], v[self.hinges]
        gradient = hinge_gradients(hinge_x)
        outer = np.einsum("hia,hkb->hiakb", gradient, gradient)
        dfdv = -self.damping[:, None, None, None, None] * outer
        if out.definite:
            dfdx = -self.stiffness[:, None, None, None, None] * outer
        else:
            dfdx = self._position_derivatives(hinge_x, hinge_v)
        kind, index = vertices.kind[self.hinges], vertices.index[self.hinges]
        for i in range(4):
            for k in range(4):
                both = (kind[:, i] == PARTICLE) & (kind[:, k] == PARTICLE)
                out.add(index[both, i], index[both, k], dfdx[both, i, :, k, :], dfdv[both, i, :, k, :])
        return True

    def _position_derivatives(self, hinge_x: np.ndarray, hinge_v: np.ndarray) -> np.ndarray:
        """∂f/∂x of every hinge's forces by central differences within the hinge, (H, 4, 3, 4, 3)."""
        step = 1e-6 * np.linalg.norm(hinge_x[:, 1] - hinge_x[:, 0], axis=1)  # (H,)
        dfdx = np.empty((len(self.hinges), 4, 3, 4, 3))
        for k in range(4):
            for axis in range(3):
                shifted = hinge_x.copy()
                shifted[:, k, axis] += step
                ahead = self.hinge_forces(shifted, hinge_v)
                shifted[:, k, axis] -= 2 * step
                behind = self.hinge_forces(shifted, hinge_v)
                dfdx[:, :, :, k, axis] = (ahead - behind) / (2 * step)[:, None, None]
        return dfdx

    def potential_energy(self, state: Kinematics) -> float:
        vertices = self.deformables.vertex_map
        x, _ = vertices.positions_velocities(state, self.deformables.anchors)
        bend = wrapped(hinge_angles(x[self.hinges]) - self.rest_angle)
        return float(0.5 * np.sum(self.stiffness * bend**2))

    @property
    def dissipative(self) -> bool:
        return bool(np.any(self.damping))

    def describe(self) -> str:
        return (f"{len(self.hinges)} hinges, k {self.stiffness.min(initial=0):g}…{self.stiffness.max(initial=0):g} "
                f"N·m/rad, c {self.damping.min(initial=0):g}…{self.damping.max(initial=0):g} N·m·s/rad")
