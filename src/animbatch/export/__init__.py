"""Exports of a baked trajectory for other tools (animation packages, spreadsheets, notebooks).

Only what a :class:`~animbatch.trajectory.Trajectory` holds is written, so an export never simulates: the CLI bakes
the scene first (or reuses its cache). Formats: ``csv``, the transform of every body at every frame
(:mod:`animbatch.export.transforms`).
"""

from __future__ import annotations

from pathlib import Path

from animbatch.export.transforms import write_transforms_csv
from animbatch.trajectory import Trajectory

#: Export formats, by name: what each writes, into ``OUT/<scene>/``.
EXPORT_FORMATS = {"csv": "transforms.csv: every body's position and orientation at every frame"}


def export(trajectory: Trajectory, folder: str | Path, kind: str) -> list[Path]:
    """Write ``trajectory`` as ``kind`` (a key of :data:`EXPORT_FORMATS`) into ``folder``; the files written."""
    if kind not in EXPORT_FORMATS:
        raise ValueError(f"unknown export format {kind!r}; choose from {', '.join(EXPORT_FORMATS)}")
    return [write_transforms_csv(trajectory, Path(folder) / "transforms.csv")]
