"""Farm stages on one machine: bake into a keyed cache, render frame ranges idempotently (in parallel too), encode.
Checked by what is (not) simulated or drawn again, pixels and video metadata."""

from __future__ import annotations

import re
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from animbatch import api
from animbatch.cli import cli
from animbatch.farm import FrameRange, bake, frame_is_complete, parse_frames, render_frames
from animbatch.farm import cache as farm_cache
from support.scenes import counting

pytestmark = pytest.mark.render

WIDTH, HEIGHT = 96, 64
# Two balls thrown across the view: 50 frames at 25 fps.
THROW = f"""
name: throw
duration: 2
fps: 25
solver: {{method: RK45, rtol: 1.0e-8, atol: 1.0e-10}}
bodies:
  - {{name: red, radius: 0.1, position: [-1, 0, 0], velocity: [1, 3, 0], color: "#ff0000"}}
  - {{name: blue, mass: 2, radius: 0.1, position: [1, 0, 0], velocity: [-1, 3, 0], color: "#0000ff"}}
fields: [{{type: gravity}}]
render:
  resolution: [{WIDTH}, {HEIGHT}]
  show_time: true
  formats: [mp4, png]
"""


@pytest.fixture
def throw(tmp_cwd):
    (tmp_cwd / "throw.yaml").write_text(THROW)
    return tmp_cwd / "throw.yaml"


