"""Hooke springs with dampers along their axis, between two bodies or a body and a fixed anchor.

For a spring from end 1 to end 2 with ``L = p1 - p2`` (the attachment points), unit vector ``u = L / |L|``, rest length
``r``, stiffness ``ks`` and damping ``kd`` (lecture notes, spring-damper)::

    f1 = -(ks (|L| - r) + kd (ṗ1 - ṗ2)·u) u,     f2 = -f1

An end on a rigid body may sit at a body point ``r_b`` (body axes, from the centre of mass): it is at
``p = x + R r_b``, moves with ``ṗ = v + ω × (R r_b)``, and its force also gives the torque ``(R r_b) × f``.

All springs are evaluated at once; forces (and torques) are scattered onto bodies with sparse incidence matrices
(one matrix product instead of a Python loop or ``np.add.at``), or, for many springs none of which ends at a body
point, by a compiled loop (:data:`COMPILED_SPRINGS`). A spring of zero length exerts no force (its direction is
undefined).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from animbatch.quaternion import cross
from animbatch.sim.forces.term import ForceJacobian, ForceTerm, Kinematics
from animbatch.sim.motion import AnchorMotion

#: Spring terms with at least this many springs (a 30×30 cloth has 5100) evaluate their forces compiled
#: (:mod:`animbatch.sim.kernels.spring_assembly`) unless ``ANIMBATCH_KERNELS=numpy``: such scenes load numba for their
#: implicit steps anyway, and explicit methods take many steps. Measured on the 64×64 cloth (24 000 springs): a
#: right-hand side in 0.47 ms instead of 1.69 ms.
COMPILED_SPRINGS = 5000


@functools.cache
def build_spring_kernel() -> str | None:
    """Build (or load from numba's disk cache) the compiled spring forces on one spring; None, or what failed."""
    from animbatch.sim.kernels import build_failure

    def build() -> None:
        from animbatch.sim.kernels.spring_assembly import spring_forces

        def frozen(array: np.ndarray) -> np.ndarray:
            array.setflags(write=False)
            return array

        spring_forces(np.zeros((2, 3)), np.zeros((2, 3)), np.array([0]), np.array([1]), np.zeros(1, bool),
                      np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1), np.ones(1), np.ones(1), np.zeros((2, 3)))
        # and as a model calls them: its spring tables are read-only arrays (numba compiles those apart), its fixed
        # anchors too
        for anchors in (frozen(np.zeros((1, 3))), np.zeros((1, 3))):
            spring_forces(np.zeros((2, 3)), np.zeros((2, 3)), frozen(np.array([0])), frozen(np.array([1])),
                          frozen(np.zeros(1, bool)), anchors, np.zeros((1, 3)), frozen(np.ones(1)), frozen(np.ones(1)),
                          frozen(np.ones(1)), np.zeros((2, 3)))

    return build_failure(build)


@dataclass(frozen=True, eq=False)
class SpringSet:
    """Spring topology and constants, shape (S,) each.

    ``first`` indexes bodies (points: particles, then rigid bodies). ``second`` indexes bodies, or anchors where
    ``second_is_anchor`` is true. ``first_offset``/``second_offset`` (S, 3): attachment points in body axes from the
    centre of mass (zero for particles, anchors and ends at a centre of mass). ``mesh`` (S,): springs of a cloth or
    lattice (not drawn by default) rather than the scene's own.
    """

    names: tuple[str, ...]
    first: np.ndarray
    second: np.ndarray
    second_is_anchor: np.ndarray
    stiffness: np.ndarray  # ks [N/m]
    damping: np.ndarray  # kd [N·s/m]
    rest_length: np.ndarray  # r [m]
    first_offset: np.ndarray
    second_offset: np.ndarray
    mesh: np.ndarray | None = None

    @property
    def count(self) -> int:
        return len(self.first)


#: Incidence matrices of at most this many entries are arrays: a few springs' ``p1 − p2`` is then a microsecond's
#: product, where a scipy.sparse product costs some twenty (three of them were most of a small chain's right-hand
#: side under Radau). Their entries are ±1 and 0, so the products are the same to the last bit or two.
DENSE_INCIDENCE = 4096


