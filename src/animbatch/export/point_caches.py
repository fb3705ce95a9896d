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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.export.vertices import deformable_vertices
from animbatch.files import atomic_path
from animbatch.render.emitted import ParticleAppearance
from animbatch.trajectory import Trajectory

POINT_CACHE_FORMATS = ("ply", "obj")

_PARTICLE_FIELDS = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("id", "<i4"), ("radius", "<f4"), ("age", "<f4"),
                    ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")]
#: A PLY triangle record: its vertex count, then its three vertex indices.
_FACE = np.dtype([("count", "u1"), ("indices", "<i4", (3,))])
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
    bodies = geometry.surfaces.patches if geometry.surfaces is not None else ()
    appearances = [ParticleAppearance(emitter) for emitter in geometry.emitters]
    # a body's triangles are the same in every file: encoded once, as PLY face records or OBJ face lines
    encode_faces: Callable[[np.ndarray], Any] = _ply_faces if kind == "ply" else _obj_faces
    faces = [encode_faces(body.triangles) for body in bodies]
    write_mesh: Callable[[Path, np.ndarray, Any], Path] = _write_mesh_ply if kind == "ply" else _write_mesh_obj
    for frame in range(trajectory.frame_count):
        if bodies:
            vertices = deformable_vertices(geometry, trajectory, frame)
            for body, encoded in zip(bodies, faces):
                path = folder / f"{file_stem(body.name)}.{frame:04d}.{kind}"
                written.append(write_mesh(path, vertices[body.start:body.stop], encoded))
        for frames, appearance in zip(trajectory.particles, appearances):
            path = folder / f"{file_stem(frames.name)}.{frame:04d}.{kind}"
            serials, size, opacity, color = appearance.at(frames, frame)
            live = serials >= 0
            if kind == "obj":
                written.append(_write_mesh_obj(path, frames.positions[frame][live], ""))
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


def _ply_faces(triangles: np.ndarray) -> bytes:
    """Triangles (T, 3) as the records of a PLY ``face`` element (a count byte, three int32 indices each)."""
    faces = np.empty(len(triangles), _FACE)
    faces["count"], faces["indices"] = 3, triangles
    return faces.tobytes()


def _obj_faces(triangles: np.ndarray) -> str:
    """Triangles (T, 3), 0-based, as OBJ ``f`` lines (1-based)."""
    return "f %d %d %d\n" * len(triangles) % tuple((np.asarray(triangles) + 1).ravel())


def _write_mesh_ply(path: Path, vertices: np.ndarray, faces: bytes) -> Path:
    records = np.empty(len(vertices), [("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    for axis, name in enumerate("xyz"):
        records[name] = vertices[:, axis]
    return _write_ply(path, records, faces, len(faces) // _FACE.itemsize)


def _write_ply(path: Path, vertices: np.ndarray, faces: bytes | None, face_count: int = 0) -> Path:
    """A binary little-endian PLY of ``vertices`` (a structured array: one property per field) and, if given,
    ``faces`` (``face_count`` records from :func:`_ply_faces`)."""
    header = ["ply", "format binary_little_endian 1.0", "comment written by animbatch",
              f"element vertex {len(vertices)}"]
    fields: dict[str, Any] = dict(vertices.dtype.fields or {})  # name -> (dtype, offset)
    header += [f"property {_PLY_TYPES[(field[0].kind, field[0].itemsize)]} {name}" for name, field in fields.items()]
    if faces is not None:
        header += [f"element face {face_count}", "property list uchar int vertex_indices"]
    with atomic_path(path) as temporary, temporary.open("wb") as handle:
        handle.write(("\n".join(header) + "\nend_header\n").encode("ascii"))
        handle.write(vertices.tobytes())
        if faces is not None:
            handle.write(faces)
    return path


def _write_mesh_obj(path: Path, vertices: np.ndarray, faces: str) -> Path:
    """A text OBJ of ``vertices`` (V, 3) [m] and ``faces`` (from :func:`_obj_faces`, or empty)."""
    text = "# written by animbatch: metres\n"
    if len(vertices):
        text += "v %.9g %.9g %.9g\n" * len(vertices) % tuple(np.asarray(vertices, float).ravel())
    with atomic_path(path) as temporary:
        temporary.write_text(text + faces, encoding="ascii")
    return path
