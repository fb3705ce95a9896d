"""Collision geometry: what touches (probes), what is touched (solids), and the distance between them.

Every contact is between a *probe* (a sphere of radius ≥ 0 fixed to a body: a particle, a rigid sphere, a box corner,
a sample point on a cylinder's rims, a capsule's cap centre, a mesh hull's vertex) and a *solid* (a plane, sphere,
box or triangle mesh fixed in the world; a sphere, box, cylinder, capsule or convex hull moving with a body). Box
against box is then corners against boxes both ways, and sphere against box is the sphere against the box; a
handful of vectorised signed-distance functions covers every pair (:mod:`animbatch.sim.contact.hulls` has the
hulls').

A box corner against another box is measured to the face that the two boxes' separating axis picks (the face axis
of least overlap, :func:`separating_direction`), not to the nearest face: when a box rests on another with edges
flush, its corners lie on the other box's side faces as much as on its top, and the nearest face would push them
sideways. Corners outside that face's extent fall back to the plain distance to the box.

What probes miss, edges crossing edges and the sides of cylinders and capsules, is found by
:mod:`animbatch.sim.contact.hulls` (boxes and mesh hulls) and :mod:`~animbatch.sim.contact.sides`.

Signed distances are positive outside, with ``normal`` the outward unit normal of the solid at the closest point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def to_plane(points: np.ndarray, point: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance [m] (K,) of points (K, 3) to a plane, and its unit normal broadcast to (K, 3)."""
    return (points - point) @ normal, np.broadcast_to(normal, points.shape)


