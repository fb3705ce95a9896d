"""The shape of spring meshes: vertices, triangles, springs by family, hinges and lumped masses.

A deformable body is a set of point masses (its vertices) joined by springs, as in the lecture notes' "spring mesh":
each vertex is a point mass, each edge a spring-damper, diagonal springs add rigidity, and "angular" springs connect
every other mass point. This module only builds the topology, in the body's own coordinates; nothing here moves.

Families of springs (each an array of vertex pairs (K, 2)):

* ``structural``: the edges (grid rows and columns; a mesh's triangle edges; a lattice's axis neighbours);
* ``shear``: diagonals (both diagonals of each grid square; a lattice's face and body diagonals). A triangle mesh has
  none: its edges already triangulate every face, so they resist shear;
* ``bend``: springs to the vertex after next (grid and lattice rows); for a triangle mesh, between the two vertices
  opposite each interior edge ("flip" springs).

Hinges (H, 4) ``[a, b, c, d]``: the interior edges ``a–b`` of a surface with the vertices ``c`` and ``d`` opposite
it in its two triangles, for dihedral angle springs. Triangles are oriented so that ``(b - a) × (c - a)`` of the
first triangle points along the surface normal.

Vertex weights: the area [m²] (surfaces) or volume [m³] (lattices) each vertex stands for, lumped from the triangles
or cells around it; mass = weight × density.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

FAMILIES = ("structural", "shear", "bend")


@dataclass(frozen=True, eq=False)
class Topology:
    """Vertices (V, 3) [m] in body coordinates; surface ``triangles`` (T, 3); spring pairs by family (K, 2);
    ``hinges`` (H, 4); ``weights`` (V,) lumped area [m²] or volume [m³] per vertex; for grids and lattices the number
    of vertices along each axis (``shape``)."""

    vertices: np.ndarray
    triangles: np.ndarray
    springs: dict[str, np.ndarray]
    hinges: np.ndarray
    weights: np.ndarray
    shape: tuple[int, ...] = field(default=())

    @property
    def vertex_count(self) -> int:
        return len(self.vertices)

    @property
    def spacing(self) -> float:
        """Mean structural edge length [m] (a natural scale for collision radii)."""
        pairs = self.springs["structural"]
        if not len(pairs):
            return 0.0
        return float(np.mean(np.linalg.norm(self.vertices[pairs[:, 0]] - self.vertices[pairs[:, 1]], axis=1)))


def triangle_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area [m²] of each triangle, (T,)."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def lumped_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Each vertex's share of the surface: a third of the area of every triangle it belongs to, (V,)."""
    return np.bincount(triangles.ravel(), weights=np.repeat(triangle_areas(vertices, triangles) / 3, 3),
                       minlength=len(vertices))


