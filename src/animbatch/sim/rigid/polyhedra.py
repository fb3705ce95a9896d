"""Closed triangle meshes: exact volume, centre of mass and inertia (divergence theorem), tessellated primitives,
and the volume and centroid of the part below a plane (for buoyancy).

Mass properties: Gauss's divergence theorem turns each volume integral ``∫ f dV`` (f = 1, x, y, z, x², …, xy, …) into a
sum over the surface triangles, exact for the polyhedron (D. Eberly, "Polyhedral Mass Properties (Revisited)", 2002).
This needs a closed surface with outward, consistently wound triangles.

Submerged part: the volume and first moment of a closed surface's part below a plane are sums of signed tetrahedra
from a point ``o`` on the plane to the surface triangles clipped to the submerged side. The cut face (the "cap") lies
in the plane through ``o``, so its tetrahedra have zero volume: the clipped triangles alone give the exact result,
for convex and non-convex shapes alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from animbatch.sim.rigid.mass_properties import MassProperties


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """``vertices`` (V, 3) [m]; ``faces`` (F, 3) vertex indices, counter-clockwise seen from outside."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def triangles(self) -> np.ndarray:
        """Corner positions per face, shape (F, 3, 3)."""
        return self.vertices[self.faces]

    def transformed(self, rotation: np.ndarray, offset: np.ndarray) -> TriangleMesh:
        return TriangleMesh(self.vertices @ rotation.T + offset, self.faces)

    def scaled(self, factors: np.ndarray) -> TriangleMesh:
        """Scale along x, y, z; a mirroring scale (odd number of negative factors) keeps faces outward."""
        factors = np.broadcast_to(np.asarray(factors, float), (3,))
        faces = self.faces[:, ::-1] if np.prod(np.sign(factors)) < 0 else self.faces
        return TriangleMesh(self.vertices * factors, faces)


def _subexpressions(w0: np.ndarray, w1: np.ndarray, w2: np.ndarray) -> tuple[np.ndarray, ...]:
    temp0 = w0 + w1
    f1 = temp0 + w2
    temp1 = w0 * w0
    temp2 = temp1 + w1 * temp0
    f2 = temp2 + w2 * f1
    f3 = w0 * temp1 + w1 * temp2 + w2 * f2
    g0 = f2 + w0 * (f1 + w0)
    g1 = f2 + w1 * (f1 + w1)
    g2 = f2 + w2 * (f1 + w2)
    return f1, f2, f3, g0, g1, g2


def volume_integrals(mesh: TriangleMesh) -> np.ndarray:
    """``∫ [1, x, y, z, x², y², z², xy, yz, zx] dV`` over the solid bounded by ``mesh`` (shape (10,))."""
    p = mesh.triangles
    x, y, z = (p[:, :, k] for k in range(3))
    d = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    f1x, f2x, f3x, g0x, g1x, g2x = _subexpressions(x[:, 0], x[:, 1], x[:, 2])
    _, f2y, f3y, g0y, g1y, g2y = _subexpressions(y[:, 0], y[:, 1], y[:, 2])
    _, f2z, f3z, g0z, g1z, g2z = _subexpressions(z[:, 0], z[:, 1], z[:, 2])
    sums = np.array([
        np.sum(d[:, 0] * f1x),
        np.sum(d[:, 0] * f2x), np.sum(d[:, 1] * f2y), np.sum(d[:, 2] * f2z),
        np.sum(d[:, 0] * f3x), np.sum(d[:, 1] * f3y), np.sum(d[:, 2] * f3z),
        np.sum(d[:, 0] * (y[:, 0] * g0x + y[:, 1] * g1x + y[:, 2] * g2x)),
        np.sum(d[:, 1] * (z[:, 0] * g0y + z[:, 1] * g1y + z[:, 2] * g2y)),
        np.sum(d[:, 2] * (x[:, 0] * g0z + x[:, 1] * g1z + x[:, 2] * g2z)),
    ])
    return sums / np.array([6, 24, 24, 24, 60, 60, 60, 120, 120, 120])


def mesh_mass_properties(mesh: TriangleMesh, *, density: float = 1.0) -> MassProperties:
    """Exact mass properties of the uniform solid bounded by a closed, outward-wound mesh."""
    integral = volume_integrals(mesh)
    volume = integral[0]
    if volume <= 0:
        raise ValueError(f"the mesh encloses a non-positive volume ({volume:.6g} m³): it is not closed, or its "
                         "triangles face inwards")
    centre = integral[1:4] / volume
    cx, cy, cz = centre
    xx, yy, zz = integral[4:7] - volume * centre**2  # ∫ x² dV about the centre of mass, etc.
    xy = integral[7] - volume * cx * cy
    yz = integral[8] - volume * cy * cz
    zx = integral[9] - volume * cz * cx
    inertia = density * np.array([[yy + zz, -xy, -zx], [-xy, xx + zz, -yz], [-zx, -yz, xx + yy]])
    return MassProperties(density * volume, volume, centre, inertia)


# ------------------------------------------------------------------------------------------------ tessellations


def box_mesh(size: np.ndarray) -> TriangleMesh:
    """Box with side lengths (a, b, c), centred on the origin (exact: 12 triangles)."""
    half = np.asarray(size, float) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5],  # x = -a/2, x = +a/2
                      [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],  # y = -b/2, y = +b/2
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])  # z = -c/2, z = +c/2
    return TriangleMesh(signs * half, faces)


