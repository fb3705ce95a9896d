"""Exports for other tools: the transforms CSV and the PLY and OBJ point caches against the trajectory they came
from and against closed forms (the USD stage: test_usd_export.py)."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.export import transforms
from animbatch.trajectory import Trajectory

G = 9.81
OMEGA = 2.0  # rad/s about z

#: A stone thrown under gravity and a box spinning about its own z axis, far from each other (no contacts).
SCENE = f"""
name: throw-and-spin
duration: 1.5
fps: 20
solver: {{method: RK45, rtol: 1.0e-10, atol: 1.0e-12}}
bodies:
  - {{name: stone, radius: 0.05, position: [0, 1, 0], velocity: [2, 4, 0.5]}}
  - {{name: box, type: rigid, shape: {{type: box, size: [0.4, 0.2, 0.1]}}, density: 500, position: [5, 5, 5],
     angular_velocity: [0, 0, {OMEGA}]}}
fields: [{{type: gravity, bodies: [stone]}}]
"""


def read(path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture
def exported(tmp_cwd):
    (tmp_cwd / "scene.yaml").write_text(SCENE)
    result = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "csv", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "csv, 30 frames" in result.output
    return read(tmp_cwd / "renders" / "throw-and-spin" / "transforms.csv")


def test_export_says_whether_it_simulated_or_read_the_cache_before_its_own_output(tmp_cwd):
    """The wait before 'csv, N frames in …' is the simulation's (17.6 s of it went unmentioned, issue 40): the first
    export says it simulated, and in how long, with the run's ledger; the second that it read the cache."""
    (tmp_cwd / "scene.yaml").write_text(SCENE)
    first = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "csv", "--no-progress"])
    again = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "csv", "--no-progress"])
    assert first.exit_code == again.exit_code == 0, first.output + again.output
    simulated, exported = first.output.splitlines()[-2:]
    assert re.match(r"[\w-]+: trajectory simulated in \d+\.\d\d s -> renders/\S+/cache/trajectory-\w+\.npz \| ", simulated)
    assert "csv, 30 frames" in exported
    assert ": trajectory read from the cache -> renders/" in again.output.splitlines()[-2]


def test_the_csv_holds_every_body_at_every_frame_exactly_as_simulated(exported, tmp_cwd):
    """30 frames × 2 bodies (1.5 s at 20 fps), in the trajectory's order, with its positions and quaternions read back exactly."""
    assert list(exported[0]) == list(transforms.COLUMNS)
    assert len(exported) == 30 * 2
    trajectory = Trajectory.load(next((tmp_cwd / "renders" / "throw-and-spin" / "cache").glob("*.npz")))
    for row in exported:
        frame, body = int(row["frame"]), trajectory.body_names.index(row["body"])
        assert row["kind"] == trajectory.body_kinds[body] and float(row["time"]) == trajectory.times[frame]
        assert [float(row[c]) for c in "xyz"] == trajectory.positions[frame, body].tolist()
        assert [float(row[c]) for c in ("qw", "qx", "qy", "qz")] == trajectory.orientations[frame, body].tolist()
    assert [row["body"] for row in exported[:4]] == ["stone", "box", "stone", "box"]


def test_the_csv_gives_the_closed_forms_of_a_throw_and_a_spin(exported):
    """The stone follows x₀ + v₀ t + ½ g t²; the box keeps its place and turns as q(t) = (cos ωt/2, 0, 0, sin ωt/2)
    (a free spin about a principal axis)."""
    for row in exported:
        t = float(row["time"])
        position = np.array([float(row[c]) for c in "xyz"])
        quaternion = np.array([float(row[c]) for c in ("qw", "qx", "qy", "qz")])
        if row["body"] == "stone":
            expected = np.array([0, 1, 0]) + np.array([2, 4, 0.5]) * t + 0.5 * np.array([0, -G, 0]) * t**2
            assert row["kind"] == "particle" and np.allclose(quaternion, [1, 0, 0, 0])
            assert np.allclose(position, expected, atol=1e-8)
        else:
            spin = np.array([np.cos(OMEGA * t / 2), 0, 0, np.sin(OMEGA * t / 2)])
            assert row["kind"] == "rigid" and np.allclose(position, [5, 5, 5], atol=1e-12)
            assert min(np.abs(quaternion - spin).max(), np.abs(quaternion + spin).max()) < 1e-7  # q and -q agree


