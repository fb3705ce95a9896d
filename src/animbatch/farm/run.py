"""A whole run on this machine, as a render farm does it: bake (simulate or reuse the cache), render the frames not
yet on disk (in worker processes), encode, and write the run's report. ``animbatch render`` is this."""

from __future__ import annotations

import contextlib
import datetime as _dt
import platform
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from animbatch.compile.plan import RunPlan
from animbatch.compile.stopwatches import stopwatch_line, stopwatch_readings
from animbatch.encode import PngSequenceWriter
from animbatch.errors import SimulationError
from animbatch.farm.cache import bake
from animbatch.farm.encode import encode
from animbatch.farm.frame_files import (
    FrameRange,
    RangeResult,
    draw_frames,
    frames_folder,
    prepare_frames,
    sweep_killed_writers,
)
from animbatch.farm.parallel import render_in_parallel, worker_count
from animbatch.farm.streamed_render import resumable_frames, stream_frames
from animbatch.files import write_json_atomic
from animbatch.progress import Progress
from animbatch.scene import LoadedScene
from animbatch.scene.overrides import Override
from animbatch.sim.ledger import summary as ledger_summary
from animbatch.sim.ledger import warn_again
from animbatch.stages import check_trajectory, failure_report, load_scene, plan, write_quantities
from animbatch.stopwatch import Stopwatch
from animbatch.trajectory import Trajectory
from animbatch.version import __version__


def _render_whole(run: RunPlan, trajectory: Trajectory, out_dir: str | Path, backend: str,
                  on_frame: Callable[[int], None]) -> tuple[RangeResult, list[Path], float]:
    """Every frame in this process: streamed into the encoders, or, when frames of this picture are on disk (an
    interrupted farm or ``--jobs`` render), the missing ones drawn as PNGs and then encoded. Returns the frames
    drawn, the outputs and the encoding time [s] (after the last frame, when streamed)."""
    scene = run.scene
    if not resumable_frames(scene, trajectory, out_dir):
        streamed = stream_frames(run, trajectory, out_dir=out_dir, backend=backend, on_frame=on_frame)
        return streamed.frames, streamed.outputs, streamed.encode_seconds
    folder = prepare_frames(scene, trajectory, out_dir)
    rendered = draw_frames(run, trajectory, FrameRange(0, trajectory.frame_count), folder, backend=backend,
                           on_frame=on_frame)
    outputs, encode_seconds = finish_outputs(scene, trajectory.frame_count, out_dir)
    return rendered, outputs, encode_seconds


def _size(resolution: list[int]) -> tuple[int, int]:
    width, height = resolution
    return width, height


def _scene_of(scene: str | Path | LoadedScene | RunPlan, overrides: Sequence[Override]) -> LoadedScene:
    """The loaded scene of a file, a loaded scene or a run plan, with ``overrides`` applied."""
    if isinstance(scene, RunPlan):
        scene = scene.scene
    if isinstance(scene, LoadedScene):
        return scene.changed(overrides) if overrides else scene
    return load_scene(scene, overrides)


@contextlib.contextmanager
def _trajectory_file(trajectory: Trajectory, source: Path | None, folder: Path) -> Iterator[Path]:
    """The file of ``trajectory`` for worker processes: ``source`` when it has one, else a temporary file in
    ``folder``, deleted afterwards."""
    if source is not None:
        yield source
        return
    with tempfile.TemporaryDirectory(dir=folder, prefix=".trajectory-") as temporary:
        yield trajectory.save(Path(temporary) / "trajectory.npz")


def finish_outputs(scene: LoadedScene, frame_count: int, out_dir: str | Path) -> tuple[list[Path], float]:
    """Once every frame is on disk: encode each video format the scene asks for, then keep the frames if ``png`` is
    one of its formats (without frames left over from a longer run) or delete them. Returns the outputs and the
    encoding time [s]."""
    formats = scene.spec.render.formats
    folder = frames_folder(scene, out_dir)
    outputs: list[Path] = []
    seconds = 0.0
    videos = tuple(kind for kind in formats if kind != "png")
    if videos:
        encoded = encode(scene, frame_count, out_dir=out_dir, kinds=videos)
        seconds = encoded.seconds
        outputs += encoded.outputs
    if "png" in formats:
        PngSequenceWriter(folder).remove_beyond(frame_count)
        outputs.append(folder)
    else:
        shutil.rmtree(folder, ignore_errors=True)
    return outputs, seconds


