"""Force Jacobians: the 3×3 blocks force terms give, and the sparse matrices implicit methods build from them.

Implicit integration (backward Euler, Radau, BDF) needs ``∂f/∂x`` and ``∂f/∂v`` of the forces on the particles; the
terms add them block by block (:meth:`ForceTerm.jacobian <animbatch.sim.forces.term.ForceTerm.jacobian>`) into a
:class:`ForceJacobian`, which assembles sparse matrices of a pattern worked out once and reused at every step
(:class:`BlockPattern`, :class:`StepPattern`). Backward Euler's whole step matrix ``M − h D − h² K`` and the
product ``K v`` can be assembled by compiled kernels (:mod:`animbatch.sim.kernels.spring_assembly`) straight from the
blocks; the numpy path builds the two matrices and sums them.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class BlockPattern:
    """Where each entry of a list of 3×3 blocks at particle pairs ``(i, j)`` (K,) lands in a (3N, 3N) CSR matrix.

    Implicit methods assemble a matrix of the same pattern at every step; working the pattern out once and then only
    summing values into their slots is several times faster than building a COO matrix and converting it each time.
    """

    def __init__(self, i: np.ndarray, j: np.ndarray, size: int) -> None:
        self.i, self.j, self.size = i, j, size
        axis = np.arange(3)
        # entry [k, a, b] of block k sits at row 3 i_k + a, column 3 j_k + b
        rows = np.broadcast_to(3 * i[:, None, None] + axis[None, :, None], (len(i), 3, 3)).ravel()
        cols = np.broadcast_to(3 * j[:, None, None] + axis[None, None, :], (len(j), 3, 3)).ravel()
        keys = rows.astype(np.int64) * size + cols
        unique, self.slot = np.unique(keys, return_inverse=True)  # sorted by row, then column: CSR order
        self.indices = (unique % size).astype(np.int32)
        self.indptr = np.searchsorted(unique // size, np.arange(size + 1)).astype(np.int32)

    def matches(self, i: np.ndarray, j: np.ndarray) -> bool:
        return np.array_equal(i, self.i) and np.array_equal(j, self.j)

    def assemble(self, data: np.ndarray) -> sp.csr_matrix:
        values = np.bincount(self.slot, weights=data, minlength=len(self.indices))  # repeated pairs add up
        return sp.csr_matrix((values, self.indices, self.indptr), shape=(self.size, self.size))


#: A part of a Jacobian as the step-matrix pattern sees it: ("plain", i, j) blocks at (i, j), or ("pairs", i, j)
#: pairs of particles (see :meth:`ForceJacobian.add_pairs`).
PartLayout = tuple[str, np.ndarray, np.ndarray]


def _block_keys(i: np.ndarray, j: np.ndarray, size: int) -> np.ndarray:
    """Flat positions ``row · size + column`` (K, 9) of the entries of 3×3 blocks at particle pairs ``(i, j)``."""
    axis = np.arange(3)
    rows = 3 * i[:, None, None] + axis[None, :, None]
    cols = 3 * j[:, None, None] + axis[None, None, :]
    return (rows.astype(np.int64) * size + cols).reshape(len(i), 9)


class StepPattern:
    """The sparsity of backward Euler's ``M − h D − h² K`` for a list of Jacobian parts (:data:`PartLayout`), and
    where each part's entries and the masses land in its CSR data: ``slots[p]`` (K, 9) for a plain part, (K, 36)
    for pairs (their (i, i), (j, j), (i, j) and (j, i) blocks), ``diagonal`` (3N,)."""

    def __init__(self, layout: list[PartLayout], particles: int) -> None:
        self.layout = layout
        size = 3 * particles
        keys = []
        for kind, i, j in layout:
            if kind == "plain":
                keys.append(_block_keys(i, j, size))
            else:
                keys.append(np.concatenate([_block_keys(i, i, size), _block_keys(j, j, size),
                                            _block_keys(i, j, size), _block_keys(j, i, size)], axis=1))
        diagonal = np.arange(size, dtype=np.int64) * (size + 1)
        unique, slot = np.unique(np.concatenate([k.ravel() for k in keys] + [diagonal]), return_inverse=True)
        self.indices = (unique % size).astype(np.int32)
        self.indptr = np.searchsorted(unique // size, np.arange(size + 1)).astype(np.int32)
        self.size = size
        self.slots = []
        offset = 0
        for k in keys:
            self.slots.append(slot[offset: offset + k.size].reshape(k.shape).astype(np.int64))
            offset += k.size
        self.diagonal = slot[offset:].astype(np.int64)

    def matches(self, layout: list[PartLayout]) -> bool:
        return len(layout) == len(self.layout) and all(
            a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])
            for a, b in zip(layout, self.layout))



#: Backward Euler's step matrices of at most this many unknowns (3 per particle) are assembled and factored as
#: arrays (:meth:`ForceJacobian.step_matrix`): a dense factorisation of 150 unknowns costs some 100 µs, less than
#: scipy.sparse's assembly of a matrix of a few particles.
DENSE_STEP_UNKNOWNS = 150


class ForceJacobian:
    """The derivatives of the forces on the N particles: ``∂f/∂x`` and ``∂f/∂v``, (3N, 3N) each, gathered from the
    terms as 3×3 blocks ``(i, j)`` = the derivative of the force on particle i with respect to particle j.

    Implicit integration (backward Euler, Radau, BDF) needs them: a stiff spring's force changes a lot when its ends
    move, and an implicit step takes that change into account. Rigid bodies are not part of this matrix (they are
    stepped explicitly by the implicit methods, see :mod:`animbatch.sim.integrators.implicit`).

    With ``definite``, terms give instead the nearest *definite* derivatives: ``∂f/∂x`` and ``∂f/∂v`` symmetric and
    negative semi-definite. The exact ``∂f/∂x`` of a compressed spring or a bent hinge is indefinite, and a
    linearised backward Euler step built on it can land far off (energy growing ten-thousandfold on a falling cloth);
    built on the definite one, ``M - h ∂f/∂v - h² ∂f/∂x`` is symmetric positive definite and the step damps.
    Newton-type solvers (Radau, BDF) want the exact ones.

    ``patterns``: a dict kept by the caller between evaluations, in which the matrices' sparsity patterns are
    remembered (see :class:`BlockPattern`).
    """

    def __init__(self, particles: int, *, definite: bool = False,
                 patterns: dict[str, BlockPattern | StepPattern] | None = None, compiled: bool = False) -> None:
        self.particles = particles
        self.definite = definite
        #: whether terms and assembly may use the compiled kernels (numba known to load; see
        #: :mod:`animbatch.sim.kernels.spring_assembly`)
        self.compiled = compiled
        self._patterns = patterns if patterns is not None else {}
        self._blocks: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {"x": [], "v": []}
        self._pairs: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {"x": [], "v": []}

    def add(self, i: np.ndarray, j: np.ndarray, dfdx: np.ndarray | None = None, dfdv: np.ndarray | None = None) -> None:
        """Add blocks (K, 3, 3) at particle pairs ``(i, j)`` (K,) (repeated pairs add up)."""
        for name, blocks in (("x", dfdx), ("v", dfdv)):
            if blocks is not None and len(i):
                self._blocks[name].append((np.asarray(i, np.intp), np.asarray(j, np.intp), blocks))

    def add_pairs(self, first: np.ndarray, second: np.ndarray, dfdx: np.ndarray | None = None,
                  dfdv: np.ndarray | None = None) -> None:
        """Add the four blocks of a spring or damper between particles ``first[k]`` and ``second[k]`` (K,): ``B`` at
        (i, i) and (j, j), ``−B`` at (i, j) and (j, i), for ``B`` = ``dfdx[k]``, ``dfdv[k]`` (K, 3, 3)."""
        for name, blocks in (("x", dfdx), ("v", dfdv)):
            if blocks is not None and len(first):
                self._pairs[name].append((np.asarray(first, np.intp), np.asarray(second, np.intp), blocks))

    def _plain_blocks(self, which: str) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Every block of ``which``, pairs written out as their four blocks."""
        parts = list(self._blocks[which])
        for first, second, blocks in self._pairs[which]:
            parts += [(first, first, blocks), (second, second, blocks), (first, second, -blocks),
                      (second, first, -blocks)]
        return parts

    def matrix(self, which: str) -> sp.csr_matrix:
        """``∂f/∂x`` (``which='x'``) or ``∂f/∂v`` (``'v'``) as a sparse (3N, 3N) matrix."""
        size = 3 * self.particles
        parts = self._plain_blocks(which)
        if not parts:
            return sp.csr_matrix((size, size))
        i = np.concatenate([i for i, _, _ in parts])
        j = np.concatenate([j for _, j, _ in parts])
        pattern = self._patterns.get(which)
        if not isinstance(pattern, BlockPattern) or not pattern.matches(i, j):
            pattern = self._patterns[which] = BlockPattern(i, j, size)
        return pattern.assemble(np.concatenate([blocks.ravel() for _, _, blocks in parts]))

    def _parts(self) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, str]]:
        """(kind, i, j, blocks, which) of every part."""
        return [(kind, i, j, blocks, which)
                for which in ("x", "v")
                for kind, table in (("plain", self._blocks), ("pairs", self._pairs))
                for i, j, blocks in table[which]]

    def step_matrix(self, mass: np.ndarray, h: float) -> sp.csr_matrix | np.ndarray:
        """Backward Euler's ``M − h ∂f/∂v − h² ∂f/∂x`` (3N, 3N), for masses ``mass`` (3N,) [kg] per velocity
        component and a step ``h`` [s]: with :attr:`compiled`, scattered straight from the blocks into a pattern
        worked out once (:class:`StepPattern`); for a few particles (:data:`DENSE_STEP_UNKNOWNS`), as an array;
        otherwise as a sum of sparse matrices."""
        if not self.compiled and 3 * self.particles <= DENSE_STEP_UNKNOWNS:
            return self._dense_step_matrix(mass, h)
        if not self.compiled:
            return sp.csr_matrix(sp.diags(mass) - h * self.matrix("v") - (h * h) * self.matrix("x"))
        from animbatch.sim.kernels.spring_assembly import scatter_pairs, scatter_plain

        parts = self._parts()
        layout: list[PartLayout] = [(kind, i, j) for kind, i, j, _, _ in parts]
        pattern = self._patterns.get("step")
        if not isinstance(pattern, StepPattern) or not pattern.matches(layout):
            pattern = self._patterns["step"] = StepPattern(layout, self.particles)
        data = np.zeros(len(pattern.indices))
        data[pattern.diagonal] += mass
        for (kind, _, _, blocks, which), slots in zip(parts, pattern.slots):
            scatter = scatter_plain if kind == "plain" else scatter_pairs
            scatter(data, slots, np.ascontiguousarray(blocks, dtype=np.float64), -(h * h) if which == "x" else -h)
        return sp.csr_matrix((data, pattern.indices, pattern.indptr), shape=(pattern.size, pattern.size))

    def _dense_step_matrix(self, mass: np.ndarray, h: float) -> np.ndarray:
        """:meth:`step_matrix` as an array, the blocks summed straight into it (a pendulum's or a few springs'
        step: scipy.sparse's sums and checks cost a hundred times the arithmetic)."""
        size = 3 * self.particles
        flat = np.zeros(size * size)
        flat[:: size + 1] = mass
        for kind, i, j, blocks, which in self._parts():
            scale = -(h * h) if which == "x" else -h
            if kind == "plain":
                keys, values = _block_keys(i, j, size), blocks.reshape(len(i), 9)
            else:  # B at (i, i) and (j, j), −B at (i, j) and (j, i)
                keys = np.concatenate([_block_keys(i, i, size), _block_keys(j, j, size), _block_keys(i, j, size),
                                       _block_keys(j, i, size)], axis=1)
                plain = blocks.reshape(len(i), 9)
                values = np.concatenate([plain, plain, -plain, -plain], axis=1)
            flat += np.bincount(keys.ravel(), weights=scale * values.ravel(), minlength=size * size)
        return flat.reshape(size, size)

    def product(self, which: str, vector: np.ndarray) -> np.ndarray:
        """``∂f/∂x · vector`` (``which='x'``) or ``∂f/∂v · vector`` (3N,), from the blocks when :attr:`compiled`."""
        if not self.compiled:
            return self.matrix(which) @ vector
        from animbatch.sim.kernels.spring_assembly import multiply_pairs, multiply_plain

        out = np.zeros(3 * self.particles)
        vector = np.ascontiguousarray(vector, dtype=np.float64)
        for i, j, blocks in self._blocks[which]:
            multiply_plain(out, i, j, blocks, vector)
        for first, second, blocks in self._pairs[which]:
            multiply_pairs(out, first, second, blocks, vector)
        return out
