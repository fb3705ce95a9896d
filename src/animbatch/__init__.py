"""animbatch: declarative YAML scenes to physically based animations, rendered headless.

The pipeline runs in one direction (see ``api``)::

    scene.yaml -> SceneSpec -> Model + y0 -> integrator -> Trajectory -> frames -> PNG / MP4

Everything is usable from Python; the ``animbatch`` command is a thin layer over :mod:`animbatch.api`.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("animbatch")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
