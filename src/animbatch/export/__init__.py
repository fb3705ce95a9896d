"""Exports of a baked run for other tools (animation packages, point-cache readers, spreadsheets, notebooks).

Only what a :class:`~animbatch.trajectory.Trajectory` holds and the scene's compiled frame geometry are written, so
an export never simulates: the CLI bakes the scene first (or reuses its cache). Formats:

- ``usd``: a USD stage of everything drawn, for Blender and Houdini (:mod:`animbatch.export.usd`);
- ``ply``, ``obj``: per-frame files of cloth, lattices and emitted particles (:mod:`animbatch.export.point_caches`);
- ``csv``: the transform of every body at every frame (:mod:`animbatch.export.transforms`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from animbatch.export.point_caches import file_stem, write_point_caches
from animbatch.export.transforms import write_transforms_csv
from animbatch.trajectory import Trajectory

#: Export formats, by name: what each writes, into ``OUT/<scene>/``.
EXPORT_FORMATS = {
    "usd": "<scene>.usdc: a USD stage of bodies, cloth, particles, camera and lights, one time code per frame",
    "ply": "ply/<name>.<frame>.ply: each cloth, lattice and emitter at each frame (binary PLY)",
    "obj": "obj/<name>.<frame>.obj: each cloth, lattice and emitter at each frame (text OBJ)",
    "csv": "transforms.csv: every body's position and orientation at every frame",
}


def export(trajectory: Trajectory, folder: str | Path, kind: str, geometry: Any = None, render: Any = None,
           fps: float = 30.0) -> list[Path]:
    """Write ``trajectory`` as ``kind`` (a key of :data:`EXPORT_FORMATS`) into ``folder``; the files written.
    ``geometry`` (the scene's :class:`~animbatch.render.frame_geometry.FrameGeometry`) is needed by every format but
    ``csv``; ``usd`` also takes the scene's ``render`` spec (camera) and ``fps``."""
    if kind not in EXPORT_FORMATS:
        raise ValueError(f"unknown export format {kind!r}; choose from {', '.join(EXPORT_FORMATS)}")
    folder = Path(folder)
    if kind == "csv":
        return [write_transforms_csv(trajectory, folder / "transforms.csv")]
    if geometry is None:
        raise ValueError(f"the {kind} export needs the scene's frame geometry")
    if kind == "usd":
        from animbatch.export.usd import write_usd  # usd-core loads only for this format

        return [write_usd(trajectory, geometry, render, fps, folder / f"{file_stem(trajectory.scene_name)}.usdc")]
    return write_point_caches(trajectory, geometry, folder / kind, kind)
