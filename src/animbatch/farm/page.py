"""A static report page of a batch or a render (``index.html``), opened from disk in any browser, no server.

For every scene or sweep variant: its video (the H.264 MP4, ``faststart``), a poster frame (the video's middle
frame, ``<video>.poster.png`` beside it), the run's ledger (method, steps, wall time per stage, conservation drifts,
warnings) and its energy plot (``quantities.png``); for a sweep, the table of its variants, sortable by any column
(click a header; numbers sort as numbers). Every path in the page is relative to it, so the folder can be moved or
zipped as a whole.
"""

from __future__ import annotations

import csv
import html
import io
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from animbatch.encode.video import middle_frame
from animbatch.farm.batch import JobResult
from animbatch.farm.sweep import BatchPlan, metrics_csv
from animbatch.files import atomic_path, write_text_atomic
from animbatch.notebook_display import drift_text
from animbatch.sim.ledger import summary

#: The poster's file name beside its video.
POSTER_SUFFIX = ".poster.png"


@dataclass(frozen=True)
class PageEntry:
    """One run on the page: its ``label``, ``status`` (ok or failed), its ``report`` (report.json as a dict; empty
    when it failed before writing one), the ``error`` of a failed run, and a sweep variant's ``values``."""

    label: str
    status: str
    report: dict[str, Any] = field(default_factory=dict)
    error: str = ""
    values: dict[str, str] = field(default_factory=dict)


def write_poster(video: Path) -> Path:
    """Save the video's middle frame as ``<video>.poster.png`` beside it (atomically); its path."""
    from PIL import Image

    target = video.with_name(video.name + POSTER_SUFFIX)
    with atomic_path(target) as partial:
        Image.fromarray(middle_frame(video)).save(partial, format="PNG")
    return target


def write_page(entries: Sequence[PageEntry], target: str | Path, *, title: str,
               table: tuple[list[str], list[list[str]]] | None = None) -> Path:
    """Write ``index.html`` at ``target`` (atomically), with a poster beside every video; ``table``: a sweep's
    columns and rows (one per entry, in order). Returns the page's path."""
    target = Path(target)
    folder = target.parent
    sections = [_section(entry, folder, number) for number, entry in enumerate(entries)]
    parts = [_HEAD.format(title=html.escape(title)), f"<h1>{html.escape(title)}</h1>",
             f"<p class=meta>{sum(e.status == 'ok' for e in entries)} of {len(entries)} runs succeeded.</p>"]
    if table is not None:
        parts.append(_table(*table))
    parts += sections
    parts.append(_SCRIPT + "</body></html>\n")
    write_text_atomic(target, "\n".join(parts))
    return target


def run_page(reports: Sequence[tuple[str | None, Any]], folder: str | Path) -> Path:
    """The page of one render (``animbatch render --report html``): ``folder/index.html``, one section per camera
    rendered (``reports``: the camera's name, or None for ``render.camera``, and the run's
    :class:`~animbatch.farm.run.RunReport`)."""
    entries = [PageEntry(report.scene + (f" ({camera} camera)" if camera else ""), "ok", dict(report.__dict__))
               for camera, report in reports]
    return write_page(entries, Path(folder) / "index.html", title=f"{reports[0][1].scene}: animbatch render")


def batch_page(plan: BatchPlan, results: Sequence[JobResult], out_dir: str | Path) -> Path:
    """The page of a batch: ``OUT/index.html``, or for a sweep ``OUT/<scene>-sweep/index.html`` beside sweep.csv
    (call after :func:`~animbatch.farm.sweep.finish_sweep`, which measures the drifts its table shows)."""
    entries = []
    for number, result in enumerate(results):
        report: dict[str, Any] = {}
        if result.report and Path(result.report).is_file():
            report = json.loads(Path(result.report).read_text(encoding="utf-8"))
        values = plan.chosen[number] if plan.sweep_folder is not None else {}
        entries.append(PageEntry(result.label, result.status, report, result.error, values))
    if plan.sweep_folder is None:
        return write_page(entries, Path(out_dir) / "index.html", title=f"animbatch batch: {len(results)} scenes")
    columns, *rows = list(csv.reader(io.StringIO(metrics_csv(list(zip(results, plan.chosen))))))
    name = plan.sweep_folder.name
    return write_page(entries, plan.sweep_folder / "index.html", title=f"{name}: {len(results)} variants",
                      table=(columns, rows))


def _relative(path: str | Path, folder: Path) -> str:
    return Path(os.path.relpath(Path(path).resolve(), folder.resolve())).as_posix()


def _video(report: dict[str, Any]) -> Path | None:
    return next((Path(p) for p in report.get("outputs", []) if str(p).endswith(".mp4") and Path(p).is_file()), None)


