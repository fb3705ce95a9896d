"""Compiled kernels (numba) for the loops that dominate, each with the pure-numpy code it replaces kept as the
fallback.

numba is a dependency, but a kernel is only ever an optimisation: when numba cannot be imported (a platform without
wheels, a broken LLVM) the numpy code runs instead, and the tests check that both give the same results to
round-off. numba is imported on first use, never at start-up: importing it and loading a cached kernel cost about a
second, and compiling a kernel the first time on a machine about five (kernels are cached on disk, ``cache=True``).
So a kernel is used only for work large enough to repay that (:data:`MIN_WORK`).

``ANIMBATCH_KERNELS`` chooses: ``auto`` (the default, as above), ``numba`` (compiled whatever the size, where numba
loads) or ``numpy`` (never compiled).

numba keys a cached kernel by the time stamp of its own file only, so a kernel that calls a kernel of another file
would load stale machine code once that file changed. The kernels are therefore cached in a folder of the user's
cache named by a hash of every kernel source (``NUMBA_CACHE_DIR``, unless it is set already): any change to any
kernel starts a fresh cache.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path

#: ``auto``, ``numba`` or ``numpy`` (see the module notes).
KERNELS_VARIABLE = "ANIMBATCH_KERNELS"
#: Below this many element-steps (particle-steps for a pool) the numpy code finishes before numba has loaded: at
#: about 30 ns per particle-step saved, loading numba (about a second) pays for itself from 3e7.
MIN_WORK = 3e7
#: A kernel build still running after this many seconds is compiling (loading from the disk cache takes far less):
#: :data:`announce` is told, once, so that a first run on a machine does not sit silent for ten seconds.
SLOW_BUILD = 1.5
#: Where to say that a slow build is under way (the CLI prints to stderr); None: say nothing (library use).
announce: Callable[[str], None] | None = None
#: The names of two kernel families, as kernels_ready is told them (and kernels_loaded asked about them).
STEPPER_KERNELS = "equations of motion"
CONTACT_KERNELS = "contact solver"
_asked: set[str] = set()  # the kernels whose build has been asked for in this process
_loaded: set[str] = set()  # the kernels built (or loaded from the disk cache) in this process


def kernel_cache_folder() -> Path:
    """Where numba caches the kernels: ``$XDG_CACHE_HOME/animbatch/kernels/<hash of their sources>`` (see the
    module notes)."""
    digest = hashlib.sha256()
    for source in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(source.name.encode())
        digest.update(source.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "animbatch" / "kernels" / digest.hexdigest()[:16]


# before numba is first imported (it reads the variable once); where it was imported first (a notebook, a program
# of the user's), its setting is read anew for each kernel defined, so the kernels are still found in this folder
# rather than compiled again (a minute and more) into a __pycache__ beside the sources, which may not be writable
_folder = os.environ.setdefault("NUMBA_CACHE_DIR", str(kernel_cache_folder()))
if "numba" in sys.modules and not getattr(sys.modules["numba"].config, "CACHE_DIR", None):
    sys.modules["numba"].config.CACHE_DIR = _folder


@functools.cache
def _numba_imports() -> bool:
    # numba's OpenMP threads sleep between kernels instead of spinning: the Python work between two calls (births,
    # records) and other processes (ffmpeg, a renderer, other Dask workers) get the cores
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    try:
        import numba  # noqa: F401
    except Exception:  # noqa: BLE001 - any failure to load (missing, or a broken LLVM) means: use numpy
        return False
    return True


def compiled_kernels(work: float = float("inf")) -> bool:
    """Whether to use a compiled kernel for ``work`` element-steps: ``ANIMBATCH_KERNELS`` allows it, numba loads,
    and (unless ``numba`` is asked for) the work repays loading it."""
    choice = os.environ.get(KERNELS_VARIABLE, "auto").strip().lower() or "auto"
    if choice not in ("auto", "numba", "numpy"):
        raise ValueError(f"{KERNELS_VARIABLE}={choice!r}: choose auto, numba or numpy")
    if choice == "numpy" or (choice == "auto" and work < MIN_WORK):
        return False
    return _numba_imports()


def build_failure(build: Callable[[], None]) -> str | None:
    """Run ``build`` (kernels called on tiny inputs, so that numba compiles them or loads them from its disk cache);
    None, or what numba or LLVM could not do. Other errors are not a build's and are raised."""
    try:
        build()
    except Exception as error:  # noqa: BLE001 - numba's typing and lowering errors, LLVM's
        if not type(error).__module__.startswith(("numba", "llvmlite")):
            raise
        return f"{type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}"
    return None


def kernels_ready(work: float, built: Callable[[], str | None], what: str, instead: str) -> bool:
    """Whether to run ``what`` compiled for ``work`` element-steps: :func:`compiled_kernels` allows it and ``built()``
    (a cached :func:`build_failure`) found nothing wrong; if it did, a warning says so and that ``instead`` runs."""
    if not compiled_kernels(work):
        return False
    failure = watched(built, what)
    if failure is not None:
        warnings.warn(f"the compiled {what} could not be built ({failure}); {instead} instead (slower, same "
                      "results). Set ANIMBATCH_KERNELS=numpy to silence this", RuntimeWarning, stacklevel=3)
    return failure is None


def watched(built: Callable[[], str | None], what: str) -> str | None:
    """``built()``, telling :data:`announce` when its first call in this process takes longer than
    :data:`SLOW_BUILD` (numba compiling, the first time on a machine)."""
    if what in _asked or announce is None:
        failure = built()
    else:
        _asked.add(what)
        timer = threading.Timer(SLOW_BUILD, announce, [f"compiling the {what} kernels (once on this machine: they "
                                                       "are cached on disk)…"])
        timer.daemon = True
        timer.start()
        try:
            failure = built()
        finally:
            timer.cancel()
    if failure is None:
        _loaded.add(what)
    return failure


def kernels_loaded(*whats: str) -> bool:
    """Whether each of the kernels ``whats`` (as :func:`kernels_ready` names them) is loaded in this process already:
    an earlier run paid for loading them, so using them again costs a run only their setup."""
    return all(what in _loaded for what in whats)
