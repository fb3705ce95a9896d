"""``animbatch farm slurm``: a script that submits one scene to a SLURM cluster without Dask, the way farm
managers split work: a bake job, then an array of render jobs (one frame chunk each) that start only if the bake
succeeded (``afterok``), then an encode job that starts only if every render task succeeded.

Each task is an ordinary animbatch command (``bake``, ``render --frames A-B``, ``encode``), idempotent and atomic,
so a failed or pre-empted task can simply be re-queued.
"""

from __future__ import annotations

import math
import shlex
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path

TEMPLATE = """#!/usr/bin/env bash
# Submit {name} to SLURM: bake -> {tasks} render tasks of {chunk} frames (array, afterok) -> encode (afterok).
# Written by 'animbatch farm slurm'. Run it on the login node:  bash {script}
# Extra sbatch options for every job (account, partition, time): SBATCH_OPTIONS="--partition=short" bash {script}
set -euo pipefail
animbatch={animbatch}
common=({options} ${{SBATCH_OPTIONS:-}})
bake=$(sbatch --parsable "${{common[@]}}" --job-name={name}-bake \\
    --wrap="$animbatch bake {scene} --out {out}{sets} --no-progress")
render=$(sbatch --parsable "${{common[@]}}" --job-name={name}-render --array=0-{last_task} \\
    --dependency=afterok:$bake \\
    --wrap="first=\\$((SLURM_ARRAY_TASK_ID * {chunk})); last=\\$((first + {chunk} - 1)); \\
$animbatch render {scene} --out {out}{sets} --frames \\$first-\\$last --jobs 1 --no-progress")
encode=$(sbatch --parsable "${{common[@]}}" --job-name={name}-encode --dependency=afterok:$render \\
    --wrap="$animbatch encode {scene} --out {out}{sets}")
echo "{name}: bake job $bake, render array $render ({tasks} tasks of {chunk} frames), encode job $encode"
"""


def animbatch_command() -> list[str]:
    """How a job runs animbatch: the installed command, or this Python with ``-m animbatch``."""
    installed = shutil.which("animbatch")
    return [installed] if installed else [sys.executable, "-m", "animbatch"]


def slurm_script(scene_path: str | Path, *, frames: int, name: str, out_dir: str | Path, chunk: int,
                 overrides: Sequence[str] = (), options: Sequence[str] = (), script: str = "submit.sh",
                 animbatch: str | None = None) -> str:
    """The submission script's text for a scene of ``frames`` frames."""
    executable = animbatch or shlex.join(animbatch_command())
    tasks = math.ceil(frames / chunk)
    sets = "".join(f" --set {shlex.quote(item)}" for item in overrides)
    return TEMPLATE.format(name=name, tasks=tasks, chunk=chunk, last_task=tasks - 1, script=script,
                           animbatch=shlex.quote(executable),
                           options=" ".join(shlex.quote(option) for option in options),
                           scene=shlex.quote(str(Path(scene_path).resolve())),
                           out=shlex.quote(str(Path(out_dir).resolve())), sets=sets)
