"""Simulate a scene's emitters over its frames: births, motion, collisions and deaths, recorded at frame times.

Per step (fixed-step methods: every step; adaptive methods: every frame interval, the *segment* solve_ivp
integrates):

1. the particles alive at the step's start move with the scene's method (:mod:`animbatch.sim.particles.advance`);
2. the particles born during the step (:mod:`animbatch.sim.particles.schedule`) take the lowest free slots, with their
   attributes (:mod:`animbatch.sim.particles.emitter`), each advanced in a straight line from its birth instant to the
   step's end;
3. every segment travelled in the step is tested against the colliders (:mod:`animbatch.sim.particles.collisions`);
4. particles whose age reached their lifetime die, freeing their slots.

So with fixed-step methods births and deaths fall on steps (at most ``dt`` late), and with adaptive methods on
frame boundaries: a particle's first partial frame is then a straight line, its collisions are found only on the
chord of each frame interval, and it may live up to one frame past its lifetime. Fixed-step methods are the ones to
use for particles; adaptive ones are there for comparison.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from animbatch.errors import OverBudget, SimulationError
from animbatch.sim.integrators.budget import budget_spent
from animbatch.sim.integrators.interface import StepSettings
from animbatch.sim.integrators.methods import METHODS
from animbatch.sim.integrators.step_plan import substeps
from animbatch.sim.particles.advance import FIXED_METHODS, Accelerations, adaptive_segment, fixed_step
from animbatch.sim.particles.body_motion import BodyMotion, BodyPose
from animbatch.sim.particles.collisions import MAX_BOUNCES, ParticleColliders, bounce
from animbatch.sim.particles.compiled import CompiledPool, colliders_met, kernel_work, numpy_pool_seconds
from animbatch.sim.particles.emitter import Emitter, Newborns
from animbatch.sim.particles.obstacles import SURFACE_GAP
from animbatch.sim.particles.pool import ParticlePool
from animbatch.sim.particles.schedule import Births
from animbatch.trajectory import ParticleFrames

#: Serials are stored as int32 in trajectories.
LARGEST_SERIAL = 2**31 - 1


@dataclass
class ParticleStats:
    """Work and events of a particle simulation (all emitters)."""

    method: str
    steps: int = 0
    rhs_evaluations: int = 0
    born: int = 0
    died: int = 0
    dropped: int = 0
    collisions: int = 0
    peak_live: int = 0
    wall_time: float = 0.0
    dt: float | None = None  # fixed-step methods: the step used [s], and how many there are per frame
    substeps_per_frame: int | None = None
    kernels: str = "numpy"  # "numba" when an emitter's pool was stepped by the compiled kernel
    per_emitter: dict[str, dict[str, int]] = field(default_factory=dict)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


class EmitterRun:
    """The running state of one emitter: its pool, and how it steps."""

    def __init__(self, emitter: Emitter, colliders: ParticleColliders | None, method: str, solver: StepSettings,
                 motion: BodyMotion | None, steps: int = 0, run_seconds: float | None = None) -> None:
        """``steps``: how many steps the run will take (fixed-step methods), and ``run_seconds`` [s] what all the
        run's pools would take in numpy (this one's alone when not given): they decide whether the compiled kernel
        repays loading."""
        self.emitter = emitter
        self.pool = ParticlePool(emitter.capacity)
        self.colliders = colliders_met(emitter, colliders)
        self.method = method
        self.solver = solver
        self.motion = motion
        self.acceleration = Accelerations(emitter.fields)
        gravity = sum((f.gravity for f in emitter.fields), np.zeros(3))
        self._gravity = float(np.linalg.norm(gravity))
        self.collisions = 0
        self.steps = 0
        # the start states of the particles born in the frame being stepped, drawn at once (None: draw per step)
        self._frame_newborns: tuple[Births, Newborns] | None = None
        # the compiled kernel, where it covers this emitter's fields, colliders and method (None: numpy)
        if run_seconds is None:
            run_seconds = numpy_pool_seconds(emitter.capacity, steps)
        self.kernel = CompiledPool.of(emitter, self.colliders, method, self._gravity,
                                      kernel_work(emitter.capacity, steps, run_seconds))

    def advance_frame(self, t0: float, t1: float, count: int, stats: ParticleStats) -> None:
        """Advance the pool over the frame interval ``[t0, t1]`` [s] in ``count`` equal steps."""
        kernel = self.kernel
        self._frame_newborns = self._draw_newborns(t0, t1) if count > 1 else None
        if kernel is None:
            for k in range(count):
                self.step(t0 + (t1 - t0) * k / count, t0 + (t1 - t0) * (k + 1) / count)
                if k % 16 == 15:  # a frame may hold thousands of steps of a large pool
                    _check_budget(t0 + (t1 - t0) * (k + 1) / count, stats)
            return
        if self.emitter.schedule.born_by(t1) == self.emitter.schedule.born_by(t0):  # no births: one fused call
            self.collisions += kernel.advance(self.pool, t0, t1, count, 0, count, age=True)
            self.steps += count
            return
        for k in range(count):  # births come between steps
            start, stop = t0 + (t1 - t0) * k / count, t0 + (t1 - t0) * (k + 1) / count
            self.collisions += kernel.advance(self.pool, t0, t1, count, k, k + 1, age=False)
            born, born_at = self.give_birth(start, stop)
            if len(born):
                self.collisions += kernel.collide_newborns(self.pool, born, born_at, stop - start)
            kernel.age(self.pool, stop)
            self.steps += 1
            if k % 16 == 15:
                _check_budget(stop, stats)

    def step(self, t0: float, t1: float) -> None:
        """Advance the pool from ``t0`` to ``t1`` [s]: move, give birth, collide, age."""
        pool, h = self.pool, t1 - t0
        frozen = ~pool.alive | pool.stuck
        start = pool.x.copy()
        if self.method in FIXED_METHODS:
            # every slot at once, free and stuck ones held in place after: a pool is mostly full, and whole-array
            # operations cost less than gathering and scattering the live ones
            x, v, a = fixed_step(self.method, self.acceleration, pool.x, pool.v, pool.acceleration, pool.mass,
                                 pool.radius, h)
            if frozen.any():
                held = frozen[:, None]
                np.copyto(x, start, where=held)
                np.copyto(v, 0.0, where=held)
                np.copyto(a, 0.0, where=held)
            pool.x, pool.v, pool.acceleration = x, v, a
            self.steps += 1
        else:
            moving = np.flatnonzero(~frozen)
            x, v, steps = adaptive_segment(self.method, self.solver.rtol, self.solver.atol,
                                           self.solver.max_step, self.acceleration, pool.x[moving], pool.v[moving],
                                           pool.mass[moving], pool.radius[moving], t0, t1)
            pool.x[moving], pool.v[moving] = x, v
            self.steps += steps
        poses = self.poses(t0, t1)
        self.carry_stuck(poses)
        born, born_at = self.give_birth(t0, t1)
        if self.colliders is not None:
            start[born] = born_at  # a newborn's path starts where it was born
            self.collide(start, h, poses)
        pool.age(t1)

    def give_birth(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Births in ``(t0, t1]``: fill free slots; return the slots and the birth points (K, 3)."""
        emitter, pool = self.emitter, self.pool
        births = emitter.schedule.births(t0, t1)
        if births.count == 0:
            return np.zeros(0, np.intp), np.zeros((0, 3))
        if births.serials[-1] > LARGEST_SERIAL:
            raise SimulationError(f"emitter {emitter.name!r} gave birth to more than {LARGEST_SERIAL} particles; "
                                  "lower its rate or shorten the animation", time=t1)
        slots = pool.allocate(births.count)
        kept = len(slots)
        newborn = self._newborns(births)
        take = slice(0, kept)  # a full pool drops the latest births
        pool.alive[slots] = True
        pool.stuck[slots] = False
        pool.serial[slots] = births.serials[take]
        pool.start_lives(slots, births.times[take], newborn.lifetime[take])
        pool.mass[slots] = newborn.mass[take]
        pool.radius[slots] = newborn.radius[take]
        # each newborn moves for the rest of the step from its own birth instant, so that births within a step
        # leave no bands or lag: one step of the method of its own length, or for an adaptive method its own
        # flight to the tolerance (a Verlet step of up to a frame held a reference run to 1e-5)
        flight = t1 - births.times[take]
        x, v = newborn.position[take], newborn.velocity[take]
        mass, radius = newborn.mass[take], newborn.radius[take]
        if self.method in FIXED_METHODS:
            a = self.acceleration(x, v, mass, radius)
            pool.x[slots], pool.v[slots], pool.acceleration[slots] = fixed_step(
                self.method, self.acceleration, x, v, a, mass, radius, flight[:, None])
        else:
            solver = self.solver
            x, v, steps = adaptive_segment(self.method, solver.rtol, solver.atol, solver.max_step, self.acceleration,
                                           x, v, mass, radius, 0.0, 1.0, durations=flight)
            pool.x[slots], pool.v[slots] = x, v
            pool.acceleration[slots] = self.acceleration(x, v, mass, radius)
            self.steps += steps
        return slots, newborn.position[take]

    def _draw_newborns(self, t0: float, t1: float) -> tuple[Births, Newborns] | None:
        """The births in ``(t0, t1]`` (a frame) and their start states, drawn at once: a particle's are its own
        (its serial picks its random numbers, its birth time its place on a moving emitter), so a step's share is
        the same whichever way it is drawn, and numpy's per-call cost is paid once a frame, not once a step. None
        when fewer than two are born."""
        births = self.emitter.schedule.births(t0, t1)
        if births.count < 2 or births.serials[-1] > LARGEST_SERIAL:  # (give_birth says when there are too many)
            return None
        return births, self.emitter.newborns(births, self.motion)

    def _newborns(self, births: Births) -> Newborns:
        """The start states of a step's ``births``: their share of the frame's drawn ones where those hold them."""
        drawn = self._frame_newborns
        if drawn is not None and births.count:
            frame, newborn = drawn
            first = int(births.serials[0] - frame.serials[0])
            last = first + births.count
            if 0 <= first and last <= frame.count and np.array_equal(frame.times[first:last], births.times):
                return newborn.part(first, last)
        return self.emitter.newborns(births, self.motion)

    def poses(self, t0: float, t1: float) -> tuple[dict[int, BodyPose], dict[int, BodyPose]] | None:
        """The poses at ``t0`` and ``t1`` [s] of the bodies and moving colliders the particles meet (None: they meet
        none)."""
        obstacles = self.colliders.obstacles if self.colliders is not None else None
        if obstacles is None or not obstacles.bodies:
            return None
        return obstacles.poses(t0, self.motion), obstacles.poses(t1, self.motion)

    def carry_stuck(self, poses: tuple[dict[int, BodyPose], dict[int, BodyPose]] | None) -> None:
        """Particles stuck to a body move with it, to where it is at the step's end."""
        pool = self.pool
        if poses is None:
            return
        on_body = np.flatnonzero(pool.alive & pool.stuck & (pool.stuck_to != -1))  # on a body or moving collider
        for body in np.unique(pool.stuck_to[on_body]):
            which = on_body[pool.stuck_to[on_body] == body]
            now = poses[1][int(body)]
            pool.x[which] = now.centre[0] + pool.stuck_at[which] @ now.rotation[0].T
            pool.v[which] = now.velocity[0] + np.cross(now.omega[0], pool.stuck_at[which] @ now.rotation[0].T)

    def collide(self, start: np.ndarray, h: float, poses: tuple[dict[int, BodyPose], dict[int, BodyPose]] | None
                ) -> None:
        """Stop every slot's path ``start → x`` (C, 3) at the colliders and bodies (at ``poses``, the step's start
        and end; see :mod:`collisions`); paths of free and stuck slots have no length and never hit."""
        pool, colliders, mode = self.pool, self.colliders, self.emitter.collision
        assert colliders is not None
        x0, x1, v, radius = start, pool.x, pool.v, pool.radius
        rest_speed = 2.0 * h * self._gravity
        moving = np.flatnonzero(pool.alive & ~pool.stuck)
        found = colliders.first_hits(x0[moving], x1[moving], radius[moving], poses)
        hit = np.isfinite(found.fraction)
        index = moving[hit]
        hits = found
        chosen = np.flatnonzero(hit)
        for bounces in range(MAX_BOUNCES + 1):
            if not len(index):
                break
            fraction, normal, material = hits.fraction[chosen], hits.normal[chosen], hits.material[chosen]
            surface, body = hits.surface_velocity[chosen], hits.body[chosen]
            self.collisions += len(index)
            at = x0[index] + fraction[:, None] * (x1[index] - x0[index]) + SURFACE_GAP * normal
            if mode == "bounce":
                # off a moving body, the bounce is of the velocity relative to its surface
                v[index] = surface + bounce(v[index] - surface, normal, colliders.restitution[material],
                                            colliders.static_friction[material],
                                            colliders.kinetic_friction[material], rest_speed)
                if bounces == MAX_BOUNCES:  # out of bounces: stay at the surface for the rest of this step
                    x1[index] = at
                    break
                x0[index] = at
                x1[index] = at + ((1.0 - fraction) * h)[:, None] * v[index]  # the rest of the step, bounced
                hits = colliders.first_hits(x0[index], x1[index], radius[index], poses)
                chosen = np.flatnonzero(np.isfinite(hits.fraction))
                index = index[chosen]
                continue
            x1[index] = at
            v[index] = surface
            if mode == "stick":
                pool.stuck[index] = True
                pool.stuck_to[index] = body
                if poses is not None:
                    for b in np.unique(body[body != -1]):
                        which = index[body == b]
                        end = poses[1][int(b)]
                        pool.stuck_at[which] = (at[body == b] - end.centre[0]) @ end.rotation[0]
            else:  # die
                pool.kill(index)
            break
        colliders.push_out(x1, v, radius, poses[1] if poses is not None else None)

    def check(self, t: float) -> None:
        """Stop on a non-finite particle, naming the emitter."""
        # beyond 1e30 m (or m/s) nothing physical is left, and positions are stored as float32 (largest 3.4e38)
        if not (np.abs(self.pool.x) < 1e30).all() or not (np.abs(self.pool.v) < 1e30).all():
            raise SimulationError(
                f"particles of emitter {self.emitter.name!r} left the finite numbers by t = {t:g} s "
                f"({self.method}); a field is too strong for the step: lower solver.dt, or use backward_euler, "
                "which takes drag implicitly", time=t, body=self.emitter.name)


