"""Median dual cells of 3D meshes (tetrahedra, hexahedra) for nodal integration.

Every mesh cell ``c`` is cut into one *piece* per vertex ``v``: the
hexahedron with corners ``v``, the midpoints of the three edges at ``v``, the
centroids of the three faces at ``v`` and the centroid of ``c``.  Its six
faces are quadrilaterals, in general not planar; each is split into two
planar triangles along a fixed diagonal:

* on a face ``f`` of ``c``: ``(v, m_vw, c_f)`` for the two edges ``vw`` of
  ``f`` at ``v`` (diagonal ``v - c_f``); such a triangle lies in the face of a
  tetrahedron and is shared by the pieces of ``v`` in the two cells on either
  side of ``f`` (or lies on the domain boundary);
* inside ``c``: ``(m_e, c_f, c_c)`` for every edge ``e`` and each of the two
  faces ``f`` at ``e`` (diagonal ``m_e - c_c``), shared by the pieces of the
  two ends of ``e`` in ``c``.

A shared triangle is stored once, with a signed piece-triangle incidence, so
the two pieces that share it see exactly the same points and opposite
normals: the pieces tile every cell and the union over the cells at a vertex
(its smoothing cell) tiles the domain, bounded by planar triangles.  Edge
midpoints and face centroids are computed from the sorted global vertex
numbers, hence bit-for-bit the same in every cell that shares them.

The orientation of every triangle with respect to its pieces is fixed on the
reference cell (outward of the piece there) and multiplied by the sign of
the cell's Jacobian at its centre: exact for affine tetrahedra, and right for
hexahedra that are not inverted (a piece of negative volume is refused).
"""

from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from skfem import MeshHex1, MeshTet1
from skfem.quadrature import get_quadrature
from skfem.refdom import RefTri

__all__ = ["median_dual_3d", "triangle_rule", "composite_facet_rule", "mesh_kind"]


def triangle_rule(npoints):
    """A symmetric rule on triangles with positive weights summing to 1.

    Degree ``2 (npoints - 1)``: 3 points for ``npoints = 2`` (degree 2), 6 for
    ``npoints = 3`` (degree 4), the degree a segment rule of ``npoints``
    Gauss points reaches minus one.

    Returns
    -------
    X : ndarray, shape (2, nq)
        Barycentric-like coordinates ``(s, r)``: the point ``a + s (b - a) + r (c - a)``.
    W : ndarray, shape (nq,)
    """
    X, W = get_quadrature(RefTri, max(1, 2 * (int(npoints) - 1)))
    return X, W / W.sum()


@lru_cache(maxsize=None)
def _reference_topology(kind):
    """Faces (outward vertex cycles), edges and the piece-triangle signs.

    Returns ``(faces, edges, face_edges, internal_sign)`` with
    ``internal_sign[e, j]`` the sign, for the piece of the first vertex of
    edge ``e``, of the triangle ``(m_e, c_f, c_c)`` with ``f`` the ``j``-th
    face at ``e``.
    """
    X = {"tet": MeshTet1, "hex": MeshHex1}[kind].init_refdom().p
    nv = X.shape[1]
    centre = X.mean(axis=1)
    if kind == "tet":
        sets = [tuple(sorted(set(range(4)) - {k})) for k in range(4)]
    else:
        sets = [tuple(np.flatnonzero(X[a] == side)) for a in range(3) for side in (0.0, 1.0)]
    faces = []
    for vs in sets:
        vs = np.array(vs)
        fc = X[:, vs].mean(axis=1)
        outward = fc - centre
        # order the face's vertices by angle around its centre, then outward
        u = X[:, vs[0]] - fc
        w = np.cross(outward, u)
        angle = np.arctan2((X[:, vs] - fc[:, None]).T @ w, (X[:, vs] - fc[:, None]).T @ u)
        cycle = vs[np.argsort(angle)]
        normal = np.cross(X[:, cycle[1]] - X[:, cycle[0]], X[:, cycle[2]] - X[:, cycle[0]])
        faces.append(tuple(cycle if normal @ outward > 0 else cycle[::-1]))
    edges = sorted({tuple(sorted((f[i], f[(i + 1) % len(f)]))) for f in faces
                    for i in range(len(f))})
    face_edges = [[j for j, f in enumerate(faces) if a in f and b in f] for a, b in edges]
    sign = np.zeros((len(edges), 2))
    for e, (a, b) in enumerate(edges):
        m = 0.5 * (X[:, a] + X[:, b])
        for j, f in enumerate(face_edges[e]):
            fc = X[:, list(faces[f])].mean(axis=1)
            normal = np.cross(fc - m, centre - m)
            sign[e, j] = np.sign(normal @ (X[:, b] - X[:, a]))
    assert nv == len({v for f in faces for v in f}) and np.all(sign != 0)
    return faces, edges, face_edges, sign


