"""Parameter sweeps (``animbatch batch scene.yaml --sweep springs[0].stiffness=100,1000,10000``): one batch job per
combination of values, each a variant of the scene named after its values, then a CSV of per-variant metrics and a
contact sheet (one frame of every variant's video, labelled) in ``renders/<scene>-sweep/``."""

from __future__ import annotations

import csv
import io
import itertools
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from animbatch import stages
from animbatch.encode.video import middle_frame
from animbatch.farm.batch import Job, JobResult
from animbatch.files import atomic_path, write_text_atomic
from animbatch.scene.overrides import Override
from animbatch.sim.integrators.guard import energy_scale
from animbatch.sim.invariants import total_energy
from animbatch.trajectory import Trajectory


@dataclass(frozen=True)
class Sweep:
    """One swept key and its values (YAML text each, as for ``--set``)."""

    key: str
    values: tuple[str, ...]


def split_values(text: str) -> list[str]:
    """Comma-separated values, keeping commas inside brackets: ``1,[0, 1, 0],3`` -> ``1``, ``[0, 1, 0]``, ``3``."""
    values, depth, current = [], 0, ""
    for char in text:
        depth += char in "[{"
        depth -= char in "]}"
        if char == "," and depth == 0:
            values.append(current.strip())
            current = ""
        else:
            current += char
    values.append(current.strip())
    return [value for value in values if value]


def parse_sweep(text: str) -> Sweep:
    """``KEY.PATH=V1,V2,…`` (at least one value)."""
    key, equals, values = text.partition("=")
    if not equals or not key.strip() or not split_values(values):
        raise ValueError(f"--sweep {text!r}: expected KEY.PATH=VALUE1,VALUE2,… (e.g. springs[0].stiffness=100,1000)")
    return Sweep(key.strip(), tuple(split_values(values)))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_") or "value"


def variants(scene_path: str, name: str, sweeps: Sequence[Sweep], overrides: Sequence[Any] = ()
             ) -> list[tuple[Job, dict[str, str]]]:
    """One job per combination of swept values: its overrides set the values and rename the scene
    ``<name>-<key>-<value>…`` (so each variant has its own output folder); with the values it stands for."""
    jobs = []
    for combination in itertools.product(*(sweep.values for sweep in sweeps)):
        chosen = {sweep.key: value for sweep, value in zip(sweeps, combination)}
        label = "-".join([name] + [f"{_slug(key.split('.')[-1])}-{_slug(value)}" for key, value in chosen.items()])
        sets = tuple(overrides) + tuple(f"{key}={value}" for key, value in chosen.items()) + (f"name={label}",)
        jobs.append((Job(scene_path, sets, label), chosen))
    return jobs


def energy_drift(job: Job, cache: str) -> float | None:
    """Largest change of the total energy over the run, relative to its energy scale (None when the scene puts
    energy in, so that a change is not drift)."""

    scene = stages.load_scene(job.scene_path, list(job.overrides))
    model = stages.compile_model(scene)
    if model.adds_energy or model.anchors.moving:
        return None
    trajectory = Trajectory.load(cache)
    energy = total_energy(model, stages.trajectory_states(model, trajectory))
    return float(np.max(np.abs(energy - energy[0])) / energy_scale(model))


def metrics_csv(rows: Sequence[tuple[JobResult, dict[str, str]]]) -> str:
    """One row per variant: its values, status, frames, wall time, solver work and energy drift."""
    keys = list(dict.fromkeys(key for _, chosen in rows for key in chosen))
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["variant", *keys, "status", "frames", "wall_time_s", "steps", "rhs_evaluations",
                     "energy_drift", "error"])
    for result, chosen in rows:
        stats = result.metrics.get("solver_stats", {})
        drift = result.metrics.get("energy_drift")
        writer.writerow([result.label, *(chosen.get(key, "") for key in keys), result.status, result.frames,
                         f"{result.wall_time:.2f}", stats.get("steps", ""), stats.get("rhs_evaluations", ""),
                         "" if drift is None else f"{drift:.3e}", result.error.splitlines()[0] if result.error else ""])
    return buffer.getvalue()


