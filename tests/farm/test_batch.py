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


@pytest.mark.slow
@pytest.mark.xdist_group("dask")
def test_a_batch_of_three_scenes_on_two_workers_gives_complete_videos_and_reports_a_failure(dask_scheduler, tmp_cwd):
    """Three scenes (45, 60 and 30 frames, in chunks of 20 frames) and one that diverges, on the tests' cluster of two
    workers. The three MP4s have every frame at the scene's size and rate, each job wrote its report, the summary
    lists all four, and the batch exits with 1 because one failed, after finishing the others. (The cluster that
    ``--workers`` starts is the one the killed-worker test runs on.)"""
    for name, duration, speed in (("one", 1.5, 1.0), ("two", 2.0, -1.0), ("three", 1.0, 0.5)):
        (tmp_cwd / f"{name}.yaml").write_text(ball(name, duration, speed))
    (tmp_cwd / "bad.yaml").write_text(ball("bad", 1.0, 1.0) + """
anchors: [{name: pin, position: [0, 2, 0]}]
springs: [{between: [pin, ball], stiffness: 1.0e6, rest_length: 0.5}]
solver: {method: euler, dt: 0.01}
""")
    result = CliRunner().invoke(cli, ["batch", "one.yaml", "two.yaml", "bad.yaml", "three.yaml", "--scheduler",
                                      dask_scheduler, "--chunk-size", "20"])
    assert result.exit_code == 1, result.output
    lines = result.output.splitlines()
    table = lines[lines.index(next(line for line in lines if line.startswith("scene"))):]
    assert [line.split()[0] for line in table[2:6]] == ["one", "two", "bad", "three"]
    assert "FAILED" in table[4] and "cannot hold this scene's springs" in table[4]
    assert table[-2:] == ["3 of 4 jobs succeeded", "page: renders/index.html"]
    page = (tmp_cwd / "renders" / "index.html").read_text()  # every job on the report page, the failure with why
    assert page.count("<video") == 3 and "3 of 4 runs succeeded" in page and "cannot hold this scene" in page
    for name, frames in (("one", 45), ("two", 60), ("three", 30)):
        reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / name / f"{name}.mp4"))
        meta = next(reader)
        assert meta["size"] == (96, 64) and meta["fps"] == 30 and sum(1 for _ in reader) == frames
        report = json.loads((tmp_cwd / "renders" / name / "report.json").read_text())
        assert report["status"] == "ok" and report["frames_drawn"] == frames
        assert report["render_tasks"] == -(-frames // 20)
        assert report["ledger"]["conservation"]["energy"]["conserved"] is True  # each job's accuracy ledger
        csv_rows = (tmp_cwd / "renders" / name / "quantities.csv").read_text().splitlines()
        assert len(csv_rows) == 1 + frames
    assert not (tmp_cwd / "renders" / "bad" / "bad.mp4").exists()
    failed = json.loads((tmp_cwd / "renders" / "bad" / "report.json").read_text())
    assert failed["status"] == "failed" and failed["exit_code"] == 3 and "'" in failed["error"]


@pytest.mark.slow
def test_a_worker_killed_mid_batch_loses_no_frame_and_redraws_none(tmp_cwd):
    """Two workers (the local cluster ``batch --workers 2`` starts) render a 180-frame scene in 6 chunks; once frames
    are appearing, one worker process is killed (SIGKILL). Dask reruns its tasks elsewhere: the batch completes, the
    MP4 has all 180 frames, every PNG is complete, and every frame that existed at the kill is the same file afterwards
    (same inode: not drawn again)."""
    import os
    import signal
    import threading
    import time

    from animbatch.farm.batch import Job, connect, run_batch
    from animbatch.farm.frame_files import frame_is_complete

    (tmp_cwd / "long.yaml").write_text(ball("long", 6.0, 0.3).replace("render: {resolution: [96, 64]}",
                                                                      "render: {resolution: [96, 64], "
                                                                      "formats: [mp4, png]}"))
    frames = tmp_cwd / "renders" / "long" / "frames"
    client, cluster = connect(2, None)
    with cluster, client:
        assert len(client.scheduler_info()["workers"]) == 2
        results = []
        runner = threading.Thread(target=lambda: results.extend(
            run_batch([Job("long.yaml")], client=client, chunk_size=30)))
        runner.start()
        deadline = time.time() + 120
        while len(list(frames.glob("frame_*.png"))) < 20 and time.time() < deadline:
            time.sleep(0.05)
        pids = client.run(os.getpid)
        os.kill(next(iter(pids.values())), signal.SIGKILL)
        existing = {path.name: path.stat().st_ino for path in frames.glob("frame_*.png")}
        runner.join(timeout=300)
    assert 20 <= len(existing) < 180  # the kill came mid-render
    assert [result.status for result in results] == ["ok"], results
    reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / "long" / "long.mp4"))
    assert next(reader)["size"] == (96, 64) and sum(1 for _ in reader) == 180
    pngs = sorted(frames.glob("frame_*.png"))
    assert len(pngs) == 180 and all(frame_is_complete(path, (96, 64)) for path in pngs)
    assert {name: (frames / name).stat().st_ino for name in existing} == existing


