"""The pipeline as library functions: load → compile → simulate → render/encode, and ``run`` for all of them.

    from animbatch import api
    scene = api.load_scene("scenes/projectile.yaml", overrides=["solver.method=DOP853"])
    model = api.compile_scene(scene.spec)
    trajectory = api.simulate(scene, model=model)
    result = api.render(scene, trajectory, model=model, out_dir="renders")

Simulation and rendering meet only at the :class:`~animbatch.trajectory.Trajectory`: a trajectory saved by
``simulate`` can be rendered later (with another camera or resolution) without simulating again.
"""

from __future__ import annotations

import datetime as _dt
import platform
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from animbatch import __version__
from animbatch.errors import SimulationError, TrajectoryError
from animbatch.files import write_json_atomic
from animbatch.integrators import DEFAULT_DT, IntegrationResult, SolverStats, make_integrator
from animbatch.integrators.budget import wall_budget
from animbatch.integrators.cost import check_cost, estimate_cost
from animbatch.integrators.guard import check_energy_growth
from animbatch.integrators.preflight import preflight
from animbatch.ledger import build_ledger, warn_again
from animbatch.ledger import summary as ledger_summary
from animbatch.model import Dynamics, Model, compile_scene
from animbatch.particles.compile import pool_sizes
from animbatch.particles.simulate import steps_per_frame
from animbatch.progress import Progress
from animbatch.scene import LoadedScene, load_scene, physics_fingerprint
from animbatch.scene.overrides import Override
from animbatch.stopwatch import Stopwatch
from animbatch.trajectory import Trajectory

__all__ = ["RenderResult", "RunReport", "check_trajectory", "compile_model", "compile_scene", "load_scene", "render",
           "run", "scene_fingerprint", "simulate"]


def simulate(scene: LoadedScene, *, model: Model | None = None, progress: Progress | None = None,
             checkpoint: tuple[int, Path] | None = None) -> Trajectory:
    """Integrate the scene and sample it at the frame times. Raises SimulationError on divergence or failure.

    ``checkpoint``: (every N frames, file): integrate in segments, saving the states after each and resuming from
    the file when it exists (see :mod:`animbatch.farm.checkpoint`)."""
    spec = scene.spec
    model = model if model is not None else compile_model(scene)
    integrator = make_integrator(spec.solver)
    progress = progress or Progress(enabled=False)
    warnings = preflight(spec, model)  # risky settings, with numbers (what is certain to fail is refused)
    frame_steps = steps_per_frame(1.0 / spec.fps, spec.solver.method, spec.solver.dt or DEFAULT_DT)
    cost = estimate_cost(model, spec.solver, pool_sizes(spec), frame_steps * (len(model.frame_times) - 1))
    check_cost(cost, spec.solver.max_cost)  # refuse what would run for hours or cannot fit, before it starts
    with wall_budget(spec.solver.max_cost, float(model.frame_times[0]), float(model.frame_times[-1])):
        result, particles, particle_stats = _integrate(scene, model, integrator, progress, checkpoint)
    states = result.states
    kinds = ("particle",) * model.particle_count + ("rigid",) * model.rigid_count
    stats = {**result.stats.as_dict(), "estimated_seconds": cost.seconds}
    ledger = build_ledger(model, states, stats, particle_stats, method=spec.solver.method,
                          adaptive=spec.solver.is_adaptive, requested_dt=spec.solver.dt or DEFAULT_DT,
                          rtol=spec.solver.rtol, drift_warning=spec.solver.drift_warning)
    return Trajectory(
        times=model.frame_times.copy(), body_names=model.body_names, positions=model.positions(states),
        velocities=model.velocities(states), orientations=model.orientations(states),
        angular_velocities=model.angular_velocities(states), body_kinds=kinds,
        anchor_names=model.anchor_names, anchor_positions=model.anchor_position.copy(),
        physics_hash=scene_fingerprint(scene), scene_name=scene.name, package_version=__version__,
        solver={**spec.solver.model_dump(), "description": integrator.describe()},
        solver_stats={**stats, "warnings": warnings}, particles=tuple(particles), particle_stats=particle_stats,
        ledger=ledger.as_dict())


