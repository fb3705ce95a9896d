"""The Gradescope autograder bundle: 'animbatch grade --bundle REF -o autograder.zip', unpacked as Gradescope does and
its run_autograder run on submissions laid out as Gradescope lays them out (the root from AUTOGRADER_ROOT): a
passing, a failing, an invalid and an over-budget submission, and none at all, each leave a results.json."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.teaching.templates import find

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("grading")]  # one worker builds the bundle once


@pytest.fixture(scope="module")
def autograder(tmp_path_factory):
    """The bundle of the spring-damper assignment (its other differences listed only, so that an over-long run
    meets the budget), unpacked into ROOT/source."""
    folder = tmp_path_factory.mktemp("bundle")
    template = find("spring_damper").text
    solved = template.replace("damping: 2.0}", "damping: 20.0}").replace("  edit:", "  differences: list\n  edit:")
    (folder / "solution.yaml").write_text(solved)
    result = CliRunner().invoke(cli, ["grade", "--bundle", str(folder / "solution.yaml"), "-o",
                                      str(folder / "autograder.zip")])
    assert result.exit_code == 0, result.output
    root = folder / "autograder"
    with zipfile.ZipFile(folder / "autograder.zip") as bundle:
        bundle.extractall(root / "source")
        modes = {info.filename: info.external_attr >> 16 for info in bundle.infolist()}
    assert modes["run_autograder"] & 0o111 and modes["setup.sh"] & 0o111  # executable, as Gradescope runs them
    return root, template, solved


def run_autograder(root: Path, files: dict[str, str]) -> dict:
    """Lay out a submission, run the bundle's run_autograder on it, and read its results.json."""
    submission = root / "submission"
    if submission.exists():
        for path in sorted(submission.rglob("*"), reverse=True):
            path.unlink() if path.is_file() else path.rmdir()
    submission.mkdir(exist_ok=True)
    for name, text in files.items():
        (submission / name).parent.mkdir(parents=True, exist_ok=True)
        (submission / name).write_text(text)
    environment = {**os.environ, "AUTOGRADER_ROOT": str(root), "ANIMBATCH_PYTHON": sys.executable}
    done = subprocess.run(["bash", str(root / "source" / "run_autograder")], env=environment, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads((root / "results" / "results.json").read_text())


def test_a_passing_submission_gets_every_point(autograder):
    root, _, solved = autograder
    results = run_autograder(root, {"spring_damper.yaml": solved})
    assert results["score"] == results["max_score"] == 3
    assert results["tests"][0]["status"] == "passed"


def test_a_failing_submission_gets_the_check_that_failed(autograder):
    root, template, _ = autograder
    results = run_autograder(root, {"spring_damper.yaml": template})
    assert results["score"] == 0 and results["tests"][0]["status"] == "failed"
    assert "largest difference" in results["tests"][0]["output"] and "Hint: c = 2" in results["tests"][0]["output"]


def test_an_invalid_submission_says_why(autograder):
    root, template, _ = autograder
    results = run_autograder(root, {"nested/mine.yaml": template.replace("stiffness:", "stifness:")})
    assert results["score"] == 0
    assert results["tests"][0]["output"] == "not checked: the submission does not validate"
    assert "did you mean 'stiffness'?" in results["output"]


def test_an_over_budget_submission_scores_nothing_and_ends(autograder):
    root, _, solved = autograder
    results = run_autograder(root, {"spring_damper.yaml": solved.replace("duration: 2", "duration: 3000")})
    assert results["score"] == 0 and results["tests"][0]["output"].startswith("not checked: over budget: ")


def test_no_scene_or_two_scenes_get_a_result_that_says_so(autograder):
    root, template, solved = autograder
    results = run_autograder(root, {"answer.txt": "20"})
    assert results == {"score": 0, "output": "No scene file (.yaml) was submitted: submit your scene."}
    results = run_autograder(root, {"a.yaml": solved, "b.yaml": template})
    assert results["score"] == 0 and results["output"].startswith("Submit one scene file; found 2: a.yaml b.yaml")


def test_the_bundled_sources_build_animbatch_with_its_templates(autograder, tmp_path):
    """setup.sh installs from the copy of animbatch in the zip: it builds into a wheel of this version with the
    templates as package data (setup.sh itself installs from PyPI, which a test does not reach)."""
    from animbatch import __version__

    root, _, _ = autograder
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path),
                           str(root / "source" / "animbatch-src")], capture_output=True, text=True, timeout=600)
    if done.returncode and "No matching distribution" in done.stderr:
        pytest.skip("pip cannot fetch setuptools to build with here (offline)")
    assert done.returncode == 0, done.stderr
    (wheel,) = tmp_path.glob("*.whl")
    assert wheel.name == f"animbatch-{__version__}-py3-none-any.whl"
    names = zipfile.ZipFile(wheel).namelist()
    assert "animbatch/teaching/templates/spring_damper.yaml" in names and "animbatch/cli.py" in names
    syntax = subprocess.run(["bash", "-n", str(root / "source" / "setup.sh")], capture_output=True, text=True)
    assert syntax.returncode == 0, syntax.stderr