@pytest.mark.slow
@pytest.mark.xdist_group("dask")
def test_a_sweep_renders_one_variant_per_value_with_metrics_and_a_contact_sheet(dask_scheduler, tmp_cwd):
    """--sweep springs[0].stiffness=20,80,320 on a bob on a spring: three variants named by their value, each with
    its video; sweep.csv lists each with its energy drift (a conservative scene: below 1e-4 of its energy scale at the
    default tolerance) and its solver work, which grows with the stiffness (ω ∝ √k, so RK45 needs more steps); the
    contact sheet has one tile per variant. On a cluster given by --scheduler, started before the test moved to its
    folder: the workers run elsewhere, and the relative scene path still means the client's file."""
    import csv

    from PIL import Image

    (tmp_cwd / "bob.yaml").write_text("""
name: bob
duration: 1
fps: 30
anchors: [{name: pin, position: [0, 1, 0]}]
bodies: [{name: bob, mass: 0.5, radius: 0.08, position: [0.3, 0.2, 0]}]
springs: [{between: [pin, bob], stiffness: 50, rest_length: 0.6}]
fields: [{type: gravity}]
render: {resolution: [96, 64]}
""")
    result = CliRunner().invoke(cli, ["batch", "bob.yaml", "--scheduler", dask_scheduler, "--sweep",
                                      "springs[0].stiffness=20,80,320"])  # on a running cluster
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((tmp_cwd / "renders" / "bob-sweep" / "sweep.csv").open()))
    assert [row["variant"] for row in rows] == ["bob-stiffness-20", "bob-stiffness-80", "bob-stiffness-320"]
    assert [row["springs[0].stiffness"] for row in rows] == ["20", "80", "320"]
    assert all(row["status"] == "ok" and float(row["energy_drift"]) < 1e-4 for row in rows)
    steps = [int(row["steps"]) for row in rows]
    assert steps[0] < steps[1] < steps[2]
    for row in rows:
        assert (tmp_cwd / "renders" / row["variant"] / f"{row['variant']}.mp4").is_file()
    sheet = Image.open(tmp_cwd / "renders" / "bob-sweep" / "contact-sheet.png")
    assert sheet.size[0] == 3 * 320


def test_sweep_values_split_on_top_level_commas_and_name_each_variant():
    from animbatch.farm.sweep import Sweep, parse_sweep, split_values, variants

    assert split_values("1,[0, 1, 0], 3") == ["1", "[0, 1, 0]", "3"]
    assert parse_sweep("bodies[ball].velocity=[1, 0, 0],[2, 0, 0]") == Sweep("bodies[ball].velocity",
                                                                             ("[1, 0, 0]", "[2, 0, 0]"))
    with pytest.raises(ValueError, match="expected KEY.PATH=VALUE1,VALUE2"):
        parse_sweep("springs[0].stiffness")
    jobs = variants("s.yaml", "s", [Sweep("a.k", ("1", "2")), Sweep("b.m", ("x",))], ("fps=10",))
    assert [job.label for job, _ in jobs] == ["s-k-1-m-x", "s-k-2-m-x"]
    assert jobs[1][0].overrides == ("fps=10", "a.k=2", "b.m=x", "name=s-k-2-m-x")
    assert jobs[1][1] == {"a.k": "2", "b.m": "x"}


