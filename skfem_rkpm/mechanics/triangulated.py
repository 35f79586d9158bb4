"""A rigid tool given as a triangulated surface (from CAD, STL, gmsh).

Exact closest points on the triangles (face, edge and vertex regions) with
the inside/outside sign taken from angle-weighted pseudo-normals at edges
and vertices (Bærentzen & Aanæs 2005, "Signed distance computation using
the angle weighted pseudonormal", IEEE TVCG 11(3)), so that the sign of the
gap is right next to sharp edges and corners too.  The search for the
closest triangle uses a k-d tree of the triangle centroids built once.
"""

from itertools import chain
from pathlib import Path

import numpy as np

from .surfaces import Surface, _inverse, _projector, _radial
from .tools import _floats

__all__ = ["TriangulatedSurface", "closest_points_on_triangles"]

# cell types read by from_file and the corner nodes that make triangles
_CORNERS = {"triangle": [[0, 1, 2]], "triangle6": [[0, 1, 2]], "triangle7": [[0, 1, 2]],
            "quad": [[0, 1, 2], [0, 2, 3]], "quad8": [[0, 1, 2], [0, 2, 3]],
            "quad9": [[0, 1, 2], [0, 2, 3]]}
_PAIRS_PER_BATCH = 1 << 19  # bounds the memory of one search batch (~100 MB)


