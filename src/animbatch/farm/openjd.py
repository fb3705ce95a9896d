"""``animbatch farm openjd``: an Open Job Description job template (specification ``jobtemplate-2023-09``) for
one scene, for render managers that take OpenJD, such as AWS Deadline Cloud, or the ``openjd`` command line.

The job has the farm's three steps: ``Bake``; ``Render``, whose tasks are the frame chunks (a task parameter
``Frames`` holding ranges such as ``48-95``) and which depends on ``Bake``; and ``Encode``, which depends on
``Render``. The scene file and the output folder are job parameters of type PATH, so a render manager can map them
to where its workers see them. Every task is an ordinary, idempotent animbatch command.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from animbatch.farm.frame_files import FrameRange
from animbatch.farm.slurm import animbatch_command

SPECIFICATION = "jobtemplate-2023-09"


def openjd_template(scene_path: str | Path, *, frames: int, name: str, out_dir: str | Path, chunk: int,
                    overrides: Sequence[str] = (), animbatch: Sequence[str] | None = None) -> dict[str, Any]:
    """The job template for a scene of ``frames`` frames, as a mapping ready to write as YAML or JSON."""
    command, *prefix = list(animbatch or animbatch_command())
    scene = ["{{Param.SceneFile}}", "--out", "{{Param.OutputDir}}",
             *[part for item in overrides for part in ("--set", item)]]

    def action(*args: str) -> dict[str, Any]:
        return {"actions": {"onRun": {"command": command, "args": [*prefix, *args]}}}

    ranges = [str(part) for part in FrameRange(0, frames).chunks(chunk)]
    return {
        "specificationVersion": SPECIFICATION,
        "name": f"animbatch {name}",
        "description": f"Bake {name}, render its {frames} frames in {len(ranges)} tasks of up to {chunk}, encode.",
        "parameterDefinitions": [
            {"name": "SceneFile", "type": "PATH", "objectType": "FILE", "dataFlow": "IN",
             "default": str(Path(scene_path).resolve()), "description": "The scene (YAML)."},
            {"name": "OutputDir", "type": "PATH", "objectType": "DIRECTORY", "dataFlow": "OUT",
             "default": str(Path(out_dir).resolve()), "description": "Where the cache, frames and videos go."},
        ],
        "steps": [
            {"name": "Bake", "script": action("bake", *scene, "--no-progress")},
            {"name": "Render", "dependencies": [{"dependsOn": "Bake"}],
             "parameterSpace": {"taskParameterDefinitions": [{"name": "Frames", "type": "STRING", "range": ranges}]},
             "script": action("render", *scene, "--frames", "{{Task.Param.Frames}}", "--jobs", "1",
                              "--no-progress")},
            {"name": "Encode", "dependencies": [{"dependsOn": "Render"}], "script": action("encode", *scene)},
        ],
    }


def openjd_yaml(template: dict[str, Any]) -> str:
    """The template as YAML, keys in the specification's order."""
    return "# Written by 'animbatch farm openjd'. Check it with: openjd check <this file>\n" + yaml.safe_dump(
        template, sort_keys=False, allow_unicode=True, width=120)
