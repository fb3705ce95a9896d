"""Exports for other tools: the transforms CSV against the trajectory it came from and against closed forms."""

from __future__ import annotations

import csv

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
    result = CliRunner().invoke(cli, ["export", "scene.yaml", "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "30 frames, 2 bodies" in result.output
    return read(tmp_cwd / "renders" / "throw-and-spin" / "transforms.csv")


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
    """--trajectory exports a file from 'animbatch simulate' without simulating; a write interrupted midway leaves
    neither the CSV nor a temporary file."""
    (tmp_cwd / "scene.yaml").write_text(SCENE)
    runner = CliRunner()
    assert runner.invoke(cli, ["simulate", "scene.yaml", "-o", "run.npz"]).exit_code == 0
    result = runner.invoke(cli, ["export", "scene.yaml", "--trajectory", "run.npz", "--out", "elsewhere"])
    assert result.exit_code == 0, result.output
    folder = tmp_cwd / "elsewhere" / "throw-and-spin"
    assert len(read(folder / "transforms.csv")) == 60 and not (folder / "cache").exists()  # nothing was baked
    (folder / "transforms.csv").unlink()
    trajectory = Trajectory.load(tmp_cwd / "run.npz")

    class Interrupted(Exception):
        pass

    def fail_after_first_rows(*args, **kwargs):
        raise Interrupted

    monkeypatch.setattr(transforms.np, "concatenate", fail_after_first_rows)
    with pytest.raises(Interrupted):
        transforms.write_transforms_csv(trajectory, folder / "transforms.csv")
    assert list(folder.iterdir()) == []
