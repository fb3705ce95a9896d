"""A class at once: 'animbatch grade FOLDER' grades a hostile folder (a solution, a wrong one, an invalid scene, a
file that is not YAML, one that is not a scene, an hour-long run, a tolerance of 1e-14, a crash, a hang, a
Gradescope-style folder) with a row for every submission, resumes, and writes a class page that a browser shows."""

from __future__ import annotations

import csv
import os
import re

import pytest
from click.testing import CliRunner

from animbatch.cli import cli
from animbatch.teaching import classroom
from animbatch.teaching.templates import find

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("grading")]  # one worker builds the class once

#: Loaded by every Python process started with the folder on PYTHONPATH: it makes the grading processes of the
#: submissions named crash and hang do just that (a crash of the interpreter and a hang no budget reaches).
HOOK = """import os, sys, time
if any(argument.endswith("crash.yaml") for argument in sys.argv):
    os.abort()
if any(argument.endswith("hang.yaml") for argument in sys.argv):
    time.sleep(600)
"""


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    root = tmp_path_factory.mktemp("class")
    template = find("spring_damper").text
    solved = template.replace("damping: 2.0}", "damping: 20.0}")
    assert solved != template
    (root / "solution.yaml").write_text(solved)
    folder = root / "submissions"
    (folder / "dave").mkdir(parents=True)
    files = {"alice.yaml": solved, "bob.yaml": template, "carol.yaml": template.replace("stiffness:", "stifness:"),
             "dave/scene.yaml": solved, "erin.txt": "my answer is 20", "frank.yaml": "::: {{{ not yaml",
             "grace.yaml": solved.replace("duration: 2", "duration: 3600"),
             "heidi.yaml": re.sub(r"^solver: .*$", "solver: {method: DOP853, rtol: 1.0e-14, atol: 1.0e-16}", solved,
                                  flags=re.M),
             "crash.yaml": solved, "hang.yaml": solved}
    for name, text in files.items():
        (folder / name).write_text(text)
    hook = root / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(HOOK)
    saved = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(hook), saved]))
    try:  # (the cluster's workers and their grading processes inherit it)
        grades = classroom.grade_class(folder, root / "solution.yaml", workers=2, grace=5.0)
    finally:
        if saved is None:
            os.environ.pop("PYTHONPATH")
        else:
            os.environ["PYTHONPATH"] = saved
    return root, folder, grades


def test_every_submission_gets_a_row_saying_what_happened(graded):
    _, _, grades = graded
    rows = {row.name: row for row in grades.rows}
    assert sorted(rows) == ["alice", "bob", "carol", "crash", "dave", "erin", "frank", "grace", "hang", "heidi"]
    assert rows["alice"].score == rows["dave"].score == 3 == rows["alice"].max_score  # the Gradescope folder too
    assert {name: rows[name].status for name in rows} == {
        "alice": "graded", "bob": "graded", "carol": "graded", "crash": "crashed", "dave": "graded", "erin": "invalid",
        "frank": "graded", "grace": "graded", "hang": "hung", "heidi": "graded"}
    for name in ("bob", "carol", "crash", "erin", "frank", "grace", "hang", "heidi"):
        assert rows[name].score == 0, name
    notes = {row.name: classroom._note(row, grades.title) for row in grades.rows}
    assert notes["carol"] == notes["frank"] == "not checked: the submission does not validate"
    assert notes["grace"].startswith("not checked: the submission changes what the assignment does not let it")
    assert notes["heidi"].startswith("not checked: the submission changes what the assignment does not let it")
    assert notes["erin"] == "erin.txt is not a scene (.yaml) or a trajectory (.npz)"
    assert notes["crash"].startswith("its grading process ended with exit code")
    assert notes["hang"].startswith("stopped after ") and "did not end" in notes["hang"]
    assert "largest difference" in rows["bob"].result["tests"][0]["output"]  # checked, and wrong


def test_the_class_table_has_every_row_and_each_check(graded):
    _, _, grades = graded
    with open(grades.folder / "class.csv", newline="") as file:
        table = list(csv.DictReader(file))
    assert [row["submission"] for row in table] == [row.name for row in grades.rows]
    assert {row["submission"]: row["critically damped path"] for row in table}["alice"] == "3"
    assert {row["submission"]: row["critically damped path"] for row in table}["erin"] == ""
    for row in grades.rows:
        assert (grades.folder / "submissions" / f"{row.name}.html").is_file()
        assert (grades.folder / "submissions" / f"{row.name}.json").is_file()


