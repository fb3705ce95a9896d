"""Buoyancy: a fluid of density ρ fills the half-space below a surface; it pushes each body up with ``ρ g V_sub``.

The force acts at the centre of buoyancy (the centroid of the submerged volume), so a floating body whose centre of
buoyancy is not under its centre of mass feels a torque that rights it (or capsizes it, if it is unstable). The
lecture notes give pressure and buoyancy for a fully immersed body; here the immersed part is found at every
evaluation:

* spheres (particles of their radius, sphere and shell shapes, sphere parts of compounds): the exact spherical cap,
  ``V = π h² (3r - h) / 3`` with its centroid ``3 (2r - h)² / (4 (3r - h))`` below the centre;
* everything else: its closed surface, clipped at the fluid surface (exact for boxes and meshes; cylinders and rods
  use a 96-sided prism), see :func:`animbatch.sim.rigid.polyhedra.submerged_volume_and_moment`.

Optional damping, ``-c v`` and ``-c_rot ω`` scaled by the submerged fraction, stands for the fluid's resistance, so
that floating bodies settle. All bodies are handled in one vectorised pass.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from animbatch.quaternion import cross
from animbatch.sim.forces.on_particles import ParticleLaw, Slots
from animbatch.sim.forces.term import (
    BodyTable,
    ForceTerm,
    Kinematics,
    TimeScale,
    fastest_spin_decay,
    selection_text,
    vector_text,
)
from animbatch.sim.rigid.polyhedra import submerged_volume_and_moment


def spherical_caps(centres: np.ndarray, radii: np.ndarray, level: float, up: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Submerged volume (K,) and its centroid (K, 3) for spheres (K, 3), (K,) under a surface at height ``level``."""
    # h: how far the bottom is under the surface (minimum and maximum: np.clip's wrapper costs more than the sum here)
    depth = np.minimum(np.maximum(level - (centres @ up - radii), 0.0), 2 * radii)
    rest = 3 * radii - depth  # >= r > 0 wherever the sphere is wet; 0 only for a dry sphere of no size
    volume = np.pi * depth**2 * rest / 3
    below = np.where(depth > 0, 3 * (2 * radii - depth) ** 2 / (4 * np.maximum(rest, np.finfo(float).tiny)), 0.0)
    return volume, centres - below[:, None] * up


