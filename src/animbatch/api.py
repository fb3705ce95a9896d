"""The pipeline as library functions: load → compile → simulate → render/encode, and the same from a notebook.

In a script or a Jupyter notebook::

    import animbatch
    run = animbatch.render("scenes/projectile.yaml", quality="draft")     # bake, draw, encode: a RunReport
    run                                   # in a notebook: the video, the accuracy ledger and the energy plot
    ball = animbatch.load("scenes/projectile.yaml")
    dragged = ball.changed({"fields[0].coefficient": 0.02})                # the same key paths as --set
    animbatch.render(dragged, set={"render.resolution": [640, 360]})
    animbatch.study(dragged, set={"study.methods": ["RK45", "DOP853"]})    # the work-precision plot and table

Step by step, for tools that keep the pieces::

    from animbatch import api
    scene = api.load_scene("scenes/projectile.yaml", overrides=["solver.method=DOP853"])
    plan = api.plan(scene)            # compiled once: model, step settings, timeline, emitters
    trajectory = api.simulate(plan)
    report = api.render(plan, trajectory, out_dir="renders")

Simulation and rendering meet only at the :class:`~animbatch.trajectory.Trajectory`: a trajectory saved by
``simulate`` can be rendered later (with another camera or resolution) without simulating again. Each entry point
returns an object that shows itself in a notebook: a run its video, ledger and energy plot; a trajectory its
ledger; a study its work-precision plot and table.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Union

from animbatch import stages
from animbatch.compile.model import compile_scene
from animbatch.compile.plan import RunPlan
from animbatch.compile.scene_builder import SceneModelBuilder
from animbatch.compile.stopwatches import StopwatchReading, stopwatch_readings
from animbatch.farm.run import RunReport, finish_outputs, run
from animbatch.progress import Progress
from animbatch.scene import LoadedScene, physics_fingerprint
from animbatch.scene.overrides import Override, as_overrides
from animbatch.sim.model import Model
from animbatch.stages import (
                              check_trajectory,
                              compile_model,
                              failure_report,
                              frame_geometry,
                              load_scene,
                              parse_scene,
                              plan,
                              scene_fingerprint,
                              scene_folder,
                              simulate_emitters,
                              write_quantities,
)
from animbatch.study.report import StudyReport
from animbatch.trajectory import Trajectory

#: A scene as the entry points take it: its file, a loaded scene, or its run plan.
SceneLike = Union[str, Path, LoadedScene, RunPlan]
#: Changes as ``--set`` makes them: key paths to Python values, or ``"key.path=value"`` texts.
Changes = Union[Mapping[str, Any], Sequence[Override]]


def load(scene: str | Path | LoadedScene, set: Changes = ()) -> LoadedScene:  # noqa: A002 (as the CLI's --set)
    """The scene at ``scene`` (a file) with every check, and with ``set``'s changes applied first; a loaded scene
    with the changes applied (see :meth:`LoadedScene.changed`). SceneError lists every problem."""
    if isinstance(scene, LoadedScene):
        return scene.changed(set) if set else scene
    return load_scene(scene, as_overrides(set))


def render(scene: SceneLike, trajectory: str | Path | Trajectory | None = None, *, quality: str | None = None,
           resolution: str | Sequence[int] | None = None, formats: str | Sequence[str] | None = None,
           set: Changes = (), out_dir: str | Path = "renders", plot: bool = True,  # noqa: A002
           progress: Progress | bool | None = None, backend: str = "auto", jobs: int | None = None,
           frames: str | None = None) -> RunReport:
    """Bake (or reuse the cache, or take ``trajectory``), draw and encode ``scene`` into ``out_dir/<scene>/``:
    ``animbatch render`` from Python. Returns the run's :class:`RunReport` (as ``report.json``), which a notebook
    shows as the video, the accuracy ledger and (``plot``, on by default) the energy plot.

    ``quality`` (draft, preview, final), ``resolution`` (``"640x360"`` or ``(640, 360)``) and ``formats``
    (``"mp4,webm"`` or a list) are ``render.quality``, ``render.resolution`` and ``render.formats``; ``set`` changes
    any other value by its key path, as ``--set`` does. ``progress``: bars on a terminal or in a notebook (default),
    True or False to choose, or a :class:`Progress`."""
    shortcuts: dict[str, Any] = {}
    if quality is not None:
        shortcuts["render.quality"] = quality
    if resolution is not None:
        shortcuts["render.resolution"] = _size(resolution)
    if formats is not None:
        shortcuts["render.formats"] = [kind.strip() for kind in formats.split(",")] if isinstance(formats, str) \
            else list(formats)
    return run(scene, overrides=[*as_overrides(set), *as_overrides(shortcuts)], out_dir=out_dir, backend=backend,
               trajectory=trajectory, progress=_progress(progress), jobs=jobs, frames=frames, plot=plot)


def simulate(scene: SceneLike, *, set: Changes = (), model: Model | None = None,  # noqa: A002
             progress: Progress | bool | None = None, checkpoint: tuple[int, Path] | None = None,
             reactions: bool = True) -> Trajectory:
    """Integrate ``scene`` (a file, a loaded scene or its run plan; ``set`` changes values first) and sample it at
    the frame times; see :func:`animbatch.stages.simulate`. The trajectory shows its accuracy ledger in a notebook.
    Raises SimulationError on divergence or failure."""
    if not isinstance(scene, RunPlan) or set:
        scene = load(scene.scene if isinstance(scene, RunPlan) else scene, set)
    return stages.simulate(scene, model=model, progress=_progress(progress), checkpoint=checkpoint,
                           reactions=reactions)


def study(scene: str | Path | LoadedScene, *, set: Changes = (), methods: Sequence[str] | None = None,  # noqa: A002
          out_dir: str | Path | None = None, progress: Callable[[str], None] | None = None) -> StudyReport:
    """What accuracy costs in time (``animbatch study``): every integrator (or ``methods``) over a sweep of
    tolerances and steps, each run's error against a reference beside its wall time. Writes study.csv, .json, .png
    and .txt into ``out_dir`` (default ``renders/<scene>/``) and returns them with the result; a notebook shows the
    work-precision plot and the table."""
    from animbatch.study import run_study, write_outputs

    loaded = load(scene, set)
    result = run_study(loaded, methods=list(methods) if methods else None,
                       progress=progress or (lambda line: None))
    paths = write_outputs(result, out_dir if out_dir is not None else Path("renders") / loaded.name)
    return StudyReport(result, paths)


def _size(resolution: str | Sequence[int]) -> list[int]:
    if isinstance(resolution, str):
        width, _, height = resolution.lower().partition("x")
        try:
            return [int(width), int(height)]
        except ValueError:
            raise ValueError(f"resolution {resolution!r}: expected WIDTHxHEIGHT, e.g. 640x360") from None
    return [int(side) for side in resolution]


def _progress(progress: Progress | bool | None) -> Progress:
    return progress if isinstance(progress, Progress) else Progress(enabled=progress)


__all__ = ["Changes", "RunPlan", "RunReport", "SceneLike", "SceneModelBuilder", "StopwatchReading", "StudyReport",
           "check_trajectory", "compile_model", "compile_scene", "failure_report", "finish_outputs", "frame_geometry",
           "load", "load_scene", "parse_scene", "physics_fingerprint", "plan", "render", "run", "scene_fingerprint",
           "scene_folder", "simulate", "simulate_emitters", "stopwatch_readings", "study", "write_quantities"]