def test_a_rerun_grades_only_what_changed(graded):
    root, folder, first = graded
    again = classroom.grade_class(folder, root / "solution.yaml", workers=1)
    assert again.graded_now == 0 and [r.score for r in again.rows] == [r.score for r in first.rows]
    (folder / "bob.yaml").write_text((folder / "alice.yaml").read_text())  # bob fixes his damping
    fixed = classroom.grade_class(folder, root / "solution.yaml", workers=1)
    assert fixed.graded_now == 1 and {r.name: r.score for r in fixed.rows}["bob"] == 3


def test_the_command_grades_a_folder(graded):
    root, folder, _ = graded
    result = CliRunner().invoke(cli, ["grade", str(folder), "--reference", str(root / "solution.yaml"),
                                      "--workers", "1"])
    assert result.exit_code == 0, result.output
    assert "10 submissions (0 graded now" in result.stdout and "index.html" in result.stdout
    refused = CliRunner().invoke(cli, ["grade", str(folder), "--reference", str(root / "solution.yaml"),
                                       "--json", "-"])
    assert refused.exit_code == 2 and "--json and --junit are for one submission" in refused.output


@pytest.mark.render
def test_the_class_page_shows_the_table_the_charts_and_links_each_submission(graded, browser):
    """In Chromium: a row per submission, a chart for the total and one per check with a bar per score, each
    name linking to that submission's page, and no errors."""
    _, _, grades = graded
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    page.goto((grades.folder / "index.html").as_uri())
    assert page.locator("tbody tr").count() == len(grades.rows)
    assert page.locator("svg.histogram").count() == 1 + len(grades.checks)
    # the total's chart: how many graded submissions scored 0 and 3, as the table on disk has them now
    bars = page.evaluate("[...document.querySelectorAll('svg.histogram')[0].querySelectorAll('rect title')]"
                         ".map(t => t.textContent)")
    with open(grades.folder / "class.csv", newline="") as file:
        scores = [row["score"] for row in csv.DictReader(file) if row["status"] == "graded"]
    assert bars == [f"{scores.count('0')} scored 0", f"{scores.count('3')} scored 3"]
    page.locator("a", has_text="alice").click()
    page.wait_for_load_state()
    assert page.url.endswith("submissions/alice.html")
    assert "PASS  critically damped path" in page.locator("pre").inner_text()
    assert not errors, errors
    page.close()


@pytest.mark.render
def test_with_reports_each_checked_submission_links_its_run(tmp_path):
    """--reports: a checked submission's row links its run's report page (a video of its motion); one that could not
    be checked has none."""
    template = find("spring_damper").text
    solved = template.replace("damping: 2.0}", "damping: 20.0}")
    (tmp_path / "solution.yaml").write_text(solved)
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "alice.yaml").write_text(solved)
    (folder / "carol.yaml").write_text(template.replace("stiffness:", "stifness:"))
    result = CliRunner().invoke(cli, ["grade", str(folder), "--reference", str(tmp_path / "solution.yaml"),
                                      "--workers", "1", "--reports", "--out", str(tmp_path / "grades")])
    assert result.exit_code == 0, result.output
    page = (tmp_path / "grades" / "index.html").read_text()
    links = re.findall(r"<a class=run href='([^']+)'>", page)
    assert links == ["runs/alice/spring-damper/index.html"]
    report = (tmp_path / "grades" / links[0]).read_text()
    assert "<video" in report and (tmp_path / "grades" / "runs" / "alice" / "spring-damper" / "spring-damper.mp4").is_file()
    assert "the run (video, ledger, energy)" in (tmp_path / "grades" / "submissions" / "alice.html").read_text()


def test_entries_that_share_a_name_get_rows_of_their_own(tmp_path):
    """A scene beside a file or a folder of the same name: the scene's row takes its whole file name."""
    for name, text in {"alice.yaml": "a", "alice.txt": "b", "bob.yaml": "c", "bob/scene.yaml": "d"}.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    found = {s.name: (s.path.relative_to(tmp_path).as_posix() if s.path else s.problem)
             for s in classroom.find_submissions(tmp_path)}
    assert found == {"alice": "alice.txt is not a scene (.yaml) or a trajectory (.npz)", "alice.yaml": "alice.yaml",
                     "bob": "bob/scene.yaml", "bob.yaml": "bob.yaml"}
