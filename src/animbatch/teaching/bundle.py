"""A Gradescope autograder for an assignment: ``animbatch grade --bundle REF -o autograder.zip``.

Gradescope builds an image from the zip: it unpacks it into ``/autograder/source`` and runs ``setup.sh`` once, as
root on its Ubuntu image; then, for each submission (its files in ``/autograder/submission``), it runs
``run_autograder``, which must leave ``/autograder/results/results.json``. Ours:

* ``setup.sh`` installs a Python of at least 3.11 (Ubuntu 22.04's own is 3.10) and animbatch into
  ``/autograder/venv``: from the copy of animbatch's sources in the zip (the version that made the bundle, so that
  the reference grades there as it did here), with its dependencies from PyPI;
* ``run_autograder`` finds the one scene (or trajectory) in the submission and runs ``animbatch grade`` on it
  against the reference in the zip, writing Gradescope's JSON; with no scene, several, or a grading that cannot
  run, it still writes a result that says why (score 0). The assignment's budget bounds the submission's
  simulation; a ``timeout`` bounds the whole grading below Gradescope's own limit.

Both scripts take their root from ``AUTOGRADER_ROOT`` (default ``/autograder``) and ``run_autograder`` its Python
from ``ANIMBATCH_PYTHON`` (default the venv's), so that they can be run elsewhere, as the tests run them.
"""

from __future__ import annotations

import importlib.metadata
import zipfile
from pathlib import Path

from animbatch import stages
from animbatch.errors import SceneError
from animbatch.scene.loader import mesh_files
from animbatch.teaching.grade import GradeError
from animbatch.version import __version__

#: Seconds the whole grading of one submission may take (Gradescope's own default limit is ten minutes).
TIMEOUT = 540

SETUP = """#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the autograder's image: a Python >= 3.11 and animbatch {version}
# (from the sources in this zip) in $ROOT/venv.
set -euo pipefail
root="${{AUTOGRADER_ROOT:-/autograder}}"
python=""
for candidate in python3.13 python3.12 python3.11 python3; do
    if command -v "$candidate" >/dev/null && "$candidate" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
        python="$candidate"; break
    fi
done
if [ -z "$python" ]; then  # Ubuntu 22.04: python3.11 is in its universe
    apt-get update && apt-get install -y python3.11 python3.11-venv
    python=python3.11
fi
if ! "$python" -m venv "$root/venv"; then
    apt-get update && apt-get install -y "$python-venv"
    "$python" -m venv "$root/venv"
fi
"$root/venv/bin/python" -m pip install --upgrade pip
"$root/venv/bin/python" -m pip install "$root/source/animbatch-src"
"$root/venv/bin/python" -m animbatch --version
"""

RUN = """#!/usr/bin/env bash
# Gradescope runs this for each submission: grade the one scene in submission/ against the reference and write
# results/results.json (score 0 and the reason when there is nothing to grade or the grading cannot run).
set -u
root="${{AUTOGRADER_ROOT:-/autograder}}"
python="${{ANIMBATCH_PYTHON:-$root/venv/bin/python}}"
results="$root/results/results.json"
mkdir -p "$root/results"
rm -f "$results"
fail() {{
    "$python" -c 'import json, sys; json.dump({{"score": 0, "output": sys.argv[1]}}, open(sys.argv[2], "w"))' \\
        "$1" "$results"
    exit 0
}}
mapfile -t scenes < <(find "$root/submission" -type f \\( -name '*.yaml' -o -name '*.yml' -o -name '*.npz' \\) | sort)
if [ "${{#scenes[@]}}" -eq 0 ]; then
    fail "No scene file (.yaml) was submitted: submit your scene."
fi
if [ "${{#scenes[@]}}" -gt 1 ]; then
    fail "Submit one scene file; found ${{#scenes[@]}}: $(basename -a "${{scenes[@]}}" | tr '\\n' ' ')"
fi
timeout {timeout} "$python" -m animbatch grade "${{scenes[0]}}" --reference "$root/source/reference/{reference}" \\
    --json "$results" > "$root/results/grade.txt" 2>&1
status=$?
cat "$root/results/grade.txt"
if [ ! -s "$results" ]; then
    if [ "$status" -eq 124 ]; then
        fail "The grading did not end within {timeout} s."
    fi
    fail "The grading could not run (exit code $status): $(tail -n 3 "$root/results/grade.txt")"
fi
"""


def write_bundle(reference: str | Path, out: str | Path) -> Path:
    """Write the autograder zip for the assignment of the scene ``reference`` (its checks, and the files it reads)
    to ``out``. Raises GradeError when the reference does not validate or declares no checks."""
    reference, out = Path(reference), Path(out)
    try:
        scene = stages.load_scene(reference)
    except SceneError as error:
        raise GradeError(f"the reference {reference} does not validate: {error}") from None
    if scene.spec.assignment is None or not scene.spec.assignment.checks:
        raise GradeError(f"{reference} declares no checks: add 'assignment: {{title: ..., checks: [...]}}' "
                         "(see docs/teaching.md)")
    package = Path(__file__).resolve().parents[1]  # the animbatch package this runs from
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as bundle:
        _script(bundle, "setup.sh", SETUP.format(version=__version__))
        _script(bundle, "run_autograder", RUN.format(timeout=TIMEOUT, reference=reference.name))
        bundle.write(reference, f"reference/{reference.name}")
        for name in mesh_files(scene.spec):
            bundle.write(reference.parent / name, f"reference/{name}")
        for source in sorted(package.rglob("*")):
            if source.is_file() and "__pycache__" not in source.parts:
                bundle.write(source, f"animbatch-src/src/animbatch/{source.relative_to(package).as_posix()}")
        bundle.writestr("animbatch-src/pyproject.toml", _pyproject())
    partial.replace(out)
    return out


def _script(bundle: zipfile.ZipFile, name: str, text: str) -> None:
    info = zipfile.ZipInfo(name)
    info.external_attr = 0o755 << 16  # executable once unpacked
    info.compress_type = zipfile.ZIP_DEFLATED
    bundle.writestr(info, text)


def _pyproject() -> str:
    """A pyproject.toml for the copied sources: this version, its runtime dependencies (no extras)."""
    requirements = [r for r in importlib.metadata.requires("animbatch") or [] if "extra ==" not in r]
    listed = ", ".join(f'"{r}"' for r in requirements)
    return (f'[build-system]\nrequires = ["setuptools>=68", "wheel"]\nbuild-backend = "setuptools.build_meta"\n\n'
            f'[project]\nname = "animbatch"\nversion = "{__version__}"\nrequires-python = ">=3.11"\n'
            f"dependencies = [{listed}]\n\n[project.scripts]\nanimbatch = \"animbatch.cli:main\"\n\n"
            '[tool.setuptools.packages.find]\nwhere = ["src"]\n\n[tool.setuptools.package-data]\n'
            'animbatch = ["py.typed", "teaching/templates/*.yaml"]\n')
