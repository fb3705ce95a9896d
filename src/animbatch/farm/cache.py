"""The trajectory cache: ``renders/<scene>/cache/trajectory-<key>.npz``.

The key is a content hash of what determines the motion: the scene's physics fingerprint (bodies, springs, fields,
timeline, mesh-file bytes; see :func:`~animbatch.scene.loader.physics_fingerprint`), the solver settings and the
package version. Camera, resolution, colours, every other render setting and the accuracy ledger's warning threshold
(``solver.drift_warning``, which only judges a run) are not in it, so changing them never re-simulates; changing
a mass, a step size or upgrading animbatch always does. A cache file whose key or contents do
not match is never used: it is replaced (and other keys' files in the folder are removed once a new bake lands).
Files are written atomically, so an interrupted bake leaves no cache that a later run could mistake for done.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path

from animbatch.compile.plan import RunPlan
from animbatch.errors import TrajectoryError
from animbatch.progress import Progress
from animbatch.provenance import simulation_code
from animbatch.scene import LoadedScene
from animbatch.sim.ledger import warn_again, with_threshold
from animbatch.stages import scene_fingerprint, simulate
from animbatch.trajectory import Trajectory
from animbatch.version import __version__

#: Solver keys that judge a run rather than shape it: changing them re-judges a cached bake, never re-simulates.
JUDGING_KEYS = ("drift_warning", "max_cost", "description")


def simulation_settings(solver: dict) -> dict:
    """The solver settings that shape the motion (without :data:`JUDGING_KEYS`)."""
    return {key: value for key, value in solver.items() if key not in JUDGING_KEYS}


def bake_key(scene: LoadedScene) -> str:
    """16 hex digits naming the simulation a scene asks for (physics, solver settings, package version)."""
    content = {"physics": scene_fingerprint(scene),
               "solver": simulation_settings(scene.spec.solver.model_dump(mode="json")), "version": __version__}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def cache_file(scene: LoadedScene, out_dir: str | Path = "renders") -> Path:
    """Where the scene's baked trajectory lives."""
    return Path(out_dir) / scene.name / "cache" / f"trajectory-{bake_key(scene)}.npz"


@dataclass
class BakeResult:
    """The baked trajectory, its cache file, and whether it was reused rather than simulated [``seconds``]."""
    trajectory: Trajectory
    path: Path
    reused: bool
    seconds: float = 0.0


def load_cached(scene: LoadedScene, path: Path) -> Trajectory | None:
    """The trajectory in ``path`` when it is a readable bake of exactly this scene's physics and solver settings
    by this code (:func:`~animbatch.provenance.simulation_code`); None otherwise (missing, truncated, or stale)."""
    if not path.is_file():
        return None
    try:
        trajectory = Trajectory.load(path)
    except TrajectoryError:
        return None

    solver = simulation_settings(trajectory.solver)
    wanted = simulation_settings(json.loads(json.dumps(scene.spec.solver.model_dump(), default=str)))  # as stored
    if (trajectory.physics_hash != scene_fingerprint(scene) or trajectory.package_version != simulation_code()
            or solver != wanted):
        return None
    threshold = scene.spec.solver.drift_warning
    if trajectory.ledger and trajectory.ledger.get("drift_warning") != threshold:

        trajectory = dataclasses.replace(trajectory, ledger=with_threshold(trajectory.ledger, threshold),
                                         solver={**trajectory.solver, "drift_warning": threshold})
    return trajectory


def bake(scene: LoadedScene | RunPlan, *, out_dir: str | Path = "renders", progress: Progress | None = None,
         force: bool = False, checkpoint_every: int | None = None) -> BakeResult:
    """The scene's trajectory from the cache, or simulated and cached (raises SimulationError as simulate does);
    ``scene``: a loaded scene, or its run plan when the caller compiled it (nothing is compiled for a cache hit).
    With ``checkpoint_every`` N, the states are saved every N frames to ``cache/checkpoint-<key>.npz``, and an
    interrupted bake resumes from there."""
    run, scene = (scene, scene.scene) if isinstance(scene, RunPlan) else (None, scene)
    path = cache_file(scene, out_dir)
    started = time.perf_counter()
    cached = None if force else load_cached(scene, path)
    if cached is not None:

        warn_again(cached.ledger)  # what the run said when it was baked holds for every use of the bake
        return BakeResult(cached, path, True, time.perf_counter() - started)
    checkpoint = (checkpoint_every, path.with_name(f"checkpoint-{bake_key(scene)}.npz")) if checkpoint_every else None
    trajectory = simulate(run if run is not None else scene, progress=progress, checkpoint=checkpoint)
    trajectory.save(path)
    stale_files = [*path.parent.glob("trajectory-*.npz"), *path.parent.glob("checkpoint-*.npz")]
    for stale in stale_files:  # other keys: older physics, solver or version
        if stale != path:
            with contextlib.suppress(FileNotFoundError):
                stale.unlink()
    return BakeResult(trajectory, path, False, time.perf_counter() - started)
