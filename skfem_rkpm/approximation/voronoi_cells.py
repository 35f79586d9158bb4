"""Voronoi smoothing cells of the particles, clipped to the domain (2D SCNI).

The cell of particle ``L`` is the part of the domain closer to ``X_L`` than
to any other particle (Chen, Wu, Yoon & You 2001, IJNME 50, Sec. 4: Voronoi
cells), ``Ω_L = V_L ∩ Ω`` with the domain ``Ω`` the union of the mesh
cells.  The mesh is split into triangles (a quadrilateral along a diagonal
that leaves both halves positive); every triangle ``T`` is cut by the
Voronoi diagram into convex *pieces* ``V_L ∩ T``, found by clipping ``T``
with the bisectors ``(x - (X_L + X_K)/2) · (X_K - X_L) ≤ 0`` of ``L`` and its
Delaunay neighbours ``K`` (the half-planes that bound ``V_L``).  The pieces
tile every triangle, so the cells tile the domain and the integration
constraint of SCNI holds (see :mod:`.nodal_integration`).

Every piece is stored as the triangles between its centre (the mean of its
corners) and its sides, as quadrilaterals with a repeated corner (the
layout of :class:`~.nodal_integration.SmoothingCells`): a corner on a
straight side (where a bisector meets a mesh edge) gives no triangle of
zero area.  The corners that are computed (all but the mesh vertices) are
rounded to a grid of 2^-40 of the domain's extent (at least 64 units in the
last place of the coordinates), so that the pieces on
either side of a Voronoi edge or a mesh edge compute the same end points;
a side met twice is stored once, with opposite signs on its two triangles.
The sides inside a cell (spokes, mesh edges within a Voronoi cell) then
cancel exactly when the pieces of a cell are merged, and neighbouring cells
share their common boundary point for point.

Boundary loads are integrated on every boundary edge with its halves
(:func:`~.nodal_integration.boundary_rule`); a Voronoi cell boundary meets a
boundary edge at its midpoint unless a third particle lies inside the circle
on that edge as diameter (an obtuse angle opposite the boundary edge): there
the loads and the cells see different points, and the patch test with
tractions holds to the accuracy of the rule instead of round-off.
"""

import numpy as np
import scipy.sparse as sp

__all__ = ["voronoi_cells", "mesh_triangles", "clip_by_bisectors"]

#: pieces with less area than this fraction of their triangle are dropped
#: (a Voronoi cell that only touches a triangle at a corner or an edge)
TINY_PIECE = 1e-12
#: computed corners are rounded to this fraction of the domain's extent, so
#: that the two pieces on a side see the same end points (2^-40, 9e-13)
SNAP = 2.0**-40


def mesh_triangles(mesh):
    """The mesh cells as counter-clockwise triangles, shape (3, ntriangles).

    Quadrilaterals are split along the diagonal that leaves both halves with
    positive area (either diagonal of a convex quadrilateral, the one at the
    reflex corner otherwise)."""
    p, t = mesh.p, mesh.t
    if t.shape[0] == 3:
        triangles = t.copy()
    elif t.shape[0] == 4:
        first = np.vstack([t[[0, 1, 2]], t[[0, 2, 3]]])   # diagonal 0-2
        second = np.vstack([t[[0, 1, 3]], t[[1, 2, 3]]])  # diagonal 1-3
        area = lambda tri: _signed_area(p, tri)  # noqa: E731
        ok = ((np.sign(area(first[:3])) == np.sign(area(first[3:])))
              & (np.abs(area(first[:3])) > 0) & (np.abs(area(first[3:])) > 0))
        halves = np.where(ok, first, second)
        triangles = np.hstack([halves[:3], halves[3:]])
    else:
        raise ValueError(f"Voronoi smoothing cells need a triangle or quadrilateral mesh, "
                         f"not cells of {t.shape[0]} vertices")
    signed = _signed_area(p, triangles)
    bad = np.flatnonzero(~(np.abs(signed) > 0))
    if bad.size:
        raise ValueError(f"mesh cell with vertices {triangles[:, bad[0]].tolist()} has a "
                         "part of zero area: it cannot carry smoothing cells; remove the "
                         "degenerate cells from the mesh")
    triangles[:, signed < 0] = triangles[::-1, signed < 0]
    return triangles