def pixels(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def test_cache_is_reused_for_a_new_camera_and_redone_for_new_physics_or_solver(throw, monkeypatch):
    """The cache key covers physics, solver settings and version, not the picture: a camera or resolution change
    reuses it; a mass or a tolerance change simulates again; a truncated cache file is never used."""
    simulated = counting(monkeypatch, farm_cache, "simulate")
    first = bake(api.load_scene(throw))
    assert not first.reused and len(simulated) == 1 and first.path.is_file()
    for overrides in (["render.camera.direction=[1, 1, 1]"], ["render.resolution=[160, 90]"], []):
        again = bake(api.load_scene(throw, overrides))
        assert again.reused and again.path == first.path and len(simulated) == 1
        assert np.array_equal(again.trajectory.positions, first.trajectory.positions)
    heavier = bake(api.load_scene(throw, ["bodies[red].mass=3"]))
    assert not heavier.reused and heavier.path != first.path and len(simulated) == 2
    assert not first.path.exists()  # the stale key's file is gone once the new bake landed
    looser = bake(api.load_scene(throw, ["bodies[red].mass=3", "solver.rtol=1.0e-6"]))
    assert not looser.reused and len(simulated) == 3
    looser.path.write_bytes(looser.path.read_bytes()[:200])  # cut short, as by a full disk
    assert not bake(api.load_scene(throw, ["bodies[red].mass=3", "solver.rtol=1.0e-6"])).reused
    assert len(simulated) == 4


@pytest.mark.slow
def test_a_render_checks_its_trajectory_and_prepares_its_frames_folder_once(throw, tmp_cwd, monkeypatch):
    """run (bake then draw) and render (a given trajectory) check the trajectory against the scene at most once and
    prepare the frames folder once, whatever path the frames take to the renderer."""
    from animbatch.farm import frame_files as farm_frames
    from animbatch.farm import run as farm_run
    from animbatch.farm import streamed_render as farm_stream

    checked = counting(monkeypatch, farm_run, "check_trajectory")
    checked_in_frames = counting(monkeypatch, farm_frames, "check_trajectory")
    prepared = counting(monkeypatch, farm_run, "prepare_frames")
    prepared_in_frames = counting(monkeypatch, farm_frames, "prepare_frames")
    prepared_in_stream = counting(monkeypatch, farm_stream, "prepare_frames")
    api.run(throw, overrides=["render.resolution=[64, 48]", "render.formats=[png]", "duration=0.2"], out_dir="renders")
    assert len(checked) + len(checked_in_frames) <= 1
    assert len(prepared) + len(prepared_in_frames) + len(prepared_in_stream) == 1
    scene = api.load_scene(throw, ["render.resolution=[64, 48]", "render.formats=[png]", "duration=0.2"])
    checked.clear(), prepared.clear(), prepared_in_stream.clear()
    api.render(scene, api.simulate(scene), out_dir="other")
    assert len(checked) + len(checked_in_frames) == 1
    assert len(prepared) + len(prepared_in_frames) + len(prepared_in_stream) == 1


@pytest.mark.slow
def test_chunked_rendering_gives_the_pixels_of_a_single_pass(throw, tmp_cwd):
    """Three chunks (0-16, 17-33, 34-49) in three renderers draw exactly the pixels of one pass over all frames: the
    camera is fitted to the whole trajectory, never to a chunk."""
    scene = api.load_scene(throw)
    trajectory = bake(scene).trajectory
    render_frames(scene, trajectory, FrameRange(0, 50), out_dir="single")
    for chunk in FrameRange(0, 50).chunks(17):
        render_frames(scene, trajectory, chunk, out_dir="chunked")
    for index in range(50):
        name = f"throw/frames/frame_{index:05d}.png"
        assert np.array_equal(pixels(tmp_cwd / "single" / name), pixels(tmp_cwd / "chunked" / name)), index
    assert pixels(tmp_cwd / "single/throw/frames/frame_00000.png").std() > 0  # frames are not blank


def test_a_truncated_frame_is_detected_and_drawn_again(throw, tmp_cwd, monkeypatch):
    """Rendering a range twice draws nothing the second time; a frame cut short (a copy interrupted, a full disk) or
    replaced by garbage is found and drawn again, and only it."""
    from animbatch.render.renderer import FrameRenderer

    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--frames", "10-19"]).exit_code == 0
    folder = tmp_cwd / "renders" / "throw" / "frames"
    assert sorted(p.name for p in folder.glob("frame_*.png")) == [f"frame_{i:05d}.png" for i in range(10, 20)]
    drawn = counting(monkeypatch, FrameRenderer, "draw")
    result = runner.invoke(cli, ["render", str(throw), "--frames", "10-19"])
    assert result.exit_code == 0, result.output
    assert drawn == []
    # the summary counts the range, not the scene (issue 40)
    assert re.search(r"throw: frames 10-19 of \d+ \(0 drawn, 10 complete already\)", result.output), result.output
    good = pixels(folder / "frame_00013.png")
    data = (folder / "frame_00013.png").read_bytes()
    (folder / "frame_00013.png").write_bytes(data[: len(data) // 2])
    (folder / "frame_00017.png").write_bytes(b"\x89PNG not really")
    assert not frame_is_complete(folder / "frame_00013.png", (WIDTH, HEIGHT))
    assert runner.invoke(cli, ["render", str(throw), "--frames", "10-19"]).exit_code == 0
    assert len(drawn) == 2
    assert np.array_equal(pixels(folder / "frame_00013.png"), good)


def test_an_interrupted_render_resumes_without_redrawing_finished_frames(throw, tmp_cwd, monkeypatch):
    """Ctrl-C while frame 6 of 0-19 is drawn: the command exits 130 with frames 0-5 complete and nothing partial
    on disk; the next run draws exactly frames 6-19 and leaves the finished ones as they were."""
    from animbatch.render.renderer import FrameRenderer

    original = FrameRenderer.draw
    calls = []

    def interrupted(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) == 7:
            raise KeyboardInterrupt
        return original(self, *args, **kwargs)

    monkeypatch.setattr(FrameRenderer, "draw", interrupted)
    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--frames", "0-19", "--jobs", "1"]).exit_code == 130
    folder = tmp_cwd / "renders" / "throw" / "frames"
    assert sorted(p.name for p in folder.iterdir() if p.name != "render-key.txt") == [
        f"frame_{i:05d}.png" for i in range(6)]  # no partial file either
    finished = {path.name: path.stat().st_mtime_ns for path in folder.glob("frame_*.png")}
    assert all(frame_is_complete(folder / name, (WIDTH, HEIGHT)) for name in finished)
    monkeypatch.setattr(FrameRenderer, "draw", original)
    drawn = counting(monkeypatch, FrameRenderer, "draw")
    assert runner.invoke(cli, ["render", str(throw), "--frames", "0-19", "--jobs", "1"]).exit_code == 0
    assert len(drawn) == 14
    assert {name: (folder / name).stat().st_mtime_ns for name in finished} == finished
    assert sorted(p.name for p in folder.glob("frame_*.png")) == [f"frame_{i:05d}.png" for i in range(20)]


@pytest.mark.slow
def test_a_render_over_its_budget_exits_4_keeps_its_frames_and_a_larger_budget_finishes_it(throw, tmp_cwd,
                                                                                            monkeypatch):
    """render.max_cost: with every frame costing 0.5 s more (a slowed renderer), 20 frames project to over 10 s, over
    a budget of 5 s (which the set-up and first frame stay within): the render stops after frame 2 with exit code 4,
    those frames complete on disk. The budget and the
    warning threshold draw nothing, so with a larger budget the next run keeps them and draws the other 18."""
    import time

    from animbatch.render.renderer import FrameRenderer

    original = FrameRenderer.draw

    def slow(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        time.sleep(0.5)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(FrameRenderer, "draw", slow)
    runner = CliRunner()
    result = runner.invoke(cli, ["render", str(throw), "--frames", "0-19", "--jobs", "1",
                                 "--set", "render.max_cost=5"])
    assert result.exit_code == 4, result.output
    assert "rendering stopped after 2 of 20 frames" in result.output and "render.max_cost" in result.output
    folder = tmp_cwd / "renders" / "throw" / "frames"
    kept = sorted(p.name for p in folder.glob("frame_*.png"))
    assert kept == ["frame_00000.png", "frame_00001.png"]
    assert all(frame_is_complete(folder / name, (WIDTH, HEIGHT)) for name in kept)
    monkeypatch.setattr(FrameRenderer, "draw", original)
    drawn = counting(monkeypatch, FrameRenderer, "draw")
    result = runner.invoke(cli, ["render", str(throw), "--frames", "0-19", "--jobs", "1", "--set",
                                 "render.max_cost=0", "--set", "solver.drift_warning=0.5", "--max-cost", "2h"])
    assert result.exit_code == 0, result.output
    assert len(drawn) == 18


def test_frames_of_another_picture_are_never_reused(throw, tmp_cwd, monkeypatch):
    """After a camera change, frames on disk from the old camera (same size, complete) are deleted and drawn again."""
    from animbatch.render.renderer import FrameRenderer

    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--frames", "0-4"]).exit_code == 0
    old = pixels(tmp_cwd / "renders/throw/frames/frame_00002.png")
    drawn = counting(monkeypatch, FrameRenderer, "draw")
    result = runner.invoke(cli, ["render", str(throw), "--frames", "0-4", "--set", "render.background=black"])
    assert result.exit_code == 0, result.output
    assert len(drawn) == 5
    new = pixels(tmp_cwd / "renders/throw/frames/frame_00002.png")
    assert old.mean() > 200 > 60 > new.mean()  # white background, then black


@pytest.mark.slow
def test_encode_needs_every_frame_and_writes_mp4_webm_and_gif(throw, tmp_cwd):
    """'animbatch encode' names the missing frames and the command to render them; once all are there it writes
    every format asked for, with the scene's frame count, size and frame rate (GIF: 1/100 s ticks, so 25 fps)."""
    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--frames", "0-29"]).exit_code == 0
    result = runner.invoke(cli, ["encode", str(throw)])
    assert result.exit_code != 0
    assert "20 of 50 frames are missing or incomplete" in result.output and "(30-49)" in result.output
    assert f"animbatch render {throw} --frames 30-49" in result.output
    assert runner.invoke(cli, ["render", str(throw), "--frames", "30-"]).exit_code == 0
    result = runner.invoke(cli, ["encode", str(throw), "--formats", "mp4,webm,gif"])
    assert result.exit_code == 0, result.output
    for kind in ("mp4", "webm", "gif"):
        reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / "throw" / f"throw.{kind}"))
        meta = next(reader)
        assert meta["size"] == (WIDTH, HEIGHT) and meta["fps"] == pytest.approx(25)
        assert sum(1 for _ in reader) == 50


@pytest.mark.slow
def test_encode_takes_the_size_the_frames_were_rendered_at_and_says_what_differs(throw, tmp_cwd):
    """After 'render --resolution 48x32' (frames kept as PNG), a plain 'encode' expects the scene's 96×64: it says the
    frames on disk are 48×32, how to encode them as they are, and how to draw them at 96×64. 'encode --resolution
    48x32' then writes a 48×32 video of all 50 frames; a missing frame's suggestion keeps the options given."""
    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--resolution", "48x32", "--jobs", "1"]).exit_code == 0
    result = runner.invoke(cli, ["encode", str(throw)])
    assert result.exit_code != 0
    message = " ".join(result.output.split())
    assert "50 of 50 frames are missing or incomplete" in message
    assert "the frames there are 48×32, but this scene, with these options, renders 96×64" in message
    assert "(--resolution 48x32," in message and f"animbatch render {throw} --frames 0-49" in message
    result = runner.invoke(cli, ["encode", str(throw), "--resolution", "48x32"])
    assert result.exit_code == 0, result.output
    reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / "throw" / "throw.mp4"))
    assert next(reader)["size"] == (48, 32) and sum(1 for _ in reader) == 50
    (tmp_cwd / "renders" / "throw" / "frames" / "frame_00007.png").unlink()
    result = runner.invoke(cli, ["encode", str(throw), "--resolution", "48x32"])
    message = " ".join(result.output.split())
    assert result.exit_code != 0 and "1 of 50 frames are missing or incomplete" in message
    assert f"render them first: animbatch render {throw} --frames 7-7 --resolution 48x32" in message


