"""What contact detection finds: contacts between a body's feature and a solid, and the kinds of solid.

Every contact is between a *probe* side (a probe sphere of a body, or another feature numbered past the probes: a
box edge, a cylinder's rim or side, a hull edge) and a *solid* side (a collider fixed in the world or one of a body's
solids); ``(probe, solid_kind, solid_index)`` names a contact from one step to the next (:func:`contact_codes`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

STATIC = -1  # "solid body" index of fixed colliders

# What a contact's solid is (``Contacts.solid_kind``); ``solid_index`` numbers solids within their kind. A box corner
# against a box touches one face of it (``*_BOX_FACE``, ``solid_index = 6 box + face``, see geometry.to_box_face).
PLANE, STATIC_SPHERE, STATIC_BOX, TRIANGLE, BODY_SPHERE, BODY_BOX, STATIC_BOX_FACE, BODY_BOX_FACE = range(8)
# edge–edge contacts between boxes: solid index 12 box + edge (of the box's hull, hulls.BodyHull.of_box); their
# "probe" is a number past the probes, 12 box + edge of the moving box (see hulls.edge_contacts and edge_pairs)
STATIC_EDGE, BODY_EDGE = 8, 9
# a cylinder's rim against a plane: solid index the plane (the deepest point of either rim), or past the planes, one
# end's rim (detection.rim_index, as the adaptive methods' events follow them); "probe" a number past the edge
# numbers, one per cylinder (see detection.rim_contacts and rim_pairs)
PLANE_RIM = 10
# probes against a body's round solid (cylinder, rod, capsule; solid index: the round) or convex hull (the hull)
BODY_ROUND, BODY_HULL = 11, 12
# see animbatch.sim.contact.sides (the adaptive methods' events follow these two as well): a round's side against
# another round's side (solid index: the other round) or against an edge (solid index: the edge's number in
# sides.EdgeSet), times 2 plus 0 or 1 (see sides._touching); two hulls' crossing edges (as the boxes')
SIDE_ROUND, SIDE_EDGE, HULL_EDGE = 13, 14, 15


@dataclass(frozen=True, eq=False)
class Contacts:
    """K contacts: ``probe_body``/``solid_body`` (K,) body indices (``solid_body`` is -1 for fixed colliders),
    ``point`` (K, 3) [m], ``normal`` (K, 3) unit, from the solid towards the probe, ``gap`` (K,) [m] (negative when
    overlapping), the pair's ``restitution``, ``static_friction``, ``kinetic_friction`` (K,), and which features
    touch: ``probe`` (K,) probe index, ``solid_kind`` and ``solid_index`` (K,) (see PLANE … BODY_BOX)."""

    probe_body: np.ndarray
    solid_body: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    restitution: np.ndarray
    static_friction: np.ndarray
    kinetic_friction: np.ndarray
    probe: np.ndarray
    solid_kind: np.ndarray
    solid_index: np.ndarray

    FIELDS = ("probe_body", "solid_body", "point", "normal", "gap", "restitution", "static_friction",
              "kinetic_friction", "probe", "solid_kind", "solid_index")

    @property
    def count(self) -> int:
        return len(self.gap)

    @classmethod
    def concatenate(cls, parts: list[Contacts]) -> Contacts:
        found = [p for p in parts if len(p.probe_body)]  # most searches find nothing most steps
        if len(found) == 1:  # as it is, but contiguous (a search's columns may be views; kernels take C arrays)
            return cls(*(np.ascontiguousarray(getattr(found[0], name)) for name in cls.FIELDS))
        if not found:
            z3, z, zi = np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.intp)
            return cls(zi, zi, z3, z3, z, z, z, z, zi, zi, zi)
        return cls(*(np.concatenate([getattr(p, name) for p in found]) for name in cls.FIELDS))

    def select(self, chosen: np.ndarray) -> Contacts:
        """The contacts at indices or mask ``chosen``."""
        return Contacts(*(getattr(self, name)[chosen] for name in self.FIELDS))


def contact_codes(contacts: Contacts) -> np.ndarray:
    """One int64 per contact that names its probe and solid, to find the same contact in another state."""
    return ((contacts.probe.astype(np.int64) << 40) | (contacts.solid_kind.astype(np.int64) << 32)
            | contacts.solid_index.astype(np.int64))




def make_contacts(world: Any, owner: np.ndarray, solid_body: np.ndarray, point: np.ndarray, normal: np.ndarray,
                  gap: np.ndarray, solid_material: np.ndarray, probe: np.ndarray, kind: int | np.ndarray,
                  index: np.ndarray) -> Contacts:
    """Contacts (K,) with the coefficients of their two materials (``world``: the ContactWorld, for the probe
    bodies' materials and the material table)."""
    table, a = world.materials, world.body_material[owner]
    count = len(owner)
    return Contacts(np.asarray(owner, np.intp), np.asarray(solid_body, np.intp), np.reshape(point, (count, 3)),
                    np.reshape(normal, (count, 3)), np.asarray(gap, float), table.restitution[a, solid_material],
                    table.static_friction[a, solid_material], table.kinetic_friction[a, solid_material],
                    np.asarray(probe, np.intp), np.broadcast_to(np.asarray(kind, np.intp), (count,)).copy(),
                    np.asarray(index, np.intp))
