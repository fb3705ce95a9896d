"""PNG frame sequences: ``frames/frame_00000.png`` …, each file written atomically.

PNG compression level 1 is used: several times faster than the default 6, for files about 1.5× larger.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from animbatch.files import atomic_path

FRAME_PATTERN = "frame_{index:05d}.png"


class PngSequenceWriter:
    """Writes frame ``k`` to ``folder/frame_0000k.png``."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.frames_written = 0

    def path_of(self, index: int) -> Path:
        return self.folder / FRAME_PATTERN.format(index=index)

    def write(self, index: int, image: np.ndarray) -> Path:
        from PIL import Image

        target = self.path_of(index)
        with atomic_path(target) as temporary:
            Image.fromarray(image).save(temporary, format="PNG", compress_level=1)
        self.frames_written += 1
        return target

    def remove_beyond(self, count: int) -> None:
        """Delete frames numbered ``count`` and above, left over from an earlier, longer run."""
        for path in self.folder.glob("frame_*.png"):
            stem = path.stem.removeprefix("frame_")
            if stem.isdigit() and int(stem) >= count:
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()
