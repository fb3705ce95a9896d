"""Batches of scenes on Dask (``animbatch batch``): each scene is a small task graph, bake → render chunks in
parallel → encode, submitted to a ``dask.distributed`` cluster: a ``LocalCluster`` sized to the machine, or an
existing scheduler (``--scheduler tcp://host:8786``, e.g. one started by dask-jobqueue on SLURM or PBS).

Every stage is idempotent and writes atomically (see :mod:`animbatch.farm`), so a task that Dask re-runs (its
worker died, or it raised and has retries left) redoes only what is missing: a finished frame is never drawn twice.
A scene that fails does not stop the others; the batch reports every job and then fails as a whole.
"""

from __future__ import annotations

import datetime
import os
import platform
import shutil
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from animbatch import stages
from animbatch.cluster import WORKER_ENV, connect
from animbatch.errors import SimulationError
from animbatch.farm import bake, render_frames
from animbatch.farm.encode import encode
from animbatch.farm.frame_files import FrameRange, frames_folder, prepare_frames, sweep_killed_writers
from animbatch.files import write_json_atomic
from animbatch.stopwatch import Stopwatch
from animbatch.trajectory import Trajectory
from animbatch.version import __version__

#: Frames per render task by default: enough to amortise a renderer's start-up, small enough to spread a scene.
CHUNK_SIZE = 48


@dataclass(frozen=True)
class Job:
    """One scene to render: its file, ``--set`` style overrides, and a label for the summary."""
    scene_path: str
    overrides: tuple[Any, ...] = ()
    label: str = ""


@dataclass
class JobResult:
    """How a job ended: ``status`` ok or failed (with ``error``), its frame count, wall time [s], outputs and
    report file."""
    label: str
    status: str
    frames: int = 0
    wall_time: float = 0.0
    error: str = ""
    outputs: list[str] = field(default_factory=list)
    report: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)


# ------------------------------------------------------------------------------------------------ tasks (on workers)


def bake_task(scene_path: str, overrides: Sequence[Any], out_dir: str) -> dict[str, Any]:
    """Simulate (or reuse the cache) and prepare the frames folder; what the render tasks need to know."""
    scene = stages.load_scene(scene_path, list(overrides))
    sweep_killed_writers(scene, out_dir)
    started = time.perf_counter()
    try:
        result = bake(scene, out_dir=out_dir)
    except SimulationError as error:  # the job's report says why, as for 'animbatch render'
        write_json_atomic(Path(out_dir) / scene.name / "report.json", stages.failure_report(scene, error, Stopwatch()))
        raise
    prepare_frames(scene, result.trajectory, out_dir)
    return {"cache": str(result.path), "reused": result.reused, "seconds": time.perf_counter() - started,
            "frames": result.trajectory.frame_count, "solver_stats": result.trajectory.solver_stats,
            "ledger": result.trajectory.ledger}


def render_task(scene_path: str, overrides: Sequence[Any], out_dir: str, baked: dict[str, Any], start: int,
                stop: int, backend: str) -> dict[str, Any]:
    """Render frames ``start`` … ``stop - 1`` from the baked cache (skipping complete ones)."""
    for name, value in WORKER_ENV.items():
        os.environ.setdefault(name, value)

    scene = stages.load_scene(scene_path, list(overrides))
    trajectory = Trajectory.load(baked["cache"])
    started = time.perf_counter()
    result = render_frames(scene, trajectory, FrameRange(start, stop), out_dir=out_dir, backend=backend)
    return {"drawn": len(result.drawn), "skipped": len(result.skipped),
            "seconds": time.perf_counter() - started, "backend": result.backend}


