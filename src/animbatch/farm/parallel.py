"""Rendering frame chunks in parallel worker processes on one machine.

Rendering, not simulation, dominates a run's wall time; so frames are split into contiguous chunks rendered by
separate processes (``spawn``ed: no VTK state is inherited), each with its own renderer, all reading the baked
trajectory from the cache. Each worker's software rasteriser (Mesa llvmpipe) is held to one thread, so that workers
do not fight over cores. A worker costs about a second to start, so small jobs stay in the calling process: at
least :data:`MIN_FRAMES_PER_WORKER` frames per worker.

Measured on 2 cores without a GPU (docs/farm.md): two workers draw 300 frames 1.81× faster than one process held to
one core, but only 1.07× faster than one free process, since llvmpipe already rasterises with a thread per core.
"""

from __future__ import annotations

import math
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from animbatch import stages
from animbatch.farm.frame_files import FrameRange, RangeResult, render_frames
from animbatch.scene import LoadedScene
from animbatch.scene.overrides import Override
from animbatch.trajectory import Trajectory

#: What a worker needs to rebuild a loaded scene: its text, file name (for messages), overrides, path and name.
SceneRecipe = tuple[str, str, tuple[Override, ...], str | None, str]

#: Below this many frames per worker, starting worker processes costs more than it saves.
MIN_FRAMES_PER_WORKER = 24


def worker_count(jobs: int | None, frames: int) -> int:
    """Processes to use for ``frames`` frames: ``jobs`` (default: one per core), fewer for short ranges."""
    wanted = jobs if jobs else (os.cpu_count() or 1)
    return max(1, min(wanted, frames // MIN_FRAMES_PER_WORKER))


def _limit_rasteriser_threads() -> None:
    os.environ["LP_NUM_THREADS"] = "1"  # Mesa llvmpipe: one thread per worker process
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def _render_chunk(recipe: SceneRecipe, trajectory_path: str, chunk: FrameRange, out_dir: str,
                  backend: str) -> RangeResult:
    """In a worker: rebuild the scene from its text and overrides, load the trajectory, render one chunk."""
    text, filename, overrides, path, name = recipe
    scene = stages.parse_scene(text, filename=filename, overrides=overrides, default_name=name,
                               path=Path(path) if path else None)
    trajectory = Trajectory.load(trajectory_path)
    return render_frames(scene, trajectory, chunk, out_dir=out_dir, backend=backend)


def render_in_parallel(scene: LoadedScene, trajectory_path: str | Path, frames: FrameRange, *, workers: int,
                       out_dir: str | Path, backend: str,
                       on_chunk: Callable[[RangeResult], None] | None = None) -> RangeResult:
    """Render ``frames`` of ``scene`` in ``workers`` processes, one contiguous chunk each; the merged result. The
    workers rebuild the scene from its text, not its file, so that a save during the render changes nothing."""
    size = math.ceil(len(frames) / workers)
    chunks = frames.chunks(size)
    total = RangeResult()
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_limit_rasteriser_threads) as pool:
        recipe: SceneRecipe = (scene.text, scene.source.filename, scene.overrides,
                               str(scene.path) if scene.path else None, scene.name)
        futures = [pool.submit(_render_chunk, recipe, str(trajectory_path), chunk, str(out_dir), backend)
                   for chunk in chunks]
        for future in as_completed(futures):
            result = future.result()
            total.drawn += result.drawn
            total.skipped += result.skipped
            total.render_seconds += result.render_seconds
            total.write_seconds += result.write_seconds
            total.backend = total.backend or result.backend
            if on_chunk is not None:
                on_chunk(result)
    total.drawn.sort()
    total.skipped.sort()
    return total