def enclosed_volumes(vertices: np.ndarray, triangles: np.ndarray, owner: np.ndarray, count: int) -> np.ndarray:
    """The volume [m³] each closed surface encloses, (count,): ``V = Σ a·(b × c) / 6`` over its triangles
    ``(a, b, c)`` (positive when they wind counter-clockwise seen from outside); ``owner`` (T,) says whose
    surface each triangle belongs to."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return np.bincount(owner, weights=np.einsum("ij,ij->i", a, np.cross(b, c)) / 6, minlength=count)


def closed_surface_problem(triangles: np.ndarray) -> str | None:
    """Why a triangle list is not one closed, consistently wound surface (what pressure needs), or None: every
    edge must join exactly two triangles, which run along it in opposite directions."""
    directed = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    border = int(np.sum(counts == 1))
    if border:
        return (f"its surface is open: {border} edge{'s' if border > 1 else ''} border one triangle only (a grid "
                "cloth is always open); pressure needs a closed mesh, such as a sphere or a box of triangles")
    shared = int(np.sum(counts > 2))
    if shared:
        return f"{shared} edge{'s' if shared > 1 else ''} join more than two triangles: not one closed surface"
    same_way = len(directed) - len(np.unique(directed, axis=0))
    if same_way:
        return (f"its triangles are not wound consistently: {same_way} edge{'s' if same_way > 1 else ''} run the "
                "same way in both of their triangles. Fix the mesh's winding (most tools have 'recalculate "
                "normals')")
    return None


def unique_edges(triangles: np.ndarray) -> np.ndarray:
    """The edges of a triangle list, each once, as sorted vertex pairs (E, 2)."""
    edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(edges, axis=0)


def open_edges(triangles: np.ndarray) -> np.ndarray:
    """The edges (B, 2) that only one of ``triangles`` (T, 3) has, as sorted vertex pairs: a sheet's border (none
    for a closed surface)."""
    edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    distinct, counts = np.unique(edges, axis=0, return_counts=True)
    return distinct[counts == 1]


def hinges(triangles: np.ndarray) -> np.ndarray:
    """``[a, b, c, d]`` for every edge ``a–b`` shared by exactly two triangles, ``c`` opposite it in the first and
    ``d`` in the second; ``a, b`` follow the first triangle's winding. Edges of three or more triangles (non-manifold)
    are left out."""
    t = len(triangles)
    if t == 0:
        return np.zeros((0, 4), np.intp)
    # each triangle contributes its edges (a, b) in winding order, with the vertex c opposite
    a = triangles[:, [0, 1, 2]].ravel()
    b = triangles[:, [1, 2, 0]].ravel()
    c = triangles[:, [2, 0, 1]].ravel()
    key_low, key_high = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((key_high, key_low))
    low, high = key_low[order], key_high[order]
    same = (low[1:] == low[:-1]) & (high[1:] == high[:-1])
    # keep runs of exactly two: a pair (i, i+1) that is not part of a longer run
    run_start = np.flatnonzero(same)
    longer = np.zeros(len(same) + 2, bool)
    longer[1:-1] = same
    exactly_two = run_start[~longer[run_start] & ~longer[run_start + 2]]
    first, second = order[exactly_two], order[exactly_two + 1]
    return np.stack([a[first], b[first], c[first], c[second]], axis=1).astype(np.intp)


def grid(size: tuple[float, float], resolution: tuple[int, int]) -> Topology:
    """A rectangular sheet ``size = (width, height)`` [m] in the local x–y plane, centred on the origin, with
    ``resolution = (nx, ny)`` vertices along x and y. Vertex ``j·nx + i`` is at column i (x) and row j (y), so vertex
    0 is the bottom-left corner. Each square is split into two triangles; the normal is +z."""
    nx, ny = resolution
    width, height = size
    xs = np.linspace(-width / 2, width / 2, nx)
    ys = np.linspace(-height / 2, height / 2, ny)
    gx, gy = np.meshgrid(xs, ys)  # (ny, nx): row j, column i
    vertices = np.stack([gx.ravel(), gy.ravel(), np.zeros(nx * ny)], axis=1)
    index = np.arange(nx * ny).reshape(ny, nx)
    v00, v10 = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    v01, v11 = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    triangles = np.concatenate([np.stack([v00, v10, v11], axis=1), np.stack([v00, v11, v01], axis=1)])
    structural = np.concatenate([np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], axis=1),
                                 np.stack([index[:-1, :].ravel(), index[1:, :].ravel()], axis=1)])
    shear = np.concatenate([np.stack([v00, v11], axis=1), np.stack([v10, v01], axis=1)])
    bend = np.concatenate([np.stack([index[:, :-2].ravel(), index[:, 2:].ravel()], axis=1),
                           np.stack([index[:-2, :].ravel(), index[2:, :].ravel()], axis=1)])
    return Topology(vertices, triangles.astype(np.intp),
                    {"structural": structural, "shear": shear, "bend": bend}, hinges(triangles),
                    lumped_areas(vertices, triangles), (nx, ny))


def triangle_mesh(vertices: np.ndarray, triangles: np.ndarray) -> Topology:
    """A surface from a triangle mesh: structural springs on its edges, bend springs across its interior edges
    (between the two opposite vertices), no shear springs."""
    vertices = np.asarray(vertices, float)
    triangles = np.asarray(triangles, np.intp)
    found = hinges(triangles)
    return Topology(vertices, triangles, {"structural": unique_edges(triangles), "shear": np.zeros((0, 2), np.intp),
                                          "bend": found[:, 2:4].copy()}, found, lumped_areas(vertices, triangles))


def lattice(size: tuple[float, float, float], resolution: tuple[int, int, int]) -> Topology:
    """A block ``size = (a, b, c)`` [m] centred on the origin, filled with ``resolution = (nx, ny, nz)`` vertices along
    x, y, z. Vertex ``(k·ny + j)·nx + i`` is at (i, j, k). Springs join axis neighbours (structural), the diagonals of
    every face and cell (shear), and vertices two apart along an axis (bend). ``triangles`` cover the block's
    boundary, facing outwards (for drawing)."""
    nx, ny, nz = resolution
    axes = [np.linspace(-s / 2, s / 2, n) for s, n in zip(size, resolution)]
    gz, gy, gx = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # (nz, ny, nx)
    vertices = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    index = np.arange(nx * ny * nz).reshape(nz, ny, nx)

    def pairs(offset: tuple[int, int, int]) -> np.ndarray:
        """Vertex pairs (p, p + offset) for every vertex whose partner is inside the block; offset in (i, j, k)."""
        di, dj, dk = offset
        source = index[max(0, -dk):nz - max(0, dk), max(0, -dj):ny - max(0, dj), max(0, -di):nx - max(0, di)]
        target = index[max(0, dk):nz - max(0, -dk) or None, max(0, dj):ny - max(0, -dj) or None,
                       max(0, di):nx - max(0, -di) or None]
        return np.stack([source.ravel(), target.ravel()], axis=1)

    structural = np.concatenate([pairs(o) for o in ((1, 0, 0), (0, 1, 0), (0, 0, 1))])
    face = [(1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1)]
    body = [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]
    shear = np.concatenate([pairs(o) for o in face + body])
    bend = np.concatenate([pairs(o) for o in ((2, 0, 0), (0, 2, 0), (0, 0, 2))])
    cell = np.prod([s / (n - 1) for s, n in zip(size, resolution)])
    # each cell gives an eighth of its volume to each of its corners
    corner_cells = np.ones((nz, ny, nx))
    for axis, n in enumerate((nz, ny, nx)):
        shape = [1, 1, 1]
        shape[axis] = n
        share = np.full(n, 2.0)
        share[[0, -1]] = 1.0
        corner_cells = corner_cells * share.reshape(shape)
    weights = corner_cells.ravel() * cell / 8
    return Topology(vertices, _box_surface(index), {"structural": structural, "shear": shear, "bend": bend},
                    np.zeros((0, 4), np.intp), weights, (nx, ny, nz))


def _box_surface(index: np.ndarray) -> np.ndarray:
    """Outward-facing triangles on the six faces of a vertex block ``index`` (nz, ny, nx)."""
    faces = []

    def sheet(grid_: np.ndarray, flip: bool) -> None:
        v00, v10 = grid_[:-1, :-1].ravel(), grid_[:-1, 1:].ravel()
        v01, v11 = grid_[1:, :-1].ravel(), grid_[1:, 1:].ravel()
        first, second = np.stack([v00, v10, v11], axis=1), np.stack([v00, v11, v01], axis=1)
        if flip:
            first, second = first[:, ::-1], second[:, ::-1]
        faces.extend([first, second])

    # (rows, columns) chosen so that (column step) × (row step) points along +axis; flip for the − faces
    sheet(index[:, :, -1], False)     # +x: rows z, columns y (y × z = x)
    sheet(index[:, :, 0], True)       # −x
    sheet(index[:, -1, :].T, False)   # +y: rows x, columns z (z × x = y)
    sheet(index[:, 0, :].T, True)     # −y
    sheet(index[-1, :, :], False)     # +z: rows y, columns x (x × y = z)
    sheet(index[0, :, :], True)       # −z
    return np.concatenate(faces).astype(np.intp)
