"""Exceptions that animbatch raises on purpose, each carrying a message meant for the user.

The CLI prints ``str(error)`` and exits with ``error.exit_code``; no traceback is shown for these. Anything else that
escapes is a bug and keeps its traceback.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


class AnimbatchError(Exception):
    """Base class of every error meant for the user."""

    exit_code: int = 1


@dataclass(frozen=True)
class SceneIssue:
    """One problem in a scene, tied to where it came from.

    ``source`` is ``"file.yaml:12:5"`` for a key in a file, ``"--set solver.dt=0"`` for a command-line override, or
    the file name alone when no position is known (an empty file, say).
    """

    source: str
    path: str
    message: str

    def __str__(self) -> str:
        where = f"{self.source}: " if self.source else ""
        what = f"{self.path}: " if self.path else ""
        return f"{where}{what}{self.message}"


@dataclass
class SceneError(AnimbatchError):
    """A scene file (or an override) that cannot be used, with every problem found in it."""

    issues: list[SceneIssue] = field(default_factory=list)
    exit_code: int = 1

    def __post_init__(self) -> None:
        super().__init__(str(self))

    def __str__(self) -> str:
        count = len(self.issues)
        lines = [str(issue) for issue in self.issues]
        if count > 1:
            lines.append(f"{count} errors")
        return "\n".join(lines)


class SimulationError(AnimbatchError):
    """The simulation failed (solver failure, non-finite state). Raised before any frame is written."""

    exit_code = 3

    def __init__(self, message: str, *, time: float | None = None, body: str | None = None,
                 details: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.time = time
        self.body = body
        self.details = details or {}


class OverBudget(SimulationError):
    """The simulation was refused before it started, or stopped, for its wall-time budget (``solver.max_cost``).
    ``estimate``: the pre-flight's estimate of the whole run [s] when it was refused; None when it was stopped."""

    def __init__(self, message: str, *, time: float | None = None, body: str | None = None,
                 estimate: float | None = None) -> None:
        super().__init__(message, time=time, body=body)
        self.estimate = estimate


class TrajectoryError(AnimbatchError):
    """A trajectory file that is missing, unreadable or belongs to another scene."""

    exit_code = 1


class RenderError(AnimbatchError):
    """Rendering or encoding failed, or no off-screen OpenGL backend is available."""

    exit_code = 4


class ExportError(AnimbatchError):
    """An export could not be written: a library it needs is missing, or the file could not be saved."""

    exit_code = 5


class StudyError(AnimbatchError):
    """A study could not measure errors: no reference run (a tight, trusted run) succeeded."""

    exit_code = 3


class AnimbatchWarning(UserWarning):
    """Base class of the warnings meant for the user: the CLI prints them as one plain line on stderr, and runs keep
    them in their reports."""


class AccuracyWarning(AnimbatchWarning):
    """A finished run whose result is less accurate than it should be: a conserved quantity drifted beyond
    ``solver.drift_warning``, or a collision was missed (see :mod:`animbatch.sim.ledger`)."""
