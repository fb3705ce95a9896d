"""Rendering a range of frames from a baked trajectory into ``renders/<scene>/frames/frame_00000.png`` …

Idempotent: a frame whose PNG is complete (it decodes, and has the scene's resolution) is skipped; a missing,
truncated or corrupt one is drawn again. Each PNG is written atomically, so a frame file either does not exist or is
complete, whatever interrupts the run. The camera is fitted to the whole trajectory, never to the range, so any
chunking of the frames draws the same pixels.

Frames on disk are only reused for the same picture: ``frames/render-key.txt`` holds a hash of everything that
decides the pixels (the trajectory's physics and solver, every render setting but the output formats and video
encoding, colours, the code that simulated the trajectory and the code that draws it: see
:mod:`animbatch.provenance`). When it differs, the old frames are deleted before any is drawn.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from animbatch.compile.plan import RunPlan
from animbatch.encode.images import BackgroundFrameWriter, FrameWriter, PngSequenceWriter
from animbatch.errors import RenderError
from animbatch.farm.cache import simulation_settings
from animbatch.files import sweep_partials, write_text_atomic
from animbatch.provenance import drawing_code
from animbatch.render.backend import select_backend
from animbatch.render.renderer import FrameRenderer
from animbatch.scene import LoadedScene
from animbatch.sim.integrators.budget import format_seconds
from animbatch.stages import check_trajectory, frame_geometry, plan
from animbatch.timeline import FrameRange, parse_frames
from animbatch.trajectory import Trajectory

__all__ = ["FrameRange", "RangeResult", "draw_frames", "frame_is_complete", "frames_folder", "parse_frames",
           "prepare_frames", "render_frames"]


def frame_is_complete(path: Path, size: tuple[int, int]) -> bool:
    """Whether ``path`` is a whole PNG of ``size`` (width, height): it exists, decodes to the end, and has that
    size. A truncated file (a copy cut short, a disk that filled up) fails the decode."""
    from PIL import Image

    try:
        with Image.open(path) as image:
            if image.format != "PNG" or image.size != tuple(size):
                return False
            image.load()  # decodes every row: catches truncation that verify() alone may miss
        return True
    except (OSError, SyntaxError, ValueError):
        return False


@dataclass
class RangeResult:
    """Frames of a range that were drawn (in order, once on disk) and that were already complete; the time spent
    drawing and, overlapping it on a background thread, writing PNGs [s]."""
    drawn: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    render_seconds: float = 0.0
    write_seconds: float = 0.0
    backend: str = ""


def output_stem(scene: LoadedScene) -> str:
    """The name of a render's videos: the scene's, with ``-<camera>`` when drawn through a named camera."""
    camera = scene.spec.render.use_camera
    return scene.name if camera is None else f"{scene.name}-{camera}"


def sweep_killed_writers(scene: LoadedScene, out_dir: str | Path) -> list[Path]:
    """Remove the temporary files that writers killed mid-write (SIGKILL, a lost node) left in the scene's folders:
    its outputs, frames and cache (:func:`animbatch.files.sweep_partials`: running writers' files are kept).
    Returns what was removed."""
    base = Path(out_dir) / scene.name
    folders = [base, frames_folder(scene, out_dir), base / "cache"]
    return [path for folder in dict.fromkeys(folders) for path in sweep_partials(folder)]


def frames_folder(scene: LoadedScene, out_dir: str | Path) -> Path:
    """Where a render's frames go: ``out_dir/<scene>/frames`` (``frames-<camera>`` for a named camera, so that the
    cameras of one scene render side by side)."""
    camera = scene.spec.render.use_camera
    return Path(out_dir) / scene.name / ("frames" if camera is None else f"frames-{camera}")


KEY_FILE = "render-key.txt"


def render_key(scene: LoadedScene, trajectory: Trajectory) -> str:
    """A hash of everything that decides a frame's pixels (see the module notes)."""
    spec = scene.spec.model_dump(mode="json", exclude={"study", "description"})
    spec["solver"] = simulation_settings(spec["solver"])  # budgets and warning thresholds draw nothing
    for key in ("formats", "video", "max_cost"):
        spec["render"].pop(key, None)
    # the code that simulated the trajectory and the code that draws it: either changed, the pixels may have
    content = {"scene": spec, "physics": trajectory.physics_hash, "solver": trajectory.solver.get("description"),
               "simulated by": trajectory.package_version, "drawn by": drawing_code()}
    return hashlib.sha256(json.dumps(content, sort_keys=True, default=str).encode()).hexdigest()[:16]


def prepare_frames(scene: LoadedScene, trajectory: Trajectory, out_dir: str | Path) -> Path:
    """Make the frames folder hold only frames of this picture: when its key differs (or is missing), delete the
    frames in it and write the new key. Returns the folder."""
    folder = frames_folder(scene, out_dir)
    key = render_key(scene, trajectory)
    stamp = folder / KEY_FILE
    if stamp.is_file() and stamp.read_text().strip() == key:
        return folder
    for stale in folder.glob("frame_*.png"):
        with contextlib.suppress(FileNotFoundError):
            stale.unlink()
    write_text_atomic(stamp, key + "\n")
    return folder


