"""Batches on Dask: a LocalCluster of two worker processes renders several scenes to complete videos; a failing
scene is reported without stopping the others."""

from __future__ import annotations

import json

import imageio_ffmpeg
import pytest
from click.testing import CliRunner

from animbatch.cli import cli

pytestmark = pytest.mark.render


def ball(name: str, duration: float, speed: float) -> str:
    return f"""
name: {name}
duration: {duration}
fps: 30
bodies: [{{name: ball, radius: 0.1, position: [0, 1, 0], velocity: [{speed}, 3, 0]}}]
fields: [{{type: gravity}}]
render: {{resolution: [96, 64]}}
"""


def test_a_batch_of_three_scenes_on_two_workers_gives_complete_videos_and_reports_a_failure(tmp_cwd):
    """Three scenes (45, 60 and 30 frames, in chunks of 20 frames) and one that diverges. The three MP4s have every
    frame at the scene's size and rate, each job wrote its report, the summary lists all four, and the batch exits
    with 1 because one failed, after finishing the others."""
    for name, duration, speed in (("one", 1.5, 1.0), ("two", 2.0, -1.0), ("three", 1.0, 0.5)):
        (tmp_cwd / f"{name}.yaml").write_text(ball(name, duration, speed))
    (tmp_cwd / "bad.yaml").write_text(ball("bad", 1.0, 1.0) + """
anchors: [{name: pin, position: [0, 2, 0]}]
springs: [{between: [pin, ball], stiffness: 1.0e6, rest_length: 0.5}]
solver: {method: euler, dt: 0.01}
""")
    result = CliRunner().invoke(cli, ["batch", "one.yaml", "two.yaml", "bad.yaml", "three.yaml", "--workers", "2",
                                      "--chunk-size", "20"])
    assert result.exit_code == 1, result.output
    lines = result.output.splitlines()
    table = lines[lines.index(next(line for line in lines if line.startswith("scene"))):]
    assert [line.split()[0] for line in table[2:6]] == ["one", "two", "bad", "three"]
    assert "FAILED" in table[4] and "cannot hold this scene's springs" in table[4]
    assert table[-1] == "3 of 4 jobs succeeded"
    for name, frames in (("one", 45), ("two", 60), ("three", 30)):
        reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / name / f"{name}.mp4"))
        meta = next(reader)
        assert meta["size"] == (96, 64) and meta["fps"] == 30 and sum(1 for _ in reader) == frames
        report = json.loads((tmp_cwd / "renders" / name / "report.json").read_text())
        assert report["status"] == "ok" and report["frames_drawn"] == frames
        assert report["render_tasks"] == -(-frames // 20)
    assert not (tmp_cwd / "renders" / "bad" / "bad.mp4").exists()
    failed = json.loads((tmp_cwd / "renders" / "bad" / "report.json").read_text())
    assert failed["status"] == "failed" and failed["exit_code"] == 3 and "'" in failed["error"]