def _integrate(scene: LoadedScene, model: Model, integrator: Any, progress: Progress,
               checkpoint: tuple[int, Path] | None) -> tuple[IntegrationResult, list, dict[str, Any]]:
    """The bodies' states at the frame times, then the emitted particles (which may ride on bodies)."""
    if model.layout.size:
        with progress.task("simulate", len(model.frame_times)) as on_frame:
            if checkpoint is None:
                result = integrator.integrate(Dynamics(model), model.y0, model.frame_times, on_frame=on_frame)
            else:
                from animbatch.farm.checkpoint import integrate_with_checkpoints

                every, path = checkpoint
                result = integrate_with_checkpoints(integrator, Dynamics(model), model.y0, model.frame_times,
                                                    every=every, path=Path(path), on_frame=on_frame)
        check_energy_growth(model, result.states, scene.spec.solver.method, result.stats.dt)
    else:  # a scene of emitters only: no body to integrate
        result = IntegrationResult(np.zeros((len(model.frame_times), 0)), SolverStats(scene.spec.solver.method))
    particles, particle_stats = simulate_emitters(scene, model, result.states, progress)
    return result, particles, particle_stats


def simulate_emitters(scene: LoadedScene, model: Model, states: np.ndarray, progress: Progress
                      ) -> tuple[list, dict[str, Any]]:
    """The scene's emitted particles at the frame times (after its bodies, whose motion ``states`` (F, n) moves
    emitters attached to them), and the statistics of their simulation; nothing when it has no emitters."""
    spec = scene.spec
    if not spec.emitters:
        return [], {}
    from animbatch.particles.body_motion import BodyMotion
    from animbatch.particles.compile import compile_particles
    from animbatch.particles.simulate import simulate_particles

    systems = compile_particles(spec, model, scene_folder(scene))
    assert systems is not None
    motion = BodyMotion(model.frame_times, model.positions(states), model.velocities(states),
                        model.orientations(states), model.angular_velocities(states))
    with progress.task("particles", len(model.frame_times)) as on_frame:
        records, stats = simulate_particles(systems.emitters, systems.colliders, model.frame_times, spec.solver,
                                            motion, dt=spec.solver.dt or DEFAULT_DT, on_frame=on_frame)
    return records, stats.as_dict()


def scene_folder(scene: LoadedScene) -> Path:
    """Where the scene's relative file names (mesh files) are resolved: the scene file's folder."""
    return scene.path.parent if scene.path is not None else Path(".")


def compile_model(scene: LoadedScene) -> Model:
    """The Model of a loaded scene, with mesh files found beside the scene file."""
    return compile_scene(scene.spec, scene_folder(scene))


def scene_fingerprint(scene: LoadedScene) -> str:
    """The physics hash of a loaded scene, including the contents of its mesh files."""
    return physics_fingerprint(scene.spec, scene_folder(scene))


def check_trajectory(scene: LoadedScene, model: Model, trajectory: Trajectory, source: str | Path = "trajectory"
                     ) -> None:
    """Refuse a trajectory that was not simulated from this scene's physics (bodies, fields, timeline)."""
    if trajectory.physics_hash != scene_fingerprint(scene):
        raise TrajectoryError(
            f"{source} was simulated from different physics than {scene.path or scene.name} (bodies, springs, fields, "
            f"mesh files, duration or fps changed). Re-run 'animbatch simulate {scene.path or 'SCENE'} -o {source}'.")
    if trajectory.body_names != model.body_names:
        raise TrajectoryError(f"{source} holds bodies {', '.join(trajectory.body_names)}, the scene has "
                              f"{', '.join(model.body_names)}")


def largest_vector(model: Model, trajectory: Trajectory, kind: str) -> float:
    """The largest |ω| [rad/s] or |L| [kg·m²/s] of any rigid body over the trajectory (0 when not drawn)."""
    if kind == "none" or model.rigid is None:
        return 0.0
    omega = trajectory.angular_velocities[:, model.particle_count:]
    if kind == "angular_velocity":
        return float(np.max(np.linalg.norm(omega, axis=-1), initial=0.0))
    states = model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                               trajectory.angular_velocities)
    momentum = model.layout.view(states, "rigid_angular_momentum")
    return float(np.max(np.linalg.norm(momentum, axis=-1), initial=0.0))


def frame_geometry(scene: LoadedScene, model: Model, trajectory: Trajectory) -> Any:
    """What the renderer draws for this scene and trajectory (a :class:`~animbatch.render.frames.FrameGeometry`),
    with the camera fitted to the whole motion: bodies, anchors, colliders and emitted particles."""
    from animbatch.render.camera import motion_bounds
    from animbatch.render.frames import FrameGeometry, body_extents, collider_points

    spec = scene.spec
    anchors = (np.vstack([model.anchors.positions(float(t)) for t in trajectory.times]) if model.anchors.moving
               else model.anchor_position)
    fixed = np.vstack([anchors, collider_points(spec, scene_folder(scene)), particle_extent(trajectory)])
    bounds = motion_bounds(trajectory.positions, body_extents(model), fixed)
    emitters = ()
    if spec.emitters:
        from animbatch.particles.compile import compile_particles

        emitters = compile_particles(spec, model, scene_folder(scene)).emitters  # type: ignore[union-attr]
    return FrameGeometry.from_scene(spec, model, bounds, largest_vector(model, trajectory, spec.render.show_vectors),
                                    scene_folder(scene), emitters)


