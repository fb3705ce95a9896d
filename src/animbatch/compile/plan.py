"""A run, compiled once: :class:`RunPlan` holds everything the stages after the compiler read (the Model, the step
settings resolved to numbers, the timeline, the emitters' particle systems), so that simulating, drawing,
encoding and reporting never compile or resolve a default again. A run is: plan -> simulate -> trajectory -> draw ->
encode."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from animbatch.compile.model import compile_scene
from animbatch.compile.particles import ParticleSystems, compile_particles
from animbatch.scene import LoadedScene
from animbatch.scene.schema import SceneSpec, SolverSpec
from animbatch.sim.integrators.step_plan import StepPlan, plan_steps
from animbatch.sim.model.model import Model
from animbatch.timeline import Timeline


@dataclass(frozen=True, eq=False)
class RunPlan:
    """One run of ``scene``: its ``model``, its ``steps`` (method and step resolved once), its emitters'
    ``particles`` (None without emitters), and ``folder``, where its relative file names (mesh files) resolve."""

    scene: LoadedScene
    model: Model
    steps: StepPlan
    particles: ParticleSystems | None
    folder: Path

    @property
    def spec(self) -> SceneSpec:
        return self.scene.spec

    @property
    def name(self) -> str:
        return self.scene.name

    @property
    def timeline(self) -> Timeline:
        """The frames: the model's frame times at the scene's fps."""
        return Timeline(self.model.frame_times, self.scene.spec.fps)


def scene_folder(scene: LoadedScene) -> Path:
    """Where the scene's relative file names (mesh files) are resolved: the scene file's folder."""
    return scene.path.parent if scene.path is not None else Path(".")


def step_plan(solver: SolverSpec, timeline: Timeline) -> StepPlan:
    """The scene's ``solver`` section resolved for a run over ``timeline``."""
    return plan_steps(solver.method, adaptive=solver.is_adaptive, dt=solver.dt, rtol=solver.rtol, atol=solver.atol,
                      max_step=solver.max_step, frame_times=timeline.times)


def plan_run(scene: LoadedScene, *, model: Model | None = None) -> RunPlan:
    """Compile ``scene`` for a run (reusing ``model`` when the caller compiled it already)."""
    folder = scene_folder(scene)
    model = model if model is not None else compile_scene(scene.spec, folder)
    particles = compile_particles(scene.spec, model, folder) if scene.spec.emitters else None
    return RunPlan(scene, model, step_plan(scene.spec.solver, Timeline(model.frame_times, scene.spec.fps)),
                   particles, folder)
