"""The stages of a run, as library functions shared by the API, the farm and ``study``:

    load (with the geometry checks) -> compile -> simulate -> frame geometry, and the checks between them
    (does a trajectory belong to this scene's physics?).

They sit above the compiler and below every driver (``api``, ``farm``, ``study``, the CLI), so that the farm can
bake and render without importing the API that drives it.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import platform
import string
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.compile.arrows import arrow_series
from animbatch.compile.checks import compile_checks
from animbatch.compile.frame_geometry import body_extents, collider_points
from animbatch.compile.frame_geometry import frame_geometry as compile_frame_geometry
from animbatch.compile.integrator import make_integrator
from animbatch.compile.model import compile_scene
from animbatch.compile.particles import particle_costs
from animbatch.compile.plan import RunPlan, plan_run, scene_folder
from animbatch.compile.stopwatches import stopwatch_readings
from animbatch.errors import SimulationError, TrajectoryError
from animbatch.files import write_text_atomic
from animbatch.plot import plot_quantities
from animbatch.progress import Progress
from animbatch.provenance import simulation_code
from animbatch.render.arrows import arrow_tips
from animbatch.render.camera import motion_bounds
from animbatch.render.frame_geometry import FrameGeometry, LabelValues, PanelSeries
from animbatch.scene import LoadedScene, physics_fingerprint
from animbatch.scene import loader as scene_loader
from animbatch.scene.overrides import Override
from animbatch.scene.schema import label_names, label_speed_names
from animbatch.sim.contact.time_stepping import measure_contact_search, numpy_contact_solve
from animbatch.sim.integrators import IntegrationResult, Integrator, SolverStats
from animbatch.sim.integrators.budget import wall_budget
from animbatch.sim.integrators.checkpoint import integrate_with_checkpoints
from animbatch.sim.integrators.cost import CostEstimate, check_cost, estimate_cost, measure_rhs
from animbatch.sim.integrators.guard import check_energy_growth
from animbatch.sim.integrators.interface import StepSettings
from animbatch.sim.ledger import QuantitySeries, build_ledger
from animbatch.sim.model import Dynamics, Model
from animbatch.sim.model.compiled import dynamics_for
from animbatch.sim.particles.body_motion import BodyMotion
from animbatch.sim.particles.simulate import simulate_particles
from animbatch.sim.preflight import preflight
from animbatch.stopwatch import Stopwatch
from animbatch.trajectory import Trajectory
from animbatch.version import __version__


def load_scene(path: str | Path, overrides: Sequence[Override] = ()) -> LoadedScene:
    """Read and validate the scene file at ``path`` (``--set`` style ``overrides`` first), with every check: format,
    names and references, and the geometry (mesh files, pin selections). SceneError lists every problem."""
    return scene_loader.load_scene(path, overrides, geometry_checks=compile_checks)


def parse_scene(text: str, *, filename: str = "<scene>", overrides: Sequence[Override] = (),
                default_name: str = "scene", path: Path | None = None) -> LoadedScene:
    """Validate scene text (YAML) with every check; ``path``'s folder finds mesh files (default: the current one)."""
    return scene_loader.parse_scene(text, filename=filename, overrides=overrides, default_name=default_name,
                                    path=path, geometry_checks=compile_checks)


def plan(scene: LoadedScene | RunPlan, *, model: Model | None = None) -> RunPlan:
    """The run plan of ``scene`` (compiled here, reusing ``model`` when given), or ``scene`` if it is one already."""
    return scene if isinstance(scene, RunPlan) else plan_run(scene, model=model)


