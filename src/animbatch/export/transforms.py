"""Every body's transform at every frame, as CSV: one row per frame and body.

Columns: ``frame``, ``time`` [s], ``body``, ``kind`` (``particle`` or ``rigid``), the centre of mass ``x``, ``y``,
``z`` [m] and the orientation as a unit quaternion ``qw``, ``qx``, ``qy``, ``qz`` (body to world; the identity for
particles), in the scene's world axes and metres. Rows are ordered by frame, then body in the trajectory's order
(particles first, then rigid bodies). Each number is written as the shortest decimal that reads back as the same
float, so reading the file gives the trajectory's values exactly.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from animbatch.files import atomic_path
from animbatch.trajectory import Trajectory

COLUMNS = ("frame", "time", "body", "kind", "x", "y", "z", "qw", "qx", "qy", "qz")


def write_transforms_csv(trajectory: Trajectory, path: str | Path) -> Path:
    """Write ``path`` (atomically: a temporary file renamed once complete) and return it."""
    frames, bodies = trajectory.positions.shape[:2]
    with atomic_path(path) as temporary, temporary.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for frame in range(frames):
            time = repr(float(trajectory.times[frame]))
            for body in range(bodies):
                values = np.concatenate([trajectory.positions[frame, body], trajectory.orientations[frame, body]])
                writer.writerow([frame, time, trajectory.body_names[body], trajectory.body_kinds[body],
                                 *(repr(float(value)) for value in values)])
    return Path(path)
