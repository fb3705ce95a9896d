"""The velocity constraint of cloth's self-collision (:mod:`animbatch.sim.deformable.self_collision` says which
surfaces collide and how): after the contacts with solids, the particles' velocities are filtered so that the drift
crosses no triangle pair (:func:`animbatch.sim.kernels.self_contact.filter_velocities`).

The kernels are compiled (numba): a pure-Python run of them would take seconds a step on a 48 × 48 sheet, so where
they cannot be compiled (``ANIMBATCH_KERNELS=numpy``, or numba does not load) self-collision is switched off and a
warning says so; the frames' crossing audit (:mod:`~animbatch.sim.deformable.intersections`) then still reports any
pass-through.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from animbatch.sim.deformable.self_collision import SelfCollisionSet
from animbatch.sim.deformable.vertices import PARTICLE
from animbatch.sim.integrators.interface import ContactSolves, VelocityConstraint
from animbatch.sim.kernels import kernels_ready

#: The inverse mass of a vertex touching a solid, as a fraction of its own: the layer above it gives way instead, so
#: that self-collision does not push the sheet into the floor (it moves it by at most this fraction of a change,
#: which the contacts take back next step); not zero, so that a pair between two held layers can still be parted.
RESTING_WEIGHT = 0.05
#: A step that moves a vertex across more than this many hash cells is a run diverging: the filter leaves it alone.
DIVERGED = 1000
#: The counters a run adds up (:data:`animbatch.sim.kernels.self_contact.STATS`, by name).
COUNTERS = ("repelled", "collisions", "passes", "zones", "largest_zone", "unresolved")


@functools.cache
def _build_failure() -> str | None:
    from animbatch.sim.kernels import build_failure

    def build() -> None:
        from animbatch.sim.kernels.self_contact import filter_velocities

        x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 0.1]])
        filter_velocities(x, np.array([[0.0, 0, 0]] * 3 + [[0, 0, -4.0]]), np.ones(4), np.full(4, 0.01),
                          np.zeros(4), np.array([[0, 1, 2]], np.int64), np.array([[0, 1], [1, 2], [0, 2]], np.int64),
                          0.05, 0.5)

    return build_failure(build)


def self_contact_compiled() -> bool:
    """Whether the self-collision kernels can run here (see the module notes)."""
    return kernels_ready(np.inf, _build_failure, "self-collision", "cloth runs without self-collision")


@dataclass
class _NoImpacts:
    def as_list(self) -> list[tuple[float, int]]:
        return []


@dataclass
class SelfContact:
    """The velocity constraint of self-collision (see the module notes), after ``inner`` (the contacts with
    solids), if any. ``totals`` adds up the kernel's counters over the run; ``acted`` says whether the last step's
    filter changed any velocity (a step whose energy it changed is not one the implicit scheme's energy guard
    should redo)."""

    system: Any  # the model's Dynamics
    surfaces: SelfCollisionSet
    inner: VelocityConstraint | None = None
    totals: dict[str, int] = field(default_factory=lambda: dict.fromkeys((*COUNTERS, "spread_out"), 0))
    acted: bool = False
    _solves: ContactSolves = field(default_factory=ContactSolves)

    def __post_init__(self) -> None:
        deformables = self.system.model.deformables
        vertex_map = deformables.vertex_map
        self._deformables = deformables
        chosen = self.surfaces.vertices
        kind = vertex_map.kind[chosen]
        self._free = np.flatnonzero(kind == PARTICLE)  # positions in the set of its particles
        self._particles = vertex_map.index[chosen[self._free]]  # and their particle numbers
        mass = np.asarray(self.system.model.bodies.mass, float)
        self._inverse_mass = np.zeros(len(chosen))
        self._inverse_mass[self._free] = 1.0 / mass[self._particles]
        self._slot = np.full(self.system.particles, -1, np.int64)  # particle -> its place in the set
        self._slot[self._particles] = self._free
        from animbatch.sim.kernels.self_contact import filter_velocities

        self._filter = filter_velocities

    @property
    def guards_energy(self) -> bool:
        """Whether the implicit scheme's energy guard may check the steps (see ``acted``): not beside contacts with
        solids, whose position corrections keep no energy accounts."""
        return self.inner is None

    @property
    def impacts(self) -> Any:
        return self.inner.impacts if self.inner is not None else _NoImpacts()

    @property
    def solves(self) -> ContactSolves:
        return self.inner.solves if self.inner is not None else self._solves

    def resolve(self, config: np.ndarray, motion: np.ndarray, h: float, *, t: float,
                bounce: bool = True) -> np.ndarray | None:
        """The contacts with solids (``inner``), then the filter on the velocities the drift will use; the
        end-of-step re-projection (``bounce`` False) is the inner constraint's alone."""
        drifting = self.inner.resolve(config, motion, h, t=t, bounce=bounce) if self.inner is not None else None
        self.acted = False
        if not bounce:
            return drifting
        state = self.system.kinematics(config, motion, t=t)
        x_all, v_all = self._deformables.vertex_map.positions_velocities(state, self._deformables.anchors)
        chosen = self.surfaces.vertices
        x, v = x_all[chosen], v_all[chosen]
        moving = drifting if drifting is not None else motion
        particle_v = moving[: 3 * self.system.particles].reshape(-1, 3)
        v[self._free] = particle_v[self._particles]
        before = v[self._free].copy()
        start = v.copy()
        surfaces = self.surfaces
        inverse_mass = self._inverse_mass
        resting = getattr(self.inner, "resting", None)
        touching = np.zeros(0, np.int64)
        if resting is not None and len(resting):  # vertices on a solid are held by it: heavy here (see RESTING_WEIGHT)
            particle = resting < len(self._slot)
            touching = np.where(particle, self._slot[np.where(particle, resting, 0)], -1)
            inverse_mass = inverse_mass.copy()
            inverse_mass[touching[touching >= 0]] *= RESTING_WEIGHT
        travel = h * float(np.sqrt((v * v).sum(axis=1)).max()) if len(v) else 0.0
        if not (np.isfinite(travel) and np.all(np.isfinite(x))) or travel > DIVERGED * surfaces.cell:
            return drifting  # a state running away: the divergence checks stop the run and name what ran away
        if surfaces.spread_out(x, x + h * v):  # a sheet spread out cannot meet itself: no search this step
            self.totals["spread_out"] += 1
            return drifting
        # a step that sweeps vertices across many cells takes larger ones, so that each box covers a few of them
        cell = max(surfaces.cell, travel / 4)
        stats = self._filter(x, v, inverse_mass, surfaces.thickness, surfaces.friction, surfaces.triangles,
                             surfaces.edges, h, cell)
        for name, count in zip(COUNTERS, stats):
            self.totals[name] = max(self.totals[name], int(count)) if name == "largest_zone" else (
                self.totals[name] + int(count))
        if len(touching):
            self._keep_out_of_solids(v, start, touching)
        change = v[self._free] - before
        if not np.any(change):
            return drifting
        self.acted = True
        particle_motion = motion[: 3 * self.system.particles].reshape(-1, 3)
        particle_motion[self._particles] += change
        if drifting is not None:
            particle_v[self._particles] += change
        return drifting

    def _keep_out_of_solids(self, v: np.ndarray, before: np.ndarray, touching: np.ndarray) -> None:
        """Take back what the filter changed of the velocities ``v`` (n, 3) of the set's vertices at ``touching``
        (the last step's contacts with solids, −1 where not in the set) along the contact's normal into the solid:
        the layer above them gave way instead (see RESTING_WEIGHT), and the solid keeps them out."""
        normal = np.asarray(getattr(self.inner, "resting_normal"))  # the contacts with solids found this step
        rows = np.flatnonzero(touching >= 0)
        slots = touching[rows]
        change = v[slots] - before[slots]
        into = np.minimum(np.einsum("ki,ki->k", change, normal[rows]), 0.0)
        np.add.at(v, slots, -into[:, None] * normal[rows])


def self_contact_constraint(system: Any, inner: VelocityConstraint | None) -> SelfContact | VelocityConstraint | None:
    """The self-collision constraint of ``system``'s model around ``inner`` (or ``inner`` alone when no body has
    self-collision on, or when its kernels cannot be compiled here: then a warning says so)."""
    deformables = system.model.deformables
    surfaces = SelfCollisionSet.of(deformables) if deformables is not None else None
    if surfaces is None:
        return inner
    if not self_contact_compiled():
        warnings.warn(f"self-collision of {', '.join(map(repr, surfaces.names))} needs its compiled kernels, which "
                      "cannot run here (ANIMBATCH_KERNELS=numpy, or numba does not load): the cloth runs without "
                      "it and may pass through itself (the ledger's surfaces entry will say so)", RuntimeWarning,
                      stacklevel=2)
        return inner
    return SelfContact(system, surfaces, inner)