def mesh_kind(mesh):
    """``"tet"`` or ``"hex"``: the cell type of a 3D mesh (refuses others)."""
    if isinstance(mesh, MeshTet1) or (mesh.t.shape[0] == 4 and mesh.dim() == 3):
        return "tet"
    if isinstance(mesh, MeshHex1) or (mesh.t.shape[0] == 8 and mesh.dim() == 3):
        return "hex"
    raise ValueError(f"nodal integration builds 3D smoothing cells on tetrahedra and "
                     f"hexahedra, not on {type(mesh).__name__} cells")


def _orientation(kind, p, t):
    """Sign of the Jacobian of every cell at its centre."""
    X = {"tet": MeshTet1, "hex": MeshHex1}[kind].init_refdom().p
    # gradients of the trilinear (linear) shape functions at the centre
    if kind == "tet":
        J = np.stack([p[:, t[k]] - p[:, t[0]] for k in (1, 2, 3)], axis=1)
    else:
        signs = 2.0 * X - 1.0  # (3, 8): ∂N_k/∂ξ_a = sign / 4 at the centre
        J = np.einsum("dkc,ak->dac", p[:, t], signs / 4.0)
    return np.linalg.det(np.moveaxis(J, -1, 0))


def median_dual_3d(mesh, npoints=2):
    """Pieces and bounding triangles of the median dual cells of a 3D mesh.

    Parameters
    ----------
    mesh : skfem.MeshTet1 or skfem.MeshHex1
        Its vertices are the particles.
    npoints : int
        Selects the rule on every triangle (:func:`triangle_rule`).

    Returns
    -------
    dict
        ``owner`` (npieces,), ``corners`` (3, npieces, 8) (vertex, the three
        edge midpoints, the three face centroids, the cell centroid),
        ``volume`` (npieces,), ``points`` (3, ntriangles, nq), ``weights``
        (nq,), ``area_vectors`` (3, ntriangles) (``∫ n dΓ`` of each triangle
        as stored), ``ends`` (3, 3, ntriangles) (its corners) and
        ``incidence`` (npieces, ntriangles) (``±1``).

    Raises
    ------
    ValueError
        For other cell types, and for cells of zero volume or pieces of
        non-positive volume (names the cell and its vertices).
    """
    kind = mesh_kind(mesh)
    faces, edges, face_edges, internal_sign = _reference_topology(kind)
    p, t = mesh.p, mesh.t
    nv, ne = t.shape
    det = _orientation(kind, p, t)
    bad = np.flatnonzero(~(np.abs(det) > 0))
    if bad.size:
        raise ValueError(f"mesh cell {bad[0]} (vertices {t[:, bad[0]].tolist()}) has zero "
                         f"volume ({bad.size} such cells): it cannot carry smoothing cells; "
                         "remove the degenerate cells from the mesh")
    orient = np.sign(det)
    centroid = p[:, np.sort(t, axis=0)].mean(axis=1)  # (3, ne)

    def face_centroid(f):  # (3, ne), from the sorted global vertices
        return p[:, np.sort(t[list(faces[f])], axis=0)].mean(axis=1)

    def midpoint(a, b):
        return 0.5 * (p[:, a] + p[:, b])

    fcs = [face_centroid(f) for f in range(len(faces))]
    piece = np.arange(nv)[:, None] * ne + np.arange(ne)  # (local vertex, cell)

    # triangles on the cell faces, keyed by (sorted face vertices, v, w)
    face_rows, face_keys, face_geo, face_sign = [], [], [], []
    for f, cycle in enumerate(faces):
        sorted_face = np.sort(t[list(cycle)], axis=0)
        k = len(cycle)
        for i, v in enumerate(cycle):
            for w, s in ((cycle[(i + 1) % k], 1.0), (cycle[(i - 1) % k], -1.0)):
                face_rows.append(piece[v])
                face_keys.append(np.vstack([sorted_face, t[v], t[w]]))
                face_geo.append((p[:, t[v]], midpoint(t[v], t[w]), fcs[f]))
                face_sign.append(s * orient)
    # (all faces of a cell type have the same number of vertices)
    unique_keys, first, inverse = np.unique(np.hstack(face_keys).T, axis=0,
                                            return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    face_ends = np.stack([np.concatenate([g[j] for g in face_geo], axis=1)[:, first]
                          for j in range(3)], axis=1)  # (3, 3, nface_tri)
    nface = len(unique_keys)

    # triangles inside the cells: (m_e, c_f, c_c), one per (edge, face at it, cell)
    rows = [np.concatenate(face_rows)]
    cols = [inverse]
    signs = [np.concatenate(face_sign)]
    inner_ends = []
    for e, (a, b) in enumerate(edges):
        m = midpoint(t[a], t[b])
        for j, f in enumerate(face_edges[e]):
            index = nface + len(inner_ends) * ne + np.arange(ne)
            inner_ends.append(np.stack([m, fcs[f], centroid], axis=1))
            rows += [piece[a], piece[b]]
            cols += [index, index]
            signs += [internal_sign[e, j] * orient, -internal_sign[e, j] * orient]
    ends = np.concatenate([face_ends] + inner_ends, axis=2)
    ntri = ends.shape[2]
    incidence = sp.csr_matrix((np.concatenate(signs),
                               (np.concatenate(rows), np.concatenate(cols))),
                              shape=(nv * ne, ntri))
    area_vectors = 0.5 * np.cross(ends[:, 1] - ends[:, 0], ends[:, 2] - ends[:, 0], axis=0)
    # volume = (1/3) ∮ x·n dΓ, exact on planar triangles (x·n is linear),
    # about the cell centroid against cancellation
    tri_centroid = ends.mean(axis=1)
    volume = np.zeros(nv * ne)
    for d in range(3):
        flux = incidence @ sp.diags(area_vectors[d])
        volume += (flux @ tri_centroid[d] - flux.sum(axis=1).A1 * np.tile(centroid[d], nv)) / 3
    bad = np.flatnonzero(~(volume > 0))
    if bad.size:
        cell = bad[0] % ne
        raise ValueError(f"mesh cell {cell} (vertices {t[:, cell].tolist()}) is too "
                         f"distorted: the piece of its vertex {t[bad[0] // ne, cell]} has "
                         f"volume {volume[bad[0]]:.3g} ({bad.size} such pieces); "
                         "untangle or remesh the cell")
    X, W = triangle_rule(npoints)
    points = (ends[:, 0, :, None] + (ends[:, 1] - ends[:, 0])[:, :, None] * X[0]
              + (ends[:, 2] - ends[:, 0])[:, :, None] * X[1])
    vertex_corners = [p[:, t[v]] for v in range(nv)]
    corners = np.concatenate([np.stack(
        [vertex_corners[v]]
        + [midpoint(t[v], t[w]) for a, w in edges if a == v]
        + [midpoint(t[v], t[a]) for a, w in edges if w == v]
        + [fcs[f] for f in range(len(faces)) if v in faces[f]] + [centroid], axis=-1)
        for v in range(nv)], axis=1)
    return {"owner": t.ravel(), "corners": corners, "volume": volume, "points": points,
            "weights": W, "area_vectors": area_vectors, "ends": ends,
            "incidence": incidence}


def composite_facet_rule(kind, npoints):
    """The boundary triangles of the smoothing cells on one reference facet.

    A facet (triangle of a tetrahedron, quadrilateral of a hexahedron) is
    split into the triangles ``(v, m_vw, c_f)`` of :func:`median_dual_3d`,
    each with :func:`triangle_rule`: loads integrated with this rule see
    exactly the points of the cells (for quadrilateral facets when they are
    parallelograms, on which the bilinear map is affine).

    Returns
    -------
    X : ndarray, shape (2, nq)
        Points on the reference facet of scikit-fem.
    W : ndarray, shape (nq,)
        Weights summing to the reference facet's measure.
    """
    corners = {"tet": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
               "hex": np.array([[0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]])}[kind]
    measure = 0.5 if kind == "tet" else 1.0
    k = corners.shape[1]
    centre = corners.mean(axis=1)
    X, W = triangle_rule(npoints)
    points, weights = [], []
    for i in range(k):
        v = corners[:, i]
        for w in (corners[:, (i + 1) % k], corners[:, (i - 1) % k]):
            m = 0.5 * (v + w)
            points.append(v[:, None] + np.outer(m - v, X[0]) + np.outer(centre - v, X[1]))
            weights.append(W * measure / (2 * k))
    return np.hstack(points), np.concatenate(weights)