def simulate(scene: LoadedScene | RunPlan, *, model: Model | None = None, progress: Progress | None = None,
             checkpoint: tuple[int, Path] | None = None, reactions: bool = True) -> Trajectory:
    """Integrate the scene and sample it at the frame times. Raises SimulationError on divergence or failure.

    ``scene``: a loaded scene (compiled here, with ``model`` if the caller compiled it) or its run plan.
    ``checkpoint``: (every N frames, file): integrate in segments, saving the states after each and resuming from
    the file when it exists (see :mod:`animbatch.sim.integrators.checkpoint`). ``reactions``: also each joint's
    reaction at every frame (what trajectory files store; a millisecond or so a frame, as much as the whole
    integration of a small jointed scene), for callers that read them; without, they are None."""
    run = plan(scene, model=model)
    spec, model, steps = run.spec, run.model, run.steps
    integrator = make_integrator(steps, model)
    progress = progress or Progress(enabled=False)
    # risky settings, with numbers (what is certain to fail is refused)
    warnings: list[str] = []
    estimated = 0.0
    system = Dynamics(model)
    if steps.method != "analytic":  # closed forms cost nothing to speak of, and cannot go unstable
        warnings = preflight(model, steps.method, steps.dt)
        particle_steps = steps.frame_substeps * (run.timeline.count - 1)
        pools = particle_costs(spec, run.particles, particle_steps)
        system, cost = choose_dynamics(model, steps, pools, particle_steps)
        check_cost(cost, spec.solver.max_cost)  # refuse what would run for hours or cannot fit, before it starts
        estimated = cost.seconds
    with wall_budget(spec.solver.max_cost, float(model.frame_times[0]), float(model.frame_times[-1])):
        result, particles, particle_stats = _integrate(run, system, integrator, progress, checkpoint)
    states = result.states
    kinds = ("particle",) * model.particle_count + ("rigid",) * model.rigid_count
    stats = {**result.stats.as_dict(), "estimated_seconds": estimated}
    ledger = build_ledger(model, states, stats, particle_stats, method=steps.method, adaptive=steps.adaptive,
                          requested_dt=steps.dt, dt_given=steps.dt_given, rtol=steps.rtol,
                          drift_warning=spec.solver.drift_warning)
    joint_loads: tuple[np.ndarray | None, ...] = (None, None, None)
    if reactions and model.joints is not None and len(states):
        joint_loads = Dynamics(model).joint_reactions(model.frame_times, states)
    return Trajectory(
        times=model.frame_times.copy(), body_names=model.body_names, positions=model.positions(states),
        velocities=model.velocities(states), orientations=model.orientations(states),
        angular_velocities=model.angular_velocities(states), body_kinds=kinds,
        anchor_names=model.anchor_names, anchor_positions=model.anchor_position.copy(),
        physics_hash=scene_fingerprint(run.scene), scene_name=run.name, package_version=simulation_code(),
        solver={**spec.solver.model_dump(), "description": integrator.describe()},
        solver_stats={**stats, "warnings": warnings}, particles=tuple(particles), particle_stats=particle_stats,
        ledger=ledger.as_dict(), clock_names=model.clocks.names if model.clocks is not None else (),
        proper_times=model.proper_times(states) if model.clocks is not None else None,
        joint_names=model.joints.names if model.joints is not None else (), joint_forces=joint_loads[0],
        joint_torques=joint_loads[1], motor_efforts=joint_loads[2] if model.joints is not None
        and model.joints.motors is not None else None,
        orientation_errors=model.orientation_errors(states).max(axis=-1) if model.layout.matrix_orientation
        and len(states) else None)


def choose_dynamics(model: Model, solver: StepSettings, pools: Sequence[tuple[Any, ...]] = (),
                    particle_steps: int = 0) -> tuple[Dynamics, CostEstimate]:
    """The Dynamics a run of ``model`` with ``solver`` settings integrates, and the run's cost estimate (with the
    emitters' ``pools`` stepped ``particle_steps`` times): compiled equations of motion where the numpy ones would
    take long enough to repay loading them. The estimate is then of the compiled ones, whose contact solve costs
    little beside the search. Every run chooses so, a study's runs too: a study times what a render costs."""
    search, touching = measure_contact_search(Dynamics(model))
    cost = estimate_cost(model, solver, pools, particle_steps, contact_seconds=search + numpy_contact_solve(touching))
    system = dynamics_for(model, cost.seconds_of("integration") + cost.seconds_of("contacts"))
    if type(system) is not Dynamics:
        cost = estimate_cost(model, solver, pools, particle_steps, rhs_seconds=measure_rhs(model, system),
                             contact_seconds=search)
    return system, cost


def _integrate(run: RunPlan, system: Dynamics, integrator: Integrator, progress: Progress,
               checkpoint: tuple[int, Path] | None) -> tuple[IntegrationResult, list, dict[str, Any]]:
    """The bodies' states at the frame times, then the emitted particles (which may ride on bodies)."""
    model = run.model
    if model.layout.size:
        with progress.task("simulate", len(model.frame_times)) as on_frame:
            if checkpoint is None:
                result = integrator.integrate(system, model.y0, model.frame_times, on_frame=on_frame)
            else:
                every, path = checkpoint
                result = integrate_with_checkpoints(integrator, system, model.y0, model.frame_times,
                                                    every=every, path=Path(path), on_frame=on_frame)
        check_energy_growth(model, result.states, run.steps.method, result.stats.dt)
    else:  # a scene of emitters only: no body to integrate
        result = IntegrationResult(np.zeros((len(model.frame_times), 0)), SolverStats(run.steps.method))
    particles, particle_stats = simulate_emitters(run, result.states, progress)
    return result, particles, particle_stats


