"""After a run: did any body end up inside another, or pass through it between two frames, without an impact?

Impacts are found during integration (events on the dense output for adaptive methods, speculative contacts for
fixed steps). This audit does not trust either: it looks at the result. At every frame, and along the straight
path from each frame to the next (states interpolated linearly at :data:`SUBSAMPLES` points), it measures the
overlap of every probe with every solid it could reach; between frames also where each pair comes closest, so that
a small body crossing a thin solid within one frame is seen. An overlap deeper than the pair's allowance, with no impact
logged for either body between the two frames, is a collision the integration missed: the run then warns, naming
the two bodies, the time and the depth.

The allowance is the larger of :data:`SLOP_MULTIPLE` times the contact slop (overlap that contact solving tolerates
and removes) and :data:`RADIUS_FRACTION` of the smaller body's radius (a chord between frames cuts a little into a
convex solid that a body rolls over). A missed impact is far deeper: a body halfway or all the way through.

Only frame times are looked at, so the cost is a few contact detections per frame, not per step.

At the frames, the contacts that probes miss are measured too: box and hull edges crossing edges, cylinders' rims on
planes, and the sides of rods, cylinders and capsules (:mod:`animbatch.sim.contact.sides`). The fixed-step methods
resolve them all at every step, and the adaptive methods' events follow them.
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from animbatch.sim.contact.contacts import (
    BODY_BOX,
    BODY_BOX_FACE,
    BODY_HULL,
    BODY_ROUND,
    BODY_SPHERE,
    HULL_EDGE,
    PLANE,
    PLANE_RIM,
    SIDE_EDGE,
    STATIC_BOX,
    STATIC_BOX_FACE,
    STATIC_EDGE,
    STATIC_SPHERE,
    TRIANGLE,
    Contacts,
    contact_codes,
)
from animbatch.sim.contact.detection import (
    ContactWorld,
    body_box_poses,
    body_reach,
    closing_margin,
    detect,
    evaluate_pairs,
    pair_gaps,
    points_moved,
    probe_centres,
)
from animbatch.sim.contact.impulses import compiled_contacts

#: Points between consecutive frames at which the straight path is checked.
SUBSAMPLES = 8
#: Most points between two frames looked at (evenly spaced ones and the pairs' closest approaches).
MAX_POINTS = 64
#: Overlap up to this many times the contact slop is tolerated.
SLOP_MULTIPLE = 10.0
#: Overlap up to this fraction of the smaller body's radius is tolerated.
RADIUS_FRACTION = 0.25

_STATIC_KINDS = {PLANE: "plane", STATIC_SPHERE: "sphere", STATIC_BOX: "box", STATIC_BOX_FACE: "box",
                 TRIANGLE: "mesh", PLANE_RIM: "plane"}


@dataclass(frozen=True)
class Overlap:
    """A body found inside a solid: ``depth`` [m] (beyond the ``allowance`` contact solving tolerates) at time
    ``time`` [s] (a frame time, or between two frames when ``between_frames``), the probe's body and what it was
    inside (a body's name or ``colliders[k] (kind)``). ``at_start``: the scene placed them so; otherwise the
    integration missed their collision."""

    depth: float
    allowance: float
    time: float
    body: str
    solid: str
    between_frames: bool = False
    at_start: bool = False

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def message(self, method: str, *, adaptive: bool) -> str:
        if self.at_start:
            return (f"body {self.body!r} starts {self.depth:.3g} m inside {self.solid}: the scene places them "
                    "overlapping, and contact solving pushes them apart with a jolt that no physics explains. Move "
                    f"them {self.depth:.3g} m further apart (positions, sizes or radii).")
        where = f"between two frames, at about t = {self.time:.4g} s" if self.between_frames else \
            f"at t = {self.time:.4g} s"
        fix = ("a smaller solver.max_step (shorter than the time the bodies take to cross each other) or "
               "solver.method: verlet" if adaptive else "a smaller solver.dt")
        return (f"body {self.body!r} was {self.depth:.3g} m inside {self.solid} {where}, with no impact logged "
                f"(contact solving tolerates {self.allowance:.3g} m): {method} missed a collision and the motion "
                f"after it is wrong. Try {fix}.")


class OverlapAudit:
    """Looks for missed contacts in a run of a model with contacts (see the module notes)."""

    def __init__(self, model: Any, system: Any) -> None:
        self.world: ContactWorld = model.contact_world
        self.slop = float(model.contact_settings.slop)
        self.system = system
        self.names = model.body_names
        self.radius = model.bodies.radius
        self.reach = body_reach(self.world, model.body_count)
        self.sources = getattr(self.world, "collider_source", None) or {}
        self.excused = np.zeros(0, np.int64)  # contact codes of the pairs that start inside each other
        # where numba is loaded already (a run long enough to go compiled loads it), the frames are searched by the
        # compiled kernels (the same contacts, to round-off) at no start-up cost: the numpy search over every
        # frame was a quarter of a dominoes run
        self.compiled = "numba" in sys.modules and compiled_contacts(0, long_run=True)

    def _state(self, y: np.ndarray, t: float) -> Any:
        """The bodies of state ``y`` at time ``t`` [s] (the time places the colliders on keyframes)."""
        return self.system.kinematics(*self.system.split(y), t=t, copy=True)

    def _travel(self, s0: Any, s1: Any) -> np.ndarray:
        """How far each body's points move between two states (P,) [m]: translation plus reach times the turn."""
        return points_moved(self.reach, s0, s1)

    def _allowance(self, contacts: Contacts) -> np.ndarray:
        radius = self.radius[contacts.probe_body]
        solid = contacts.solid_body >= 0
        radius = np.where(solid, np.minimum(radius, self.radius[np.maximum(contacts.solid_body, 0)]), radius)
        return np.maximum(SLOP_MULTIPLE * self.slop, RADIUS_FRACTION * radius)

    def _solid_name(self, kind: int, index: int, body: int) -> str:
        if body >= 0:
            return f"body {self.names[body]!r}"
        if kind in (STATIC_EDGE, SIDE_EDGE, HULL_EDGE):  # numbered by edge: the collider's kind is all that is named
            return "a fixed box's edge"
        solid = index // 6 if kind == STATIC_BOX_FACE else index
        sources = self.sources.get(STATIC_BOX if kind == STATIC_BOX_FACE else PLANE if kind == PLANE_RIM else kind)
        number = f"colliders[{int(sources[solid])}]" if sources is not None and solid < len(sources) else "a collider"
        return f"{number} ({_STATIC_KINDS.get(kind, 'collider')})"

    def run(self, states: np.ndarray, times: np.ndarray, impacts: list[tuple[float, int]]
            ) -> dict[str, Overlap | None]:
        """The deepest overlaps over the frames ``states`` (F, n) at ``times`` (F,): ``starts_inside``, present in
        the first frame (the scene's doing), and ``missed``, a collision the integration missed; None where there
        is none. Pairs that start inside each other are left out of the second.

        ``impacts``: the (time [s], body index) the integration logged; an overlap between two frames is forgiven
        to a pair of which either body had an impact logged in that interval (a chord cuts across a bounce)."""
        found: dict[str, Overlap | None] = {"starts_inside": None, "missed": None}
        if not self.world.collides.any() or len(states) == 0:
            return found
        impact_times = np.array([t for t, _ in impacts], float)
        impact_bodies = np.array([b for _, b in impacts], np.intp)
        start = self._state(states[0], float(times[0]))
        first = detect(self.world, start, 0.0, edges=True, compiled=self.compiled)
        first = first.select(-first.gap > self._allowance(first))
        self.excused = np.zeros(0, np.int64)
        deepest = self._deepest(first, float(times[0]), False)
        found["starts_inside"] = dataclasses.replace(deepest, at_start=True) if deepest is not None else None
        self.excused = np.unique(contact_codes(first))
        worst = None
        for k in range(1, len(states)):
            end = self._state(states[k], float(times[k]))
            bounced = impact_bodies[(impact_times > times[k - 1]) & (impact_times <= times[k])]
            for fraction, contacts in self._between(states[k - 1], states[k], start, end, bounced):
                worst = self._deeper(worst, contacts, float(times[k - 1] + fraction * (times[k] - times[k - 1])),
                                     True)
            worst = self._deeper(worst, detect(self.world, end, 0.0, edges=True, compiled=self.compiled),
                                 float(times[k]), False)
            start = end
        found["missed"] = worst
        return found

    def _between(self, y0: np.ndarray, y1: np.ndarray, start: Any, end: Any, bounced: np.ndarray
                 ) -> list[tuple[float, Contacts]]:
        """The pairs that could meet on the straight path between two frames, evaluated at points along it:
        (fraction of the way, contacts) for each point looked at.

        A pair touching at either frame may be rolling or sliding over the solid (a chord cuts across a curved
        path), and one that bounced has an impact logged; only pairs apart at both frames, with no impact between,
        must stay apart in between. Of those, a pair whose two gaps together exceed what its two sides travel
        cannot meet (triangle inequality). The rest are looked at on :data:`SUBSAMPLES` evenly spaced points and at
        each one's point of closest approach (:meth:`_closest_fraction`), where a thin solid or a small fast body
        is crossed however short the overlap."""
        travel = self._travel(start, end)
        candidates = detect(self.world, start, 0.0, travel=travel, compiled=self.compiled)
        if not candidates.count:
            return []
        quiet = ~(np.isin(candidates.probe_body, bounced) | np.isin(candidates.solid_body, bounced))
        candidates = candidates.select(quiet)
        gaps = [pair_gaps(self.world, state, candidates.probe, candidates.solid_kind, candidates.solid_index)
                for state in (start, end)]
        closing = closing_margin(candidates.probe_body, candidates.solid_body, 0.0, travel)
        allowance = self._allowance(candidates)
        could_meet = (gaps[0] > allowance) & (gaps[1] > allowance) & (closing > gaps[0] + gaps[1])
        candidates = candidates.select(could_meet)
        if not candidates.count:
            return []
        closest = self._closest_fraction(candidates, start, end)
        fractions = np.unique(np.concatenate([np.arange(1, SUBSAMPLES + 1) / (SUBSAMPLES + 1), closest]))
        if len(fractions) > MAX_POINTS:  # many fast pairs at once: an even spread of their closest approaches
            fractions = fractions[np.linspace(0, len(fractions) - 1, MAX_POINTS).astype(int)]
        looked = []
        for fraction in fractions:
            y = (1 - fraction) * y0 + fraction * y1
            self.system.project(y, joints=False)  # unit quaternions (an interpolated look, not a state to keep)
            at = (1 - fraction) * start.t + fraction * end.t
            looked.append((float(fraction), evaluate_pairs(self.world, self._state(y, at), candidates.probe,
                                                           candidates.solid_kind, candidates.solid_index)))
        return looked

    def _closest_fraction(self, contacts: Contacts, start: Any, end: Any) -> np.ndarray:
        """For each pair (K,), the fraction of the way between two frames at which its probe comes closest to the
        solid, with both moving in straight lines: where it crosses the mid-plane of a box's thinnest side or a
        triangle's plane, else where it is nearest the solid's centre (planes: the probe's path stays on one side)."""
        world = self.world
        p0 = probe_centres(world, start)[contacts.probe]
        p1 = probe_centres(world, end)[contacts.probe]
        c0, c1 = np.zeros_like(p0), np.zeros_like(p0)
        axis = np.zeros_like(p0)  # the normal of the plane crossed, where there is one
        kind, index = contacts.solid_kind, contacts.solid_index
        statics, later = world.statics_at(start.t), world.statics_at(end.t)  # colliders on keyframes move too
        spheres = kind == BODY_SPHERE
        c0[spheres] = probe_centres(world, start)[index[spheres]]
        c1[spheres] = probe_centres(world, end)[index[spheres]]
        for kinds, body in (((STATIC_BOX, STATIC_BOX_FACE), False), ((BODY_BOX, BODY_BOX_FACE), True)):
            chosen = np.isin(kind, kinds)
            if not chosen.any():
                continue
            box = np.where(kind[chosen] == kinds[1], index[chosen] // 6, index[chosen])
            if body:
                (centre0, rotation0), (centre1, _) = body_box_poses(world, start), body_box_poses(world, end)
                half = world.boxes.half[box]
                c0[chosen], c1[chosen], rotation = centre0[box], centre1[box], rotation0[box]
            else:
                c0[chosen], c1[chosen] = statics.box_centre[box], later.box_centre[box]
                rotation, half = statics.box_rotation[box], statics.box_half[box]
            thinnest = np.argmin(half, axis=1)
            axis[chosen] = rotation[np.arange(len(box)), :, thinnest]
        solids = np.isin(kind, (BODY_ROUND, BODY_HULL))  # towards the solid body's centre of mass
        c0[solids], c1[solids] = start.x[contacts.solid_body[solids]], end.x[contacts.solid_body[solids]]
        fixed = kind == STATIC_SPHERE
        c0[fixed], c1[fixed] = statics.sphere_centre[index[fixed]], later.sphere_centre[index[fixed]]
        triangles = kind == TRIANGLE
        if triangles.any():
            corners = statics.triangles[index[triangles]]
            c0[triangles], c1[triangles] = corners.mean(axis=1), later.triangles[index[triangles]].mean(axis=1)
            normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            axis[triangles] = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        r0, r1 = p0 - c0, p1 - c1  # the probe relative to the solid's centre, at both frames
        move = r1 - r0
        nearest = np.clip(-np.einsum("ki,ki->k", r0, move) / np.maximum(np.einsum("ki,ki->k", move, move), 1e-300),
                          0.0, 1.0)
        s0, s1 = np.einsum("ki,ki->k", r0, axis), np.einsum("ki,ki->k", r1, axis)
        crosses = s0 * s1 < 0
        nearest[crosses] = s0[crosses] / (s0[crosses] - s1[crosses])
        nearest[kind == PLANE] = 0.0
        return nearest

    def _deepest(self, contacts: Contacts, t: float, between_frames: bool) -> Overlap | None:
        """The deepest of ``contacts`` beyond its allowance, leaving out the pairs that started inside each other;
        None when there is none."""
        if contacts.count and len(self.excused):
            contacts = contacts.select(~np.isin(contact_codes(contacts), self.excused))
        if not contacts.count:
            return None
        allowance = self._allowance(contacts)
        k = int(np.argmax(-contacts.gap - allowance))
        if -contacts.gap[k] <= allowance[k]:
            return None
        kind = int(contacts.solid_kind[k])
        return Overlap(float(-contacts.gap[k]), float(allowance[k]), t, self.names[int(contacts.probe_body[k])],
                       self._solid_name(kind, int(contacts.solid_index[k]), int(contacts.solid_body[k])),
                       between_frames)

    def _deeper(self, worst: Overlap | None, contacts: Contacts, t: float, between_frames: bool) -> Overlap | None:
        """``worst``, or the deepest of ``contacts`` when that is deeper."""
        deepest = self._deepest(contacts, t, between_frames)
        return deepest if deepest is not None and (worst is None or deepest.depth > worst.depth) else worst
