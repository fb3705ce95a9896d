"""The pipeline as library functions: load → compile → simulate → render/encode, and ``run`` for all of them.

    from animbatch import api
    scene = api.load_scene("scenes/projectile.yaml", overrides=["solver.method=DOP853"])
    plan = api.plan(scene)            # compiled once: model, step settings, timeline, emitters
    trajectory = api.simulate(plan)
    result = api.render(plan, trajectory, out_dir="renders")

Simulation and rendering meet only at the :class:`~animbatch.trajectory.Trajectory`: a trajectory saved by
``simulate`` can be rendered later (with another camera or resolution) without simulating again.
"""

from __future__ import annotations

from animbatch.compile.model import compile_scene
from animbatch.compile.plan import RunPlan
from animbatch.compile.scene_builder import SceneModelBuilder
from animbatch.compile.stopwatches import StopwatchReading, stopwatch_readings
from animbatch.farm.run import RenderResult, RunReport, finish_outputs, render, run
from animbatch.scene import physics_fingerprint
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
                              simulate,
                              simulate_emitters,
                              write_quantities,
)

__all__ = ["RenderResult", "RunPlan", "RunReport", "SceneModelBuilder", "StopwatchReading", "check_trajectory",
           "compile_model", "compile_scene", "failure_report", "finish_outputs", "frame_geometry", "load_scene",
           "parse_scene", "physics_fingerprint", "plan", "render", "run", "scene_fingerprint", "scene_folder",
           "simulate", "simulate_emitters", "stopwatch_readings", "write_quantities"]