def simulate_emitters(run: RunPlan, states: np.ndarray, progress: Progress | None = None
                      ) -> tuple[list, dict[str, Any]]:
    """The run's emitted particles at the frame times (after its bodies, whose motion ``states`` (F, n) moves
    emitters attached to them), and the statistics of their simulation; nothing when it has no emitters."""
    systems, model = run.particles, run.model
    if systems is None:
        return [], {}
    progress = progress or Progress(enabled=False)
    motion = BodyMotion(model.frame_times, model.positions(states), model.velocities(states),
                        model.orientations(states), model.angular_velocities(states))
    with progress.task("particles", len(model.frame_times)) as on_frame:
        records, stats = simulate_particles(systems.emitters, systems.colliders, model.frame_times, run.steps,
                                            motion, dt=run.steps.dt, on_frame=on_frame)
    return records, stats.as_dict()


def compile_model(scene: LoadedScene) -> Model:
    """The Model of a loaded scene, with mesh files found beside the scene file (a run compiles it once, into its
    plan: :func:`plan`)."""
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
    momentum = model.layout.view(trajectory_states(model, trajectory), "rigid_angular_momentum")
    return float(np.max(np.linalg.norm(momentum, axis=-1), initial=0.0))


def frame_geometry(run: RunPlan, trajectory: Trajectory) -> FrameGeometry:
    """What the renderer draws for this run and trajectory, with the camera fitted to the whole motion: bodies,
    anchors, colliders and emitted particles."""
    spec, model, scene = run.spec, run.model, run.scene
    anchors = (np.vstack([model.anchors.positions(float(t)) for t in trajectory.times]) if model.anchors.moving
               else model.anchor_position)
    fixed = np.vstack([anchors, collider_points(spec, run.folder), particle_extent(trajectory)])
    bounds = motion_bounds(trajectory.positions, body_extents(model), fixed)
    emitters = run.particles.emitters if run.particles is not None else ()
    geometry = compile_frame_geometry(spec, model, bounds,
                                      largest_vector(model, trajectory, spec.render.show_vectors),
                                      run.folder, emitters, (trajectory.positions, trajectory.times),
                                      trajectory.particles)
    arrows = None
    framed = [bounds]  # what the camera fits: the motion, and what is drawn beyond it (arrows, target curves)
    if spec.render.arrows is not None:
        arrows = arrow_series(spec, model, trajectory_states(model, trajectory), np.asarray(trajectory.times),
                              np.asarray(trajectory.velocities), bounds)
        if arrows is not None:
            framed.append(arrow_tips(arrows, np.asarray(trajectory.positions)))
    if geometry.target_segments is not None:
        framed.append(geometry.target_segments.reshape(-1, 3))
    points = np.vstack(framed)
    low, high = np.nanmin(points, axis=0), np.nanmax(points, axis=0)  # (bodies not yet shown are NaN)
    quantities = (quantity_series(model, trajectory) if model.body_count and
                  (spec.render.energy_panel is not None or label_asks_for_quantities(spec.render.time_label))
                  else None)  # one pass over the trajectory, shared by the overlay and the panel
    return dataclasses.replace(geometry, label=label_values(scene, model, trajectory, quantities), arrows=arrows,
                               panel=panel_series(scene, quantities, trajectory), bounds=np.stack([low, high]))


def panel_series(scene: LoadedScene, quantities: QuantitySeries | None, trajectory: Trajectory
                 ) -> PanelSeries | None:
    """The series the energy panel plots, when the scene asks for one (the quantities of quantities.csv)."""
    panel = scene.spec.render.energy_panel
    if panel is None or quantities is None:
        return None
    series: dict[str, tuple[np.ndarray, str]] = {}
    if "energy" in panel.quantities:
        series.update({"kinetic [J]": (quantities.kinetic, "left"), "potential [J]": (quantities.potential, "left"),
                       "total [J]": (quantities.total, "left")})
    if "momentum" in panel.quantities:
        series["|p| [kg·m/s]"] = (np.linalg.norm(quantities.momentum, axis=1), "right")
    return PanelSeries(np.asarray(trajectory.times, float), series, panel.height)


