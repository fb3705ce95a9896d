"""The flat state vector and its documented layout.

All integrators see one flat float64 vector ``y``. The layout names its blocks, in order (blocks of size zero are
left out, so a scene of particles only has just the first and fourth)::

    configuration:  particle_position      (N×3, m)
                    rigid_position         (B×3, m)        centre of mass x
                    rigid_orientation      (B×4, 1)        unit quaternion q = [w, x, y, z]
                    proper_time            (K×1, s)        clocks' proper time τ, only when a scene has clocks
    motion:         particle_velocity      (N×3, m/s)
                    rigid_momentum         (B×3, kg·m/s)   P = M v
                    rigid_angular_momentum (B×3, kg·m²/s)  L = I(t) ω, world axes

This is the lecture notes' rigid-body state ``S = [x, R, P, L]`` with the rotation R stored as a quaternion; with
``solver.orientation: matrix`` the block ``rigid_orientation`` holds R itself instead (B×9, row by row), which the
integration does not keep a rotation (see :meth:`StateLayout.matrix_orientation`).
Configuration blocks come first and motion blocks after them, each contiguous, so that partitioned (symplectic)
integrators can take ``y[config]`` and ``y[motion]`` as views without copying.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

#: Whether a block holds configuration (positions, orientations, clocks) or motion (velocities, momenta).
Role = Literal["config", "motion"]


@dataclass(frozen=True)
class StateBlock:
    """One named block of the state vector: ``y[offset : offset + size]`` viewed with ``shape``."""

    name: str
    offset: int
    shape: tuple[int, ...]
    unit: str
    role: Role
    owners: tuple[str, ...]  # name of the body owning each row of the block

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @property
    def span(self) -> slice:
        return slice(self.offset, self.offset + self.size)


@dataclass(frozen=True)
class StateLayout:
    """The ordered blocks of a state vector."""

    blocks: tuple[StateBlock, ...]

    @classmethod
    def for_bodies(cls, particles: tuple[str, ...], rigid: tuple[str, ...] = (),
                   clocks: tuple[str, ...] = (), *, matrices: bool = False) -> StateLayout:
        """The layout for N particles and B rigid bodies (names in state order), and K clocks they carry; with
        ``matrices``, orientations as rotation matrices (9 numbers each) rather than quaternions (4)."""
        specs: list[tuple[str, tuple[str, ...], int, str, Role]] = [
                 ("particle_position", particles, 3, "m", "config"),
                 ("rigid_position", rigid, 3, "m", "config"),
                 ("rigid_orientation", rigid, 9 if matrices else 4, "1", "config"),
                 ("proper_time", clocks, 1, "s", "config"),
                 ("particle_velocity", particles, 3, "m/s", "motion"),
                 ("rigid_momentum", rigid, 3, "kg·m/s", "motion"),
                 ("rigid_angular_momentum", rigid, 3, "kg·m²/s", "motion")]
        blocks, offset = [], 0
        for name, owners, width, unit, role in specs:
            if owners:
                blocks.append(StateBlock(name, offset, (len(owners), width), unit, role, owners))
                offset += len(owners) * width
        return cls(tuple(blocks))

    @property
    def matrix_orientation(self) -> bool:
        """Whether orientations are rotation matrices R (B, 3, 3) integrated as ``dR/dt = [ω]× R``, rather than
        unit quaternions."""
        return self.has("rigid_orientation") and self.block("rigid_orientation").shape[1] == 9

    def has(self, name: str) -> bool:
        return any(block.name == name for block in self.blocks)

    @property
    def size(self) -> int:
        return sum(block.size for block in self.blocks)

    def block(self, name: str) -> StateBlock:
        for block in self.blocks:
            if block.name == name:
                return block
        raise KeyError(f"no state block {name!r}; blocks: {', '.join(b.name for b in self.blocks)}")

    def view(self, y: np.ndarray, name: str) -> np.ndarray:
        """The block ``name`` of ``y`` (shape ``(n,)``, or ``(frames, n)``) as a view with the block's shape."""
        block = self.block(name)
        return y[..., block.span].reshape(*y.shape[:-1], *block.shape)

    def _span_of(self, role: str) -> slice:
        blocks = [b for b in self.blocks if b.role == role]
        return slice(blocks[0].offset, blocks[-1].offset + blocks[-1].size) if blocks else slice(0, 0)

    @property
    def config(self) -> slice:
        """Positions (and, later, orientations): a contiguous slice."""
        return self._span_of("config")

    @property
    def motion(self) -> slice:
        """Velocities (and, later, momenta): a contiguous slice."""
        return self._span_of("motion")

    def describe_index(self, index: int) -> tuple[str, str]:
        """``(body name, quantity)`` of state component ``index``, e.g. ``("bob", "velocity y")``."""
        for block in self.blocks:
            if block.offset <= index < block.offset + block.size:
                row, column = divmod(index - block.offset, block.shape[-1])
                quantity = block.name.split("_", 1)[-1].replace("_", " ")
                components = {1: " ", 3: "xyz", 4: "wxyz"}[block.shape[-1]]
                return block.owners[row], f"{quantity} {components[column]}".rstrip()
        raise IndexError(f"state index {index} is outside the state (size {self.size})")
