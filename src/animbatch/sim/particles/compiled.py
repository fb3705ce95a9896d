"""An emitter's pool stepped by the compiled kernel (:mod:`animbatch.sim.kernels.particle_pool`) where it can be.

The kernel covers particles under gravity, drag, wind and buoyancy, meeting fixed planes, spheres and boxes or
nothing, stepped with explicit Euler, semi-implicit Euler or velocity Verlet: fountains, sparks, rain, snow on a
crate, smoke. Anything else (meshes, rigid bodies, moving colliders, the other methods) runs the numpy code of
:class:`~animbatch.sim.particles.simulate.EmitterRun`, as does everything when numba is missing or
``ANIMBATCH_KERNELS=numpy`` is set. :meth:`CompiledPool.of` decides, once per emitter.

A frame without births is one kernel call that takes every particle through all the frame's steps. A frame with
births goes step by step, as the numpy code does: move and collide the pool, give birth, collide the newborns'
paths, age. The one difference from the numpy code is the order of deaths by ``collision: die`` and births within a
step (the numpy code frees those slots after the step's births): a full pool may then drop a different number of
births; the particles themselves are the same.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.sim.kernels import build_failure, compiled_kernels, watched
from animbatch.sim.particles.collisions import MAX_BOUNCES, ParticleColliders
from animbatch.sim.particles.emitter import Emitter
from animbatch.sim.particles.obstacles import SURFACE_GAP
from animbatch.sim.particles.pool import ParticlePool

#: Below this many particle-steps a call runs on the calling thread alone: numba's threads sleep between calls
#: (OMP_WAIT_POLICY=PASSIVE), and waking them takes longer than a small pool's step.
SERIAL_WORK = 50_000
#: Methods the kernel steps with (its METHOD_CODES, named here so that deciding costs no numba import).
KERNEL_METHODS = ("euler", "symplectic_euler", "verlet")


@dataclass(frozen=True, eq=False)
class CompiledPool:
    """The numbers the kernel needs for one emitter: its method and collision mode codes, its field table
    (F, FIELD_COLUMNS) and collider table (S, SOLID_COLUMNS) (see :mod:`animbatch.sim.kernels.particle_pool`), and
    |g| [m/s²]; the colliders again as the kernel's quick clearance test reads them: the planes (P, 6), each a point
    and a unit normal, and the spheres and boxes as a collider table, or None when there are none."""

    method: int
    mode: int
    fields: np.ndarray
    solids: np.ndarray
    gravity: float
    planes: np.ndarray
    others: np.ndarray | None

    @classmethod
    def of(cls, emitter: Emitter, colliders: ParticleColliders | None, method: str, gravity: float, work: float
           ) -> CompiledPool | None:
        """The kernel's form of this emitter, or None where the numpy code runs (see the module notes):
        ``colliders``, those the emitter meets (None: none); ``work``, the particle-steps ahead (capacity × steps),
        which must repay loading numba (:func:`~animbatch.sim.kernels.compiled_kernels`)."""
        if not cls.covers(emitter, colliders, method) or not compiled_kernels(work):
            return None
        from animbatch.sim.kernels import particle_pool as kernel

        fields = emitter.fields

        table = np.zeros((len(fields), kernel.FIELD_COLUMNS))
        for row, law in zip(table, fields):  # each law writes its own row (see animbatch.sim.forces.on_particles)
            law.kernel_row(row, kernel)
        solids = solid_table(colliders, kernel) if colliders is not None else np.zeros((0, kernel.SOLID_COLUMNS))
        mode = emitter.collision if colliders is not None else "pass"
        compiled = cls(kernel.METHOD_CODES[method], kernel.MODE_CODES[mode], table, solids, float(gravity),
                       *clearance_tables(solids, kernel))
        # a kernel that does not build must not stop the run
        failure = watched(lambda: build_failure(compiled.compile_now), "particle")
        if failure is not None:
            warnings.warn(f"the compiled particle kernel could not be built ({failure}); emitter {emitter.name!r} "
                          "runs the numpy code instead (same results, slower). Set ANIMBATCH_KERNELS=numpy to "
                          "silence this", RuntimeWarning, stacklevel=2)
            return None
        return compiled

    @staticmethod
    def covers(emitter: Emitter, colliders: ParticleColliders | None, method: str) -> bool:
        """Whether the kernel can step this emitter (its fields, the ``colliders`` it meets, ``method``)."""
        if method not in KERNEL_METHODS or not all(law.compiled for law in emitter.fields):
            return False
        # meshes, bodies and moving colliders are traced by the numpy code
        return colliders is None or colliders.obstacles is None or colliders.obstacles.empty

    @functools.cached_property
    def summary_table(self) -> np.ndarray | None:
        """The field table as :func:`~animbatch.sim.kernels.particle_pool.advance_one` takes it: None when the
        kernel's scalar summary covers it (gravity and at most one drag), so that the table's code is compiled out."""
        from animbatch.sim.kernels.particle_pool import field_summary

        return None if field_summary(self.fields)[0] else self.fields

    @functools.cached_property
    def after_first_plane(self) -> np.ndarray | None:
        """The solids :func:`~animbatch.sim.kernels.particle_pool.advance_one` tests from their table (it reads the
        first plane into scalars): all but the first plane, or None when there are no others."""
        from animbatch.sim.kernels.particle_pool import SOLID, SOLID_PLANE

        planes = np.flatnonzero(self.solids[:, SOLID] == SOLID_PLANE)
        rest = np.delete(self.solids, planes[:1], axis=0)
        return np.ascontiguousarray(rest) if len(rest) else None

    def compile_now(self) -> None:
        """Build (or load from the disk cache) every kernel on a pool of one particle before the run starts, so that a
        kernel that fails to build is found before any particle has moved, and so that the first compilation is not
        counted in any frame's time."""
        from animbatch.sim.kernels.particle_pool import age_pool

        pool = ParticlePool(1)
        self.advance(pool, 0.0, 1.0, 1, 0, 1, age=True)  # one step per call, and several
        self.advance(pool, 0.0, 1.0, 2, 0, 2, age=True)
        self.collide_newborns(pool, np.zeros(1, np.int64), np.zeros((1, 3)), 1.0)
        self.age(pool, 1.0)
        age_pool(pool.alive, pool.stuck, pool.v, pool.birth, pool.lifetime, 1.0)  # what large pools age with

    def advance(self, pool: ParticlePool, start: float, stop: float, steps: int, first: int, last: int, *,
                age: bool) -> int:
        """Steps ``first`` … ``last - 1`` of the ``steps`` that divide ``[start, stop]`` [s] for the whole pool;
        with ``age``, deaths by age at the end of each step too. Returns the collisions."""
        import numba

        from animbatch.sim.kernels.particle_pool import advance_one, advance_pool

        # the instants as the numpy loop computes them, so that both take the same steps
        times = start + (stop - start) * np.arange(first, last + 1) / steps
        # no particle can die in these steps: their ages are not read (two arrays fewer through memory a step)
        age = age and pool.may_die_by(float(times[-1]))
        threads = numba.get_num_threads()
        if pool.capacity * (last - first) < SERIAL_WORK:  # waking the threads would cost more than the work
            numba.set_num_threads(1)
        try:
            if last - first == 1:  # a pool with births: one step per call, in the loop made for it
                hits, deaths, soonest = advance_one(pool.x, pool.v, pool.acceleration, pool.alive, pool.stuck,
                                                    pool.mass, pool.radius, pool.birth, pool.lifetime, times,
                                                    self.method, self.fields, self.summary_table, self.solids,
                                                    self.planes, self.after_first_plane, self.mode, MAX_BOUNCES,
                                                    SURFACE_GAP, self.gravity, age)
            else:
                hits, deaths, soonest = advance_pool(pool.x, pool.v, pool.acceleration, pool.alive, pool.stuck,
                                                     pool.mass, pool.radius, pool.birth, pool.lifetime, times,
                                                     self.method, self.fields, self.solids, self.planes, self.others,
                                                     self.mode, MAX_BOUNCES, SURFACE_GAP, self.gravity, age)
        finally:
            numba.set_num_threads(threads)
        pool.died += int(deaths)
        if age:
            pool.first_death = float(soonest)
        return int(hits)

    def collide_newborns(self, pool: ParticlePool, slots: np.ndarray, starts: np.ndarray, h: float) -> int:
        """The paths of particles born in a step of ``h`` [s], from ``starts`` (K, 3) to where they are now, against
        the colliders. Returns the collisions."""
        from animbatch.sim.kernels.particle_pool import collide_paths

        hits, deaths = collide_paths(np.ascontiguousarray(slots, np.int64), np.ascontiguousarray(starts, float),
                                     pool.x, pool.v, pool.alive, pool.stuck, pool.radius, self.solids, self.mode,
                                     MAX_BOUNCES, SURFACE_GAP, self.gravity, float(h))
        pool.died += int(deaths)
        return int(hits)

    def age(self, pool: ParticlePool, now: float) -> None:
        """Particles whose age at ``now`` [s] reached their lifetime die."""
        from animbatch.sim.kernels.particle_pool import age_pool

        if pool.capacity < SERIAL_WORK:  # numpy's passes cost less than waking the threads
            pool.age(now)
            return
        if not pool.may_die_by(now):
            return
        deaths, soonest = age_pool(pool.alive, pool.stuck, pool.v, pool.birth, pool.lifetime, float(now))
        pool.died += int(deaths)
        pool.first_death = float(soonest)


