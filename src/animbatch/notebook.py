"""``%%animbatch``: render the scene written in a Jupyter cell, with ``animbatch render``'s options on the magic line.

    %load_ext animbatch

    %%animbatch --quality draft --set solver.method=RK45
    name: toss
    duration: 2
    bodies:
      - {name: ball, type: particle, mass: 1, position: [0, 0, 0], velocity: [4, 0, 6]}
    fields: [{type: gravity}]

The cell's output is the run: its video, accuracy ledger and energy plot (see :class:`~animbatch.api.RunReport`),
written like any render into ``renders/<name>/`` (``--out`` to change). Mesh files are found beside the notebook.
A scene that does not validate shows its errors as ``<cell>:line:column`` with the fix, and the cell fails (so that
"run all" stops there), without a Python traceback.
"""

from __future__ import annotations

import shlex
from typing import Any

import click

from animbatch import api, cli
from animbatch.errors import AnimbatchError, SceneError
from animbatch.farm.run import RunReport

#: How the cell's scene is named in messages (``<cell>:4:7``).
CELL = "<cell>"


class CellError(Exception):
    """A cell that cannot be rendered: IPython shows only the message (``_render_traceback_``), no traceback."""

    def _render_traceback_(self) -> list[str]:
        return str(self).splitlines()


def render_cell(line: str, cell: str) -> list[RunReport]:
    """Render the scene in ``cell`` with the options of ``line`` (as ``animbatch render``'s); the runs' reports, one
    per camera asked for. Raises CellError with the message a terminal would print."""
    try:
        context = cli.render.make_context("%%animbatch", [CELL, *shlex.split(line)])
    except click.exceptions.Exit:  # --help was printed
        return []
    except (click.ClickException, ValueError) as error:  # an unknown option, a bad value, unbalanced quotes
        raise CellError(_message(error)) from None
    options: dict[str, Any] = dict(context.params)
    options.pop("scene")
    try:
        scene = api.parse_scene(cell, filename=CELL, default_name="cell")
        return cli.render_scene(scene, **options)
    except (AnimbatchError, click.ClickException) as error:
        raise CellError(_message(error)) from None


def animbatch_magic(line: str, cell: str) -> RunReport | None:
    """The ``%%animbatch`` cell magic: the last run is the cell's output; the others (``--camera all``) are
    displayed above it."""
    reports = render_cell(line, cell)
    if len(reports) > 1:
        from IPython.display import display

        for report in reports[:-1]:
            display(report)
    return reports[-1] if reports else None


def load_ipython_extension(ipython: Any) -> None:
    """``%load_ext animbatch``: register the ``%%animbatch`` cell magic."""
    ipython.register_magic_function(animbatch_magic, magic_kind="cell", magic_name="animbatch")


def _message(error: Exception) -> str:
    if isinstance(error, click.ClickException):
        return f"error: {error.format_message()}"
    if isinstance(error, SceneError):
        return str(error)
    return f"error: {error}"