#: An explicit step h of ``v' = -α v`` stays bounded only while α h < 2 (Euler's |1 - α h| ≤ 1; the symplectic
#: methods and Verlet share the bound along the real axis).
EXPLICIT_RATE_LIMIT = 2.0


def check_stability(emitter: Emitter, method: str, h: float) -> None:
    """Refuse, before any particle moves, a fixed step ``h`` [s] of an explicit ``method`` that a law of the emitter
    makes unstable for its lightest, largest particle (a velocity rate ``α = -∂a/∂v`` with α h ≥ 2: drag on tiny
    particles, quadratic drag at the fastest launch or fall, a fluid's damping meant for bodies), naming the law and
    the fix."""
    if method not in METHODS or not METHODS[method].fixed_step or METHODS[method].implicit:
        return
    mass, radius = max(emitter.mass.smallest, 1e-300), max(emitter.radius.largest, 0.0)
    gravity = float(np.linalg.norm(sum((law.gravity for law in emitter.fields), np.zeros(3))))
    for law in emitter.fields:
        alpha = law.largest_rate(mass, radius, emitter.speed.largest, gravity)
        if alpha is not None and alpha * h >= EXPLICIT_RATE_LIMIT:
            raise SimulationError(
                f"emitter {emitter.name!r}: {law.describe()} slows its lightest particles ({mass:.3g} kg, radius "
                f"{radius:.3g} m) at a rate of {alpha:.3g} /s, and a {method} step of {h:.3g} s is stable only below "
                f"{EXPLICIT_RATE_LIMIT / alpha:.3g} s: the particles would gain speed every step. Use "
                f"solver.dt ≤ {0.9 * EXPLICIT_RATE_LIMIT / alpha:.3g} s, or solver.method: backward_euler (which "
                "takes the rate implicitly), or heavier particles or a weaker field", body=emitter.name)


