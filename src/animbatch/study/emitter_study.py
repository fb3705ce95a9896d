"""Studying a scene of emitters: its particles run with each integrator and compared with a reference one by one.

Everything about an emitted particle (when it is born, where, how fast, how long it lives) follows from its serial,
its number in birth order, whatever the step (:mod:`animbatch.sim.particles.schedule`). So every run of a scene
holds the same particles at each frame, and a run's error is measured as for bodies: the RMS over frames and over
the particles alive in both runs of their distance from the reference, over the length scale. The study keeps the
positions in double precision (a trajectory stores single), so that errors below 1e-7 can be measured.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from animbatch.compile.particles import ParticleSystems
from animbatch.errors import SimulationError, StudyError
from animbatch.sim.model import Model
from animbatch.sim.particles.simulate import ParticleStats, simulate_particles
from animbatch.study.measure import Motion, Scales, final_error, position_error
from animbatch.study.reference import REFERENCE_RTOLS, Reference
from animbatch.study.runs import RunOutcome, RunSetting, RunTimeout
from animbatch.trajectory import ParticleFrames


def particle_motion(records: list[ParticleFrames], births: list[int]) -> Motion:
    """The particles of every emitter at the frame times as a Motion: one column per particle ever born
    (``births`` per emitter, in the order of ``records``), positions (F, P, 3) [m], NaN where it is not alive.
    Velocities are not recorded (NaN); orientations are the identity."""
    frames = records[0].positions.shape[0]
    offsets = np.concatenate([[0], np.cumsum(births)]).astype(int)
    positions = np.full((frames, int(offsets[-1]), 3), np.nan)
    for record, offset in zip(records, offsets):
        frame, slot = np.nonzero(record.serials >= 0)
        positions[frame, offset + record.serials[frame, slot]] = record.positions[frame, slot]
    orientations = np.zeros((*positions.shape[:2], 4))
    orientations[..., 0] = 1.0
    return Motion(positions, np.full_like(positions, np.nan), orientations)


def particle_scales(model: Model, motion: Motion) -> Scales:
    """Length scale: the diagonal of the box the particles sweep; speed scale: the largest distance a particle
    travels between frames over the frame interval (velocities are not recorded), at least L over the duration."""
    positions = motion.positions
    extent = float(np.linalg.norm(np.nanmax(positions, axis=(0, 1)) - np.nanmin(positions, axis=(0, 1))))
    length = max(extent, 1e-9)
    interval = float(model.frame_times[1] - model.frame_times[0]) if len(model.frame_times) > 1 else 1.0
    travelled = np.linalg.norm(np.diff(positions, axis=0), axis=-1)
    fastest = float(np.nanmax(travelled)) / interval if np.isfinite(travelled).any() else 0.0
    return Scales(length, max(fastest, length / max(float(model.frame_times[-1]), 1e-9)))


def execute_particles(model: Model, systems: ParticleSystems, setting: RunSetting, scales: Scales, *,
                      repeats: int, timeout: float) -> RunOutcome:
    """Run the emitters with one setting: untimed for their frames, then ``repeats`` timed runs (one only when a
    run takes more than a few seconds). ``outcome.particles`` holds the frames."""
    # atol [m and m/s alike]: rtol times the smaller of the length and speed scales
    steps = setting.steps(atol=(setting.rtol or 1e-3) * min(scales.length, scales.speed))
    interval = float(model.frame_times[1] - model.frame_times[0]) if len(model.frame_times) > 1 else 1.0

    def run(record: bool) -> tuple[list[ParticleFrames], float, ParticleStats]:
        deadline = time.perf_counter() + timeout

        def on_frame(frame: int, t: float) -> None:
            if time.perf_counter() > deadline:
                raise RunTimeout

        started = time.perf_counter()
        records, stats = simulate_particles(systems.emitters, systems.colliders, model.frame_times, steps, None,
                                            dt=setting.dt or interval, on_frame=on_frame, record=record,
                                            precision=np.float64)
        return records, time.perf_counter() - started, stats

    from threadpoolctl import threadpool_limits  # as for bodies: one thread, so that methods compare fairly

    with threadpool_limits(limits=1):
        try:
            records, first_time, stats = run(record=True)
        except RunTimeout:
            return RunOutcome(setting, "timeout", f"took longer than {timeout:g} s")
        except SimulationError as error:
            return RunOutcome(setting, "failed", str(error))
        # the compiled kernels count no RHS evaluations (None: not counted, rather than 0)
        outcome = RunOutcome(setting, "ok", steps=stats.steps, rhs_evaluations=stats.rhs_evaluations or None,
                             particles=records)
        for _ in range(repeats if first_time < 2.0 else min(repeats, 1)):
            try:
                outcome.wall_times.append(run(record=False)[1])
            except RunTimeout:
                outcome.wall_times.append(timeout)
    outcome.wall_time = min(outcome.wall_times, default=first_time)
    return outcome


#: The most particle-frames (frames × particles born) a study compares: each run's matched positions take 24 bytes
#: a particle-frame, and the reference, its check and a run are held at once (about 0.4 GB at this bound; a few
#: frames of many particles also cost the adaptive methods' stages, some 800 bytes a live particle for DOP853).
MOST_PARTICLE_FRAMES = 5e6


def births_by_end(model: Model, systems: ParticleSystems) -> list[int]:
    """How many particles each emitter gives birth to over the scene (their serials are 0 … that - 1)."""
    return [emitter.schedule.born_by(float(model.frame_times[-1])) for emitter in systems.emitters]


def check_study_size(model: Model, systems: ParticleSystems) -> None:
    """Refuse, before any run, a study whose particles would not fit in memory, saying what to change."""
    born = sum(births_by_end(model, systems))
    frames = len(model.frame_times)
    if frames * born > MOST_PARTICLE_FRAMES:
        raise StudyError(f"the study would compare {born:,} particles at {frames} frames one by one "
                         f"({frames * born:.3g} particle-frames, at most {MOST_PARTICLE_FRAMES:.0e}, about "
                         f"{72 * frames * born / 1e9:.1f} GB): shorten the scene (--set duration=…) or lower the "
                         "emitters' rates or bursts for the study")


def particle_reference(model: Model, systems: ParticleSystems, *, timeout: float,
                       progress: Callable[[str], None], fixed: tuple[str, float] | None = None) -> Reference:
    """The emitters' reference: DOP853 at the tightest of :data:`REFERENCE_RTOLS` that succeeds, checked against
    DOP853 a decade looser (as for bodies), or ``fixed``: (method, dt [s]) checked against twice the step. The
    scales come from a Verlet run at one step per frame first."""
    check_study_size(model, systems)
    births = births_by_end(model, systems)
    interval = float(model.frame_times[1] - model.frame_times[0]) if len(model.frame_times) > 1 else 1.0
    rough = execute_particles(model, systems, RunSetting("verlet", dt=interval), Scales(1.0, 1.0), repeats=0,
                              timeout=timeout)
    scales = (particle_scales(model, particle_motion(rough.particles, births)) if rough.particles is not None
              else Scales(1.0, 1.0))
    tries = ([RunSetting(fixed[0], dt=fixed[1])] if fixed is not None else
             [RunSetting("DOP853", rtol=rtol) for rtol in REFERENCE_RTOLS])
    attempts: list[RunOutcome] = []
    for setting in tries:
        progress(f"reference: {setting.method} at {setting.label} …")
        attempts.append(execute_particles(model, systems, setting, scales, repeats=0, timeout=timeout))
        if attempts[-1].particles is not None:
            break
    primary = attempts[-1]
    if primary.particles is None:
        tried = "; ".join(f"{run.setting.method} at {run.setting.label}: {run.reason}" for run in attempts)
        raise StudyError(f"no reference for the study: every tight run failed ({tried}). Shorten the scene "
                         "(--set duration=…) or give it more time (--timeout T: reference runs get 10 T).")
    setting = primary.setting
    check_setting = (RunSetting(setting.method, dt=2 * setting.dt) if setting.dt is not None
                     else RunSetting(setting.method, rtol=10 * (setting.rtol or 0.0)))
    progress(f"reference check: {check_setting.method} at {check_setting.label} …")
    check = execute_particles(model, systems, check_setting, scales, repeats=0, timeout=timeout)
    motion = particle_motion(primary.particles, births)
    description = f"{primary.setting.method} at {primary.setting.label}"
    if check.particles is None:
        return Reference(motion, f"{description} (unchecked: {check.setting.method} {check.status})", scales,
                         np.inf, np.inf)
    checked = particle_motion(check.particles, births)
    return Reference(motion, f"{description}, checked against {check_setting.method} at {check_setting.label}",
                     scales, position_error(model, checked, motion, scales), final_error(checked, motion, scales))
