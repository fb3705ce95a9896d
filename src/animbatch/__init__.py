"""animbatch: declarative YAML scenes to physically based animations, rendered headless.

The pipeline runs in one direction (see ``api``)::

    scene.yaml -> SceneSpec -> Model + y0 -> integrator -> Trajectory -> frames -> PNG / MP4

Everything is usable from Python (``animbatch.render("scene.yaml", quality="draft")`` in a script or a notebook,
``%load_ext animbatch`` for the ``%%animbatch`` cell magic); the ``animbatch`` command is a thin layer over
:mod:`animbatch.api`.
"""

from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from animbatch.version import __version__

#: The notebook and script entry points, imported on first use (``import animbatch`` stays cheap).
_ENTRY_POINTS = ("load", "render", "simulate", "study")

if TYPE_CHECKING:
    from animbatch.api import load, render, simulate, study


def __getattr__(name: str) -> Any:
    if name in _ENTRY_POINTS:
        from animbatch import api

        return getattr(api, name)
    raise AttributeError(f"module 'animbatch' has no attribute {name!r}")


class _Package(types.ModuleType):
    """This package's module. ``animbatch.render`` and ``animbatch.study`` are also subpackages (the drawing and the
    work-precision study), and importing a subpackage sets it as an attribute of its parent, which would hide the
    entry point of the same name. So those attributes are never set: ``animbatch.render`` stays the function, and
    ``from animbatch.render.camera import …`` still finds the subpackage (imports go through ``sys.modules``)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _ENTRY_POINTS and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def load_ipython_extension(ipython: Any) -> None:
    """``%load_ext animbatch`` in IPython or Jupyter: the ``%%animbatch`` cell magic (see :mod:`animbatch.notebook`)."""
    from animbatch.notebook import load_ipython_extension as register

    register(ipython)


__all__ = ["__version__", "load", "load_ipython_extension", "render", "simulate", "study"]