def _incidence(rows: np.ndarray, signs: np.ndarray, columns: np.ndarray, shape: tuple[int, int]
               ) -> sp.csr_matrix | np.ndarray:
    matrix = sp.csr_matrix((signs, (rows, columns)), shape=shape)
    return matrix.toarray() if shape[0] * shape[1] <= DENSE_INCIDENCE else matrix


def _transposed(matrix: sp.csr_matrix | np.ndarray) -> sp.csr_matrix | np.ndarray:
    return np.ascontiguousarray(matrix.T) if isinstance(matrix, np.ndarray) else matrix.T.tocsr()


@dataclass(frozen=True, eq=False)
class _Attachment:
    """The springs whose end (first or second) sits at a point of a rigid body: which springs, which bodies."""

    springs: np.ndarray  # (K,) spring indices
    rigid: np.ndarray  # (K,) rigid body indices
    offset: np.ndarray  # (K, 3) body axes, from the centre of mass
    torque_scatter: sp.csr_matrix | np.ndarray  # (B, K): +1 at (rigid, k)


def _attachment(ends: np.ndarray, offsets: np.ndarray, on_body: np.ndarray, first_rigid: int,
                rigid_count: int) -> _Attachment | None:
    selected = np.flatnonzero(on_body & (ends >= first_rigid) & np.any(offsets != 0, axis=1))
    if len(selected) == 0:
        return None
    rigid = ends[selected] - first_rigid
    scatter = _incidence(rigid, np.ones(len(selected)), np.arange(len(selected)), (rigid_count, len(selected)))
    return _Attachment(selected, rigid, offsets[selected], scatter)


