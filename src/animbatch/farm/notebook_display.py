"""How a run shows itself in a Jupyter notebook: its video, its accuracy ledger and its energy plot, in one cell
output (``RunReport._repr_html_``).

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


def ledger_html(ledger: dict[str, Any]) -> str:
    """The accuracy ledger as a table: the method and its step, then each conservation law, whether the scene
    conserves it (and why not) and how far it drifted."""
    if not ledger:
        return ""
    step = ledger.get("step", {})
    shown = ", ".join(f"{name} {value:.4g} s" for name, value in step.items() if isinstance(value, float))
    rows = [f"<tr><th>method</th><td colspan=2>{html.escape(str(ledger.get('method')))} "
            f"({html.escape(str(ledger.get('kind')))}){': ' + html.escape(shown) if shown else ''}</td></tr>"]
    for name, law in ledger.get("conservation", {}).items():
        drift = law.get("drift")
        measured = f"drift {drift:.3g} {html.escape(str(law.get('unit', '')))}" if drift is not None else "—"
        rows.append(f"<tr><th>{html.escape(name.replace('_', ' '))}</th>"
                    f"<td>{'conserved' if law.get('conserved') else 'not conserved'}: "
                    f"{html.escape(str(law.get('reason', '')))}</td><td>{measured}</td></tr>")
    warnings = ledger.get("warnings") or []
    rows += [f'<tr><th>warning</th><td colspan=2>{html.escape(str(warning))}</td></tr>' for warning in warnings]
    return "<table>" + "".join(rows) + "</table>"


def plot_html(quantities: list[str]) -> str:
    """The energy plot (quantities.png), embedded, when the run drew it; '' otherwise."""
    for name in quantities:
        path = Path(name)
        if path.suffix == ".png" and path.is_file():
            return f'<img style="max-width:100%" alt="energy, momenta and speeds" src="{_embedded(path, "image/png")}">'
    return ""


def run_html(scene: str, summary: str, outputs: list[str], ledger: dict[str, Any], quantities: list[str]) -> str:
    """The whole cell output of a run."""
    parts = [f"<h3>{html.escape(scene)}</h3>", video_html(outputs), ledger_html(ledger), plot_html(quantities),
             f"<pre style='white-space:pre-wrap'>{html.escape(summary)}</pre>"]
    return "<div class='animbatch-run'>" + "".join(part for part in parts if part) + "</div>"