def _signed_area(p, tri):
    a, b, c = (p[:, tri[j]] for j in range(3))
    return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))


def clip_by_bisectors(polygons, counts, particles, others):
    """The part of every convex polygon closer to its particle than to its
    other point: one Sutherland-Hodgman step for many polygons at once.

    Parameters
    ----------
    polygons : ndarray, shape (m, V, 2)
        Counter-clockwise corners, the first ``counts[i]`` of row ``i`` used.
    counts : ndarray, shape (m,)
    particles, others : ndarray, shape (m, 2)
        Polygon ``i`` keeps the half-plane
        ``(x - (particles[i] + others[i]) / 2) · (others[i] - particles[i]) ≤ 0``.

    Returns
    -------
    polygons : ndarray, shape (m, V + 1, 2)
    counts : ndarray, shape (m,)
        0 where nothing is left.
    """
    m, V = polygons.shape[:2]
    j = np.arange(V)
    valid = j < counts[:, None]
    normal = others - particles
    level = np.einsum("mvk,mk->mv", polygons - 0.5 * (particles + others)[:, None], normal)
    level = np.where(valid, level, 0.0)
    after = (j + 1) % np.maximum(counts, 1)[:, None]
    following = np.take_along_axis(polygons, after[..., None], axis=1)
    level_after = np.take_along_axis(level, after, axis=1)
    keep = valid & (level <= 0)
    cross = valid & (((level < 0) & (level_after > 0)) | ((level > 0) & (level_after < 0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(cross, level / (level - level_after), 0.0)
    crossing = polygons + s[..., None] * (following - polygons)
    emitted = keep.astype(int) + cross
    slot = np.cumsum(emitted, axis=1) - emitted
    out = np.zeros((m, V + 1, 2))
    r, c = np.nonzero(keep)
    out[r, slot[r, c]] = polygons[r, c]
    r, c = np.nonzero(cross)
    out[r, slot[r, c] + keep[r, c]] = crossing[r, c]
    return out, emitted.sum(axis=1)


def _delaunay_neighbours(points):
    """The Delaunay neighbours of every point, shape (npoints, max degree),
    padded with -1."""
    from scipy.spatial import Delaunay  # 0.1-0.15 s CPU to import: not on FEM runs

    n = points.shape[0]
    if n < 3:
        indptr = np.arange(n + 1) * (n - 1)
        indices = np.array([k for i in range(n) for k in range(n) if k != i], dtype=int)
    else:
        indptr, indices = Delaunay(points, qhull_options="QJ Qbb Qc").vertex_neighbor_vertices
    degree = np.diff(indptr)
    table = np.full((n, max(int(degree.max(initial=0)), 1)), -1)
    table[np.repeat(np.arange(n), degree), np.arange(len(indices)) - np.repeat(indptr[:-1],
                                                                             degree)] = indices
    return table


def voronoi_cells(mesh):
    """The Voronoi cells of a 2D mesh's vertices clipped to its cells.

    Parameters
    ----------
    mesh : skfem.MeshTri or skfem.MeshQuad
        Its vertices are the particles.

    Returns
    -------
    dict with ``owner`` (npieces,), ``corners`` (2, npieces, 4: the
    triangles centre - side with their last corner repeated), ``area`` (npieces,),
    ``ends`` (2, 2, nsides: start and end of every distinct side) and
    ``incidence`` (npieces x nsides, ±1), the fields of
    :class:`~.nodal_integration.SmoothingCells`.

    Raises
    ------
    ValueError
        For other meshes, degenerate cells, or a particle whose cell is
        empty (it lies outside the cells; names the particle).
    """
    if mesh.dim() != 2:
        raise ValueError("Voronoi smoothing cells are built in 2D; for 3D meshes use "
                         "the median dual cells (smoothing='median_dual')")
    p = mesh.p[:, :mesh.nvertices]
    points = p.T
    triangles = mesh_triangles(mesh)
    neighbours = _delaunay_neighbours(points)
    corners = p[:, triangles]  # (2, 3, ntri)
    tri, particle = _candidates(corners, points)
    polygons = np.zeros((len(tri), 3 + neighbours.shape[1], 2))
    polygons[:, :3] = corners[:, :, tri].transpose(2, 1, 0)
    counts = np.full(len(tri), 3)
    for k in range(neighbours.shape[1]):
        other = neighbours[particle, k]
        rows = np.flatnonzero((other >= 0) & (counts > 0))
        width = 3 + k
        clipped, counts[rows] = clip_by_bisectors(polygons[rows, :width], counts[rows],
                                                  points[particle[rows]], points[other[rows]])
        polygons[rows, :width + 1] = clipped
    # far from the origin the grid is at least a few units in the last place
    grid = max(SNAP * np.ptp(p, axis=1).max(), 64 * np.spacing(np.abs(p).max()))
    area = _polygon_areas(polygons, counts)
    floor = TINY_PIECE * np.abs(_polygon_areas(corners.transpose(2, 1, 0), np.full(
        corners.shape[2], 3)))
    kept = np.flatnonzero((counts >= 3) & (area > floor[tri]))
    polygons = _snapped(polygons[kept], corners[:, :, tri[kept]].transpose(2, 1, 0), grid)
    owner, pieces = _piece_triangles(polygons, counts[kept], particle[kept])
    empty = np.setdiff1d(np.arange(points.shape[0]), owner)
    if empty.size:
        I = empty[0]
        raise ValueError(f"particle {I} at ({p[0, I]:.6g}, {p[1, I]:.6g}) has an empty "
                         "Voronoi cell in the mesh: it is not inside the cells of the mesh")
    ends, incidence = _distinct_sides(pieces)
    return {"owner": owner,
            "corners": np.concatenate([pieces, pieces[:, 2:]], axis=1).transpose(2, 0, 1),
            "area": _polygon_areas(pieces, np.full(len(pieces), 3)),
            "ends": ends, "incidence": incidence}


def _piece_triangles(polygons, counts, particles):
    """Convex polygons (m, V, 2) with ``counts`` corners cut into the
    triangles centre - side (the centre: the mean of the corners, inside);
    sides of zero length (corners that rounding made equal) give none.
    Returns the owners (nf,) and corners (nf, 3, 2), counter-clockwise."""
    j = np.arange(polygons.shape[1])
    used = j < counts[:, None]
    centre = np.sum(np.where(used[..., None], polygons, 0.0), axis=1) / counts[:, None]
    following = np.take_along_axis(polygons, ((j + 1) % counts[:, None])[..., None], axis=1)
    rows, cols = np.nonzero(used & np.any(polygons != following, axis=2))
    triangles = np.stack([centre[rows], polygons[rows, cols], following[rows, cols]], axis=1)
    return particles[rows], triangles


def _distinct_sides(triangles):
    """The distinct sides of triangles (nf, 3, 2) and their incidence.

    Returns ``ends`` (2, 2, nsides), start and end point of every side, and
    the (nf x nsides) incidence: +1 where the triangle's counter-clockwise
    boundary runs along the side, -1 against it.  Sides with the same end
    points (bit for bit) are one side."""
    starts = triangles.reshape(-1, 2)
    ends = triangles[:, [1, 2, 0]].reshape(-1, 2)
    backwards = (starts[:, 0] > ends[:, 0]) | ((starts[:, 0] == ends[:, 0])
                                                & (starts[:, 1] > ends[:, 1]))
    first = np.where(backwards[:, None], ends, starts)
    second = np.where(backwards[:, None], starts, ends)
    sides, index = np.unique(np.hstack([first, second]), axis=0, return_inverse=True)
    incidence = sp.csr_matrix((np.where(backwards, -1.0, 1.0),
                               (np.repeat(np.arange(len(triangles)), 3), index.ravel())),
                              shape=(len(triangles), len(sides)))
    return sides.reshape(-1, 2, 2).transpose(2, 1, 0), incidence


def _candidates(corners, points):
    """Pairs (triangle, particle) whose Voronoi cell may meet the triangle.

    A point ``x`` of a triangle is owned by a particle no farther than the
    nearest of the triangle's corners (particles themselves), and that is at
    most ``ρ`` away: the circumradius ``R`` for a triangle without an obtuse
    angle (the circumcentre is inside; the kites corner - side midpoints -
    circumcentre tile the triangle and lie within ``R`` of their corner),
    the longest side (the diameter of the triangle) otherwise.  So only
    particles within ``ρ`` of the triangle qualify: those within ``ρ`` plus
    the largest corner distance of the centroid, then filtered by their
    distance to the triangle itself."""
    from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

    a, b, c = (corners[:, j] for j in range(3))
    sides = np.stack([np.linalg.norm(b - c, axis=0), np.linalg.norm(c - a, axis=0),
                      np.linalg.norm(a - b, axis=0)])
    twice_area = np.abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
    longest = sides.max(axis=0)
    obtuse = 2 * longest**2 > np.sum(sides**2, axis=0)
    rho = np.where(obtuse, longest, sides.prod(axis=0) / (2.0 * twice_area))
    centroid = corners.mean(axis=1)
    spread = np.linalg.norm(corners - centroid[:, None], axis=0).max(axis=0)
    near = cKDTree(points).query_ball_point(centroid.T, (rho + spread) * (1 + 1e-9))
    tri = np.repeat(np.arange(len(near)), [len(n) for n in near])
    particle = np.concatenate(near).astype(int)
    close = _distance_to_triangle(points[particle], corners[:, :, tri]) <= rho[tri] * (1 + 1e-9)
    return tri[close], particle[close]


def _distance_to_triangle(x, corners):
    """Distance of points x (m, 2) to the triangles corners (2, 3, m) (0 inside)."""
    x = x.T
    distance = np.full(x.shape[1], np.inf)
    inside = np.ones(x.shape[1], dtype=bool)
    for j in range(3):
        a, b = corners[:, j], corners[:, (j + 1) % 3]
        edge = b - a
        t = np.clip(np.sum((x - a) * edge, axis=0) / np.sum(edge * edge, axis=0), 0.0, 1.0)
        distance = np.minimum(distance, np.linalg.norm(x - a - t * edge, axis=0))
        inside &= edge[0] * (x[1] - a[1]) - edge[1] * (x[0] - a[0]) >= 0
    return np.where(inside, 0.0, distance)


def _polygon_areas(polygons, counts):
    """Shoelace areas of padded polygons (m, V, 2) with ``counts`` corners."""
    j = np.arange(polygons.shape[1])
    after = (j + 1) % np.maximum(counts, 1)[:, None]
    following = np.take_along_axis(polygons, after[..., None], axis=1)
    cross = polygons[..., 0] * following[..., 1] - following[..., 0] * polygons[..., 1]
    return 0.5 * np.sum(np.where(j < counts[:, None], cross, 0.0), axis=1)


def _snapped(polygons, triangles, grid):
    """The corners of the pieces (m, V, 2) rounded to multiples of ``grid``,
    except their triangles' own corners (m, 3, 2), the mesh vertices, kept
    exactly: a point that two pieces compute with different round-off
    becomes the same point."""
    own = np.any(np.all(polygons[:, :, None] == triangles[:, None], axis=3), axis=2)
    return np.where(own[..., None], polygons, np.round(polygons / grid) * grid)
