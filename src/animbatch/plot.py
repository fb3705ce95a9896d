"""The per-frame quantities of a run as a picture: energy, momentum, angular momentum and the bodies' speeds over
time (matplotlib, off-screen), for a teacher to show beside the video.

The conserved ones carry their drift in their panel's title; a quantity the scene does not conserve says why not.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from animbatch.files import atomic_path
from animbatch.notebook_display import drift_text
from animbatch.sim.ledger import QuantitySeries

#: Bodies drawn one line each in the speed panel; with more, the mean and the fastest are drawn instead.
MOST_SPEED_LINES = 10


def _title(name: str, ledger: dict[str, Any]) -> str:
    entry = ledger.get("conservation", {}).get(name)
    label = name.replace("_", " ")
    if not entry:
        return label
    if entry.get("drift") is not None:
        return f"{label} (conserved; drift {drift_text(entry)})"
    return f"{label} (not conserved: {entry['reason']})"


def plot_quantities(series: QuantitySeries, target: str | Path, *, scene: str, ledger: dict[str, Any]) -> Path:
    """Draw the series into a PNG at ``target`` (written atomically); returns the path."""
    # a Figure without pyplot: drawn off-screen by Agg, never touching the backend a notebook or script chose
    from matplotlib.figure import Figure  # heavy (about 0.3 s): only when plotting

    figure = Figure(figsize=(9, 11), dpi=100)
    axes = figure.subplots(4, 1, sharex=True)
    t = series.times
    energy, momentum, angular, speed = axes
    energy.plot(t, series.kinetic, label="kinetic")
    energy.plot(t, series.potential, label="potential")
    energy.plot(t, series.total, label="total", color="black", linewidth=2)
    energy.set_ylabel("energy [J]")
    for axis, values, unit, name in ((momentum, series.momentum, "kg·m/s", "momentum"),
                                     (angular, series.angular_momentum, "kg·m²/s", "angular_momentum")):
        for component, label in enumerate("xyz"):
            axis.plot(t, values[:, component], label=label)
        axis.set_ylabel(f"{name.replace('_', ' ')} [{unit}]")
    angular.set_ylabel("angular momentum\nabout the centre of mass [kg·m²/s]")
    if len(series.body_names) <= MOST_SPEED_LINES:
        for index, name in enumerate(series.body_names):
            speed.plot(t, series.speeds[:, index], label=name)
    else:
        speed.plot(t, series.speeds.mean(axis=1), label=f"mean of {len(series.body_names)} bodies")
        speed.plot(t, series.speeds.max(axis=1), label="fastest body")
    speed.set_ylabel("speed [m/s]")
    speed.set_xlabel("time [s]")
    for axis, name in zip(axes, ("energy", "momentum", "angular_momentum", "")):
        if name:
            axis.set_title(_title(name, ledger), fontsize=9)
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8, loc="best")
    speed.set_title("speed of each body's centre of mass", fontsize=9)
    method = ledger.get("method", "")
    figure.suptitle(f"{scene}: quantities at the frame times ({method})" if method else scene)
    # fixed margins (room for the two-line y label and the suptitle): tight_layout measured every text and took
    # 40 % of the plot's time
    figure.subplots_adjust(left=0.1, right=0.97, bottom=0.05, top=0.94, hspace=0.22)
    with atomic_path(target) as partial:
        figure.savefig(partial, format="png")
    return Path(target)