def test_a_sweep_block_in_the_scene_stands_for_sweep_options(tmp_cwd, monkeypatch):
    """sweep: {springs[0].stiffness: [20, 80], bodies[bob].velocity: [[0, 0, 0], [1, 0, 0]]} plans the four
    combinations, each variant with the block itself removed (a variant is not swept again)."""
    from animbatch.farm import batch as batch_module

    planned = []
    monkeypatch.setattr(batch_module, "run_batch", lambda jobs, **kwargs: planned.extend(jobs) or [])
    monkeypatch.setattr("animbatch.farm.sweep.contact_sheet", lambda rows, target: target)
    (tmp_cwd / "bob.yaml").write_text("""
name: bob
anchors: [{name: pin, position: [0, 1, 0]}]
bodies: [{name: bob, mass: 0.5, position: [0.3, 0.2, 0]}]
springs: [{between: [pin, bob], stiffness: 50}]
sweep:
  springs[0].stiffness: [20, 80]
  bodies[bob].velocity: [[0, 0, 0], [1, 0, 0]]
""")
    result = CliRunner().invoke(cli, ["batch", "bob.yaml"])
    assert result.exit_code == 0, result.output
    assert [job.label for job in planned] == ["bob-stiffness-20-velocity-0_0_0", "bob-stiffness-20-velocity-1_0_0",
                                              "bob-stiffness-80-velocity-0_0_0", "bob-stiffness-80-velocity-1_0_0"]
    assert planned[3].overrides == ("sweep={}", "springs[0].stiffness=80", "bodies[bob].velocity=[1, 0, 0]",
                                    "name=bob-stiffness-80-velocity-1_0_0")


def test_batch_takes_the_frame_options_render_takes(tmp_cwd, monkeypatch):
    """--resolution, --quality and --formats apply to every scene of a batch, as render's do (a draft pass over a
    batch needed --set "render.resolution=[320,240]"; issue 40); a bad value is named by its flag."""
    from animbatch.farm import batch as batch_module
    from animbatch.stages import load_scene

    planned = []
    monkeypatch.setattr(batch_module, "run_batch", lambda jobs, **kwargs: planned.extend(jobs) or [])
    for name in ("one", "two"):
        (tmp_cwd / f"{name}.yaml").write_text(ball(name, 0.5, 1.0))
    result = CliRunner().invoke(cli, ["batch", "one.yaml", "two.yaml", "--resolution", "320x240", "--quality",
                                      "draft", "--formats", "mp4,png", "--report", "none"])
    assert result.exit_code == 0, result.output
    for job in planned:
        render = load_scene(job.scene_path, list(job.overrides)).spec.render
        assert list(render.resolution) == [320, 240] and render.quality == "draft"
        assert list(render.formats) == ["mp4", "png"]
    assert len(planned) == 2
    bad = CliRunner().invoke(cli, ["batch", "one.yaml", "--resolution", "320by240", "--report", "none"])
    assert bad.exit_code != 0 and "--resolution 320by240" in bad.output


def test_the_batch_summary_says_when_a_job_ran_but_its_ledger_warns():
    """A job that succeeded with an accuracy warning is marked so in the table, with the warning's start."""
    from animbatch.farm.batch import JobResult, summary

    warned = JobResult("orbit", "ok", 30, 2.0, metrics={"ledger": {"warnings": ["the energy drifted by 30 %"]}})
    clean = JobResult("ball", "ok", 30, 1.0, metrics={"ledger": {"warnings": []}})
    lines = summary([warned, clean]).splitlines()
    assert "ok with 1 accuracy warning: the energy drifted by 30 %" in lines[2]
    assert lines[3].endswith("ok")
