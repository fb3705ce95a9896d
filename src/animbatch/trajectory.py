"""The hand-off between simulation and rendering: states sampled at frame times, with where they came from.

File format (``.npz``, version 1), readable with numpy alone (``np.load(path)``; no pickled objects):

=====================  ==============  =================================================================
key                    shape / type    meaning
=====================  ==============  =================================================================
``format``             str             ``"animbatch-trajectory"``
``format_version``     int             ``3``
``times``              (F,) float64    frame times ``k / fps`` [s]
``body_names``         (N,) str        body names: particles first, then rigid bodies, each in scene order
``body_kinds``         (N,) str        ``particle`` or ``rigid``
``positions``          (F, N, 3)       centre-of-mass positions [m]
``velocities``         (F, N, 3)       centre-of-mass velocities [m/s]
``orientations``       (F, N, 4)       unit quaternions [w, x, y, z], body to world (identity for particles)
``angular_velocities`` (F, N, 3)       angular velocities ω [rad/s], world axes (zero for particles)
``anchor_names``       (A,) str        anchor names
``anchor_positions``   (A, 3)          anchor positions [m]
``physics_hash``       str             SHA-256 of the scene's physics (bodies, fields, springs, timeline)
``scene_name``         str             the scene's name
``package_version``    str             animbatch version and fingerprint of the code that simulated it
``solver``             str (JSON)      solver settings used
``solver_stats``       str (JSON)      RHS evaluations, steps, Jacobian evaluations, wall time, …
``emitter_names``      (E,) str        emitters, in scene order (version 3; absent or empty without emitters)
``particles_K_positions`` (F, C, 3)    emitter K's slots at each frame [m], float32 (C: its capacity)
``particles_K_serials``   (F, C)       int32 serial of the particle in each slot, -1 where the slot is free
``particles_K_ages``      (F, C)       float32 age of each particle [s]
``particle_stats``     str (JSON)      births, deaths, drops, collisions, steps of the particle simulation
``ledger``             str (JSON)      the run's accuracy ledger (:mod:`animbatch.sim.ledger`; not in older files)
``orientation_errors`` (F,) float64    the largest ‖RᵀR − I‖ at each frame (only with solver.orientation: matrix)
=====================  ==============  =================================================================

Version 2 files (without particles) are still read.

Example::

    data = np.load("run.npz")
    ball = list(data["body_names"]).index("ball")
    heights = data["positions"][:, ball, 1]
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from animbatch.errors import TrajectoryError
from animbatch.files import atomic_path

FORMAT = "animbatch-trajectory"
FORMAT_VERSION = 3
READABLE_VERSIONS = (2, 3)


@dataclass
class ParticleFrames:
    """One emitter's particles at the frame times (F frames, C slots): ``positions`` (F, C, 3) float32 [m];
    ``serials`` (F, C) int32, the serial of the particle in each slot, -1 where the slot is free; ``ages`` (F, C)
    float32 [s]. ``radius`` is not stored: it follows from the serial like every attribute."""

    name: str
    positions: np.ndarray
    serials: np.ndarray
    ages: np.ndarray

    @property
    def live_counts(self) -> np.ndarray:
        return np.count_nonzero(self.serials >= 0, axis=1)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Body states at frame times: ``times`` (F,) [s]; ``positions``/``velocities`` (F, N, 3) [m], [m/s];
    ``orientations`` (F, N, 4); ``angular_velocities`` (F, N, 3) [rad/s]."""

    times: np.ndarray
    body_names: tuple[str, ...]
    positions: np.ndarray
    velocities: np.ndarray
    orientations: np.ndarray
    angular_velocities: np.ndarray
    body_kinds: tuple[str, ...]
    anchor_names: tuple[str, ...]
    anchor_positions: np.ndarray
    physics_hash: str
    scene_name: str
    package_version: str
    solver: dict[str, Any] = field(default_factory=dict)
    solver_stats: dict[str, Any] = field(default_factory=dict)
    particles: tuple[ParticleFrames, ...] = ()
    particle_stats: dict[str, Any] = field(default_factory=dict)
    ledger: dict[str, Any] = field(default_factory=dict)
    clock_names: tuple[str, ...] = ()  # bodies that carry proper-time clocks
    proper_times: np.ndarray | None = None  # (F, K) [s] their proper times
    joint_names: tuple[str, ...] = ()  # the scene's joints, in order
    joint_forces: np.ndarray | None = None  # (F, J, 3) [N] each joint's constraint force on its first body
    joint_torques: np.ndarray | None = None  # (F, J, 3) [N·m] and its torque, about the joint's point
    motor_efforts: np.ndarray | None = None  # (F, M) [N·m or N] the motors' torques or forces, in joint order
    orientation_errors: np.ndarray | None = None  # (F,) the largest ‖RᵀR − I‖ of integrated rotation matrices

    @property
    def frame_count(self) -> int:
        return len(self.times)

    def _heading(self) -> str:
        bodies = len(self.body_names)
        return (f"{self.scene_name}: {self.frame_count} frames, {self.times[0]:g}–{self.times[-1]:g} s, "
                f"{bodies} bod{'y' if bodies == 1 else 'ies'}")

    def _repr_html_(self) -> str:
        """In a Jupyter notebook: what was simulated and its accuracy ledger (``animbatch.render`` draws it)."""
        from animbatch.notebook_display import trajectory_html

        return trajectory_html(self._heading(), self.ledger)

    def _repr_pretty_(self, printer: Any, cycle: bool) -> None:
        """In IPython's terminal: what was simulated, not every array."""
        printer.text(f"Trajectory({self._heading()})")

    def save(self, path: str | Path) -> Path:
        """Write the trajectory atomically to ``path`` (``.npz`` is appended when missing)."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        with atomic_path(path) as temporary, open(temporary, "wb") as stream:
            extra: dict[str, Any] = {**self._particle_arrays(), **self._clock_arrays(), **self._joint_arrays()}
            if self.orientation_errors is not None:
                extra["orientation_errors"] = self.orientation_errors
            np.savez(stream, format=np.str_(FORMAT), format_version=np.int64(FORMAT_VERSION), times=self.times,
                     body_names=np.array(self.body_names, dtype=str), body_kinds=np.array(self.body_kinds, dtype=str),
                     positions=self.positions, velocities=self.velocities, orientations=self.orientations,
                     angular_velocities=self.angular_velocities, anchor_names=np.array(self.anchor_names, dtype=str),
                     anchor_positions=self.anchor_positions.reshape(-1, 3), physics_hash=np.str_(self.physics_hash),
                     scene_name=np.str_(self.scene_name), package_version=np.str_(self.package_version),
                     solver=np.str_(json.dumps(self.solver)), solver_stats=np.str_(json.dumps(self.solver_stats)),
                     emitter_names=np.array([p.name for p in self.particles], dtype=str),
                     particle_stats=np.str_(json.dumps(self.particle_stats)), ledger=np.str_(json.dumps(self.ledger)),
                     **extra)
        return path

    def _clock_arrays(self) -> dict[str, np.ndarray]:
        if self.proper_times is None:
            return {}
        return {"clock_names": np.array(self.clock_names, dtype=str), "proper_times": self.proper_times}

    def _joint_arrays(self) -> dict[str, np.ndarray | None]:
        if self.joint_forces is None:
            return {}
        arrays: dict[str, np.ndarray | None] = {"joint_names": np.array(self.joint_names, dtype=str),
                                                "joint_forces": self.joint_forces,
                                                "joint_torques": self.joint_torques}
        if self.motor_efforts is not None:
            arrays["motor_efforts"] = self.motor_efforts
        return arrays

    def _particle_arrays(self) -> dict[str, np.ndarray]:
        arrays = {}
        for k, frames in enumerate(self.particles):
            arrays[f"particles_{k}_positions"] = frames.positions
            arrays[f"particles_{k}_serials"] = frames.serials
            arrays[f"particles_{k}_ages"] = frames.ages
        return arrays

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a trajectory file, checking its format and the consistency of its arrays."""
        path = Path(path)
        if not path.is_file():
            raise TrajectoryError(f"{path}: no such trajectory file "
                                  f"(write one with 'animbatch simulate SCENE -o {path}')")
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:  # truncated files raise the last
            raise TrajectoryError(f"{path}: not a readable .npz trajectory ({error})") from None
        if str(arrays.get("format", "")) != FORMAT:
            raise TrajectoryError(f"{path}: not an animbatch trajectory (missing format marker)")
        version = int(arrays.get("format_version", -1))
        if version not in READABLE_VERSIONS:
            raise TrajectoryError(f"{path}: trajectory format version {version}; this animbatch reads version "
                                  f"{FORMAT_VERSION}. Re-run 'animbatch simulate'.")
        required = {"times", "body_names", "body_kinds", "positions", "velocities", "orientations",
                    "angular_velocities", "physics_hash"}
        missing = required - arrays.keys()
        if missing:
            raise TrajectoryError(f"{path}: incomplete trajectory, missing {', '.join(sorted(missing))}")
        times = arrays["times"]
        names = tuple(str(n) for n in arrays["body_names"])
        for key, width in (("positions", 3), ("velocities", 3), ("orientations", 4), ("angular_velocities", 3)):
            expected = (len(times), len(names), width)
            if arrays[key].shape != expected:
                raise TrajectoryError(f"{path}: {key} has shape {arrays[key].shape}, expected {expected}")
        particles = []
        for k, name in enumerate(arrays.get("emitter_names", ())):
            keys = [f"particles_{k}_{part}" for part in ("positions", "serials", "ages")]
            if any(key not in arrays for key in keys):
                raise TrajectoryError(f"{path}: incomplete trajectory, the particles of emitter {name!r} are missing")
            positions, serials, ages = (arrays[key] for key in keys)
            if positions.shape[:2] != serials.shape or serials.shape != ages.shape or len(serials) != len(times):
                raise TrajectoryError(f"{path}: the particle arrays of emitter {name!r} disagree in shape")
            particles.append(ParticleFrames(str(name), positions, serials, ages))
        clock_names, proper_times = cls._clocks_of(arrays, len(times), path)
        joint_names, joint_forces, joint_torques, motor_efforts = cls._joints_of(arrays, len(times), path)
        return cls(times, names, arrays["positions"], arrays["velocities"], arrays["orientations"],
                   arrays["angular_velocities"], tuple(str(k) for k in arrays["body_kinds"]),
                   tuple(str(n) for n in arrays.get("anchor_names", ())),
                   arrays.get("anchor_positions", np.zeros((0, 3))).reshape(-1, 3),
                   str(arrays["physics_hash"]), str(arrays.get("scene_name", "")),
                   str(arrays.get("package_version", "")),
                   json.loads(str(arrays.get("solver", "{}"))), json.loads(str(arrays.get("solver_stats", "{}"))),
                   tuple(particles), json.loads(str(arrays.get("particle_stats", "{}"))),
                   json.loads(str(arrays.get("ledger", "{}"))), clock_names=clock_names, proper_times=proper_times,
                   joint_names=joint_names, joint_forces=joint_forces, joint_torques=joint_torques,
                   motor_efforts=motor_efforts,
                   orientation_errors=cls._orientation_errors_of(arrays, len(times), path))

    @staticmethod
    def _orientation_errors_of(arrays: dict[str, np.ndarray], frames: int, path: Path) -> np.ndarray | None:
        """The largest ‖RᵀR − I‖ at each frame (F,), in a file of a run with rotation matrices."""
        errors = arrays.get("orientation_errors")
        if errors is not None and errors.shape != (frames,):
            raise TrajectoryError(f"{path}: orientation_errors has shape {errors.shape}, expected {(frames,)}")
        return errors

    @staticmethod
    def _joints_of(arrays: dict[str, np.ndarray], frames: int, path: Path
                   ) -> tuple[tuple[str, ...], np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """The joints' names, reactions (F, J, 3) and motor efforts (F, M) of a file, if it has joints."""
        if "joint_forces" not in arrays:
            return (), None, None, None
        names = tuple(str(n) for n in arrays.get("joint_names", ()))
        for key in ("joint_forces", "joint_torques"):
            if arrays.get(key) is None or arrays[key].shape != (frames, len(names), 3):
                raise TrajectoryError(f"{path}: {key} is missing or has the wrong shape, expected "
                                      f"{(frames, len(names), 3)}")
        return names, arrays["joint_forces"], arrays["joint_torques"], arrays.get("motor_efforts")

    @staticmethod
    def _clocks_of(arrays: dict[str, np.ndarray], frames: int, path: Path
                   ) -> tuple[tuple[str, ...], np.ndarray | None]:
        """The clocks' names and proper times (F, K) of a file, if it has clocks."""
        if "proper_times" not in arrays:
            return (), None
        names = tuple(str(n) for n in arrays.get("clock_names", ()))
        times = arrays["proper_times"]
        if times.shape != (frames, len(names)):
            raise TrajectoryError(f"{path}: proper_times has shape {times.shape}, expected {(frames, len(names))}")
        return names, times