def encode_task(scene_path: str, overrides: Sequence[Any], out_dir: str, baked: dict[str, Any],
                *chunks: dict[str, Any], plot: bool = False) -> dict[str, Any]:
    """Encode the videos and write the job's report.json (with ``plot``, quantities.png too); returns the
    report."""
    scene = stages.load_scene(scene_path, list(overrides))
    kinds = tuple(kind for kind in scene.spec.render.formats if kind != "png")
    outputs: list[str] = []
    seconds = 0.0
    if kinds:
        encoded = encode(scene, baked["frames"], out_dir=out_dir, kinds=kinds)
        outputs += [str(path) for path in encoded.outputs]
        seconds = encoded.seconds
    folder = frames_folder(scene, out_dir)
    if "png" in scene.spec.render.formats:
        outputs.append(str(folder))
    else:
        shutil.rmtree(folder, ignore_errors=True)

    quantities = stages.write_quantities(scene, stages.compile_model(scene), Trajectory.load(baked["cache"]),
                                      Path(out_dir) / scene.name, plot=plot)
    report = {"scene": scene.name, "scene_file": scene_path, "status": "ok", "frames": baked["frames"],
              "frames_drawn": sum(chunk["drawn"] for chunk in chunks),
              "frames_skipped": sum(chunk["skipped"] for chunk in chunks), "render_tasks": len(chunks),
              "stages": {"load_cache" if baked["reused"] else "simulate": baked["seconds"],
                         "render": sum(chunk["seconds"] for chunk in chunks), "encode": seconds},
              "cache": baked["cache"], "cache_reused": baked["reused"], "solver_stats": baked["solver_stats"],
              "ledger": baked.get("ledger", {}), "quantities": [str(path) for path in quantities], "outputs": outputs,
              "backend": next((c["backend"] for c in chunks if c["backend"]), ""),
              "package_version": __version__, "host": platform.node(),
              "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "resolution": list(scene.spec.render.resolution), "fps": scene.spec.fps}  # as a render's report
    path = Path(out_dir) / scene.name / "report.json"
    write_json_atomic(path, report)
    return {**report, "report": str(path)}


# ------------------------------------------------------------------------------------------------ the batch (client)


def frame_count(job: Job) -> tuple[str, int]:
    """The scene's name and number of frames, read on the client to plan the render chunks (raises SceneError)."""
    scene = stages.load_scene(job.scene_path, list(job.overrides))
    return scene.name, scene.spec.frame_count


def submit(client: Any, job: Job, out_dir: str, *, chunk_size: int, backend: str, retries: int,
           plot: bool = False) -> Any:
    """Submit one job's graph; the future of its encode task (whose result is the report)."""
    _, frames = frame_count(job)
    tag = uuid.uuid4().hex[:8]
    name = job.label or Path(job.scene_path).stem
    # the workers of a cluster given by --scheduler run in folders of their own: paths as the client means them
    job = replace(job, scene_path=str(Path(job.scene_path).resolve()))
    out_dir = str(Path(out_dir).resolve())
    options = {"pure": False, "retries": retries}
    baked = client.submit(bake_task, job.scene_path, job.overrides, out_dir, key=f"bake-{name}-{tag}", **options)
    chunks = [client.submit(render_task, job.scene_path, job.overrides, out_dir, baked, chunk.start, chunk.stop,
                            backend, key=f"render-{name}-{chunk}-{tag}", **options)
              for chunk in FrameRange(0, frames).chunks(chunk_size)]
    return client.submit(encode_task, job.scene_path, job.overrides, out_dir, baked, *chunks, plot=plot,
                         key=f"encode-{name}-{tag}", **options)


def run_batch(jobs: Sequence[Job], *, out_dir: str | Path = "renders", workers: int | None = None,
              scheduler: str | None = None, chunk_size: int = CHUNK_SIZE, backend: str = "auto", retries: int = 2,
              client: Any = None, on_result: Callable[[JobResult], None] | None = None,
              plot: bool = False) -> list[JobResult]:
    """Run every job to the end (a failed one does not stop the others); one result per job, in job order. With
    ``plot``, each job also draws its quantities.png (for the report page)."""
    from distributed import as_completed  # optional and heavy: only for Dask batches

    own = client is None
    cluster = None
    if own:
        client, cluster = connect(workers, scheduler)
    started = time.perf_counter()
    results: dict[int, JobResult] = {}
    try:
        futures = {}
        for number, job in enumerate(jobs):
            label = job.label or Path(job.scene_path).stem
            try:
                futures[submit(client, job, str(out_dir), chunk_size=chunk_size, backend=backend,
                               retries=retries, plot=plot)] = number
            except Exception as error:  # an invalid scene: reported, the others still run
                results[number] = JobResult(label, "failed", error=str(error))
                if on_result:
                    on_result(results[number])
        for future in as_completed(list(futures)):
            number = futures[future]
            job = jobs[number]
            label = job.label or Path(job.scene_path).stem
            try:
                report = future.result()
                results[number] = JobResult(label, "ok", report["frames"], time.perf_counter() - started,
                                            outputs=report["outputs"], report=report["report"],
                                            metrics={"solver_stats": report["solver_stats"],
                                                     "cache": report["cache"], "ledger": report.get("ledger", {})})
            except Exception as error:
                results[number] = JobResult(label, "failed", wall_time=time.perf_counter() - started,
                                            error=f"{type(error).__name__}: {error}")
            if on_result:
                on_result(results[number])
    finally:
        if own:
            client.close()
            if cluster is not None:
                cluster.close()
    return [results[number] for number in range(len(jobs))]


def summary(results: Sequence[JobResult]) -> str:
    """The batch's table: scene, frames, wall time (since the batch started), status."""
    width = max([len(r.label) for r in results] + [5])
    lines = [f"{'scene':<{width}}  {'frames':>6}  {'wall time':>9}  status", "-" * (width + 28)]
    for r in results:
        status = r.status if r.status == "ok" else f"FAILED: {r.error.splitlines()[0][:100] if r.error else ''}"
        warned = (r.metrics or {}).get("ledger", {}).get("warnings", [])
        if warned:  # it ran, but the ledger says the result is not to be trusted as it is
            status += f" with {len(warned)} accuracy warning{'s' if len(warned) > 1 else ''}: {warned[0][:100]}…"
        lines.append(f"{r.label:<{width}}  {r.frames:>6}  {r.wall_time:>8.1f}s  {status}")
    failed = sum(r.status != "ok" for r in results)
    lines.append(f"{len(results) - failed} of {len(results)} jobs succeeded")
    return "\n".join(lines)