def test_export_takes_a_trajectory_file_and_leaves_nothing_half_written(tmp_cwd, monkeypatch):
    """--trajectory exports a file from 'animbatch simulate' without simulating, and so does the trajectory file
    given alone for the CSV; a write interrupted midway leaves neither the CSV nor a temporary file."""
    (tmp_cwd / "scene.yaml").write_text(SCENE)
    runner = CliRunner()
    assert runner.invoke(cli, ["simulate", "scene.yaml", "-o", "run.npz"]).exit_code == 0
    result = runner.invoke(cli, ["export", "scene.yaml", "--trajectory", "run.npz", "--out", "elsewhere", "--format",
                                 "csv"])
    assert result.exit_code == 0, result.output
    folder = tmp_cwd / "elsewhere" / "throw-and-spin"
    assert len(read(folder / "transforms.csv")) == 60 and not (folder / "cache").exists()  # nothing was baked
    (folder / "transforms.csv").unlink()
    # the trajectory file alone: enough for the CSV; a format that needs shapes and looks asks for the scene
    result = runner.invoke(cli, ["export", "run.npz", "--out", "elsewhere", "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert len(read(folder / "transforms.csv")) == 60
    (folder / "transforms.csv").unlink()
    result = runner.invoke(cli, ["export", "run.npz", "--format", "usd"])
    assert result.exit_code == 2 and "animbatch export SCENE.yaml --trajectory run.npz --format usd" in result.output
    result = runner.invoke(cli, ["export", "run.npz", "--format", "csv", "--set", "duration=1", "--dt", "0.01"])
    assert result.exit_code == 2 and "--set, --dt cannot change a trajectory file" in result.output
    trajectory = Trajectory.load(tmp_cwd / "run.npz")

    class Interrupted(Exception):
        pass

    def fail_after_first_rows(*args, **kwargs):
        raise Interrupted

    monkeypatch.setattr(transforms.np, "concatenate", fail_after_first_rows)
    with pytest.raises(Interrupted):
        transforms.write_transforms_csv(trajectory, folder / "transforms.csv")
    assert list(folder.iterdir()) == []


#: A sheet pinned at its top corners, hanging under gravity, beside a nozzle spraying drops straight up at
#: 2 m/s ± 0.5 m/s in a vacuum with no gravity of their own.
CACHED = """
name: caches
duration: 0.5
fps: 20
seed: 5
solver: {method: backward_euler, dt: 0.005, drift_warning: 0.05}  # BE damps: 1.4 % of the energy
bodies:
  - {name: sheet, type: cloth, grid: {size: [0.4, 0.3], resolution: [5, 4]}, position: [0, 1, 0], density: 0.2,
     structural: {stiffness: 200}, pin: [{corners: [top-left, top-right]}]}
emitters:
  - name: nozzle
    source: {type: point, position: [2, 0, 0]}
    rate: 100
    lifetime: {mean: 1.0, spread: 0.0}
    speed: {mean: 2.0, spread: 0.5}
    direction: {axis: [0, 1, 0], cone: 0}
    radius: {mean: 0.01, spread: 0.002}
    color: {mean: "#ff8000", spread: 0.0}
fields: [{type: gravity, bodies: [sheet]}]
"""


def read_ply(path) -> tuple[np.ndarray, np.ndarray | None]:
    """The vertex records and the triangles (T, 3) or None of a binary little-endian PLY, parsed from its header."""
    data = path.read_bytes()
    header, body = data.split(b"end_header\n", 1)
    lines = header.decode("ascii").splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    types = {"float": "<f4", "int": "<i4", "uchar": "u1"}
    fields, counts, element = [], {}, None
    for line in lines[2:]:
        words = line.split()
        if words[0] == "element":
            element = words[1]
            counts[element] = int(words[2])
        elif words[0] == "property" and element == "vertex":
            fields.append((words[2], types[words[1]]))
    vertices = np.frombuffer(body, fields, counts["vertex"])
    triangles = None
    if "face" in counts:
        faces = np.frombuffer(body, [("n", "u1"), ("v", "<i4", (3,))], counts["face"], offset=vertices.nbytes)
        assert np.all(faces["n"] == 3)
        triangles = faces["v"]
    return vertices, triangles


@pytest.mark.slow
def test_ply_and_obj_sequences_hold_the_cloth_and_the_particles_of_every_frame(tmp_cwd):
    """One file per frame and object. The sheet's triangles are the same in every file and its pinned corners stay
    put; each drop's PLY vertex carries its serial as id, its age and radius, and its height is the straight rise
    y = v t of a drop shot up in a vacuum (v = its distance over its age); OBJ holds the same positions as text."""
    (tmp_cwd / "scene.yaml").write_text(CACHED)
    result = CliRunner().invoke(cli, ["export", "scene.yaml", "--format", "ply", "--format", "obj", "--no-progress"])
    assert result.exit_code == 0, result.output
    folder = tmp_cwd / "renders" / "caches"
    trajectory = Trajectory.load(next((folder / "cache").glob("*.npz")))
    assert sorted(p.name for p in (folder / "ply").iterdir())[:3] == ["nozzle.0000.ply", "nozzle.0001.ply",
                                                                      "nozzle.0002.ply"]
    assert len(list((folder / "ply").glob("sheet.*.ply"))) == len(list((folder / "obj").glob("*.obj"))) / 2 == 10
    first, triangles = read_ply(folder / "ply" / "sheet.0000.ply")
    assert len(first) == 20 and triangles.shape == (24, 3)
    top = np.flatnonzero(np.isclose(first["y"], first["y"].max()))
    corners = top[[np.argmin(first["x"][top]), np.argmax(first["x"][top])]]
    record = trajectory.particles[0]
    for frame in (3, 9):
        sheet, same = read_ply(folder / "ply" / f"sheet.{frame:04d}.ply")
        assert np.array_equal(same, triangles)
        assert np.array_equal(sheet[["x", "y", "z"]][corners], first[["x", "y", "z"]][corners])
        assert sheet["y"].min() < first["y"].min() - 0.01
        obj = (folder / "obj" / f"sheet.{frame:04d}.obj").read_text().splitlines()
        vertices = np.array([[float(v) for v in line.split()[1:]] for line in obj if line.startswith("v ")])
        faces = np.array([[int(v) for v in line.split()[1:]] for line in obj if line.startswith("f ")])
        assert np.allclose(vertices, np.stack([sheet["x"], sheet["y"], sheet["z"]], axis=1), atol=1e-6)
        assert np.array_equal(faces - 1, triangles)

        drops, none = read_ply(folder / "ply" / f"nozzle.{frame:04d}.ply")
        live = record.serials[frame] >= 0
        assert none is None and len(drops) == live.sum() > 5
        assert np.array_equal(drops["id"], record.serials[frame][live])
        assert np.array_equal(drops["age"], record.ages[frame][live])
        assert np.all((drops["radius"] >= 0.008 - 1e-7) & (drops["radius"] <= 0.012 + 1e-7))
        assert np.allclose(drops["x"], 2, atol=1e-6) and np.allclose(drops["z"], 0, atol=1e-6)
        flown = drops["age"] > 0.005  # older than a step (one born within the last step has not moved yet)
        speed = drops["y"][flown] / drops["age"][flown]
        assert flown.sum() > 5 and np.all((speed > 1.5 - 1e-3) & (speed < 2.5 + 1e-3))
        assert (drops["red"], drops["green"], drops["blue"]) == pytest.approx((255, 128, 0), abs=1)
