"""Which code simulated a trajectory and which draws it, so that a cached bake, or a frame drawn from one, is reused
only by the code that made it.

The version alone does not say: a source checkout, or an install from a branch, changes the solver without changing
the version, and a bake made before the change would be drawn as if the new code had made it. A trajectory records
:func:`simulation_code`: the version and a fingerprint of every source file that decides what is simulated and how
(the scene loader's defaults, the compiler, the simulation, the stages that run it and the trajectory format). The
files that only draw, encode or export a trajectory are left out: changing them does not make a bake stale.
A frame records both that and :func:`drawing_code`, the fingerprint of the renderer's sources.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable
from pathlib import Path

from animbatch.version import __version__

#: Subpackages and modules of animbatch whose code does not change a trajectory (relative to the package folder).
NOT_SIMULATION = ("render", "encode", "export", "cli.py", "doctor.py", "plot.py", "progress.py")


#: Subpackages of animbatch whose code decides a frame's pixels, given its trajectory.
DRAWING = ("render",)


@functools.cache
def simulation_code() -> str:
    """``<version>+<fingerprint>``: the package version and the first 12 hex digits of a SHA-256 over the names and
    contents of the package's simulation sources (read once per process, about 10 ms)."""
    return _fingerprint(lambda top: top not in NOT_SIMULATION)


@functools.cache
def drawing_code() -> str:
    """``<version>+<fingerprint>`` of the renderer's sources (:data:`DRAWING`), as :func:`simulation_code`."""
    return _fingerprint(lambda top: top in DRAWING)


def _fingerprint(chosen: Callable[[str], bool]) -> str:
    """The version and a SHA-256 (12 hex digits) over the names and contents of the package's sources whose first
    path part (a subpackage or a module) is ``chosen``."""
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for source in sorted(root.rglob("*.py")):
        name = source.relative_to(root).as_posix()
        if not chosen(name.split("/")[0]):
            continue
        digest.update(name.encode())
        digest.update(source.read_bytes())
    return f"{__version__}+{digest.hexdigest()[:12]}"