@dataclass(frozen=True, eq=False)
class Buoyancy(ForceTerm):
    """Buoyant force and fluid damping on the selected bodies.

    Sphere pieces: ``sphere_owner`` (K,) point index, ``sphere_rigid`` (K,) rigid index or -1 for particles,
    ``sphere_offset`` (K, 3) centre in body axes from the centre of mass, ``sphere_radius`` (K,). Surface pieces:
    ``triangles`` (T, 3, 3) in body axes from the centre of mass, ``triangle_owner`` (T,) point index,
    ``triangle_rigid`` (T,) rigid index. ``bodies`` (S,) are the selected points, ``full_volume`` (S,) their volumes.
    """

    kind = "buoyancy"

    density: float
    g: float
    level: float
    up: np.ndarray
    linear_damping: float
    angular_damping: float
    bodies: np.ndarray
    full_volume: np.ndarray
    sphere_owner: np.ndarray
    sphere_rigid: np.ndarray
    sphere_offset: np.ndarray
    sphere_radius: np.ndarray
    triangles: np.ndarray
    triangle_owner: np.ndarray
    triangle_rigid: np.ndarray
    first_rigid: int
    names: tuple[str, ...]

    def time_scale(self, state: Kinematics, bodies: BodyTable, gravity: float) -> TimeScale | None:
        """The fastest relaxation in the fluid, fully submerged: c / m of a velocity or c_rot / I of a spin."""
        found = []
        if self.linear_damping and len(self.bodies):
            rates = self.linear_damping / bodies.mass[self.bodies]
            k = int(np.argmax(rates))
            found.append(TimeScale(float(rates[k]), f"fluid damping on {self.names[self.bodies[k]]!r} (its "
                                                     f"velocity relaxes in {1 / rates[k]:.3g} s when submerged)",
                                   turns=False))
        rigid = self.bodies[self.bodies >= self.first_rigid] - self.first_rigid
        spin = fastest_spin_decay(self.angular_damping, rigid, bodies, "fluid damping")
        found += [spin] if spin is not None else []
        return max(found, key=lambda scale: scale.rate, default=None)

    @functools.cached_property
    def _off_centre_spheres(self) -> np.ndarray:
        """Indices of the sphere pieces on rigid bodies whose centre is not the body's centre of mass."""
        return np.flatnonzero((self.sphere_rigid >= 0) & np.any(self.sphere_offset != 0, axis=1))

    @functools.cached_property
    def _one_sphere_each(self) -> bool:
        """Whether no point owns two sphere pieces."""
        return len(np.unique(self.sphere_owner)) == len(self.sphere_owner)

    @property
    def dissipative(self) -> bool:
        return True  # buoyancy alone is conservative, but its damping is not; the fluid's energy is not tracked

    def submerged(self, state: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Submerged volume [m³] (P,) and centre of buoyancy [m] (P, 3) of every point (zero where not selected)."""
        count = len(state.x)
        volume = np.zeros(count)
        moment = np.zeros((count, 3))
        if len(self.sphere_owner):
            centres = state.x[self.sphere_owner]  # a copy (fancy indexing)
            off_centre = self._off_centre_spheres
            if len(off_centre):  # spheres of compounds; a sphere shape's own sphere sits at its centre of mass
                centres[off_centre] += state.lever(self.sphere_rigid[off_centre], self.sphere_offset[off_centre])
            caps, centroids = spherical_caps(centres, self.sphere_radius, self.level, self.up)
            if self._one_sphere_each:  # the common case: assign, no sums (the same numbers: 0 + w is w)
                volume[self.sphere_owner] = caps
                moment[self.sphere_owner] = caps[:, None] * centroids
            else:
                volume += np.bincount(self.sphere_owner, weights=caps, minlength=count)
                for k in range(3):
                    moment[:, k] += np.bincount(self.sphere_owner, weights=caps * centroids[:, k], minlength=count)
        if len(self.triangles):
            assert state.rotation is not None
            world = np.einsum("tij,tcj->tci", state.rotation[self.triangle_rigid], self.triangles)
            world += state.x[self.triangle_owner][:, None, :]
            surface_point = self.level * self.up
            part_volume, part_moment = submerged_volume_and_moment(world, self.triangle_owner, count, surface_point,
                                                                   self.up)
            volume += part_volume
            moment += part_moment
        centre = np.divide(moment, volume[:, None], out=state.x.copy(), where=volume[:, None] > 0)
        return volume, centre

    @functools.cached_property
    def _rigid_selected(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Which selected points are rigid bodies (S,) bool, their point indices and their rigid indices."""
        rigid = self.bodies >= self.first_rigid
        return rigid, self.bodies[rigid], self.bodies[rigid] - self.first_rigid

    @functools.cached_property
    def _has_volume(self) -> np.ndarray:
        """Which selected points have a volume (S,) bool (a particle of no radius has none)."""
        return self.full_volume > 0

    def accumulate(self, t: float, state: Kinematics, force: np.ndarray, torque: np.ndarray | None) -> None:
        volume, centre = self.submerged(state)
        lift = (self.density * self.g * volume)[:, None] * self.up  # (P, 3)
        fraction = np.divide(volume[self.bodies], self.full_volume, out=np.zeros(len(self.bodies)),
                             where=self._has_volume)
        pushed = lift[self.bodies]
        if self.linear_damping:
            pushed = pushed - (self.linear_damping * fraction)[:, None] * state.v[self.bodies]
        force[self.bodies] += pushed
        if torque is not None and state.omega is not None:
            rigid, points, which = self._rigid_selected
            torque[which] += cross(centre[points] - state.x[points], lift[points])
            if self.angular_damping:
                torque[which] -= (self.angular_damping * fraction[rigid])[:, None] * state.omega[which]

    def describe(self) -> str:
        damping = ""
        if self.linear_damping or self.angular_damping:
            damping = f", damping {self.linear_damping:g} N·s/m, {self.angular_damping:g} N·m·s"
        return (f"ρ = {self.density:g} kg/m³ below height {self.level:g} m along {vector_text(self.up)}, "
                f"g = {self.g:g} m/s²{damping} on {selection_text(self.bodies, self.names)}")


def build_buoyancy(bodies: BodyTable, index: np.ndarray | None, *, density: float, g: float, level: float,
                   up: np.ndarray, linear_damping: float, angular_damping: float) -> Buoyancy:
    """Archimedes' force of a fluid of ``density`` [kg/m³] below height ``level`` [m] along ``up`` (3,), under
    gravity ``g`` [m/s²], with fluid damping of the submerged part (``linear_damping`` [1/s], ``angular_damping``
    [1/s]) on the selected points."""
    selected = np.arange(bodies.count) if index is None else np.asarray(index)
    up = np.asarray(up, float) / np.linalg.norm(up)
    particles = selected[selected < bodies.first_rigid]  # each a sphere of its radius, at its centre
    sphere_owner, sphere_rigid = [particles], [np.full(len(particles), -1)]
    sphere_offset, sphere_radius = [np.zeros((len(particles), 3))], [bodies.radius[particles]]
    triangles, triangle_owner, triangle_rigid = [], [], []
    full_volume = 4 / 3 * np.pi * bodies.radius[selected] ** 3  # replaced below for rigid bodies
    for position in np.flatnonzero(selected >= bodies.first_rigid):  # rigid bodies: few, and built once
        point = selected[position]
        rigid = point - bodies.first_rigid
        assert bodies.rigid is not None  # there are rigid points
        geometry = bodies.rigid.geometry[rigid]
        centre = bodies.rigid.centre[rigid]
        spheres = geometry.spheres
        sphere_owner.append(np.full(len(spheres), point))
        sphere_rigid.append(np.full(len(spheres), rigid))
        sphere_offset.append(spheres[:, :3] - centre)
        sphere_radius.append(spheres[:, 3])
        if len(geometry.triangles):
            triangles.append(geometry.triangles - centre)
            triangle_owner.append(np.full(len(geometry.triangles), point))
            triangle_rigid.append(np.full(len(geometry.triangles), rigid))
        full_volume[position] = geometry.displaced_volume
    return Buoyancy(density, g, level, up, linear_damping, angular_damping, selected,
                    full_volume, np.concatenate(sphere_owner).astype(np.intp),
                    np.concatenate(sphere_rigid).astype(np.intp), np.concatenate(sphere_offset),
                    np.concatenate(sphere_radius).astype(float),
                    np.concatenate(triangles) if triangles else np.zeros((0, 3, 3)),
                    np.concatenate(triangle_owner) if triangle_owner else np.zeros(0, np.intp),
                    np.concatenate(triangle_rigid) if triangle_rigid else np.zeros(0, np.intp),
                    bodies.first_rigid, bodies.names)


@dataclass(frozen=True, eq=False)
class BuoyancyOnParticles(ParticleLaw):
    """Buoyancy on emitted particles: ``a = ρ g V_sub up / m`` (V_sub: the submerged cap of the particle's sphere
    below ``level`` [m] along the unit ``up`` (3,)), with the fluid's damping ``-c v V_sub / V`` (``damping`` c
    [N·s/m])."""

    density: float
    g: float
    level: float
    up: np.ndarray
    damping: float

    def describe(self) -> str:
        return f"buoyancy ρ = {self.density:g} kg/m³ below {self.level:g} m"

    def _fraction(self, slots: Slots) -> tuple[np.ndarray, np.ndarray]:
        """The submerged volume (K,) [m³] and its fraction of each sphere (K,)."""
        volume, _ = spherical_caps(slots.x, slots.radius, self.level, self.up)
        return volume, volume / (4.0 / 3.0 * np.pi * slots.radius ** 3)

    def add_acceleration(self, slots: Slots, out: np.ndarray) -> None:
        volume, fraction = self._fraction(slots)
        out += (self.density * self.g * volume / slots.mass)[:, None] * self.up
        if self.damping:
            out -= (self.damping * fraction / slots.mass)[:, None] * slots.v

    def rates(self, slots: Slots) -> np.ndarray | None:
        if not self.damping:
            return None
        rates = np.zeros((len(slots.mass), 2))
        rates[:, 0] = self.damping * self._fraction(slots)[1] / slots.mass
        return rates

    @property
    def compiled(self) -> bool:
        return True

    def largest_rate(self, mass: float, radius: float, speed: float, gravity: float) -> float | None:
        return self.damping / mass if self.damping else None  # fully submerged

    def kernel_row(self, row: np.ndarray, kernel: ModuleType) -> None:
        row[kernel.KIND] = kernel.FIELD_BUOYANCY
        row[kernel.VECTOR:kernel.VECTOR + 3] = self.up
        row[kernel.DENSITY], row[kernel.BUOYANCY_G] = self.density, self.g
        row[kernel.LEVEL], row[kernel.DAMPING] = self.level, self.damping
