"""A study's outputs: a table for the terminal, CSV and JSON files, and the work-precision plot (PNG), each written
atomically."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from animbatch.files import atomic_path, write_json_atomic, write_text_atomic
from animbatch.study.study import TARGETS, StudyResult

CSV_COLUMNS = ["method", "setting", "rtol", "dt", "status", "position_error", "final_error", "energy_drift",
               "momentum_drift", "angular_momentum_drift", "contact_time_error", "impacts", "limited_by_reference",
               "error_over_tolerance",
               "wall_time", "rhs_evaluations", "steps", "jacobian_evaluations", "lu_decompositions", "reason"]


def _number(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}e}"


def table(result: StudyResult) -> str:
    """The runs and the figures of merit as plain text."""
    lines = [f"study of {result.scene}: reference {result.reference}",
             f"length scale {result.length_scale:.3g} m, speed scale {result.speed_scale:.3g} m/s; "
             f"errors are relative to them; reference accuracy {result.reference_floor:.1e}",
             f"conserved: {', '.join(k for k, v in result.conserved.items() if v) or 'nothing (drifts not shown)'}"]
    contacts = result.reference_impacts is not None
    if contacts:
        lines.append(f"collisions: the reference bounces {result.reference_impacts} times; 'contact' is the largest "
                     "error of a bounce time [s], with the run's number of bounces")
    for method, why in result.skipped.items():
        lines.append(f"skipped {method}: {why}")
    header = (f"{'method':<17}{'setting':<16}{'pos. error':>11}{'final':>10}{'E drift':>10}"
              + (f"{'contact':>16}" if contacts else "") + f"{'err/rtol':>10}"
              f"{'time [s]':>10}{'RHS':>9}{'steps':>9}{'jac/LU':>12}  note")
    lines += ["", header, "-" * len(header)]
    for row in result.rows:
        if row.status != "ok":
            lines.append(f"{row.method:<17}{row.setting:<16}{row.status.upper():>11}  "
                         f"{row.reason.splitlines()[0][:110] if row.reason else ''}")
            continue
        ratio = row.error_over_tolerance
        work = f"{row.jacobian_evaluations}/{row.lu_decompositions}" if row.jacobian_evaluations else ""
        contact = f"{_number(row.contact_time_error, 1)} ({row.impacts})" if contacts else ""
        lines.append(f"{row.method:<17}{row.setting:<16}{_number(row.position_error):>11}"
                     f"{_number(row.final_error, 1):>10}{_number(row.energy_drift, 1):>10}"
                     + (f"{contact:>16}" if contacts else "") +
                     f"{'' if ratio is None else f'{ratio:.2g}':>10}{row.wall_time:>10.3g}"
                     f"{_count(row.rhs_evaluations):>9}{_count(row.steps):>9}{work:>12}  "
                     f"{'limited by reference' if row.limited_by_reference else ''}")
    lines += ["", f"{'method':<17}" + "".join(f"{f'time to {t:g} [s]':>18}" for t in TARGETS)
              + f"{'order':>8}{'failed':>8}"]
    for merit in result.merits:
        order = "—" if merit.order is None else f"{merit.order:.2f}"
        lines.append(f"{merit.method:<17}" + "".join(f"{str(merit.time_to[t]):>18}" for t in TARGETS)
                     + f"{order:>8}{merit.failures:>8}")
    return "\n".join(lines)


def _count(value: int | None) -> str:
    """A count, or '—' where it was not counted (the compiled particle kernels count no RHS evaluations)."""
    return "—" if value is None else str(value)


def csv_text(result: StudyResult) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, CSV_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    for row in result.rows:
        writer.writerow({**row.__dict__, "error_over_tolerance": row.error_over_tolerance})
    return buffer.getvalue()


def plot(result: StudyResult, target: str | Path) -> None:
    """Log–log error against wall time, one line per method; hollow markers for points limited by the reference,
    the reference's accuracy as a dashed line, failed runs counted in the legend."""
    # a Figure without pyplot: drawn off-screen by Agg, never touching the backend a notebook or script chose
    import matplotlib  # heavy (about 0.3 s): only when plotting
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 5.5), dpi=110)
    axes = figure.subplots()
    markers = "osD^v<>ph*"
    colours = matplotlib.colormaps["tab20"]
    for number, merit in enumerate(result.merits):
        rows = [r for r in result.rows if r.method == merit.method and r.status == "ok" and r.position_error
                and r.wall_time]  # in sweep order: loosest tolerance or largest step first
        label = merit.method + (f" ({merit.failures} failed)" if merit.failures else "")
        if not rows:
            axes.plot([], [], linestyle="none", label=label + ": no successful run")
            continue
        line, = axes.plot([r.wall_time for r in rows], [r.position_error for r in rows],
                          marker=markers[number % len(markers)], label=label, color=colours(number % 20),
                          linestyle="-" if rows[0].rtol else "--")
        limited = [r for r in rows if r.limited_by_reference]
        if limited:
            axes.plot([r.wall_time for r in limited], [r.position_error for r in limited], linestyle="none",
                      marker=markers[number % len(markers)], markersize=11, markerfacecolor="white",
                      color=line.get_color())
    if result.reference_floor > 0:
        axes.axhline(result.reference_floor, color="grey", linestyle=":", label="reference accuracy")
    for value in TARGETS:
        axes.axhline(value, color="lightgrey", linewidth=0.8)
    axes.set(xscale="log", yscale="log", xlabel="wall time [s] (best of repeats, one thread)",
             ylabel="RMS position error / length scale",
             title=f"{result.scene}: error against time (reference: {result.reference.split(',')[0]})")
    axes.grid(True, which="major", alpha=0.3)
    axes.legend(fontsize=8, loc="best")
    figure.tight_layout()
    with atomic_path(target) as partial:
        figure.savefig(partial, format="png")


def write_outputs(result: StudyResult, folder: str | Path) -> dict[str, Path]:
    """Write ``study.csv``, ``study.json``, ``study.png`` and ``study.txt`` (the table) into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {kind: folder / f"study.{kind}" for kind in ("csv", "json", "png", "txt")}
    write_text_atomic(paths["csv"], csv_text(result))
    write_json_atomic(paths["json"], result.as_dict())
    write_text_atomic(paths["txt"], table(result) + "\n")
    plot(result, paths["png"])
    return paths


@dataclass
class StudyReport:
    """A study and the files it wrote (``csv``, ``json``, ``png``, ``txt``); a notebook shows the work-precision
    plot and the table."""

    result: StudyResult
    paths: dict[str, Path]

    def _repr_html_(self) -> str:
        from animbatch.notebook_display import study_html

        return study_html(self.result.scene, self.paths["png"], table(self.result))