@functools.cache
def build_particle_kernels() -> str | None:
    """Build (or load from numba's disk cache) the emitted particles' kernels on a pool of one particle under
    gravity, twice: over a floor alone, and over a floor and a sphere (the kernel's two compilations: planes only,
    and with spheres or boxes); None, or what failed."""
    from animbatch.sim.kernels import particle_pool as kernel

    fields = np.zeros((1, kernel.FIELD_COLUMNS))
    fields[0, kernel.KIND], fields[0, kernel.VECTOR + 1] = kernel.FIELD_GRAVITY, -9.81
    floor = np.zeros(kernel.SOLID_COLUMNS)
    floor[kernel.SOLID], floor[kernel.NORMAL + 1] = kernel.SOLID_PLANE, 1.0
    ball = np.zeros(kernel.SOLID_COLUMNS)
    ball[kernel.SOLID], ball[kernel.RADIUS] = kernel.SOLID_SPHERE, 1.0
    for solids in (floor[None], np.stack([floor, ball])):
        pool = CompiledPool(kernel.METHOD_VERLET, kernel.MODE_BOUNCE, fields, solids, 9.81,
                            *clearance_tables(solids, kernel))
        failure = build_failure(pool.compile_now)
        if failure is not None:
            return failure
    return None


def clearance_tables(solids: np.ndarray, kernel: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """The collider table ``solids`` (S, SOLID_COLUMNS) split for the kernel's quick clearance test: its planes
    (P, 6), each a point and a unit normal, and its spheres and boxes as a collider table, or None when it has
    none."""
    is_plane = solids[:, kernel.SOLID] == kernel.SOLID_PLANE
    planes = np.ascontiguousarray(np.hstack([solids[is_plane, kernel.CENTRE:kernel.CENTRE + 3],
                                             solids[is_plane, kernel.NORMAL:kernel.NORMAL + 3]]))
    others = np.ascontiguousarray(solids[~is_plane]) if (~is_plane).any() else None
    return planes, others


def solid_table(colliders: ParticleColliders, kernel: Any) -> np.ndarray:
    """The fixed colliders as the kernel's table: planes, then spheres, then boxes (the numpy code's order), each
    with its coefficients against the particles."""
    statics = colliders.statics
    rows = []
    for kind, count, material in ((kernel.SOLID_PLANE, len(statics.plane_point), statics.plane_material),
                                  (kernel.SOLID_SPHERE, len(statics.sphere_centre), statics.sphere_material),
                                  (kernel.SOLID_BOX, len(statics.box_centre), statics.box_material)):
        for k in range(count):
            row = np.zeros(kernel.SOLID_COLUMNS)
            row[kernel.SOLID] = kind
            m = material[k]
            row[kernel.RESTITUTION] = colliders.restitution[m]
            row[kernel.STATIC_FRICTION] = colliders.static_friction[m]
            row[kernel.KINETIC_FRICTION] = colliders.kinetic_friction[m]
            if kind == kernel.SOLID_PLANE:
                row[kernel.CENTRE:kernel.CENTRE + 3] = statics.plane_point[k]
                row[kernel.NORMAL:kernel.NORMAL + 3] = statics.plane_normal[k]
            elif kind == kernel.SOLID_SPHERE:
                row[kernel.CENTRE:kernel.CENTRE + 3] = statics.sphere_centre[k]
                row[kernel.RADIUS] = statics.sphere_radius[k]
            else:
                row[kernel.CENTRE:kernel.CENTRE + 3] = statics.box_centre[k]
                row[kernel.HALF:kernel.HALF + 3] = statics.box_half[k]
                row[kernel.ROTATION:kernel.ROTATION + 9] = np.ravel(statics.box_rotation[k])
            rows.append(row)
    return np.array(rows, float).reshape(-1, kernel.SOLID_COLUMNS)


#: What the numpy code's step of a pool costs: a fixed part (some forty numpy calls, whatever the pool's size) and a
#: part per slot [s]. Measured: 0.45-0.5 ms and 130-270 ns a slot (Verlet under gravity and quadratic drag, with and
#: without a floor, pools of 100 to 30 000 slots). Fireworks' three pools of 2500 at 1 ms steps took 2 ms a step in
#: numpy while their 1.2·10⁷ particle-steps, counted alone, were far from paying for numba (and each pool alone, at
#: 0.46 s, short of COMPILE_AFTER: the decision counts every emitter of the run).
NUMPY_POOL_STEP = 0.4e-3
NUMPY_SLOT_STEP = 150e-9


def numpy_pool_seconds(capacity: float, steps: float) -> float:
    """What the numpy code would take [s] to step a pool of ``capacity`` slots ``steps`` times."""
    return steps * (NUMPY_POOL_STEP + capacity * NUMPY_SLOT_STEP)


def kernel_work(capacity: float, steps: float, run_seconds: float) -> float:
    """The work (element-steps) to weigh the kernel by, for a pool of ``capacity`` slots stepped ``steps`` times in a
    run whose pools would take ``run_seconds`` [s] in numpy (:func:`numpy_pool_seconds` of every emitter: numba,
    once loaded, serves them all): the pool's particle-steps, or :data:`~animbatch.sim.kernels.MIN_WORK` (the kernel
    repays loading numba) where the run would take :data:`~animbatch.sim.model.compiled.COMPILE_AFTER` or more, as
    for the bodies' equations of motion."""
    from animbatch.sim.kernels import MIN_WORK
    from animbatch.sim.model.compiled import COMPILE_AFTER

    particle_steps = capacity * steps
    return max(particle_steps, MIN_WORK) if run_seconds >= COMPILE_AFTER else particle_steps


def colliders_met(emitter: Emitter, colliders: ParticleColliders | None) -> ParticleColliders | None:
    """The colliders an emitter's particles meet: none with ``collision: pass`` or when there are none."""
    if emitter.collision == "pass" or colliders is None or colliders.empty:
        return None
    return colliders


def particle_step_seconds(emitter: Emitter, colliders: ParticleColliders | None, method: str, work: float) -> float:
    """What advancing one of the emitter's particles by one step costs [s], births and records included, for the
    cost pre-flight: the compiled kernel's figure where it will run (``work``: the particle-steps ahead), else the
    numpy code's."""
    from animbatch.sim.integrators.cost import COMPILED_PARTICLE_STEP_SECONDS, PARTICLE_STEP_SECONDS

    met = colliders_met(emitter, colliders)
    compiled = CompiledPool.covers(emitter, met, method) and compiled_kernels(work)
    return COMPILED_PARTICLE_STEP_SECONDS if compiled else PARTICLE_STEP_SECONDS