@pytest.mark.slow
def test_parallel_workers_draw_the_same_frames_as_one_process(throw, tmp_cwd):
    """--jobs 2 renders the 50 frames in two worker processes (spawned, each with its own renderer): the frames are
    identical to those of one process, and the report says two workers drew all 50."""
    import json

    runner = CliRunner()
    assert runner.invoke(cli, ["render", str(throw), "--jobs", "1", "--out", "one"]).exit_code == 0
    result = runner.invoke(cli, ["render", str(throw), "--jobs", "2", "--out", "two"])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_cwd / "two/throw/report.json").read_text())
    assert report["workers"] == 2 and report["frames_drawn"] == 50 and report["frames"] == "0-49"
    for index in range(50):
        name = f"throw/frames/frame_{index:05d}.png"
        assert np.array_equal(pixels(tmp_cwd / "one" / name), pixels(tmp_cwd / "two" / name)), index


def test_frame_ranges_parse_like_a_farm_manager_writes_them():
    assert parse_frames("120-239", 300) == FrameRange(120, 240)
    assert parse_frames("120-", 300) == FrameRange(120, 300)
    assert parse_frames("7", 300) == FrameRange(7, 8)
    assert parse_frames(None, 300) == FrameRange(0, 300)
    assert parse_frames("250-400", 300) == FrameRange(250, 300)
    for bad in ("300-310", "20-10", "a-b", "-5"):
        with pytest.raises(ValueError):
            parse_frames(bad, 300)
    assert FrameRange(0, 50).chunks(17) == [FrameRange(0, 17), FrameRange(17, 34), FrameRange(34, 50)]