def _section(entry: PageEntry, folder: Path, number: int) -> str:
    report = entry.report
    parts = [f"<section id=run-{number} class='run {html.escape(entry.status)}'>",
             f"<h2>{html.escape(entry.label)} <span class=status>{html.escape(entry.status)}</span></h2>"]
    if entry.values:
        parts.append("<p class=values>" + ", ".join(f"<code>{html.escape(k)}</code> = {html.escape(v)}"
                                                     for k, v in entry.values.items()) + "</p>")
    if entry.error:
        parts.append(f"<pre class=error>{html.escape(entry.error)}</pre>")
    video = _video(report)
    parts.append("<div class=media>")
    if video is not None:
        width, height = report["resolution"]
        poster = write_poster(video)
        parts.append(f"<video controls muted playsinline preload=auto width={width} height={height} "
                     f"poster='{html.escape(_relative(poster, folder))}'>"
                     f"<source src='{html.escape(_relative(video, folder))}' type='video/mp4'></video>")
    plot = next((Path(p) for p in report.get("quantities", []) if str(p).endswith(".png") and Path(p).is_file()),
                None)
    if plot is not None:
        parts.append(f"<img class=plot alt='energy, momentum and speeds against time' "
                     f"src='{html.escape(_relative(plot, folder))}'>")
    parts.append("</div>")
    if report:
        parts.append(_ledger(report))
    parts.append("</section>")
    return "\n".join(parts)


def _ledger(report: dict[str, Any]) -> str:
    """The run's ledger as a definition list: the ledger's summary line (method, step, work, drifts), wall time per
    stage, each conservation law's drift or why it does not hold, then the warnings."""
    ledger = report.get("ledger") or {}
    stages = report.get("stages") or {}
    rows = [("run", summary(ledger) if ledger else str((report.get("solver") or {}).get("method", ""))),
            ("wall time", ", ".join(f"{name} {seconds:.2f} s" for name, seconds in stages.items()))]
    for name, law in (ledger.get("conservation") or {}).items():
        label = name.replace("_", " ")
        if law.get("conserved") and law.get("drift") is not None:
            rows.append((f"{label} drift", drift_text(law)))
        elif not law.get("conserved"):
            rows.append((label, f"not conserved: {law.get('reason', '')}"))
    items = "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in rows)
    warnings = ledger.get("warnings") or []
    listed = ("<ul class=warnings>" + "".join(f"<li>{html.escape(str(w))}</li>" for w in warnings) + "</ul>"
              if warnings else "<p class=clean>no accuracy warnings</p>")
    return f"<dl class=ledger>{items}</dl>{listed}"


def _table(columns: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th data-column={k} tabindex=0>{html.escape(c)}</th>" for k, c in enumerate(columns))
    # the first cell links to the run's section (rows are in the order of the sections)
    body = "".join(f"<tr><td><a href='#run-{number}'>{html.escape(row[0])}</a></td>"
                   + "".join(f"<td>{html.escape(cell)}</td>" for cell in row[1:]) + "</tr>"
                   for number, row in enumerate(rows))
    return (f"<table id=sweep class=sortable><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
            "<p class=meta>Click a column's header to sort by it (again to reverse).</p>")


_HEAD = """<!doctype html>
<html lang=en><head><meta charset=utf-8><title>{title}</title>
<meta name=viewport content="width=device-width, initial-scale=1">
<style>
body {{ font: 15px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 1400px; padding: 0 1em; color: #222; }}
h1 {{ margin-bottom: 0.2em; }} .meta {{ color: #666; }}
section.run {{ border-top: 1px solid #ddd; padding: 1em 0; }}
.status {{ font-size: 0.6em; padding: 0.15em 0.5em; border-radius: 0.3em; background: #d9f2dd;
           vertical-align: middle; }}
.failed .status {{ background: #f8d7d7; }}
.media {{ display: flex; flex-wrap: wrap; gap: 1em; align-items: flex-start; }}
video {{ max-width: 100%; height: auto; background: #000; }} img.plot {{ max-width: 420px; height: auto; }}
dl.ledger {{ display: grid; grid-template-columns: max-content auto; gap: 0.2em 1em; }}
dl.ledger dt {{ color: #555; }} dl.ledger dd {{ margin: 0; }}
ul.warnings li {{ color: #8a4b00; }} .clean {{ color: #2b6e35; }} pre.error {{ color: #a00; white-space: pre-wrap; }}
table.sortable {{ border-collapse: collapse; margin: 1em 0; }}
table.sortable th, table.sortable td {{ border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }}
table.sortable th {{ cursor: pointer; background: #f3f3f3; user-select: none; }}
table.sortable td:first-child {{ text-align: left; }}
table.sortable th[aria-sort=ascending]::after {{ content: " ▲"; }}
table.sortable th[aria-sort=descending]::after {{ content: " ▼"; }}
</style></head><body>"""

# Sorting: numbers as numbers (blank cells last), anything else as text; a second click reverses.
_SCRIPT = """<script>
document.querySelectorAll("table.sortable th").forEach(function (header) {
  header.addEventListener("click", function () {
    var table = header.closest("table"), body = table.tBodies[0], column = Number(header.dataset.column);
    var ascending = header.getAttribute("aria-sort") !== "ascending";
    table.querySelectorAll("th").forEach(function (other) { other.removeAttribute("aria-sort"); });
    header.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    function key(row) {
      var text = row.cells[column].textContent.trim(), number = Number(text);
      return text === "" ? null : (isNaN(number) ? text : number);
    }
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = key(a), y = key(b);
      if (x === null || y === null) { return (x === null) - (y === null); }
      var order = (typeof x === "number" && typeof y === "number") ? x - y : String(x).localeCompare(String(y));
      return ascending ? order : -order;
    });
    rows.forEach(function (row) { body.appendChild(row); });
  });
});
</script>"""