@dataclass
class RunReport:
    """Everything a run did, written as ``report.json`` beside its outputs."""

    scene: str
    scene_file: str | None
    physics_hash: str
    package_version: str
    stages: dict[str, float]  # seconds per stage: load, compile, simulate (or load_trajectory), render, encode
    solver: dict[str, Any]
    solver_stats: dict[str, Any]
    frame_count: int
    resolution: tuple[int, int]
    fps: int
    backend: str
    outputs: list[str]
    trajectory_file: str | None = None
    particle_stats: dict[str, Any] = field(default_factory=dict)
    created: str = field(default_factory=lambda: _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
    host: str = field(default_factory=platform.node)
    status: str = "ok"
    frames: str = ""  # the range rendered, "0-299"
    frames_drawn: int = 0  # frames drawn by this run (the others were complete on disk)
    frames_skipped: int = 0
    workers: int = 1  # render processes
    cache: str | None = None  # the baked trajectory file
    cache_reused: bool = False
    ledger: dict[str, Any] = field(default_factory=dict)  # the accuracy ledger (see animbatch.sim.ledger)
    quantities: list[str] = field(default_factory=list)  # quantities.csv (and .png) beside the report
    stopwatches: dict[str, dict[str, Any]] = field(default_factory=dict)  # name -> start, stop, elapsed, expected

    def summary(self) -> str:
        """One line for logs: outputs, frames, timings, solver work and the accuracy ledger."""
        solver = ledger_summary(self.ledger) if self.ledger else str(self.solver_stats.get("method"))
        if self.particle_stats:
            particles = self.particle_stats
            solver += f"; particles: {particles.get('born')} born, peak {particles.get('peak_live')} live"
        if self.trajectory_file:
            solver = f"from {self.trajectory_file} ({solver})"
        timings = ", ".join(f"{stage} {seconds:.2f} s" for stage, seconds in self.stages.items())
        width, height = self.resolution
        target = self.outputs[0] if self.outputs else "(no output)"
        watches = "".join(f" | {stopwatch_line(name, reading)}" for name, reading in self.stopwatches.items())
        count = f"{self.frame_count} frames"
        if self.frames and self.frames != f"0-{self.frame_count - 1}":  # a range (--frames): what this run did
            count = (f"frames {self.frames} of {self.frame_count} ({self.frames_drawn} drawn, {self.frames_skipped} "
                     "complete already)")
        return (f"{self.scene}: {count} {width}×{height} @ {self.fps} fps -> {target} | "
                f"{timings} | {solver} | {self.backend}{watches}")

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """In IPython's terminal: the summary line, not every field."""
        printer.text(self.summary())

    def _repr_html_(self) -> str:
        """In a Jupyter notebook: the video, the accuracy ledger and the energy plot (with ``plot``)."""
        from animbatch.notebook_display import run_html

        return run_html(self.scene, self.summary(), self.outputs, self.ledger, self.quantities)


def run(scene: str | Path | LoadedScene | RunPlan, *, overrides: Sequence[Override] = (),
        out_dir: str | Path = "renders", backend: str = "auto", trajectory: str | Path | Trajectory | None = None,
        progress: Progress | None = None, jobs: int | None = None, frames: str | None = None,
        plot: bool = False) -> RunReport:
    """Bake, render and encode one scene, as a render farm does, on this machine; write its report.

    ``scene``: a scene file, a loaded scene (changed from Python, say) or its run plan; ``overrides`` (``--set``
    style) are applied to it first.

    * **bake**: ``trajectory`` when given (a :class:`Trajectory` or its file, checked to be this scene's physics),
      else the cached one (``renders/<scene>/cache/``) when the physics, solver settings and package version match,
      else simulated and cached;
    * **render** and **encode**: by default in this process, every frame streamed into the encoders as it is drawn
      (PNG frames too when ``png`` is one of the formats; see :mod:`animbatch.farm.streamed_render`). With ``jobs`` > 1,
      or when frames of this picture are already on disk (an interrupted ``jobs`` or farm render), the frames not
      yet complete are drawn as PNGs into ``renders/<scene>/frames/`` (in ``jobs`` worker processes, fewer for
      short animations) and then encoded; the frame files are deleted unless ``png`` is one of the formats.

    With ``frames`` (``"120-239"``) only that range is rendered, and nothing is encoded (``animbatch encode`` does
    that once every range is done); the report is written for whole runs only, with ``quantities.csv`` (and, with
    ``plot``, ``quantities.png``) beside it.
    """
    watch = Stopwatch()
    progress = progress or Progress(enabled=False)
    with watch.stage("load"):
        loaded = _scene_of(scene, overrides)
    sweep_killed_writers(loaded, out_dir)  # what a killed run left half-written is never mistaken for output
    with watch.stage("compile"):
        compiled = scene if isinstance(scene, RunPlan) and not overrides else plan(loaded)
    scene = loaded
    model = compiled.model
    cache = None
    source: Path | None = None
    if trajectory is not None:
        with watch.stage("load_trajectory"):
            if not isinstance(trajectory, Trajectory):
                source = Path(trajectory)
                trajectory = Trajectory.load(source)
                warn_again(trajectory.ledger)
            check_trajectory(scene, model, trajectory, source or "the trajectory given")  # before drawing
    else:
        try:
            baked = bake(compiled, out_dir=out_dir, progress=progress)
        except SimulationError as error:  # the reason goes in the report too, where batch tools look for it
            write_json_atomic(Path(out_dir) / scene.name / "report.json", failure_report(scene, error, watch))
            raise
        watch.add("load_cache" if baked.reused else "simulate", baked.seconds)
        trajectory, source, cache = baked.trajectory, baked.path, baked
    span = compiled.timeline.frames(frames)
    spec = scene.spec
    # one process streams the whole animation into the encoders; --jobs N draws PNG frames in N processes, and
    # --frames draws a range for a farm (both encode from the PNGs)
    workers = worker_count(jobs, len(span)) if jobs else 1
    started = time.perf_counter()
    encode_seconds = 0.0
    with progress.task("render", len(span)) as on_frame:
        def each(i: int) -> None:
            on_frame(i, float(trajectory.times[i]))

        if frames is None and workers == 1:
            rendered, outputs, encode_seconds = _render_whole(compiled, trajectory, out_dir, backend, each)
        else:
            folder = prepare_frames(scene, trajectory, out_dir)  # before any worker starts: stale frames go
            if workers > 1:
                with _trajectory_file(trajectory, source, folder) as shared:  # what the worker processes read
                    def each_drawn(chunk: RangeResult) -> None:
                        for i in chunk.drawn:
                            each(i)

                    rendered = render_in_parallel(scene, shared, span, workers=workers, out_dir=out_dir,
                                                  backend=backend, on_chunk=each_drawn)
            else:
                # checked above (a baked trajectory is this scene's by its cache key), and the folder just prepared
                rendered = draw_frames(compiled, trajectory, span, folder, backend=backend, on_frame=each)
            outputs = [frames_folder(scene, out_dir)]
            if frames is None:
                outputs, encode_seconds = finish_outputs(scene, trajectory.frame_count, out_dir)
    # the stage's wall time (with worker processes the frames' own times add up to more than the stage took); when
    # streamed, encoding overlapped it and only ffmpeg's tail after the last frame counts as encoding
    watch.add("render", time.perf_counter() - started - encode_seconds)
    if frames is None and any(kind != "png" for kind in spec.render.formats):
        watch.add("encode", encode_seconds)
    report = RunReport(scene.name, str(scene.path) if scene.path else None, trajectory.physics_hash, __version__,
                       dict(watch.seconds), trajectory.solver, trajectory.solver_stats, trajectory.frame_count,
                       _size(spec.render.resolution), spec.fps, rendered.backend or "(none: frames were complete)",
                       [str(p) for p in outputs], str(source) if source is not None and cache is None else None,
                       trajectory.particle_stats, frames=str(span), frames_drawn=len(rendered.drawn),
                       frames_skipped=len(rendered.skipped), workers=workers,
                       cache=str(cache.path) if cache else None, cache_reused=bool(cache and cache.reused),
                       ledger=trajectory.ledger,
                       stopwatches={reading.name: reading.as_dict()
                                    for reading in stopwatch_readings(spec.stopwatches, trajectory)})
    if frames is None:
        folder = Path(out_dir) / scene.name
        report.quantities = [str(path) for path in write_quantities(scene, model, trajectory, folder, plot=plot)]
        camera = spec.render.use_camera
        write_json_atomic(folder / ("report.json" if camera is None else f"report-{camera}.json"), report.__dict__)
    return report