@dataclass(frozen=True, eq=False)
class SpringForces(ForceTerm):
    """The spring term for a model: all springs at once, with body-point attachments where the scene gives them."""

    kind = "spring"
    has_potential = True

    springs: SpringSet
    anchors: AnchorMotion
    #: (S, P): +1 at (s, first), -1 at (s, second) for the second ends on points, so that one sparse product gives
    #: every spring's ``p1 - p2`` (a pinned 64×64 cloth: 0.2 ms, against 0.9 ms for gathering ends)
    difference: sp.csr_matrix | np.ndarray
    #: (S, A): -1 at (s, anchor) for the springs whose second end is an anchor
    anchor_difference: sp.csr_matrix | np.ndarray
    #: the anchors' share of ``p1 - p2`` (S, 3) [m] when they never move (computed once), else None
    fixed_anchor_difference: np.ndarray | None
    #: (P, S) = differenceᵀ: +1 at (first, s), -1 at (second, s), spring forces onto points
    scatter: sp.csr_matrix | np.ndarray
    first_attachment: _Attachment | None
    second_attachment: _Attachment | None

    @classmethod
    def build(cls, springs: SpringSet, anchors: AnchorMotion, point_count: int, first_rigid: int) -> SpringForces:
        s = np.arange(springs.count)
        to_body = ~springs.second_is_anchor
        rigid_count = point_count - first_rigid
        difference = _incidence(np.concatenate([s, s[to_body]]),
                                np.concatenate([np.ones(springs.count), -np.ones(int(to_body.sum()))]),
                                np.concatenate([springs.first, springs.second[to_body]]),
                                (springs.count, point_count))
        anchored = np.flatnonzero(springs.second_is_anchor)
        anchor_difference = _incidence(anchored, -np.ones(len(anchored)), springs.second[anchored],
                                       (springs.count, anchors.count))
        fixed = (anchor_difference @ anchors.positions(0.0) if anchors.count and not anchors.moving else None)
        return cls(springs, anchors, difference, anchor_difference, fixed, _transposed(difference),
                   _attachment(springs.first, springs.first_offset, np.ones(springs.count, bool), first_rigid,
                               rigid_count),
                   _attachment(springs.second, springs.second_offset, to_body, first_rigid, rigid_count))

    def _levers(self, state: Kinematics, attachment: _Attachment | None) -> np.ndarray | None:
        """World vectors from each spring end's centre of mass to its attachment point, (S, 3), or None."""
        if attachment is None:
            return None
        levers = np.zeros((self.springs.count, 3))
        levers[attachment.springs] = state.lever(attachment.rigid, attachment.offset)
        return levers

    def _differences(self, state: Kinematics
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
        """``L = p1 - p2`` and ``ṗ1 - ṗ2`` between the attachment points of every spring (S, 3) each, and the levers
        of both ends (or None)."""
        axis, relative = self.difference @ state.x, self.difference @ state.v
        if self.fixed_anchor_difference is not None:
            axis += self.fixed_anchor_difference
        elif self.anchors.count:  # moving anchors: where they are now, and how fast
            axis += self.anchor_difference @ self.anchors.positions(state.t)
            relative += self.anchor_difference @ self.anchors.velocities(state.t)
        lever1, lever2 = self._levers(state, self.first_attachment), self._levers(state, self.second_attachment)
        for lever, attachment, sign in ((lever1, self.first_attachment, 1.0), (lever2, self.second_attachment, -1.0)):
            if lever is not None:
                assert attachment is not None and state.omega is not None
                k = attachment.springs
                axis[k] += sign * lever[k]
                relative[k] += sign * cross(state.omega[attachment.rigid], lever[k])
        return axis, relative, lever1, lever2

    def spring_forces(self, state: Kinematics) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Force on each spring's first end ``f1`` [N] (S, 3), and the levers of both ends (or None)."""
        springs = self.springs
        axis, relative, lever1, lever2 = self._differences(state)  # L, ṗ1 - ṗ2
        length = np.sqrt(np.einsum("ij,ij->i", axis, axis))
        unit = np.divide(axis, length[:, None], out=np.zeros_like(axis), where=length[:, None] > 0)
        closing = np.einsum("ij,ij->i", relative, unit)  # (ṗ1 - ṗ2)·u
        magnitude = springs.stiffness * (length - springs.rest_length) + springs.damping * closing
        return -magnitude[:, None] * unit, lever1, lever2

    @functools.cached_property
    def compiled(self) -> bool:
        """Whether :meth:`accumulate` runs compiled (:func:`animbatch.sim.kernels.spring_assembly.spring_forces`): for
        :data:`COMPILED_SPRINGS` springs or more, none of them at a body point, where the kernels load."""
        from animbatch.sim.kernels import MIN_WORK, kernels_ready

        if self.first_attachment is not None or self.second_attachment is not None:
            return False
        return kernels_ready(MIN_WORK if self.springs.count >= COMPILED_SPRINGS else 0.0, build_spring_kernel,
                             "spring forces", "numpy evaluates the springs")

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        if self.compiled:
            from animbatch.sim.kernels.spring_assembly import spring_forces

            springs, anchors = self.springs, self.anchors
            anchor_x = anchors.positions(state.t) if anchors.count else np.zeros((1, 3))
            anchor_v = anchors.velocities(state.t) if anchors.count and anchors.moving else np.zeros_like(anchor_x)
            spring_forces(state.x, state.v, springs.first, springs.second, springs.second_is_anchor, anchor_x,
                          anchor_v, springs.stiffness, springs.damping, springs.rest_length, force)
            return
        f1, lever1, lever2 = self.spring_forces(state)
        force += self.scatter @ f1
        for lever, attachment, sign in ((lever1, self.first_attachment, 1.0), (lever2, self.second_attachment, -1.0)):
            if lever is not None:
                assert torque is not None and attachment is not None
                k = attachment.springs
                torque += attachment.torque_scatter @ cross(lever[k], sign * f1[k])

    def jacobian(self, t: float, state: Kinematics, out: ForceJacobian) -> bool:
        """Exact derivatives of the spring-damper forces on particle ends. With ``u = L/l``, ``P = I - u uᵀ``,
        ``w = ṗ1 - ṗ2`` and ``m = ks (l - r) + kd w·u`` (so ``f1 = -m u``)::

            ∂f1/∂p1 = -ks u uᵀ - (kd / l) u (P w)ᵀ - (m / l) P,      ∂f1/∂ṗ1 = -kd u uᵀ

        and ``∂f1/∂p2 = -∂f1/∂p1``, ``∂f2/∂p2 = ∂f1/∂p1`` (likewise for velocities). Ends on rigid bodies and
        anchors have no particle columns; a particle end still gets its own block.

        Definite form (``out.definite``, Choi & Ko 2002): ``∂f1/∂p1 = -ks (u uᵀ + max(0, 1 - r / l) P)``, without the
        damper's dependence on position: a compressed spring then stiffens nothing sideways (it would buckle).
        """
        springs = self.springs
        axis, relative, _, _ = self._differences(state)
        if out.compiled:
            from animbatch.sim.kernels.spring_assembly import spring_blocks

            dfdx, dfdv = spring_blocks(axis, relative, springs.stiffness, springs.damping, springs.rest_length,
                                       out.definite)
        else:
            dfdx, dfdv = self._blocks(axis, relative, out.definite)
        n = state.first_rigid
        first, second = springs.first, springs.second
        first_particle = first < n
        second_particle = ~springs.second_is_anchor & (second < n)
        both = first_particle & second_particle
        if both.all():  # a cloth or lattice: no copies
            out.add_pairs(first, second, dfdx, dfdv)
            return True
        out.add_pairs(first[both], second[both], dfdx[both], dfdv[both])
        for end, alone in ((first, first_particle & ~both), (second, second_particle & ~both)):
            out.add(end[alone], end[alone], dfdx[alone], dfdv[alone])
        return True

    def _blocks(self, axis: np.ndarray, relative: np.ndarray, definite: bool) -> tuple[np.ndarray, np.ndarray]:
        """``∂f1/∂p1`` and ``∂f1/∂ṗ1`` (S, 3, 3) of every spring (see :meth:`jacobian`), in numpy."""
        springs = self.springs
        length = np.sqrt(np.einsum("ij,ij->i", axis, axis))
        safe = np.maximum(length, 1e-12)
        unit = axis / safe[:, None]
        along = np.einsum("ij,ij->i", relative, unit)
        magnitude = springs.stiffness * (length - springs.rest_length) + springs.damping * along
        outer = unit[:, :, None] * unit[:, None, :]
        across = np.eye(3) - outer  # P
        across_relative = relative - along[:, None] * unit  # P w
        if definite:
            stretch = np.maximum(0.0, 1.0 - springs.rest_length / safe)
            dfdx = -springs.stiffness[:, None, None] * (outer + stretch[:, None, None] * across)
        else:
            dfdx = (-springs.stiffness[:, None, None] * outer
                    - (springs.damping / safe)[:, None, None] * unit[:, :, None] * across_relative[:, None, :]
                    - (magnitude / safe)[:, None, None] * across)
        dfdv = -springs.damping[:, None, None] * outer
        degenerate = length < 1e-12  # no direction: treat as a zero-length spring, f = -ks L - kd L̇
        dfdx[degenerate] = -springs.stiffness[degenerate, None, None] * np.eye(3)
        dfdv[degenerate] = -springs.damping[degenerate, None, None] * np.eye(3)
        return dfdx, dfdv

    def potential_energy(self, state: Kinematics) -> float:
        """Elastic energy ½ ks (|L| - r)² summed over springs [J] (dampers store none)."""
        axis, _, _, _ = self._differences(state)
        length = np.linalg.norm(axis, axis=1)
        return float(0.5 * np.sum(self.springs.stiffness * (length - self.springs.rest_length) ** 2))

    @property
    def dissipative(self) -> bool:
        return bool(np.any(self.springs.damping))

    @property
    def adds_energy(self) -> bool:
        """Springs to moving anchors can pump energy in."""
        springs = self.springs
        return any(int(a) in self.anchors.paths for a in springs.second[springs.second_is_anchor])

    def describe(self) -> str:
        springs = self.springs
        anchored = int(springs.second_is_anchor.sum())
        parts = f"{springs.count - anchored} body–body, {anchored} body–anchor"
        attached = sum(len(a.springs) for a in (self.first_attachment, self.second_attachment) if a is not None)
        points = f", {attached} end{'s' if attached != 1 else ''} at body points" if attached else ""
        k = f"ks {springs.stiffness.min():g}…{springs.stiffness.max():g} N/m"
        c = f"kd {springs.damping.min():g}…{springs.damping.max():g} N·s/m"
        return f"{springs.count} spring{'s' if springs.count != 1 else ''} ({parts}{points}), {k}, {c}"
