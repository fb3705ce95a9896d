"""How a run shows itself in a Jupyter notebook: its video, its accuracy ledger and its energy plot, in one cell
output (``RunReport._repr_html_``; a trajectory shows its ledger, a study its plot and table).

The video and the plot are embedded in the page (base64), so that a notebook saved with its outputs shows them
anywhere, without the render folder; a video too large to embed (over ``EMBED_LIMIT``) is linked by its path.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

#: The largest video [bytes] embedded in a notebook's output; larger ones are linked.
EMBED_LIMIT = 20_000_000
#: The video formats a browser plays, with their MIME types, in the order tried.
PLAYABLE = {".mp4": "video/mp4", ".webm": "video/webm"}


def _embedded(path: Path, kind: str) -> str:
    return f"data:{kind};base64,{base64.b64encode(path.read_bytes()).decode()}"


def video_html(outputs: list[str]) -> str:
    """A looping <video> of the run's first playable output, embedded when small enough; '' without one."""
    for suffix, kind in PLAYABLE.items():
        for output in outputs:
            path = Path(output)
            if path.suffix == suffix and path.is_file():
                source = _embedded(path, kind) if path.stat().st_size <= EMBED_LIMIT else html.escape(str(path))
                return f'<video controls autoplay loop muted playsinline style="max-width:100%" src="{source}"></video>'
    return ""


def drift_text(law: dict[str, Any]) -> str:
    """A conserved quantity's drift over a run as a share of its scale, ``"4.5e-13 % of 11.86 J"`` (the report page,
    the notebook's ledger and the energy plot all say it so)."""
    return f"{100 * law['drift']:.2g} % of {law.get('scale', 0):.4g} {law.get('unit', '')}".rstrip()


def ledger_html(ledger: dict[str, Any]) -> str:
    """The accuracy ledger as a table: the method and its step, the work of each part (bodies, emitted particles),
    then, for the bodies, each conservation law, whether the scene conserves it (and why not) and how far it
    drifted (relative to the run's scale of that quantity), then the warnings."""
    if not ledger:
        return ""
    step = ledger.get("step", {})
    shown = ", ".join(f"{name} {value:.4g} s" for name, value in step.items() if isinstance(value, float))
    rows = [_row("method", f"{ledger.get('method')} ({ledger.get('kind')}){': ' + shown if shown else ''}")]
    work = ledger.get("work", {})
    for part in ("bodies", "particles"):
        if part in work:
            done = work[part]
            factored = f", {done['factorisations']} factorisations" if done.get("factorisations") else ""
            rows.append(_row(f"work ({part})", f"{done.get('steps')} steps, {done.get('rhs_evaluations')} "
                                               f"right-hand sides{factored}"))
    if "bodies" in work:  # the laws are the bodies'; emitted particles are not in them
        for name, law in ledger.get("conservation", {}).items():
            drift = law.get("drift")
            measured = f"drift {drift_text(law)}" if drift is not None else "—"
            verdict = "conserved" if law.get("conserved") else "not conserved"
            rows.append(f"<tr><th>{html.escape(name.replace('_', ' '))}</th>"
                        f"<td>{verdict}: {html.escape(str(law.get('reason', '')))}</td>"
                        f"<td>{html.escape(measured)}</td></tr>")
    rows += [_row("warning", str(warning)) for warning in ledger.get("warnings") or []]
    return "<table>" + "".join(rows) + "</table>"


def _row(heading: str, text: str) -> str:
    return f"<tr><th>{html.escape(heading)}</th><td colspan=2>{html.escape(text)}</td></tr>"


def plot_html(quantities: list[str]) -> str:
    """The energy plot (quantities.png), embedded, when the run drew it; '' otherwise."""
    for name in quantities:
        path = Path(name)
        if path.suffix == ".png" and path.is_file():
            # the four stacked panels at the video's width, not the page's: a cell's output stays a screen or two
            return (f'<img style="width:640px;max-width:100%" alt="energy, momenta and speeds" '
                    f'src="{_embedded(path, "image/png")}">')
    return ""


def trajectory_html(heading: str, ledger: dict[str, Any]) -> str:
    """A simulated run without pictures: its heading and its accuracy ledger."""
    return f"<div class='animbatch-trajectory'><h3>{html.escape(heading)}</h3>{ledger_html(ledger)}</div>"


def study_html(scene: str, plot: Path, table: str) -> str:
    """A work-precision study: its plot (embedded) above its table."""
    return (f"<div class='animbatch-study'><h3>{html.escape(scene)}: what accuracy costs in time</h3>"
            f"{plot_html([str(plot)])}<pre>{html.escape(table)}</pre></div>")


def run_html(scene: str, summary: str, outputs: list[str], ledger: dict[str, Any], quantities: list[str]) -> str:
    """The whole cell output of a run."""
    parts = [f"<h3>{html.escape(scene)}</h3>", video_html(outputs), ledger_html(ledger), plot_html(quantities),
             f"<pre style='white-space:pre-wrap'>{html.escape(summary)}</pre>"]
    return "<div class='animbatch-run'>" + "".join(part for part in parts if part) + "</div>"
