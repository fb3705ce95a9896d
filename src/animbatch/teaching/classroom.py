"""Grading a whole class at once: every submission in a folder, in parallel on Dask, into a class table.

``animbatch grade SUBMISSIONS_DIR --reference REF`` finds one submission per entry of the folder: a scene file
(``alice.yaml``), or a folder holding one (``alice/scene.yaml``, with its meshes beside it), as Gradescope's export
lays them out; any other file gets a row saying it is not a scene. The reference is simulated once and saved; each
submission is then graded against that trajectory by its own ``animbatch grade`` process, so that a submission
that crashes the interpreter, or hangs where no budget can reach (loading, a compiled kernel), costs only its own
row: the process is killed past the assignment's budget plus :data:`GRACE` and the row says so.

Outputs, in the output folder: ``class.csv`` (one row per submission: score, status, each check's points),
``index.html`` (the table, the spread of the total and of each check's points as bar charts, a link to each
submission's page), ``submissions/<name>.html`` and ``.json`` (its grade as people and Gradescope read it), and
``grades.json``, which makes a re-run grade only what is new or changed (the reference and animbatch's code
included: a changed reference grades everyone again).
"""

from __future__ import annotations

import csv
import hashlib
import html
import io
import json
import statistics
import subprocess
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

from animbatch import stages
from animbatch.cluster import connect
from animbatch.errors import SceneError, SimulationError, TrajectoryError
from animbatch.files import write_text_atomic
from animbatch.provenance import simulation_code
from animbatch.teaching.grade import MIN_BUDGET, GradeError

#: Files a submission can be: a scene, or a trajectory from 'animbatch simulate'.
SUBMISSION_SUFFIXES = (".yaml", ".yml", ".npz")
#: Seconds a grading process may run beyond its simulation's budget (its start-up, loading the compiled kernels,
#: the checks) before it is taken to hang and is killed.
GRACE = 60.0


@dataclass(frozen=True)
class Submission:
    """One student's work: ``name`` (the file's stem or the folder's name), the scene or trajectory ``path`` to
    grade (None when there is none), ``problem`` (why it cannot be graded; '' when it can) and a ``digest`` of
    every file it consists of."""

    name: str
    path: Path | None
    problem: str
    digest: str


@dataclass
class Row:
    """A submission's grade in the class table: ``status`` graded (its checks ran or were scored), or not graded
    (``invalid``: nothing that can be graded, ``crashed``, ``hung``, ``error``: the grading itself failed), with
    the Gradescope-shaped ``result`` and the grading's own ``table`` (text)."""

    name: str
    digest: str
    status: str
    score: float = 0.0
    max_score: float = 0.0
    result: dict[str, Any] = field(default_factory=dict)
    table: str = ""
    report: str = ""  # its run's report page, relative to the output folder ('' without one)


def find_submissions(folder: Path, skip: Path | None = None) -> list[Submission]:
    """Every entry of ``folder`` (not hidden, not ``skip``) as a submission, by name (the file's stem; its whole name
    where two entries share a stem)."""
    found: list[Submission] = []
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith(".") or (skip is not None and entry.resolve() == skip.resolve()):
            continue
        if entry.is_file():
            problem = "" if entry.suffix in SUBMISSION_SUFFIXES else (
                f"{entry.name} is not a scene (.yaml) or a trajectory (.npz)")
            found.append(Submission(entry.stem, entry if not problem else None, problem, _digest([entry], folder)))
        elif entry.is_dir():
            files = sorted(path for path in entry.rglob("*") if path.is_file() and not path.name.startswith("."))
            scenes = [path for path in files if path.suffix in SUBMISSION_SUFFIXES]
            problem = ("" if len(scenes) == 1 else "no scene file (.yaml) in it" if not scenes else
                       f"{len(scenes)} scene files in it ({', '.join(p.name for p in scenes[:4])}): keep one")
            found.append(Submission(entry.name, scenes[0] if not problem else None, problem, _digest(files, folder)))
    stems = [submission.name for submission in found]
    return [submission if stems.count(submission.name) == 1 or submission.path is None
            or submission.path.parent != folder else
            Submission(submission.path.name, submission.path, submission.problem, submission.digest)
            for submission in found]