def label_asks_for_quantities(label: str) -> bool:
    """Whether a text overlay shows energies or speeds (which cost a pass over the trajectory)."""
    fields = {field for _, field, _, _ in string.Formatter().parse(label) if field}
    return bool(fields & {"E", "KE", "PE"} or label_speed_names(label))


def label_values(scene: LoadedScene, model: Model, trajectory: Trajectory,
                 quantities: QuantitySeries | None = None) -> LabelValues:
    """The numbers the scene's text overlay shows at each frame; energies and speeds only when it asks for them
    (from ``quantities``, or a pass over the trajectory)."""
    label = scene.spec.render.time_label
    shown = set(label_names(label, "stopwatch"))
    watches = {reading.name: reading for reading in stopwatch_readings(scene.spec.stopwatches, trajectory)
               if reading.name in shown}
    clocks = {name: trajectory.proper_times[:, trajectory.clock_names.index(name)]
              for name in label_names(label, "proper_time") if trajectory.proper_times is not None}
    values = LabelValues(np.asarray(trajectory.times), float(scene.spec.fps), stopwatches=watches,
                         wall_simulate=float(trajectory.solver_stats.get("wall_time", 0.0)), proper_times=clocks)
    if "R_error" in {field for _, field, _, _ in string.Formatter().parse(label) if field}:
        # integrated rotation matrices' distance from rotations; quaternions are rotations by construction
        errors = trajectory.orientation_errors
        values.series["R_error"] = errors if errors is not None else np.zeros(len(trajectory.times))
    if not label_asks_for_quantities(label) or not model.body_count:
        return values
    series = quantities if quantities is not None else quantity_series(model, trajectory)
    values.series.update({"E": series.total, "KE": series.kinetic, "PE": series.potential})
    values.speeds.update({name: series.speeds[:, series.body_names.index(name)] for name in label_speed_names(label)})
    return values


def particle_extent(trajectory: Trajectory) -> np.ndarray:
    """Two corners (2, 3) of the box around every emitted particle at every frame (a 1st–99th percentile box, so
    that a few strays do not shrink the view), or none (0, 3)."""
    corners = []
    for frames in trajectory.particles:
        live = frames.positions[frames.serials >= 0]
        if len(live):
            corners += [np.percentile(live, 1, axis=0), np.percentile(live, 99, axis=0)]
    return np.array(corners, float).reshape(-1, 3)


def quantity_series(model: Model, trajectory: Trajectory) -> QuantitySeries:
    """The run's energies, momenta and speeds at the frame times (what quantities.csv and the text overlay show)."""
    return QuantitySeries.of_states(model, trajectory_states(model, trajectory))


def trajectory_states(model: Model, trajectory: Trajectory) -> np.ndarray:
    """The model's flat states (F, n) at the trajectory's frames (from its per-body arrays)."""
    return model.states_from(trajectory.positions, trajectory.velocities, trajectory.orientations,
                             trajectory.angular_velocities, trajectory.proper_times)


def write_quantities(scene: LoadedScene, model: Model, trajectory: Trajectory, folder: str | Path, *,
                     plot: bool = False) -> list[Path]:
    """Write the run's per-frame quantities (energy, momentum, angular momentum, speeds) to ``quantities.csv`` in
    ``folder``, and with ``plot`` draw them to ``quantities.png``; nothing for a scene without bodies."""
    if not model.body_count:
        return []
    series = quantity_series(model, trajectory)
    folder = Path(folder)
    written = [folder / "quantities.csv"]
    write_text_atomic(written[0], series.csv())
    if plot:

        written.append(plot_quantities(series, folder / "quantities.png", scene=scene.name,
                                       ledger=trajectory.ledger))
    return written


def failure_report(scene: LoadedScene, error: SimulationError, watch: Stopwatch) -> dict[str, Any]:
    """The report of a run whose simulation failed: what failed, when, which body, and the message."""
    return {"scene": scene.name, "scene_file": str(scene.path) if scene.path else None, "status": "failed",
            "exit_code": error.exit_code, "error": str(error), "time": error.time, "body": error.body,
            "details": error.details, "solver": scene.spec.solver.model_dump(), "stages": dict(watch.seconds),
            "package_version": __version__, "outputs": [],
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), "host": platform.node()}


