"""Checkpointed integration for long bakes: the frames are integrated in segments of ``every`` frames, and after
each segment the states so far are saved (atomically) to ``cache/checkpoint-<key>.npz``. A bake that is
interrupted resumes from the last checkpoint instead of from the start.

Each segment starts the integrator afresh from the last frame's state. For semi-implicit and backward Euler that is
the very same computation as one uninterrupted run. Verlet re-evaluates the rate it carries, and adaptive methods
choose new steps, so a checkpointed bake of those agrees with an uninterrupted one to the solver's accuracy, not
bit for bit (a resumed bake gives exactly what the same checkpointed bake would have given uninterrupted).
"""

from __future__ import annotations

import contextlib
import json
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from animbatch.files import atomic_path
from animbatch.sim.integrators import IntegrationResult, Integrator, SolverStats
from animbatch.sim.integrators.interface import EquationsOfMotion, FrameCallback


def _load(path: Path, size: int) -> tuple[np.ndarray, SolverStats] | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            states, stats = data["states"], SolverStats.from_dict(json.loads(str(data["stats"])))
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):  # missing or cut short
        return None
    return (states, stats) if states.ndim == 2 and states.shape[1] == size and len(states) >= 1 else None


def _save(path: Path, states: np.ndarray, stats: SolverStats) -> None:
    with atomic_path(path) as temporary, open(temporary, "wb") as stream:
        np.savez(stream, states=states, stats=np.str_(json.dumps(asdict(stats))))


def integrate_with_checkpoints(integrator: Integrator, system: EquationsOfMotion, y0: np.ndarray, times: np.ndarray,
                               *, every: int, path: Path, on_frame: FrameCallback | None = None) -> IntegrationResult:
    """Integrate over ``times`` in segments of ``every`` frames, saving the states after each to ``path`` and
    resuming from it when it holds a valid prefix; the checkpoint is deleted once the run is complete."""
    states = np.empty((len(times), len(y0)))
    stats = SolverStats(integrator.method)
    saved = _load(path, len(y0))
    if saved is not None and len(saved[0]) <= len(times):
        done, stats = len(saved[0]), saved[1]
        states[:done] = saved[0]
    else:
        done = 1
        states[0] = y0
    for frame in range(done):
        if on_frame is not None:
            on_frame(frame, float(times[frame]))
    while done < len(times):
        stop = min(done - 1 + every, len(times) - 1)
        shifted = None if on_frame is None else (lambda k, t, base=done - 1: k and on_frame(base + k, t))
        part = integrator.integrate(system, states[done - 1], times[done - 1:stop + 1], on_frame=shifted)
        states[done:stop + 1] = part.states[1:]
        stats.add(part.stats)
        done = stop + 1
        if done < len(times):
            _save(path, states[:done], stats)
    with contextlib.suppress(FileNotFoundError):
        path.unlink()
    return IntegrationResult(states, stats)