def _digest(files: list[Path], folder: Path) -> str:
    digest = hashlib.sha256()
    for path in files:
        digest.update(path.relative_to(folder).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def grade_one(path: str, reference: str, checks: str, timeout: float, report: str | None = None,
              budget: float = 0.0) -> dict[str, Any]:
    """Grade one submission in its own ``animbatch grade`` process (killed after ``timeout`` [s], its budget and
    the grace): the Gradescope JSON and the table, or why there is none. With ``report`` (a folder), a submission
    whose checks ran also gets its run's report page there (the video at draft quality, the ledger, the energy
    plot), its simulation within ``budget`` [s]. Runs on a Dask worker."""
    command = [sys.executable, "-m", "animbatch", "grade", path, "--reference", reference, "--checks", checks,
               "--json", "-"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": "hung", "message": f"stopped after {timeout:.3g} s: its grading did not end within its "
                                             "budget and the grace for starting up"}
    if done.returncode in (0, 1):
        graded = {"status": "graded", "result": json.loads(done.stdout), "table": done.stderr}
        checked = not any(test["output"].startswith("not checked") for test in graded["result"].get("tests", []))
        if report is not None and checked:
            graded["report"] = _report_page(path, report, timeout, budget)
        return graded
    last = done.stderr.strip().splitlines()[-1] if done.stderr.strip() else ""
    if done.returncode == 2:
        return {"status": "error", "message": f"the grading could not run: {last}"}
    return {"status": "crashed", "message": f"its grading process ended with exit code {done.returncode}"
                                            + (f": {last}" if last else "")}


def _report_page(path: str, folder: str, timeout: float, budget: float) -> str:
    """Render a submission's report page into ``folder`` ('animbatch render --report html', draft quality): the
    page's path, or '' when it could not be made."""
    command = [sys.executable, "-m", "animbatch", "render", path, "--report", "html", "--quality", "draft", "--out",
               folder, "--max-cost", f"{budget:.6g}", "--no-progress"]
    try:
        subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return ""
    pages = sorted(Path(folder).glob("*/index.html"))
    return str(pages[0]) if pages else ""


@dataclass
class ClassGrades:
    """The class's grades: one row per submission, in name order, and the check names and points in order."""

    rows: list[Row]
    checks: list[tuple[str, float]]
    title: str
    folder: Path
    graded_now: int = 0

    @property
    def max_score(self) -> float:
        return sum(points for _, points in self.checks)


def grade_class(submissions: str | Path, reference: str | Path, *, out: str | Path | None = None,
                checks_from: str | Path | None = None, workers: int | None = None, scheduler: str | None = None,
                on_row: Callable[[Row], None] | None = None, grace: float = GRACE,
                reports: bool = False) -> ClassGrades:
    """Grade every submission in the folder ``submissions`` against ``reference`` (a solved scene, or a trajectory
    with ``checks_from``) into ``out`` (default: ``<submissions>-grades`` beside the folder), on a Dask cluster (a
    LocalCluster of ``workers`` processes, or ``scheduler``); ``on_row`` hears of each row as it is done. A grading
    process that runs ``grace`` [s] past its submission's budget is killed. With ``reports``, each submission whose
    checks ran also gets its run's report page (video, ledger, energy plot) under ``runs/``."""
    folder, reference = Path(submissions), Path(reference)
    out_dir = Path(out) if out is not None else folder.with_name(folder.name + "-grades")
    out_dir.mkdir(parents=True, exist_ok=True)
    teacher = Path(checks_from) if checks_from is not None else reference
    try:
        scene = stages.load_scene(teacher)
    except SceneError as error:
        raise GradeError(f"the reference {teacher} does not validate: {error}") from None
    assignment = scene.spec.assignment
    if assignment is None or not assignment.checks:
        raise GradeError(f"{teacher} declares no checks: add 'assignment: {{title: ..., checks: [...]}}' "
                         "(see docs/teaching.md)")
    trajectory_file = reference if reference.suffix == ".npz" else out_dir / "reference.npz"
    key = _digest([path for path in (reference, teacher) if path.is_file()], reference.parent)
    key = hashlib.sha256(f"{key} {simulation_code()} reports={reports}".encode()).hexdigest()[:16]
    state_file = out_dir / "grades.json"
    state = json.loads(state_file.read_text()) if state_file.is_file() else {}
    known = state.get("rows", {}) if state.get("reference") == key else {}
    if reference.suffix != ".npz" and (not known or not trajectory_file.is_file()):
        try:
            stages.simulate(scene, reactions=False).save(trajectory_file)
        except (SimulationError, TrajectoryError) as error:
            raise GradeError(f"the reference {reference} cannot be used: {error}") from None
    wall = _recorded_seconds(trajectory_file)
    budget = max(assignment.budget * wall, MIN_BUDGET)
    timeout = budget + grace

    rows: dict[str, Row] = {}
    todo = []
    for submission in find_submissions(folder, skip=out_dir):
        previous = known.get(submission.name)
        if previous is not None and previous["digest"] == submission.digest:
            rows[submission.name] = Row(**previous)
        elif submission.problem:
            rows[submission.name] = Row(submission.name, submission.digest, "invalid",
                                        max_score=sum(c.points for c in assignment.checks),
                                        result={"output": submission.problem})
        else:
            todo.append(submission)
    for row in rows.values():
        if on_row:
            on_row(row)
    graded_now = len(todo)
    if todo:
        client, cluster = connect(workers, scheduler)
        try:
            from distributed import as_completed

            futures = {client.submit(grade_one, str(s.path.resolve()), str(trajectory_file.resolve()),
                                     str(teacher.resolve()), timeout,
                                     str((out_dir / "runs" / s.name).resolve()) if reports else None, budget,
                                     pure=False, retries=0): s
                       for s in todo if s.path is not None}
            for future in as_completed(list(futures)):
                submission = futures[future]
                try:
                    outcome = future.result()
                except Exception as error:  # the worker itself died (a crash Dask saw): the row says so
                    outcome = {"status": "crashed", "message": f"{type(error).__name__}: {error}"}
                rows[submission.name] = row = _row(submission, outcome, assignment.checks, out_dir)
                if on_row:
                    on_row(row)
                _save_state(state_file, key, rows)  # each row kept as it comes: an interrupted run resumes
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    _save_state(state_file, key, rows)
    grades = ClassGrades([rows[name] for name in sorted(rows)], [(c.name, c.points) for c in assignment.checks],
                         assignment.title, out_dir, graded_now)
    write_class_outputs(grades)
    return grades


def _recorded_seconds(trajectory_file: Path) -> float:
    from animbatch.trajectory import Trajectory

    trajectory = Trajectory.load(trajectory_file)
    return float(trajectory.solver_stats.get("wall_time", 0.0) + trajectory.particle_stats.get("wall_time", 0.0))


def _row(submission: Submission, outcome: dict[str, Any], checks: list[Any], out_dir: Path) -> Row:
    max_score = float(sum(check.points for check in checks))
    if outcome["status"] != "graded":
        return Row(submission.name, submission.digest, outcome["status"], 0.0, max_score,
                   {"output": outcome["message"]})
    result = outcome["result"]
    report = outcome.get("report", "")
    return Row(submission.name, submission.digest, "graded", float(result["score"]), float(result["max_score"]),
               result, outcome.get("table", ""),
               Path(report).resolve().relative_to(out_dir.resolve()).as_posix() if report else "")


def _save_state(path: Path, key: str, rows: dict[str, Row]) -> None:
    write_text_atomic(path, json.dumps({"reference": key, "rows": {name: asdict(row) for name, row in rows.items()}},
                                       indent=1) + "\n")


# ------------------------------------------------------------------------------------------ the class table


def check_points(row: Row) -> dict[str, float]:
    """Each check's points in a row (empty when the submission was not graded)."""
    return {test["name"]: float(test["score"]) for test in row.result.get("tests", [])}


def write_class_outputs(grades: ClassGrades) -> None:
    """class.csv, index.html and each submission's page and JSON, in ``grades.folder``."""
    names = [name for name, _ in grades.checks]
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(["submission", "score", "max_score", "status", *names, "note"])
    for row in grades.rows:
        points = check_points(row)
        writer.writerow([row.name, f"{row.score:g}", f"{row.max_score:g}", row.status,
                         *(f"{points[n]:g}" if n in points else "" for n in names), _note(row, grades.title)])
    write_text_atomic(grades.folder / "class.csv", text.getvalue())
    pages = grades.folder / "submissions"
    pages.mkdir(exist_ok=True)
    for row in grades.rows:
        write_text_atomic(pages / f"{row.name}.json", json.dumps(row.result, indent=2) + "\n")
        write_text_atomic(pages / f"{row.name}.html", _submission_page(row, grades.title))
    write_text_atomic(grades.folder / "index.html", class_page(grades))


_STYLE = """body{font-family:system-ui,sans-serif;margin:2em;max-width:70em}table{border-collapse:collapse}
td,th{border-bottom:1px solid #ddd;padding:.3em .8em;text-align:left}td.n{text-align:right}
.failed{color:#b00020}.charts{display:flex;flex-wrap:wrap;gap:2em}figure{margin:0}pre{white-space:pre-wrap}"""


def _submission_page(row: Row, title: str) -> str:
    body = row.table or str(row.result.get("output", ""))
    return (f"<!doctype html><html><head><meta charset=utf-8><title>{html.escape(row.name)}: "
            f"{html.escape(title)}</title><style>{_STYLE}</style></head><body><h1>{html.escape(row.name)}</h1>"
            f"<p>{row.score:g} / {row.max_score:g} points ({html.escape(row.status)}) · <a href='../index.html'>the "
            f"class</a> · <a href='{quote(row.name)}.json'>results.json</a>"
            + (f" · <a href='../{quote(row.report)}'>the run (video, ledger, energy)</a>" if row.report else "")
            + f"</p><pre>{html.escape(body)}</pre>"
            "</body></html>\n")


def _bars(label: str, values: list[float], top: float) -> str:
    """An SVG bar chart of how many rows scored each value of ``values`` (0 … ``top`` points)."""
    counts: dict[float, int] = {}
    for value in values:
        counts[value] = counts.get(value, 0) + 1
    keys = sorted(set(counts) | {0.0, float(top)})
    width, height, bar = 40 * len(keys) + 20, 140, 30
    tallest = max(counts.values(), default=1)
    parts = []
    for k, key in enumerate(keys):
        count = counts.get(key, 0)
        h = 90 * count / tallest  # the tallest 90 px, its count above it, the points below the baseline (115)
        x = 10 + 40 * k
        parts.append(f"<rect x='{x}' y='{115 - h:.1f}' width='{bar}' height='{h:.1f}' fill='#3d7cc9'>"
                     f"<title>{count} scored {key:g}</title></rect><text x='{x + bar / 2}' y='{111 - h:.1f}' "
                     f"text-anchor='middle' font-size='11'>{count}</text><text x='{x + bar / 2}' y='131' "
                     f"text-anchor='middle' font-size='11'>{key:g}</text>")
    return (f"<figure><figcaption>{html.escape(label)}</figcaption><svg class='histogram' width='{width}' "
            f"height='{height}' role='img' aria-label='{html.escape(label)}'>{''.join(parts)}</svg></figure>")


def _note(row: Row, title: str) -> str:
    """Why a row scored what it did, in a line, when not from its checks alone: why it was not graded, or the
    grade's own message (it did not validate, its run failed or went over budget, it changed what it may not)."""
    if row.status != "graded":
        return str(row.result.get("output", "")).strip().splitlines()[0]
    unchecked = {test["output"] for test in row.result.get("tests", []) if test["output"].startswith("not checked")}
    return unchecked.pop() if len(unchecked) == 1 else ""


def class_page(grades: ClassGrades) -> str:
    """The class page: a summary, a bar chart of the total and of each check's points, and the table."""
    graded = [row for row in grades.rows if row.status == "graded"]
    totals = [row.score for row in graded]
    summary = (f"{len(grades.rows)} submissions, {len(graded)} graded"
               + (f"; median {statistics.median(totals):g} / {grades.max_score:g}, mean "
                  f"{statistics.fmean(totals):.3g}" if totals else ""))
    charts = [_bars(f"total ({grades.max_score:g} points)", totals, grades.max_score)]
    for name, points in grades.checks:
        charts.append(_bars(f"{name} ({points:g})", [check_points(row).get(name, 0.0) for row in graded], points))
    head = "".join(f"<th>{html.escape(name)}</th>" for name, _ in grades.checks)
    lines = []
    for row in grades.rows:
        earned = check_points(row)
        cells = "".join(f"<td class=n>{earned[name]:g}</td>" if name in earned else "<td></td>"
                        for name, _ in grades.checks)
        note = _note(row, grades.title)
        lines.append(f"<tr class='{'graded' if row.status == 'graded' else 'failed'}'><td><a href='submissions/"
                     f"{quote(row.name)}.html'>{html.escape(row.name)}</a></td><td class=n>{row.score:g}</td>"
                     f"<td>{html.escape(row.status)}</td>{cells}<td>{html.escape(note)}</td><td>"
                     + (f"<a class=run href='{quote(row.report)}'>run</a>" if row.report else "") + "</td></tr>")
    return (f"<!doctype html><html><head><meta charset=utf-8><title>{html.escape(grades.title)}: the class</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(grades.title)}</h1><p>{summary} · "
            "<a href='class.csv'>class.csv</a></p>"
            f"<div class=charts>{''.join(charts)}</div><table><thead><tr><th>submission</th><th>score</th>"
            f"<th>status</th>{head}<th>note</th><th>report</th></tr></thead><tbody>{''.join(lines)}</tbody></table></body></html>\n")


def class_summary(grades: ClassGrades) -> str:
    """The class table for the terminal: one line per submission, then where the outputs are."""
    width = max([len(row.name) for row in grades.rows] + [10])
    lines = [f"{'submission':<{width}}  {'score':>9}  status"]
    for row in grades.rows:
        note = _note(row, grades.title)
        note = f": {note}" if note else ""
        lines.append(f"{row.name:<{width}}  {row.score:>4g} / {row.max_score:<3g}  {row.status}{note}")
    lines.append(f"{len(grades.rows)} submissions ({grades.graded_now} graded now, the others unchanged since the "
                 f"last run) -> {grades.folder / 'index.html'}, {grades.folder / 'class.csv'}")
    return "\n".join(lines)