def particle_extent(trajectory: Trajectory) -> np.ndarray:
    """Two corners (2, 3) of the box around every emitted particle at every frame (a 1st–99th percentile box, so
    that a few strays do not shrink the view), or none (0, 3)."""
    corners = []
    for frames in trajectory.particles:
        live = frames.positions[frames.serials >= 0]
        if len(live):
            corners += [np.percentile(live, 1, axis=0), np.percentile(live, 99, axis=0)]
    return np.array(corners, float).reshape(-1, 3)


def write_quantities(scene: LoadedScene, model: Model, trajectory: Trajectory, folder: str | Path, *,
                     plot: bool = False) -> list[Path]:
    """Write the run's per-frame quantities (energy, momentum, angular momentum, speeds) to ``quantities.csv`` in
    ``folder``, and with ``plot`` draw them to ``quantities.png``; nothing for a scene without bodies."""
    if not model.body_count:
        return []
    from animbatch.files import write_text_atomic
    from animbatch.ledger import QuantitySeries

    states = model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                               trajectory.angular_velocities)
    series = QuantitySeries.of_states(model, states)
    folder = Path(folder)
    written = [folder / "quantities.csv"]
    write_text_atomic(written[0], series.csv())
    if plot:
        from animbatch.plot import plot_quantities

        written.append(plot_quantities(series, folder / "quantities.png", scene=scene.name,
                                       ledger=trajectory.ledger))
    return written


@dataclass
class RenderResult:
    """What a render wrote, and how long drawing and encoding took [s]."""

    outputs: list[Path]
    frame_count: int
    backend: str
    render_seconds: float
    encode_seconds: float
    resolution: tuple[int, int]
    fps: int


def render(scene: LoadedScene, trajectory: Trajectory, *, model: Model | None = None,
           out_dir: str | Path = "renders", backend: str = "auto", progress: Progress | None = None) -> RenderResult:
    """Draw every frame of ``trajectory`` and write the scene's outputs into ``out_dir/<scene name>/``, in this
    process: ``run`` without the bake (the same frames, videos and file rules, see :func:`run`).

    The trajectory must come from this scene's physics (TrajectoryError otherwise); frames already complete on disk
    for this picture are not drawn again; every file is written atomically.
    """
    from animbatch.farm import render_frames
    from animbatch.farm.frames import FrameRange, prepare_frames

    model = model if model is not None else compile_model(scene)
    check_trajectory(scene, model, trajectory)
    prepare_frames(scene, trajectory, out_dir)
    progress = progress or Progress(enabled=False)
    with progress.task("render", trajectory.frame_count) as on_frame:
        rendered = render_frames(scene, trajectory, FrameRange(0, trajectory.frame_count), out_dir=out_dir,
                                 backend=backend, model=model,
                                 on_frame=lambda i: on_frame(i, float(trajectory.times[i])))
    outputs, encode_seconds = finish_outputs(scene, trajectory.frame_count, out_dir)
    return RenderResult(outputs, trajectory.frame_count, rendered.backend or "(none: frames were complete)",
                        rendered.render_seconds, encode_seconds, tuple(scene.spec.render.resolution),  # type: ignore[arg-type]
                        scene.spec.fps)


def finish_outputs(scene: LoadedScene, frame_count: int, out_dir: str | Path) -> tuple[list[Path], float]:
    """Once every frame is on disk: encode each video format the scene asks for, then keep the frames if ``png`` is
    one of its formats (without frames left over from a longer run) or delete them. Returns the outputs and the
    encoding time [s]."""
    from animbatch.encode import PngSequenceWriter
    from animbatch.farm.encode import encode
    from animbatch.farm.frames import frames_folder

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
    ledger: dict[str, Any] = field(default_factory=dict)  # the accuracy ledger (see animbatch.ledger)
    quantities: list[str] = field(default_factory=list)  # quantities.csv (and .png) beside the report

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
        return (f"{self.scene}: {self.frame_count} frames {width}×{height} @ {self.fps} fps -> {target} | "
                f"{timings} | {solver} | {self.backend}")