def render_frames(scene: LoadedScene | RunPlan, trajectory: Trajectory, frames: FrameRange, *,
                  out_dir: str | Path = "renders", backend: str = "auto",
                  on_frame: Callable[[int], None] | None = None) -> RangeResult:
    """Draw the frames of ``frames`` that are not complete on disk, on their own: check that the trajectory is this
    scene's and that the frames folder holds only this picture first (a worker, a farm task); ``on_frame(index)``
    after each frame. ``scene``: a loaded scene, or its run plan when the caller compiled it."""
    run = plan(scene)
    check_trajectory(run.scene, run.model, trajectory)
    folder = prepare_frames(run.scene, trajectory, out_dir)
    return draw_frames(run, trajectory, frames, folder, backend=backend, on_frame=on_frame)


def draw_frames(run: RunPlan, trajectory: Trajectory, frames: FrameRange, folder: Path, *, backend: str = "auto",
                on_frame: Callable[[int], None] | None = None) -> RangeResult:
    """Draw the frames of ``frames`` that are not complete in ``folder``, for a trajectory already checked against
    the run's scene and a folder already prepared (:func:`render_frames` does both)."""
    if frames.stop > trajectory.frame_count:
        raise ValueError(f"frames {frames} asked for; the trajectory has {trajectory.frame_count} (0-"
                         f"{trajectory.frame_count - 1})")
    writer = PngSequenceWriter(folder)
    size = tuple(run.spec.render.resolution)
    result = RangeResult()
    todo = []
    for index in frames:
        (result.skipped if frame_is_complete(writer.path_of(index), size) else todo).append(index)
    if todo:
        draw_into(writer, run, trajectory, todo, backend=backend, result=result, on_frame=on_frame)
    return result


def draw_into(writer: FrameWriter, run: RunPlan, trajectory: Trajectory, todo: list[int], *, backend: str,
              result: RangeResult, on_frame: Callable[[int], None] | None = None,
              queued: int = 2) -> None:
    """Draw frames ``todo`` in order with one renderer and hand each to ``writer`` on a background thread (PNG files,
    or the videos' pipes), within ``render.max_cost``; ``result`` gets the frames written and the time spent drawing
    and writing, and ``on_frame(index)`` is called once each is written; at most ``queued`` frames wait to be
    written. Leaving, even on an error, first finishes the frames handed over."""

    def written(index: int, seconds: float) -> None:
        result.write_seconds += seconds
        result.drawn.append(index)
        if on_frame is not None:
            on_frame(index)

    chosen = select_backend(backend)
    result.backend = chosen.name
    geometry = frame_geometry(run, trajectory)
    budget = RenderBudget(run.spec.render.max_cost, len(todo))
    with contextlib.ExitStack() as stack:
        renderer = stack.enter_context(FrameRenderer(run.spec.render, geometry, chosen))
        # entered last, so closed first: the frames handed over are finished before the renderer goes
        background = stack.enter_context(BackgroundFrameWriter(writer, written, queued))
        for done, index in enumerate(todo, start=1):
            started = time.perf_counter()
            image = renderer.draw(float(trajectory.times[index]), trajectory.positions[index],
                                  trajectory.orientations[index], trajectory.angular_velocities[index],
                                  (trajectory.particles, index) if trajectory.particles else None)
            result.render_seconds += time.perf_counter() - started
            background.submit(index, image)
            budget.after_frame(done)  # the frames submitted are finished on disk before the error leaves


class RenderBudget:
    """``render.max_cost`` [s] for one render process drawing ``frames`` frames: after the second frame (the first
    one also builds the scene's actors) the rest is projected at that pace, and a render that would exceed the
    budget stops there; one that runs over anyway stops when the budget is spent. Frames drawn are kept."""
    def __init__(self, seconds: float, frames: int) -> None:
        self.seconds, self.frames = seconds, frames
        self.started = time.perf_counter()
        self.second_started: float | None = None

    def after_frame(self, done: int) -> None:
        now = time.perf_counter()
        if done == 1:
            self.second_started = now
        if not self.seconds or done >= self.frames:
            return
        elapsed = now - self.started
        per_frame = (now - self.second_started) / (done - 1) if done >= 2 else None
        projected = elapsed + per_frame * (self.frames - done) if per_frame is not None else None
        if elapsed > self.seconds or (projected is not None and projected > self.seconds):

            pace = (f"about {format_seconds(projected)} at {per_frame:.3g} s per frame" if projected is not None
                    else f"more than the {format_seconds(elapsed)} the first frame took")
            raise RenderError(
                f"rendering stopped after {done} of {self.frames} frames: drawing them all would take {pace}, "
                f"more than the budget of {format_seconds(self.seconds)} (render.max_cost). The {done} frames drawn "
                "are kept; run again with --set render.max_cost=SECONDS (0 = no limit) to draw the rest, or lower "
                "render.resolution, fps or anti_aliasing")