class _TriangleError(ValueError):
    """A refused triangulation; ``triangles`` are the numbers of the
    triangles concerned, so that a file reader can name their cells."""

    def __init__(self, message, triangles):
        super().__init__(message)
        self.triangles = [int(k) for k in np.atleast_1d(triangles)]


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def closest_points_on_triangles(x, a, b, c):
    """Exact closest points of ``x`` on the triangles ``(a, b, c)``, row by row.

    The Voronoi regions of the vertices, edges and face are tested in turn
    (Ericson, *Real-Time Collision Detection*, 2005, Sec. 5.1.5).

    Parameters
    ----------
    x, a, b, c : ndarray (P, 3)

    Returns
    -------
    point : ndarray (P, 3)
    region : ndarray (P,) of int
        0 face, 1 edge AB, 2 edge BC, 3 edge CA, 4 vertex A, 5 vertex B,
        6 vertex C.
    """
    ab, ac, ap, bp, cp = b - a, c - a, x - a, x - b, x - c
    d1, d2, d3 = _dot(ab, ap), _dot(ac, ap), _dot(ab, bp)
    d4, d5, d6 = _dot(ac, bp), _dot(ab, cp), _dot(ac, cp)
    vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
    conditions = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3),
                  (vc <= 0) & (d1 >= 0) & (d3 <= 0), (d6 >= 0) & (d5 <= d6),
                  (vb <= 0) & (d2 >= 0) & (d6 <= 0),
                  (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
    region = np.select(conditions, [4, 5, 1, 6, 3, 2], 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_ab = np.where(region == 1, d1 / (d1 - d3), 0.0)
        s_ca = np.where(region == 3, d2 / (d2 - d6), 0.0)
        s_bc = np.where(region == 2, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0)
        total = np.where(region == 0, va + vb + vc, 1.0)
    v, w = vb / total, vc / total
    choices = [a + v[:, None] * ab + w[:, None] * ac, a + s_ab[:, None] * ab,
               b + s_bc[:, None] * (c - b), a + s_ca[:, None] * ac, a, b, c]
    point = choices[0]
    for k in range(1, 7):
        point = np.where((region == k)[:, None], choices[k], point)
    return point, region


def _merged(points, triangles):
    """Points with exact duplicates merged and unused ones dropped."""
    unique, inverse = np.unique(points, axis=0, return_inverse=True)
    triangles = inverse.reshape(-1)[triangles]
    used, compact = np.unique(triangles, return_inverse=True)
    return unique[used], compact.reshape(triangles.shape)


def _checked_input(points, triangles, where):
    pts = _floats(points, f"{where}: points", "(m, 3)")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{where}: points must have shape (m, 3), not {pts.shape}")
    bad = ~np.all(np.isfinite(pts), axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{where}: point {k} is not finite: {pts[k].tolist()}")
    tri = np.asarray(triangles)
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise ValueError(f"{where}: triangles must have shape (k, 3) with k >= 1, "
                         f"not {tri.shape}")
    if not np.issubdtype(tri.dtype, np.integer):
        raise ValueError(f"{where}: triangles must hold integer point numbers, "
                         f"not {tri.dtype}")
    out = (tri < 0) | (tri >= len(pts))
    if out.any():
        k = int(np.flatnonzero(out.any(axis=1))[0])
        raise _TriangleError(f"{where}: triangle {k} refers to points {tri[k].tolist()}, "
                             f"but the point numbers run from 0 to {len(pts) - 1}", k)
    return pts, tri.astype(np.int64)


def _check_degenerate(corners, where):
    """Refuse triangles whose corners coincide or are collinear."""
    e = corners[:, [1, 2, 0]] - corners
    longest = np.max(np.einsum("kij,kij->ki", e, e), axis=1)
    twice_area = np.linalg.norm(np.cross(e[:, 0], -e[:, 2]), axis=1)
    bad = np.flatnonzero(~(twice_area > 1e-10 * longest))
    if bad.size:
        first = ", ".join(str(k) for k in bad[:10])
        raise _TriangleError(f"{where}: {bad.size} degenerate triangle(s) (coinciding "
                             f"or collinear corners), first: {first}; triangle {bad[0]} "
                             f"has the corners {corners[bad[0]].tolist()}; remove them "
                             "or remesh", bad[:1])


def _edges(tri, points, where):
    """Unique edges (E, 2) and the edge of every triangle side (k, 3)
    (sides AB, BC, CA); refuses non-manifold edges and inconsistent
    orientation, which would make the sign of the gap meaningless."""
    k = len(tri)
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    unique, inverse, counts = np.unique(np.sort(directed, axis=1), axis=0,
                                        return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    forward = np.bincount(inverse, directed[:, 0] < directed[:, 1], len(unique))
    for bad, problem, fix in (
            (counts > 2, "is shared by more than two triangles",
             "the sign of the gap is undefined on a non-manifold surface"),
            ((counts == 2) & (forward != 1), "is run through in the same direction by "
             "its two triangles", "orient all triangles counter-clockwise seen from "
             "the body")):
        if bad.any():
            e = int(np.flatnonzero(bad)[0])
            owners = sorted({int(j % k) for j in np.flatnonzero(inverse == e)})
            ends = points[unique[e]].tolist()
            raise _TriangleError(f"{where}: the edge from {ends[0]} to {ends[1]} "
                                 f"{problem} (triangles {owners}); {fix}", owners)
    return unique, inverse.reshape(3, k).T


class TriangulatedSurface(Surface):
    """A rigid tool given by triangles: the body is on the side the
    counter-clockwise (right-hand rule) normal of the triangles points to.

    Parameters
    ----------
    points : array_like (m, 3)
        Vertices; exact duplicates are merged (as in STL files).
    triangles : array_like (k, 3) of int
        Point numbers of each triangle, counter-clockwise seen from the body.
    motion, rotation, name
        See :class:`~skfem_rkpm.mechanics.surfaces.Surface`.

    Raises
    ------
    ValueError
        Non-finite points, bad point numbers, degenerate triangles (named),
        an edge of more than two triangles or two triangles of opposite
        orientation.

    Notes
    -----
    Open surfaces are allowed: a point behind a free edge is signed by the
    normal of its triangle, like an open tool end in 2D; extend the tool
    beyond the reach of the workpiece.  On faces ``C = 0``; in the region of
    an edge with direction ``t``, ``C = s (I - t tᵀ - n nᵀ)/ρ``; in the region
    of a vertex ``C = s (I - n nᵀ)/ρ`` (``ρ = |x - x_C|``, ``s`` the sign of the
    gap).
    """

    def __init__(self, points, triangles, motion=(0.0, 0.0, 0.0), rotation=None,
                 name="surface"):
        super().__init__(motion, rotation, name)
        where = f"tool surface {self.name!r}"
        pts, tri = _merged(*_checked_input(points, triangles, where))
        corners = pts[tri]
        _check_degenerate(corners, where)
        edges, self._side_edges = _edges(tri, pts, where)
        self.points, self.triangles = pts, tri
        a, b, c = corners.transpose(1, 0, 2)
        cross = np.cross(b - a, c - a)
        self._face_normal = cross / np.linalg.norm(cross, axis=1)[:, None]
        edge_normal = np.zeros((len(edges), 3))
        np.add.at(edge_normal, self._side_edges.T.ravel(), np.tile(self._face_normal, (3, 1)))
        vertex_normal = np.zeros((len(pts), 3))
        for i in range(3):
            u, v = corners[:, (i + 1) % 3] - corners[:, i], corners[:, (i + 2) % 3] - corners[:, i]
            angle = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), _dot(u, v))
            np.add.at(vertex_normal, tri[:, i], angle[:, None] * self._face_normal)
        self._edge_normal = _normalized(edge_normal)
        self._vertex_normal = _normalized(vertex_normal)
        direction = pts[edges[:, 1]] - pts[edges[:, 0]]
        self._edge_direction = _normalized(direction)
        self._centroids = corners.mean(axis=1)
        self._reach = np.linalg.norm(corners - self._centroids[:, None], axis=2).max(axis=1)
        from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

        self._tree = cKDTree(self._centroids)
        self._scale = np.abs(pts).max() + np.ptp(pts, axis=0).max()

    @classmethod
    def from_file(cls, path, name=None, motion=(0.0, 0.0, 0.0), rotation=None):
        """The tool of a surface mesh file read with meshio (STL, OBJ, gmsh
        ``.msh``, ...); quadrilaterals are split into two triangles,
        second-order cells reduced to their corners, other cells ignored.
        Nothing in the file is executed.

        Parameters
        ----------
        path : str or Path
        name : str, optional
            Default: the file name without suffix.
        motion, rotation
            See :class:`~skfem_rkpm.mechanics.surfaces.Surface`.

        Raises
        ------
        ValueError
            The file is missing or unreadable, holds no triangles or
            quadrilaterals, or its surface is refused by the constructor;
            the message names the file.
        """
        import meshio

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"tool surface file {str(path)!r} does not exist")
        try:
            with np.errstate(over="ignore"):  # meshio's STL size check on ASCII files
                mesh = meshio.read(path)
        except Exception as error:  # meshio raises many kinds for a bad file
            raise ValueError(f"cannot read the tool surface file {str(path)!r} "
                             f"with meshio: {error}") from None
        blocks, origin, seen = [], [], {}
        for cells in mesh.cells:
            if cells.type in _CORNERS:
                corners = np.array(_CORNERS[cells.type])
                blocks.append(cells.data[:, corners].reshape(-1, 3))
                first = seen.get(cells.type, 0)
                seen[cells.type] = first + len(cells.data)
                origin += [(cells.type, first + k // len(corners))
                           for k in range(len(blocks[-1]))]
        if not blocks:
            found = sorted({cells.type for cells in mesh.cells}) or ["none"]
            raise ValueError(f"tool surface file {str(path)!r} holds no triangles or "
                             f"quadrilaterals (cell types: {', '.join(found)}); a tool "
                             "needs a surface mesh")
        points = np.asarray(mesh.points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"tool surface file {str(path)!r} has points of shape "
                             f"{points.shape}; a tool surface needs 3D points")
        name = path.stem if name is None else name
        try:
            return cls(points, np.concatenate(blocks), motion, rotation, name)
        except ValueError as error:
            cell = ""
            if isinstance(error, _TriangleError):
                cells = ", ".join(f"triangle {k}: {origin[k][0]} cell {origin[k][1]}"
                                  for k in error.triangles)
                cell = f" (in the file, counted from 0 by cell type: {cells})"
            raise ValueError(f"tool surface file {str(path)!r}: {error}{cell}") from None

    @property
    def nfeatures(self):
        return len(self.triangles)

    def _project_body(self, x):
        best = self._closest_triangles(x)
        a, b, c = self.points[self.triangles[best]].transpose(1, 0, 2)
        point, region = closest_points_on_triangles(x, a, b, c)
        return (*self._frames(x, point, region, best), best)

    def _closest_triangles(self, x):
        """The triangle holding the closest point of every row of ``x``.

        The triangle of the nearest centroid gives an upper bound ``U`` of
        the distance.  A triangle lies in the disk of its plane around its
        centroid with radius its reach (the largest centroid-to-corner
        distance), so the distance to that disk is a lower bound; only
        triangles whose centroid lies within ``U`` plus the largest reach
        can have a lower bound under ``U``, and only those with a lower bound
        under ``U`` are measured exactly.
        """
        _, first = self._tree.query(x)
        a, b, c = self.points[self.triangles[first]].transpose(1, 0, 2)
        bound = np.linalg.norm(x - closest_points_on_triangles(x, a, b, c)[0], axis=1)
        bound += 1e-12 * self._scale  # rounding of the bounds
        best, best_distance = first.copy(), np.full(len(x), np.inf)
        for rows, tris in self._candidates(x, bound + self._reach.max()):
            rows, tris = self._within(x, rows, tris, bound)
            a, b, c = self.points[self.triangles[tris]].transpose(1, 0, 2)
            distance = np.linalg.norm(x[rows] - closest_points_on_triangles(
                x[rows], a, b, c)[0], axis=1)
            order = np.lexsort((distance, rows))
            rows, tris, distance = rows[order], tris[order], distance[order]
            head = np.r_[True, rows[1:] != rows[:-1]] if rows.size else rows > 0
            rows, tris, distance = rows[head], tris[head], distance[head]
            better = distance < best_distance[rows]
            best[rows[better]], best_distance[rows[better]] = tris[better], distance[better]
        return best

    def _within(self, x, rows, tris, bound):
        """The pairs whose lower bound (the distance from ``x`` to the disk
        holding the triangle) does not exceed ``bound``."""
        v = x[rows] - self._centroids[tris]
        normal = self._face_normal[tris]
        height = _dot(v, normal)
        in_plane = np.linalg.norm(v - height[:, None] * normal, axis=1)
        outside = np.maximum(in_plane - self._reach[tris], 0.0)
        keep = height ** 2 + outside ** 2 <= bound[rows] ** 2
        return rows[keep], tris[keep]

    def _candidates(self, x, radius):
        """Batches ``(rows, triangles)`` of all pairs with the triangle's
        centroid within ``radius[row]`` of ``x[row]``, at most about
        ``_PAIRS_PER_BATCH`` pairs each (one point's pairs are never split)."""
        radius = radius * (1.0 + 1e-9)
        counts = self._tree.query_ball_point(x, radius, return_length=True)
        before = np.concatenate([[0], np.cumsum(counts)])
        start = 0
        while start < len(x):
            stop = int(np.searchsorted(before, before[start] + _PAIRS_PER_BATCH,
                                       side="right")) - 1
            stop = min(max(stop, start + 1), len(x))
            lists = self._tree.query_ball_point(x[start:stop], radius[start:stop],
                                                return_sorted=False)
            sizes = counts[start:stop]
            tris = np.fromiter(chain.from_iterable(lists), dtype=np.intp,
                               count=int(sizes.sum()))
            yield np.repeat(np.arange(start, stop), sizes), tris
            start = stop

    def _frames(self, x, point, region, tri):
        """Normal, gap and curvature from the region of the closest point;
        at an edge or vertex the normal runs from ``x_C`` to ``x``, signed by
        the angle-weighted pseudo-normal (the 3D ``_vertex_frame`` of
        :mod:`.tools`)."""
        pseudo = self._face_normal[tri].copy()
        on_edge, on_vertex = (region >= 1) & (region <= 3), region >= 4
        edge = self._side_edges[tri, np.clip(region - 1, 0, 2)]
        pseudo[on_edge] = self._edge_normal[edge[on_edge]]
        vertex = self.triangles[tri, np.clip(region - 4, 0, 2)]
        pseudo[on_vertex] = self._vertex_normal[vertex[on_vertex]]
        u, rho = _radial(x - point, pseudo)
        sign = np.where(_dot(x - point, pseudo) >= 0.0, 1.0, -1.0)
        face = region == 0
        normal = np.where(face[:, None], pseudo, sign[:, None] * u)
        gap = np.where(face, _dot(x - point, pseudo), sign * rho)
        t = self._edge_direction[edge]
        along = np.where(on_edge[:, None, None], t[:, :, None] * t[:, None, :], 0.0)
        curvature = (sign * _inverse(rho))[:, None, None] * (_projector(u) - along)
        curvature[face] = 0.0
        return point, normal, gap, curvature

    def _outline_body(self, resolution, extent):
        return self.points, self.triangles

    def _describe(self):
        return f"{len(self.triangles)} triangles, {len(self.points)} points"


def _normalized(v):
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]