FAKE_SBATCH = r"""#!/usr/bin/env bash
# A stand-in for SLURM's sbatch: records the call, runs the job (each array task in turn) at once, prints an id.
echo "$*" >> "$SBATCH_LOG"
array=""; wrap=""
for argument in "$@"; do
    case "$argument" in
        --array=*) array="${argument#--array=}" ;;
        --wrap=*) wrap="${argument#--wrap=}" ;;
    esac
done
if [ -n "$array" ]; then
    for task in $(seq "${array%-*}" "${array#*-}"); do SLURM_ARRAY_TASK_ID=$task bash -c "$wrap" >&2; done
else
    bash -c "$wrap" >&2
fi
echo $((RANDOM + 1000))
"""


@pytest.mark.slow
def test_slurm_script_submits_bake_then_an_array_of_render_chunks_then_encode(throw, tmp_cwd):
    """'animbatch farm slurm' writes a script whose three sbatch calls chain by afterok; run against a stand-in
    sbatch that executes each job (array tasks in turn), it produces the complete video: 50 frames in 2 tasks."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    result = CliRunner().invoke(cli, ["farm", "slurm", str(throw), "--chunk-size", "25", "--sbatch-option",
                                      "--time=00:10:00"])
    assert result.exit_code == 0, result.output
    script = tmp_cwd / "renders" / "throw" / "submit-slurm.sh"
    text = script.read_text()
    assert "--array=0-1" in text and text.count("--dependency=afterok:") == 2
    bin_dir = tmp_cwd / "bin"
    bin_dir.mkdir()
    (bin_dir / "sbatch").write_text(FAKE_SBATCH)
    (bin_dir / "sbatch").chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}:{Path(sys.executable).parent}:{os.environ['PATH']}",
           "SBATCH_LOG": str(tmp_cwd / "sbatch.log")}
    done = subprocess.run(["bash", str(script)], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    calls = (tmp_cwd / "sbatch.log").read_text().splitlines()
    assert len(calls) == 3 and all("--time=00:10:00" in call for call in calls)
    assert "--job-name=throw-bake" in calls[0] and "--array=0-1" in calls[1] and "afterok" in calls[2]
    reader = imageio_ffmpeg.read_frames(str(tmp_cwd / "renders" / "throw" / "throw.mp4"))
    assert next(reader)["size"] == (WIDTH, HEIGHT) and sum(1 for _ in reader) == 50


def run_openjd_job(template: dict, parameters: dict[str, str]) -> list[list[str]]:
    """A minimal stand-in for an OpenJD render manager: runs each step after the steps it depends on, one task per
    value of its task parameters, with ``{{Param.X}}`` and ``{{Task.Param.X}}`` filled in. Returns the commands."""
    import re
    import subprocess

    values = {f"Param.{d['name']}": parameters.get(d["name"], d.get("default")) for d in
              template["parameterDefinitions"]}
    done: set[str] = set()
    commands = []
    steps = list(template["steps"])
    while steps:
        step = next(s for s in steps if {d["dependsOn"] for d in s.get("dependencies", [])} <= done)
        definitions = step.get("parameterSpace", {}).get("taskParameterDefinitions", [])
        assert len(definitions) <= 1 and all(isinstance(d["range"], list) for d in definitions)
        tasks = [{}] if not definitions else [{f"Task.Param.{definitions[0]['name']}": v}
                                               for v in definitions[0]["range"]]
        for task in tasks:
            run = step["script"]["actions"]["onRun"]
            command = [re.sub(r"\{\{(.+?)\}\}", lambda m: str({**values, **task}[m.group(1)]), part)
                       for part in [run["command"], *run["args"]]]
            commands.append(command)
            if command[1:3] == ["-m", "animbatch"]:  # in this process (the SLURM test runs the real executable)
                result = CliRunner().invoke(cli, command[3:])
                assert result.exit_code == 0, (command, result.output)
            else:
                subprocess.run(command, check=True, capture_output=True, timeout=300)
        done.add(step["name"])
        steps.remove(step)
    return commands


@pytest.mark.slow
def test_openjd_template_bakes_then_renders_frame_chunks_then_encodes(throw, tmp_cwd):
    """'animbatch farm openjd' writes a job template of three steps (Bake; Render, one task per chunk of at most 25
    frames, after Bake; Encode after Render). Run step by step with its parameters, it gives the complete video."""
    import yaml

    result = CliRunner().invoke(cli, ["farm", "openjd", str(throw), "--chunk-size", "25"])
    assert result.exit_code == 0, result.output
    template = yaml.safe_load((tmp_cwd / "renders" / "throw" / "openjd-job.yaml").read_text())
    assert template["specificationVersion"] == "jobtemplate-2023-09"
    assert [step["name"] for step in template["steps"]] == ["Bake", "Render", "Encode"]
    render, encode = template["steps"][1:]
    assert render["dependencies"] == [{"dependsOn": "Bake"}] and encode["dependencies"] == [{"dependsOn": "Render"}]
    assert render["parameterSpace"]["taskParameterDefinitions"][0]["range"] == ["0-24", "25-49"]
    elsewhere = tmp_cwd / "shared"  # the output folder is a job parameter: a render manager may map it
    commands = run_openjd_job(template, {"OutputDir": str(elsewhere)})
    assert [c[c.index("--frames") + 1] for c in commands if "--frames" in c] == ["0-24", "25-49"]
    reader = imageio_ffmpeg.read_frames(str(elsewhere / "throw" / "throw.mp4"))
    assert next(reader)["size"] == (WIDTH, HEIGHT) and sum(1 for _ in reader) == 50
    assert len(list((elsewhere / "throw" / "frames").glob("*.png"))) == 50


def test_openjd_template_passes_the_reference_validator(throw, tmp_cwd):
    """Where the reference implementation (openjd-model) is installed, it accepts the template."""
    model = pytest.importorskip("openjd.model")
    import yaml

    CliRunner().invoke(cli, ["farm", "openjd", str(throw), "--set", "bodies[red].mass=2"])
    template = yaml.safe_load((tmp_cwd / "renders" / "throw" / "openjd-job.yaml").read_text())
    assert model.decode_job_template(template=template).name == "animbatch throw"


def test_an_interrupted_checkpointed_bake_resumes_from_its_last_checkpoint(throw, monkeypatch):
    """bake --checkpoint-every 10 on the 50-frame scene, interrupted during its third segment: the checkpoint holds
    frames 0-20 and no cache exists. The next bake integrates only the remaining segments (frames 20-49) and, with
    semi-implicit Euler (no state carried between steps), gives exactly the uninterrupted trajectory."""
    from animbatch.sim.integrators import FixedStepIntegrator

    overrides = ["solver.method=symplectic_euler", "solver.dt=0.001"]
    plain = bake(api.load_scene(throw, overrides), out_dir="plain").trajectory
    scene = api.load_scene(throw, overrides)
    original = FixedStepIntegrator.integrate
    starts = []

    def interrupted(self, system, y0, times, **kwargs):
        starts.append(round(float(times[0]) * 25))
        if len(starts) == 3:
            raise KeyboardInterrupt
        return original(self, system, y0, times, **kwargs)

    monkeypatch.setattr(FixedStepIntegrator, "integrate", interrupted)
    with pytest.raises(KeyboardInterrupt):
        bake(scene, checkpoint_every=10)
    folder = Path("renders/throw/cache")
    assert [p.name.split("-")[0] for p in folder.iterdir()] == ["checkpoint"] and starts == [0, 10, 20]
    starts.clear()
    monkeypatch.setattr(FixedStepIntegrator, "integrate", lambda self, *a, **k: starts.append(
        round(float(a[2][0]) * 25)) or original(self, *a, **k))
    resumed = bake(scene, checkpoint_every=10)
    assert starts == [20, 30, 40]
    assert np.array_equal(resumed.trajectory.positions, plain.positions)
    assert np.array_equal(resumed.trajectory.velocities, plain.velocities)
    assert [p.name.split("-")[0] for p in folder.iterdir()] == ["trajectory"]  # the checkpoint went with success


def test_background_frame_writer_reports_frames_in_order_once_on_disk(tmp_path):
    """Frames handed to the background writer are reported in order, each only once its file is a whole PNG, and
    never more than ``depth`` wait at once."""
    from animbatch.encode.images import BackgroundFrameWriter, PngSequenceWriter

    writer = PngSequenceWriter(tmp_path)
    reported = []

    def written(index, seconds):
        assert frame_is_complete(writer.path_of(index), (WIDTH, HEIGHT)) and seconds >= 0
        reported.append(index)

    with BackgroundFrameWriter(writer, written, depth=2) as background:
        for index in range(7):
            background.submit(index, np.full((HEIGHT, WIDTH, 3), 30 * index, np.uint8))
            assert len(reported) >= index - 1  # at most two frames waiting
    assert reported == list(range(7))
    assert pixels(writer.path_of(6))[0, 0].tolist() == [180, 180, 180]


def test_background_frame_writer_finishes_handed_frames_when_interrupted_and_raises_write_errors(tmp_path):
    """Ctrl-C while frames wait to be written: they are still finished whole, and the interrupt goes on. A frame
    that cannot be written raises its error from the writer, not silently."""
    from animbatch.encode.images import BackgroundFrameWriter, PngSequenceWriter

    writer = PngSequenceWriter(tmp_path / "frames")
    with pytest.raises(KeyboardInterrupt):
        with BackgroundFrameWriter(writer, lambda index, seconds: None, depth=3) as background:
            for index in range(3):
                background.submit(index, np.zeros((HEIGHT, WIDTH, 3), np.uint8))
            raise KeyboardInterrupt
    assert all(frame_is_complete(writer.path_of(index), (WIDTH, HEIGHT)) for index in range(3))
    blocked = tmp_path / "not-a-folder"
    blocked.write_text("a file where the frames folder should be")
    with pytest.raises(OSError):
        with BackgroundFrameWriter(PngSequenceWriter(blocked), lambda index, seconds: None) as background:
            background.submit(0, np.zeros((HEIGHT, WIDTH, 3), np.uint8))


@pytest.mark.slow
def test_a_streamed_render_puts_every_frame_in_every_video_in_order(throw, tmp_cwd):
    """render (one process) pipes each frame into ffmpeg as it is drawn: the mp4 and the gif hold all 50 frames at
    the scene's size and rate, and frame k of the video is frame k drawn (the PNG of the same run), not a neighbour
    (the balls move and the clock changes from frame to frame)."""
    from animbatch.farm.run import run as farm_run

    report = farm_run(throw, overrides=["render.formats=[mp4, gif, png]"], out_dir="renders")
    assert report.workers == 1 and report.frames_drawn == 50 and report.stages["encode"] >= 0
    folder = tmp_cwd / "renders" / "throw"
    for kind in ("mp4", "gif"):
        reader = imageio_ffmpeg.read_frames(str(folder / f"throw.{kind}"), pix_fmt="rgb24")
        meta = next(reader)
        assert meta["size"] == (WIDTH, HEIGHT) and meta["fps"] == pytest.approx(25)
        video = [np.frombuffer(frame, np.uint8).reshape(HEIGHT, WIDTH, 3).astype(float) for frame in reader]
        assert len(video) == 50
        if kind == "mp4":  # each video frame is nearest to the PNG of its own index among its neighbours'
            drawn = [pixels(folder / "frames" / f"frame_{j:05d}.png").astype(float) for j in range(50)]
            for k in range(50):
                near = range(max(0, k - 2), min(50, k + 3))
                assert min(near, key=lambda j: np.square(video[k] - drawn[j]).mean()) == k, k


def test_a_video_writer_whose_encoder_died_says_so_and_leaves_no_file(tmp_path):
    """ffmpeg gone mid-video (killed, out of disk): the next frame raises RenderError naming the video, and leaving
    the writer removes the partial file; nothing appears under the final name."""
    from animbatch.encode import VideoWriter
    from animbatch.errors import RenderError

    target = tmp_path / "out.mp4"
    with pytest.raises(RenderError, match="ffmpeg stopped while encoding .*out.mp4"):
        with VideoWriter(target, (WIDTH, HEIGHT), 25) as writer:
            writer.write(np.zeros((HEIGHT, WIDTH, 3), np.uint8))
            writer._process.kill()
            writer._process.wait()
            for _ in range(50):  # the pipe's buffer may take a frame or two before the write fails
                writer.write(np.zeros((HEIGHT, WIDTH, 3), np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_the_next_run_sweeps_what_a_killed_writer_left_and_keeps_what_live_writers_write(throw, tmp_cwd):
    """A writer killed with SIGKILL leaves its temporary files for good (issue 40: '.frame_00023.png.partial-24437.png',
    '.throw.mp4.partial-24437.mp4'). The next run removes those whose process is gone from this host, in the scene's
    output, frames and cache folders, and keeps a running writer's and another host's (a farm's shared folder)."""
    import subprocess
    import sys

    from animbatch.files import partial_path, sweep_partials

    folder = tmp_cwd / "renders" / "throw"
    (folder / "frames").mkdir(parents=True)
    (folder / "cache").mkdir()
    killed = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    killed.kill()
    killed.wait()  # its pid is free now: nothing of this host runs under it
    written_by_killed = subprocess.run(
        [sys.executable, "-c", "import sys; from pathlib import Path; from animbatch.files import partial_path; "
         "[print(partial_path(Path(p))) for p in sys.argv[1:]]", *(str(folder / name) for name in (
             "throw.mp4", "frames/frame_00023.png", "cache/trajectory-x.npz"))],
        capture_output=True, text=True, check=True).stdout.split()
    left = [Path(name) for name in written_by_killed]
    legacy = folder / "frames" / f".frame_00024.png.partial-{killed.pid}.png"  # named by an older version
    live = partial_path(folder / "frames" / "frame_00099.png")  # this process: a writer still running
    elsewhere = folder / f".throw.mp4.partial-othernode-{killed.pid}.mp4"  # another host's, on a shared folder
    for path in [*left, legacy, live, elsewhere]:
        path.write_bytes(b"half a file")
    assert sorted(sweep_partials(folder / "frames")) == sorted([left[1], legacy])
    left[1].write_bytes(b"half a file")
    legacy.write_bytes(b"half a file")
    assert api.run(throw, out_dir="renders").frame_count == 50
    assert not any(path.exists() for path in [*left, legacy])
    assert live.exists() and elsewhere.exists()
    assert (folder / "throw.mp4").is_file()