def failure_report(scene: LoadedScene, error: SimulationError, watch: Stopwatch) -> dict[str, Any]:
    """The report of a run whose simulation failed: what failed, when, which body, and the message."""
    return {"scene": scene.name, "scene_file": str(scene.path) if scene.path else None, "status": "failed",
            "exit_code": error.exit_code, "error": str(error), "time": error.time, "body": error.body,
            "details": error.details, "solver": scene.spec.solver.model_dump(), "stages": dict(watch.seconds),
            "package_version": __version__, "outputs": [],
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), "host": platform.node()}


def run(scene_path: str | Path, *, overrides: Sequence[Override] = (), out_dir: str | Path = "renders",
        backend: str = "auto", trajectory_path: str | Path | None = None, progress: Progress | None = None,
        jobs: int | None = None, frames: str | None = None, plot: bool = False) -> RunReport:
    """Bake, render and encode one scene, as a render farm does, on this machine; write its report.

    * **bake**: the trajectory from the cache (``renders/<scene>/cache/``) when the physics, solver settings and
      package version match, else simulated and cached (or read from ``trajectory_path``);
    * **render**: the frames not yet complete on disk, in ``jobs`` worker processes (default: one per core, fewer
      for short animations), into ``renders/<scene>/frames/``;
    * **encode**: every video format the scene asks for; the frame files are then deleted unless ``png`` is one of
      the formats.

    With ``frames`` (``"120-239"``) only that range is rendered, and nothing is encoded (``animbatch encode`` does
    that once every range is done); the report is written for whole runs only, with ``quantities.csv`` (and, with
    ``plot``, ``quantities.png``) beside it.
    """
    from animbatch.farm import bake, parse_frames, render_frames
    from animbatch.farm.frames import frames_folder, prepare_frames
    from animbatch.farm.parallel import render_in_parallel, worker_count

    watch = Stopwatch()
    progress = progress or Progress(enabled=False)
    with watch.stage("load"):
        scene = load_scene(scene_path, overrides)
    with watch.stage("compile"):
        model = compile_model(scene)
    cache = None
    if trajectory_path is not None:
        with watch.stage("load_trajectory"):
            trajectory = Trajectory.load(trajectory_path)
            check_trajectory(scene, model, trajectory, trajectory_path)  # before rendering, naming the file
            warn_again(trajectory.ledger)
        source = Path(trajectory_path)
    else:
        try:
            baked = bake(scene, out_dir=out_dir, model=model, progress=progress)
        except SimulationError as error:  # the reason goes in the report too, where batch tools look for it
            write_json_atomic(Path(out_dir) / scene.name / "report.json", failure_report(scene, error, watch))
            raise
        watch.add("load_cache" if baked.reused else "simulate", baked.seconds)
        trajectory, source, cache = baked.trajectory, baked.path, baked
    span = parse_frames(frames, trajectory.frame_count)
    prepare_frames(scene, trajectory, out_dir)  # before any worker starts: stale frames of another picture go
    workers = worker_count(jobs, len(span))
    # the stage's wall time: with worker processes the frames' own times add up to more than the stage took
    with watch.stage("render"), progress.task("render", len(span)) as on_frame:
        if workers > 1:
            rendered = render_in_parallel(scene_path, overrides, source, span, workers=workers, out_dir=out_dir,
                                          backend=backend, on_chunk=lambda chunk: [
                                              on_frame(i, float(trajectory.times[i])) for i in chunk.drawn])
        else:
            rendered = render_frames(scene, trajectory, span, out_dir=out_dir, backend=backend, model=model,
                                     on_frame=lambda i: on_frame(i, float(trajectory.times[i])))
    spec = scene.spec
    if frames is None:
        outputs, encode_seconds = finish_outputs(scene, trajectory.frame_count, out_dir)
        if any(kind != "png" for kind in spec.render.formats):
            watch.add("encode", encode_seconds)
    else:
        outputs = [frames_folder(scene, out_dir)]
    report = RunReport(scene.name, str(scene.path) if scene.path else None, trajectory.physics_hash, __version__,
                       dict(watch.seconds), trajectory.solver, trajectory.solver_stats, trajectory.frame_count,
                       tuple(spec.render.resolution), spec.fps, rendered.backend or "(none: frames were complete)",
                       [str(p) for p in outputs], str(trajectory_path) if trajectory_path else None,
                       trajectory.particle_stats, frames=str(span), frames_drawn=len(rendered.drawn),
                       frames_skipped=len(rendered.skipped), workers=workers,
                       cache=str(cache.path) if cache else None, cache_reused=bool(cache and cache.reused),
                       ledger=trajectory.ledger)
    if frames is None:
        folder = Path(out_dir) / scene.name
        report.quantities = [str(path) for path in write_quantities(scene, model, trajectory, folder, plot=plot)]
        write_json_atomic(folder / "report.json", report.__dict__)
    return report
