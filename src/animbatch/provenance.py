"""Which code simulated a trajectory, so that a cached bake is reused only by the code that made it.

The version alone does not say: a source checkout, or an install from a branch, changes the solver without changing
the version, and a bake made before the change would be drawn as if the new code had made it. A trajectory records
:func:`simulation_code`: the version and a fingerprint of every source file that decides what is simulated and how
(the scene loader's defaults, the compiler, the simulation, the stages that run it and the trajectory format). The
files that only draw, encode or export a trajectory are left out: changing them does not make a bake stale.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from animbatch.version import __version__

#: Subpackages and modules of animbatch whose code does not change a trajectory (relative to the package folder).
NOT_SIMULATION = ("render", "encode", "export", "cli.py", "doctor.py", "plot.py", "progress.py")


@functools.cache
def simulation_code() -> str:
    """``<version>+<fingerprint>``: the package version and the first 12 hex digits of a SHA-256 over the names and
    contents of the package's simulation sources (read once per process, about 10 ms)."""
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for source in sorted(root.rglob("*.py")):
        name = source.relative_to(root).as_posix()
        if name.split("/")[0] in NOT_SIMULATION:
            continue
        digest.update(name.encode())
        digest.update(source.read_bytes())
    return f"{__version__}+{digest.hexdigest()[:12]}"
