"""Per-frame files of cloth, lattices and emitted particles, for tools without USD: PLY or OBJ sequences.

One file per frame and object, ``<folder>/<name>.<frame>.<ply|obj>`` with the frame index zero-padded to four
digits (``flag.0000.ply``, ``flag.0001.ply``, … as Houdini's ``$F4`` and Blender's sequence importers read them;
frame ``k`` is time ``k / fps``). Each file is written atomically.

- A cloth or lattice: its vertices [m] (float32) and its triangles, the same in every file.
- An emitter: its live particles, vertices only. PLY adds per-vertex ``id`` (the particle's serial, the same all
  its life), ``radius`` [m], ``age`` [s] and ``red``, ``green``, ``blue``, ``alpha`` (0…255, sRGB, as drawn); OBJ
  has positions only.

PLY files are binary little-endian; OBJ files are text.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.export.frames import deformable_vertices
from animbatch.files import atomic_path
from animbatch.render.emitted import ParticleAppearance
from animbatch.trajectory import Trajectory

POINT_CACHE_FORMATS = ("ply", "obj")

_PARTICLE_FIELDS = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("id", "<i4"), ("radius", "<f4"), ("age", "<f4"),
                    ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")]
_PLY_TYPES = {("f", 4): "float", ("i", 4): "int", ("u", 1): "uchar"}  # (numpy kind, bytes) -> PLY type


def file_stem(name: str) -> str:
    """A scene name as a file name stem: letters, digits, ``-`` and ``_`` kept, anything else ``_``."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "_"


def write_point_caches(trajectory: Trajectory, geometry: Any, folder: str | Path, kind: str) -> list[Path]:
    """Write a ``kind`` (``ply`` or ``obj``) sequence for every cloth, lattice and emitter into ``folder``; the
    files written, frame by frame."""
    if kind not in POINT_CACHE_FORMATS:
        raise ValueError(f"unknown point cache format {kind!r}; choose from {', '.join(POINT_CACHE_FORMATS)}")
    folder = Path(folder)
    written: list[Path] = []
    bodies = geometry.deformables.bodies if geometry.deformables is not None else ()
    appearances = [ParticleAppearance(emitter) for emitter in geometry.emitters]
    for frame in range(trajectory.frame_count):
        if bodies:
            vertices = deformable_vertices(geometry, trajectory, frame)
            for body in bodies:
                path = folder / f"{file_stem(body.name)}.{frame:04d}.{kind}"
                triangles = body.triangles - body.vertices.start
                writer = _write_mesh_ply if kind == "ply" else _write_mesh_obj
                written.append(writer(path, vertices[body.vertices], triangles))
        for frames, appearance in zip(trajectory.particles, appearances):
            path = folder / f"{file_stem(frames.name)}.{frame:04d}.{kind}"
            serials, size, opacity, color = appearance.at(frames, frame)
            live = serials >= 0
            if kind == "obj":
                written.append(_write_mesh_obj(path, frames.positions[frame][live], np.zeros((0, 3), int)))
                continue
            records = np.empty(int(live.sum()), _PARTICLE_FIELDS)
            for axis, name in enumerate("xyz"):
                records[name] = frames.positions[frame][live, axis]
            records["id"], records["radius"], records["age"] = serials[live], size[live], frames.ages[frame][live]
            for channel, name in enumerate(("red", "green", "blue")):
                records[name] = np.round(255 * color[live, channel])
            records["alpha"] = np.round(255 * opacity[live])
            written.append(_write_ply(path, records, None))
    return written


def _write_mesh_ply(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> Path:
    records = np.empty(len(vertices), [("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    for axis, name in enumerate("xyz"):
        records[name] = vertices[:, axis]
    return _write_ply(path, records, triangles)


def _write_ply(path: Path, vertices: np.ndarray, triangles: np.ndarray | None) -> Path:
    """A binary little-endian PLY of ``vertices`` (a structured array: one property per field) and, if given,
    ``triangles`` (T, 3)."""
    header = ["ply", "format binary_little_endian 1.0", "comment written by animbatch",
              f"element vertex {len(vertices)}"]
    fields = vertices.dtype.fields or {}
    header += [f"property {_PLY_TYPES[(kind.kind, kind.itemsize)]} {name}" for name, (kind, _) in fields.items()]
    body = [vertices.tobytes()]
    if triangles is not None:
        header += [f"element face {len(triangles)}", "property list uchar int vertex_indices"]
        faces = np.empty(len(triangles), [("count", "u1"), ("indices", "<i4", (3,))])
        faces["count"], faces["indices"] = 3, triangles
        body.append(faces.tobytes())
    with atomic_path(path) as temporary, temporary.open("wb") as handle:
        handle.write(("\n".join(header) + "\nend_header\n").encode("ascii"))
        for part in body:
            handle.write(part)
    return path


def _write_mesh_obj(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> Path:
    """A text OBJ of ``vertices`` (V, 3) [m] and triangles (T, 3) (0-based here, 1-based in the file)."""
    lines = ["# written by animbatch: metres"]
    if len(vertices):
        lines.append(("v %.9g %.9g %.9g\n" * len(vertices) % tuple(np.asarray(vertices, float).ravel()))[:-1])
    if len(triangles):
        lines.append(("f %d %d %d\n" * len(triangles) % tuple((np.asarray(triangles) + 1).ravel()))[:-1])
    with atomic_path(path) as temporary:
        temporary.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path
