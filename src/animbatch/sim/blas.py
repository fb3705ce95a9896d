"""How many threads BLAS (numpy's and scipy's OpenBLAS) may use while a system is integrated.

A small system makes thousands of BLAS calls a second on matrices of a few dozen rows: a ragdoll's joint rows and
the response of its contacts within them, the resting forces of a few crates. OpenBLAS splits such calls over its
threads. On an idle machine that gains nothing measurable (a ragdoll's 1.5 s: 7.2 s either way); on a busy one (two
runs side by side, a farm node's other jobs, the test suite's workers) every call waits for threads that other
processes hold: measured here under load, a 100 × 90 Cholesky solve took 4.6 ms on two threads against 0.33 ms on
one, and the ragdoll's 1.5 s took 23 s against 10.5 s. So a small system is integrated with BLAS on one thread
(:func:`threads_for_state`); a large one (a cloth's factorisations, a big pile) keeps BLAS's own choice, and the
places that know better set their own (:mod:`animbatch.sim.integrators.cholesky`).
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any

#: Systems with at most this many state numbers (some 200 rigid bodies or 500 particles) run BLAS on one thread:
#: their matrices stay below the size where splitting a call pays (the jointed contacts' dense forms stop at 1200
#: velocity components, :data:`animbatch.sim.contact.jointed.DENSE_COLUMNS`).
SMALL_STATE = 3000


@functools.cache
def _controller() -> Any:
    """threadpoolctl's view of the BLAS libraries, made once they are all loaded: numpy's and scipy's (scipy.linalg
    brings its own OpenBLAS, which a controller made before it would not see)."""
    import scipy.linalg  # noqa: F401  (loads scipy's BLAS)
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def blas_threads(count: int) -> Any:
    """A context in which BLAS (numpy's and scipy's) runs on ``count`` threads."""
    return _controller().limit(limits=count, user_api="blas")


def threads_for_state(size: int) -> Any:
    """The context to integrate a system of ``size`` state numbers in: BLAS on one thread for a small one (see the
    module notes), nothing changed for a large one."""
    return blas_threads(1) if size <= SMALL_STATE else contextlib.nullcontext()