def icosphere(radius: float, subdivisions: int = 3) -> TriangleMesh:
    """Sphere approximated by a subdivided icosahedron: 20·4^subdivisions triangles, vertices on the sphere."""
    t = (1 + 5**0.5) / 2
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
             (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    points = [np.array(v, float) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        midpoints: dict[tuple[int, int], int] = {}

        def midpoint(i: int, j: int) -> int:
            key = (min(i, j), max(i, j))
            if key not in midpoints:
                m = points[i] + points[j]
                points.append(m / np.linalg.norm(m))
                midpoints[key] = len(points) - 1
            return midpoints[key]

        refined = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    return TriangleMesh(np.array(points) * radius, np.array(faces))


def cylinder_mesh(radius: float, length: float, segments: int = 64) -> TriangleMesh:
    """Cylinder along z, centred on the origin: a regular ``segments``-gon prism with capped ends."""
    angles = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(segments)], axis=1)
    bottom, top = ring - [0, 0, length / 2], ring + [0, 0, length / 2]
    vertices = np.vstack([bottom, top, [[0, 0, -length / 2], [0, 0, length / 2]]])
    i = np.arange(segments)
    j = (i + 1) % segments
    side = np.vstack([np.stack([i, j, segments + j], 1), np.stack([i, segments + j, segments + i], 1)])
    caps = np.vstack([np.stack([np.full(segments, 2 * segments), j, i], 1),
                      np.stack([np.full(segments, 2 * segments + 1), segments + i, segments + j], 1)])
    return TriangleMesh(vertices, np.vstack([side, caps]))


def capsule_mesh(radius: float, length: float, segments: int = 32) -> TriangleMesh:
    """Capsule along z, ``length`` tip to tip: the convex hull of two hemispheres' rings (``segments`` around,
    ``segments // 4`` latitude rings per cap) and their poles."""
    half = length / 2 - radius
    angles = 2 * np.pi * np.arange(segments) / segments
    rings = []
    for latitude in np.linspace(0, np.pi / 2, max(segments // 4, 2), endpoint=False):
        ring = np.stack([np.cos(angles) * np.cos(latitude), np.sin(angles) * np.cos(latitude),
                         np.full(segments, np.sin(latitude))], axis=1) * radius
        rings += [ring + [0, 0, half], ring * [1, 1, -1] - [0, 0, half]]
    vertices = np.vstack([*rings, [[0, 0, half + radius], [0, 0, -half - radius]]])
    return convex_mesh(vertices)


def convex_mesh(points: np.ndarray) -> TriangleMesh:
    """The convex hull of points (V, 3) as a closed mesh, its triangles wound outwards."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    vertices = points[hull.vertices]
    renumber = np.full(len(points), -1)
    renumber[hull.vertices] = np.arange(len(hull.vertices))
    faces = renumber[hull.simplices]
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - vertices.mean(axis=0)) > 0
    faces[~outward] = faces[~outward][:, ::-1]
    return TriangleMesh(vertices, faces)


# ------------------------------------------------------------------------------------------------ below a plane


def submerged_volume_and_moment(triangles: np.ndarray, owner: np.ndarray, count: int, surface_point: np.ndarray,
                                 up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Volume [m³] and first moment ∫ x dV [m⁴] of each body's part below the plane through ``surface_point``
    with normal ``up``.

    ``triangles``: (T, 3, 3) world-space corners of the closed surfaces of all bodies; ``owner``: (T,) body index of
    each triangle; ``count``: number of bodies. Returns volume (count,) and moment (count, 3), the moment about the
    world origin (centre of buoyancy = moment / volume).
    """
    relative = triangles - surface_point  # origin on the plane: the cut face contributes nothing
    height = relative @ up  # (T, 3), negative below the surface
    under = height < 0
    submerged = under.sum(axis=1)

    pieces = [relative[submerged == 3]]
    owners = [owner[submerged == 3]]
    for k in (1, 2):
        selected = submerged == k
        if not selected.any():
            continue
        p, h, u = relative[selected], height[selected], under[selected]
        # Rotate each triangle's corners (keeping their cyclic order, hence the winding) so that the odd corner —
        # the only one under water (k = 1), or the only one above (k = 2) — comes first.
        first = np.argmax(u, axis=1) if k == 1 else np.argmin(u, axis=1)
        order = (first[:, None] + np.arange(3)) % 3
        p = np.take_along_axis(p, order[:, :, None], axis=1)
        h = np.take_along_axis(h, order, axis=1)
        a, b, c = p[:, 0], p[:, 1], p[:, 2]
        ab = a + (b - a) * (h[:, 0] / (h[:, 0] - h[:, 1]))[:, None]  # where edge a→b crosses the surface
        ca = a + (c - a) * (h[:, 0] / (h[:, 0] - h[:, 2]))[:, None]
        if k == 1:  # only a is under: the triangle (a, ab, ca)
            pieces.append(np.stack([a, ab, ca], axis=1))
            owners.append(owner[selected])
        else:  # b and c are under: the quadrilateral (ab, b, c, ca), as two triangles
            pieces += [np.stack([ab, b, c], axis=1), np.stack([ab, c, ca], axis=1)]
            owners += [owner[selected], owner[selected]]
    tris = np.concatenate(pieces)
    who = np.concatenate(owners)
    signed = np.einsum("ij,ij->i", tris[:, 0], np.cross(tris[:, 1], tris[:, 2])) / 6  # tetrahedra from the origin
    volume = np.bincount(who, weights=signed, minlength=count)
    centroids = tris.sum(axis=1) / 4  # centroid of each tetrahedron (origin, p0, p1, p2)
    moment = np.stack([np.bincount(who, weights=signed * centroids[:, k], minlength=count) for k in range(3)], axis=1)
    return volume, moment + volume[:, None] * surface_point