def steps_per_frame(interval: float, method: str, dt: float) -> int:
    """Calls of EmitterRun.step per frame interval [s]: fixed-step methods take steps of at most ``dt`` [s] that
    divide it; adaptive ones integrate each frame interval as one segment (their own steps inside)."""
    return substeps(interval, dt) if method in FIXED_METHODS else 1


def _check_budget(t: float, stats: ParticleStats) -> None:
    spent = budget_spent(t, "the emitted particles' simulation")
    if spent is not None:
        raise OverBudget(f"{spent}; up to {stats.peak_live} particles were alive at once", time=t)


def simulate_particles(emitters: tuple[Emitter, ...], colliders: dict[str, ParticleColliders | None],
                       times: np.ndarray, solver: StepSettings, motion: BodyMotion | None, *, dt: float,
                       on_frame: Callable[[int, float], None] | None = None, record: bool = True,
                       precision: type = np.float32) -> tuple[list[ParticleFrames], ParticleStats]:
    """Simulate every emitter over the frame ``times`` (F,) [s]; fixed-step methods step at most ``dt`` [s].

    Returns the particles at each frame (unless ``record`` is False: then only the statistics, for measuring) and the
    statistics. Positions are kept in single ``precision`` (what a trajectory stores), unless asked otherwise (a
    study compares runs beyond it). Raises SimulationError when a particle's state stops being finite."""
    started = time.perf_counter()
    method = solver.method
    frames = len(times)
    if len(times) > 1:
        interval = float(times[1] - times[0])
        for emitter in emitters:
            check_stability(emitter, method, interval / steps_per_frame(interval, method, dt))
    total_steps = sum(steps_per_frame(float(b - a), method, dt) for a, b in zip(times[:-1], times[1:]))
    run_seconds = sum(numpy_pool_seconds(e.capacity, total_steps) for e in emitters)
    runs = [EmitterRun(e, colliders.get(e.name), method, solver, motion, total_steps, run_seconds) for e in emitters]
    records = [ParticleFrames(run.emitter.name,
                              np.zeros((frames if record else 1, run.pool.capacity, 3), precision),
                              np.full((frames if record else 1, run.pool.capacity), -1, np.int32),
                              np.zeros((frames if record else 1, run.pool.capacity), np.float32)) for run in runs]
    stats = ParticleStats(method)
    for run in runs:
        born, born_at = run.give_birth(-np.inf, float(times[0]))  # bursts at the very start
        if run.colliders is not None and len(born):
            start = run.pool.x.copy()
            start[born] = born_at
            run.collide(start, 0.0, run.poses(float(times[0]), float(times[0])))
    for frame in range(frames):
        t1 = float(times[frame])
        if frame:
            t0 = float(times[frame - 1])
            count = steps_per_frame(t1 - t0, method, dt)
            if method in FIXED_METHODS:
                stats.dt, stats.substeps_per_frame = (t1 - t0) / count, count
            for run in runs:
                with np.errstate(all="ignore"):  # a diverging particle is caught by check(), once per frame
                    run.advance_frame(t0, t1, count, stats)
                run.check(t1)
            _check_budget(t1, stats)
        for run, kept in zip(runs, records):
            pool = run.pool
            stats.peak_live = max(stats.peak_live, pool.live_count)
            row = frame if record else 0
            kept.positions[row] = pool.x
            kept.serials[row] = np.where(pool.alive, pool.serial, -1)
            kept.ages[row] = np.where(pool.alive, t1 - pool.birth, 0.0)
        if on_frame is not None:
            on_frame(frame, t1)
    for run in runs:
        pool = run.pool
        stats.kernels = "numba" if run.kernel is not None else stats.kernels
        stats.steps += run.steps
        stats.rhs_evaluations += run.acceleration.evaluations
        stats.born += pool.born
        stats.died += pool.died
        stats.dropped += pool.dropped
        stats.collisions += run.collisions
        stats.per_emitter[run.emitter.name] = {"capacity": pool.capacity, "born": pool.born, "died": pool.died,
                                               "dropped": pool.dropped, "collisions": run.collisions,
                                               "live_at_end": pool.live_count}
    stats.wall_time = time.perf_counter() - started
    return records, stats