def contact_sheet(rows: Sequence[tuple[JobResult, dict[str, str]]], target: Path, *, tile_width: int = 320,
                  columns: int = 4) -> Path:
    """A grid of one frame (the middle one) of each variant's video, labelled with its values; failed variants
    are grey tiles with "failed"."""
    from PIL import Image, ImageDraw


    tiles = []
    for result, chosen in rows:
        video = next((Path(p) for p in result.outputs if str(p).endswith((".mp4", ".webm"))), None)
        image = None
        if result.status == "ok" and video is not None and video.is_file():
            image = Image.fromarray(middle_frame(video))
        tile_height = int(tile_width * 9 / 16) if image is None else int(tile_width * image.height / image.width)
        tile = Image.new("RGB", (tile_width, tile_height + 18), "white")
        if image is None:
            tile.paste((200, 200, 200), (0, 0, tile_width, tile_height))
        else:
            tile.paste(image.resize((tile_width, tile_height)), (0, 0))
        caption = ", ".join(f"{key.split('.')[-1]}={value}" for key, value in chosen.items())
        ImageDraw.Draw(tile).text((4, tile_height + 3), caption + ("" if result.status == "ok" else "  (failed)"),
                                  fill="black")
        tiles.append(tile)
    width = tile_width * min(columns, len(tiles))
    height = sum(max(t.height for t in tiles[row:row + columns]) for row in range(0, len(tiles), columns))
    sheet = Image.new("RGB", (width, height), "white")
    y = 0
    for row in range(0, len(tiles), columns):
        for column, tile in enumerate(tiles[row:row + columns]):
            sheet.paste(tile, (column * tile_width, y))
        y += max(t.height for t in tiles[row:row + columns])
    with atomic_path(target) as partial:
        sheet.save(partial, format="PNG")
    return target


@dataclass(frozen=True)
class BatchPlan:
    """The jobs of a batch: one per scene, or one per variant of a sweep (with the values each stands for, and the
    folder its CSV and contact sheet go to)."""

    jobs: list[Job]
    chosen: list[dict[str, str]]
    sweep_folder: Path | None = None


def plan_batch(scenes: Sequence[Path], settings: Sequence[Override], sweeps: Sequence[str], out_dir: Path
               ) -> BatchPlan:
    """The jobs for ``animbatch batch``: a ``sweep:`` block in a lone scene stands for ``--sweep`` options; every
    variant is validated before any work starts (SceneError). ValueError names a bad ``--sweep``."""

    if not sweeps and len(scenes) == 1:
        block = stages.load_scene(scenes[0], list(settings)).spec.sweep
        sweeps = [f"{key}=" + ",".join(json.dumps(value) for value in values) for key, values in block.items()]
    if not sweeps:
        return BatchPlan([Job(str(path), tuple(settings)) for path in scenes], [])
    if len(scenes) != 1:
        raise ValueError("a sweep takes exactly one scene")
    parsed = [parse_sweep(text) for text in sweeps]
    base = stages.load_scene(scenes[0], list(settings))
    planned = variants(str(scenes[0]), base.name, parsed, tuple(settings) + ("sweep={}",))
    for job, _ in planned:
        stages.load_scene(job.scene_path, list(job.overrides))
    return BatchPlan([job for job, _ in planned], [values for _, values in planned],
                     Path(out_dir) / f"{base.name}-sweep")


def finish_sweep(plan: BatchPlan, results: Sequence[JobResult]) -> list[Path]:
    """After a sweep's jobs: each variant's energy drift, then ``sweep.csv`` and the contact sheet; their paths."""

    assert plan.sweep_folder is not None
    for job, result in zip(plan.jobs, results):
        if result.status == "ok":
            result.metrics["energy_drift"] = energy_drift(job, result.metrics["cache"])
    rows = list(zip(results, plan.chosen))
    csv_path = plan.sweep_folder / "sweep.csv"
    write_text_atomic(csv_path, metrics_csv(rows))
    return [csv_path, contact_sheet(rows, plan.sweep_folder / "contact-sheet.png")]