def to_sphere(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points (K, 3) to spheres (K, 3), (K,), and outward normals (K, 3)."""
    offset = points - centres
    length = np.sqrt(np.einsum("ij,ij->i", offset, offset))
    normal = np.divide(offset, length[:, None], out=np.tile([0.0, 1.0, 0.0], (len(points), 1)),
                       where=length[:, None] > 1e-12)
    return length - radii, normal


def to_box(points: np.ndarray, centres: np.ndarray, rotations: np.ndarray, halves: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points (K, 3) to boxes (centres (K, 3), rotations (K, 3, 3) box-to-world, half sides
    (K, 3)), and outward normals. Inside a box, the normal is that of the nearest face."""
    local = np.einsum("kji,kj->ki", rotations, points - centres)  # Rᵀ (p - c)
    clamped = np.clip(local, -halves, halves)
    outside = local - clamped
    distance = np.sqrt(np.einsum("ij,ij->i", outside, outside))
    is_outside = distance > 1e-12
    normal_local = np.divide(outside, distance[:, None], out=np.zeros_like(outside), where=is_outside[:, None])
    # inside: leave through the nearest face
    depth = halves - np.abs(local)  # (K, 3) distance to each pair of faces
    axis = np.argmin(depth, axis=1)
    rows = np.arange(len(points))
    inside_normal = np.zeros_like(local)
    inside_normal[rows, axis] = np.where(local[rows, axis] >= 0, 1.0, -1.0)
    normal_local = np.where(is_outside[:, None], normal_local, inside_normal)
    signed = np.where(is_outside, distance, -depth[rows, axis])
    return signed, np.einsum("kij,kj->ki", rotations, normal_local)


def separating_direction(centre_a: np.ndarray, rotation_a: np.ndarray, half_a: np.ndarray, centre_b: np.ndarray,
                         rotation_b: np.ndarray, half_b: np.ndarray) -> np.ndarray:
    """Unit directions (K, 3) from boxes b towards boxes a along the face axis (of either box) on which they overlap
    least, or are farthest apart: the separating axis test over the six face normals. Boxes are given as centres
    (K, 3), rotations (K, 3, 3) box-to-world and half sides (K, 3)."""
    axes = np.concatenate([np.swapaxes(rotation_a, 1, 2), np.swapaxes(rotation_b, 1, 2)], axis=1)  # (K, 6, 3)
    reach = (np.einsum("kmj,kj->km", np.abs(np.einsum("kmi,kij->kmj", axes, rotation_a)), half_a)
             + np.einsum("kmj,kj->km", np.abs(np.einsum("kmi,kij->kmj", axes, rotation_b)), half_b))
    along = np.einsum("kmi,ki->km", axes, centre_a - centre_b)
    best = np.argmin(reach - np.abs(along), axis=1)
    rows = np.arange(len(best))
    return axes[rows, best] * np.where(along[rows, best] >= 0, 1.0, -1.0)[:, None]


def to_box_face(points: np.ndarray, centres: np.ndarray, rotations: np.ndarray, halves: np.ndarray,
                directions: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Signed distances (K,) of points to the face of each box whose outward normal is closest to ``directions``
    (K, 3), those normals (K, 3), the faces (K,) numbered ``2 axis + (1 if the + face)``, and whether each point
    lies within its face's extent, to ``tolerance`` [m] (elsewhere the face's plane is not the box)."""
    local_direction = np.einsum("kji,kj->ki", rotations, directions)
    axis = np.argmax(np.abs(local_direction), axis=1)
    rows = np.arange(len(points))
    positive = local_direction[rows, axis] >= 0
    local = np.einsum("kji,kj->ki", rotations, points - centres)
    distance = np.where(positive, local[rows, axis], -local[rows, axis]) - halves[rows, axis]
    lateral = np.abs(local) - halves
    lateral[rows, axis] = -np.inf
    normal = rotations[rows, :, axis] * np.where(positive, 1.0, -1.0)[:, None]
    return distance, normal, 2 * axis + positive, np.all(lateral <= tolerance, axis=1)


def to_face_plane(points: np.ndarray, centres: np.ndarray, rotations: np.ndarray, halves: np.ndarray,
                  faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (K,) of points to the planes of given box faces (numbered as in :func:`to_box_face`), and
    their outward normals (K, 3): for following a face contact once it has been found."""
    axis, sign = faces // 2, np.where(faces % 2 == 1, 1.0, -1.0)
    rows = np.arange(len(points))
    normal = rotations[rows, :, axis] * sign[:, None]
    return np.einsum("ki,ki->k", points - centres, normal) - halves[rows, axis], normal


def to_triangles(points: np.ndarray, triangles: np.ndarray, sides: np.ndarray | None = None,
                 depth: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Distance of points (K, 3) to triangles (K, 3, 3) and the unit direction from the closest point to each point
    (the triangle's normal, oriented towards the point, when the point lies on it).

    Without ``sides`` the distance is unsigned: a triangle is solid from both faces. That lets a point probe (a box
    corner, a hull's vertex) through a mesh once it sinks a hair past a face, for it is then measured from the far
    side. With ``sides`` (K, 3), points on the side of each triangle where the point belongs (its body's centre of
    mass), a point up to ``depth`` [m] (K,) past the triangle's plane is read as having sunk in:
    - over the face, its distance is negative and its normal the face's, towards its side: it is pushed back out;
    - beside an edge or a corner, there is no contact (inf): the triangle whose face it is over holds it, and the
      edge of a flat neighbour must not push it sideways.
    Points further past are taken to be on the other side, as without ``sides`` (a body overhanging the side of a
    mesh block is beyond that side's plane, not in it).

    Closest point on a triangle after Ericson, "Real-Time Collision Detection", 5.1.5, vectorised over K.
    """
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = points - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = points - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = 1.0 / (va + vb + vc)
        closest = a + ab * (vb * denominator)[:, None] + ac * (vc * denominator)[:, None]  # inside the face
        edge_ab = a + ab * (d1 / (d1 - d3))[:, None]
        edge_ac = a + ac * (d2 / (d2 - d6))[:, None]
        edge_bc = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None]
    regions = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), edge_ab),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), edge_ac),
        ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), edge_bc),
    ]
    decided = np.zeros(len(points), bool)
    for condition, point in regions:
        use = condition & ~decided
        closest[use] = point[use]
        decided |= use
    offset = points - closest
    distance = np.sqrt(np.einsum("ij,ij->i", offset, offset))
    face = np.cross(ab, ac)
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    height = np.einsum("ij,ij->i", face, ap)  # along the face's own normal (from its winding)
    normal = np.divide(offset, distance[:, None], out=face * np.where(height >= 0, 1.0, -1.0)[:, None],
                       where=distance[:, None] > 1e-9)
    if sides is not None:
        belongs = np.einsum("ij,ij->i", face, sides - a)
        sunk = (belongs * height <= 0) & (belongs != 0) & (np.abs(height) <= depth)
        over_face = sunk & ~decided
        distance[over_face] = -np.abs(height[over_face])
        normal[over_face] = np.sign(belongs[over_face])[:, None] * face[over_face]
        distance[sunk & decided] = np.inf
    return distance, normal


def to_round(points: np.ndarray, centres: np.ndarray, axes: np.ndarray, half_lengths: np.ndarray,
             radii: np.ndarray, rounded: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points (K, 3) to solids round about an axis: cylinders (flat ends) or capsules
    (``rounded``: hemispherical ends), each given by its centre (K, 3), unit axis (K, 3), the half length of its
    straight part (K,) and radius (K,); and outward normals (K, 3). Exact for both.

    A capsule is every point within ``r`` of its axis segment. For a cylinder, with ``a`` the point's coordinate
    along the axis and ``ρ`` its distance from it, ``dρ = ρ - r`` and ``da = |a| - h``: outside both, the distance
    is to the rim, ``√(dρ² + da²)``; outside one, to the side or the end face; inside, the nearer of the two."""
    offset = points - centres
    along = np.einsum("ij,ij->i", offset, axes)
    radial = offset - along[:, None] * axes
    rho = np.sqrt(np.einsum("ij,ij->i", radial, radial))
    # across the axis from a point on it: any direction across will do
    helper = np.where(np.abs(axes[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    fallback = np.cross(axes, helper)
    fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
    unit_radial = np.divide(radial, rho[:, None], out=fallback.copy(), where=rho[:, None] > 1e-12)
    end = np.sign(along)[:, None] * axes
    end = np.where(np.abs(along)[:, None] > 0, end, axes)
    d_rho, d_along = rho - radii, np.abs(along) - half_lengths
    rim = np.hypot(np.maximum(d_rho, 0.0), np.maximum(d_along, 0.0))
    rim_normal = (np.maximum(d_rho, 0.0)[:, None] * unit_radial + np.maximum(d_along, 0.0)[:, None] * end)
    rim_normal = np.divide(rim_normal, rim[:, None], out=np.zeros_like(rim_normal), where=rim[:, None] > 0)
    inside_normal = np.where((d_rho >= d_along)[:, None], unit_radial, end)
    distance = np.where(rim > 0, rim, np.maximum(d_rho, d_along))
    normal = np.where((rim > 0)[:, None], rim_normal, inside_normal)
    # capsules: from the nearest point of the axis segment
    nearest = centres + np.clip(along, -half_lengths, half_lengths)[:, None] * axes
    capsule_distance, capsule_normal = to_sphere(points, nearest, radii)
    capsule_normal = np.where((np.abs(along) <= half_lengths)[:, None] & (rho <= 1e-12)[:, None], fallback,
                              capsule_normal)
    return (np.where(rounded, capsule_distance, distance),
            np.where(rounded[:, None], capsule_normal, normal))


def round_distance(points: np.ndarray, centres: np.ndarray, axes: np.ndarray, half_lengths: np.ndarray,
                   radii: np.ndarray, rounded: np.ndarray) -> np.ndarray:
    """The signed distance of :func:`to_round` alone (K,), without normals: for searches that look at many
    points."""
    offset = points - centres
    along = np.einsum("ij,ij->i", offset, axes)
    rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", offset, offset) - along * along, 0.0))
    d_rho, d_along = rho - radii, np.abs(along) - half_lengths
    flat = np.where((d_rho > 0) & (d_along > 0), np.hypot(d_rho, d_along), np.maximum(d_rho, d_along))
    capsule = np.hypot(rho, np.maximum(d_along, 0.0)) - radii
    return np.where(rounded, capsule, flat)


def segment_distance(start_a: np.ndarray, along_a: np.ndarray, start_b: np.ndarray, along_b: np.ndarray
                     ) -> np.ndarray:
    """Distance [m] (K,) between segments ``start + s along``, s in [0, 1] (K, 3 each; non-zero lengths), after
    Ericson, "Real-Time Collision Detection", 5.1.9, vectorised."""
    return segment_closest(start_a, along_a, start_b, along_b)[0]


def segment_closest(start_a: np.ndarray, along_a: np.ndarray, start_b: np.ndarray, along_b: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`segment_distance`'s distance (K,) [m], and the parameters s and t (K,) of the closest points on
    segments a and b (for parallel segments, one pair of closest points of many)."""
    between = start_a - start_b
    aa, ee = np.einsum("ij,ij->i", along_a, along_a), np.einsum("ij,ij->i", along_b, along_b)
    bb = np.einsum("ij,ij->i", along_a, along_b)
    cc, ff = np.einsum("ij,ij->i", along_a, between), np.einsum("ij,ij->i", along_b, between)
    denominator = aa * ee - bb * bb
    s = np.where(denominator > 1e-12 * aa * ee, np.clip((bb * ff - cc * ee) / np.where(denominator > 0,
                                                                                       denominator, 1.0), 0, 1), 0.0)
    t = (bb * s + ff) / ee
    s = np.where(t < 0, np.clip(-cc / aa, 0, 1), np.where(t > 1, np.clip((bb - cc) / aa, 0, 1), s))
    t = np.clip(t, 0, 1)
    return np.linalg.norm(start_a + s[:, None] * along_a - start_b - t[:, None] * along_b, axis=1), s, t


@dataclass(frozen=True, eq=False)
class Probes:
    """Spheres attached to bodies: ``owner`` (Q,) body (point) index, ``offset`` (Q, 3) centre in body axes from the
    centre of mass, ``radius`` (Q,) (0 for corner and surface points), ``box`` (Q,) the body box (index into
    :class:`BodyBoxes`) whose corner the probe is, or -1."""

    owner: np.ndarray
    offset: np.ndarray
    radius: np.ndarray
    box: np.ndarray

    @property
    def count(self) -> int:
        return len(self.owner)


@dataclass(frozen=True, eq=False)
class BodyCylinders:
    """Solids round about an axis moving with bodies: cylinders and rods, and capsules (``rounded`` (C,) bool):
    ``owner`` (C,), ``offset`` (C, 3) centre and ``axis`` (C, 3) unit axis in body axes from the centre of mass,
    ``half_length`` (C,) of the straight part and ``radius`` (C,) [m]."""

    owner: np.ndarray
    offset: np.ndarray
    axis: np.ndarray
    half_length: np.ndarray
    radius: np.ndarray
    rounded: np.ndarray

    @property
    def count(self) -> int:
        return len(self.owner)


def cylinder_support(centre: np.ndarray, axis: np.ndarray, half_length: np.ndarray, radius: np.ndarray,
                     direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points (C, 3) of cylinders (``centre`` (C, 3), unit ``axis`` (C, 3), ``half_length`` and ``radius`` (C,))
    farthest along ``direction`` (3,): on the rim of the end that way, at the radius along the direction's part
    across the axis; and whether each is one point (C,) bool: not when the direction is along the axis (a whole end
    face is farthest, and its rim probes hold that contact)."""
    along = axis @ direction
    across = direction - along[:, None] * axis
    size = np.linalg.norm(across, axis=1)
    single = size >= 1e-9 * max(1.0, float(np.linalg.norm(direction)))
    unit = across / np.where(single, size, 1.0)[:, None]
    return (centre + (np.sign(along) * half_length)[:, None] * axis + radius[:, None] * unit), single


@dataclass(frozen=True, eq=False)
class BodyBoxes:
    """Boxes moving with bodies: ``owner`` (X,), ``offset`` (X, 3) and ``rotation`` (X, 3, 3) in body axes from the
    centre of mass, ``half`` (X, 3) half side lengths."""

    owner: np.ndarray
    offset: np.ndarray
    rotation: np.ndarray
    half: np.ndarray

    @property
    def count(self) -> int:
        return len(self.owner)


@dataclass(frozen=True, eq=False)
class StaticColliders:
    """Fixed obstacles, by kind; ``*_material`` are indices into the material table.

    Planes: ``plane_point``/``plane_normal`` (L, 3). Spheres: ``sphere_centre`` (S, 3), ``sphere_radius`` (S,).
    Boxes: ``box_centre`` (X, 3), ``box_rotation`` (X, 3, 3), ``box_half`` (X, 3). Triangles of all meshes:
    ``triangles`` (T, 3, 3) with ``triangle_material`` (T,).
    """

    plane_point: np.ndarray
    plane_normal: np.ndarray
    plane_material: np.ndarray
    sphere_centre: np.ndarray
    sphere_radius: np.ndarray
    sphere_material: np.ndarray
    box_centre: np.ndarray
    box_rotation: np.ndarray
    box_half: np.ndarray
    box_material: np.ndarray
    triangles: np.ndarray
    triangle_material: np.ndarray

    @classmethod
    def empty(cls) -> StaticColliders:
        z3, z, zi = np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.intp)
        return cls(z3, z3, zi, z3, z, zi, z3, np.zeros((0, 3, 3)), z3, zi, np.zeros((0, 3, 3)), zi)

    @property
    def count(self) -> int:
        return len(self.plane_point) + len(self.sphere_centre) + len(self.box_centre) + len(self.triangles)
