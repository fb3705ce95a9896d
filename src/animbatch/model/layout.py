"""The flat state vector and its documented layout.

All integrators see one flat float64 vector ``y``. The layout names its blocks, in order::

    [ particle_position (N×3, m) | particle_velocity (N×3, m/s) ]

Configuration blocks (positions) come first and motion blocks (velocities) after them, each contiguous, so that
partitioned (symplectic) integrators can take ``y[config]`` and ``y[motion]`` as views without copying.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np


@dataclass(frozen=True)
class StateBlock:
    """One named block of the state vector: ``y[offset : offset + size]`` viewed with ``shape``."""

    name: str
    offset: int
    shape: tuple[int, ...]
    unit: str
    role: Literal["config", "motion"]
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
    def for_particles(cls, names: tuple[str, ...]) -> StateLayout:
        n = len(names)
        return cls((StateBlock("particle_position", 0, (n, 3), "m", "config", names),
                    StateBlock("particle_velocity", 3 * n, (n, 3), "m/s", "motion", names)))

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
                quantity = block.name.split("_", 1)[-1]
                return block.owners[row], f"{quantity} {'xyz'[column]}" if block.shape[-1] == 3 else quantity
        raise IndexError(f"state index {index} is outside the state (size {self.size})")
