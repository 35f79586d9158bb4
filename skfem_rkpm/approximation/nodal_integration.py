"""Nodal integration of RK bases: SCNI, its stabilization, and DNI.

One integration point per particle.  Every particle ``L`` owns a conforming
*smoothing cell* ``Ω_L`` built from the background mesh: the median dual
cell, made of one *piece* per adjacent mesh cell ``c`` (the quadrilateral
vertex - edge midpoint - centroid of ``c`` - other edge midpoint).  The
pieces tile every mesh cell exactly, so the cells tile the domain and two
neighbours share their whole common boundary.  In 3D (tetrahedra,
hexahedra) a piece is the hexahedron vertex - edge midpoints - face
centroids - cell centroid, bounded by planar triangles shared exactly by
its neighbours (:mod:`.median_dual_3d`); everything below holds with
areas read as volumes and segments as triangles (not axisymmetric).

Stabilized conforming nodal integration (SCNI; Chen, Wu, Yoon & You 2001,
IJNME 50; finite strain: Chen, Yoon & Wu 2002, IJNME 53) replaces
the material gradient at the particle by its average over the cell, turned
into a boundary integral by the divergence theorem,

    b_I(X_L) = (1/A_L) ∫_{Ω_L} ∇Ψ_I dΩ = (1/A_L) ∮_{∂Ω_L} Ψ_I n dΓ,

evaluated with a Gauss rule on every straight segment of ``∂Ω_L``.  Because
the cells conform, ``Σ_L A_L b_I(X_L) = ∮_Γ Ψ_I n dΓ`` exactly (interior
segments cancel): the integration constraint holds with nodal weights ``A_L``
whatever the segment rule, and a rule exact for linear functions along a
segment makes ``b_I`` reproduce linear gradients.  So the linear patch test
passes to round-off.

Axisymmetric (``x`` = R): the smoothing is done in the measure ``R dA``,

    V_L = ∫_{Ω_L} R dA,   h_I(L) = (1/V_L) ∫_{Ω_L} Ψ_I dA,
    b_I(L) = (1/V_L) ∫_{Ω_L} ∇Ψ_I R dA = (1/V_L) [∮ Ψ_I R n dΓ - e_R ∫_{Ω_L} Ψ_I dA],

with ``h_I`` the smoothed hoop term (``(u_R/R)`` averaged with weight ``R``)
and the nodal weight ``2π V_L``.  Then ``V_L (b_IR + h_I) = ∮ Ψ_I R n_R dΓ``
and ``V_L b_IZ = ∮ Ψ_I R n_Z dΓ``: the axisymmetric integration constraint
holds exactly, and ``b``, ``h`` reproduce the gradients and ``u_R/R`` of
linear fields exactly (with a piece rule exact for linear functions).  The
hoop term ``Ψ_I(X_L)/R_L`` at the particle with weight ``2π R_L A_L`` would
meet both only if every particle sat at the centroid of its cell.  The RK
basis presents this scheme as one point per particle with value
``Ψ̄_I = (1/A_L)∫ Ψ_I dA``, radius ``R̄_L = V_L / A_L`` (the centroid) and
``dx = A_L``, so that the usual axisymmetric form (hoop ``Ψ/R``, weight
``2πR dx``) computes exactly ``h_I`` and ``2π V_L``.

Modified SCNI (Puso, Chen, Zywicz & Elmer 2008, IJNME 74) adds the energy of
the differences between the piece gradients ``b_I(k) = ∮_{∂Ω_k} Ψ_I n / A_k``
and the cell gradient, ``α Σ_L Σ_{k ⊂ L} A_k (B_k - B_L)ᵀ C (B_k - B_L)``;
both reproduce linear fields, so the term vanishes on them and the patch test
is untouched.

Direct nodal integration (DNI) takes the exact gradients at the particles with
the cell areas as weights; it misses the integration constraint.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem.element import DiscreteField

from .basis_views import linear_mesh_class
from .median_dual_3d import composite_facet_rule, median_dual_3d, mesh_kind
from .voronoi_cells import voronoi_cells
from .shape import ShapeTable

__all__ = ["NODAL_SCHEMES", "SmoothingCells", "smoothing_cells", "boundary_rule",
           "NodalGeometry", "NodalQuadrature", "smoothed_gradients", "nodal_table",
           "nodal_quadrature", "jump_operator", "stabilization_matrix"]

NODAL_SCHEMES = ("scni", "dni")
#: the smoothing cells SCNI can use (:func:`smoothing_cells`)
SMOOTHING_CELLS = ("median_dual", "voronoi")


def boundary_rule(npoints, mesh=None):
    """The rule of the smoothing cells' boundary pieces on one reference facet.

    2D: composite Gauss rule on [0, 1], ``npoints`` points on each half (SCNI
    cells split every boundary edge at its midpoint).  3D (``mesh`` of
    tetrahedra or hexahedra): the facet split into the triangles vertex - edge
    midpoint - facet centroid, each with the triangle rule
    (:func:`~.median_dual_3d.composite_facet_rule`).  Loads integrated with
    this rule on whole facets see exactly the points of the cells.

    Returns
    -------
    X : ndarray, shape (facet dim, nq)
    W : ndarray, shape (nq,)
    """
    if mesh is not None and mesh.dim() == 3:
        return composite_facet_rule(mesh_kind(mesh), npoints)
    t, w = _gauss01(npoints)
    return np.concatenate([t / 2, 0.5 + t / 2])[None, :], np.concatenate([w, w]) / 2


def _gauss01(npoints):
    t, w = np.polynomial.legendre.leggauss(npoints)
    return (t + 1) / 2, w / 2


@dataclass
class SmoothingCells:
    """The pieces of the smoothing cells and the segments that bound them.

    In 3D the "segments" are the planar triangles that bound the pieces
    (:func:`~.median_dual_3d.median_dual_3d`) and ``area`` is a volume.

    Attributes
    ----------
    owner : ndarray, shape (npieces,)
        Particle (mesh vertex) of each piece.
    corners : ndarray, shape (dim, npieces, 4) or (3, npieces, 8)
        Piece corners.  2D, counter-clockwise: vertex, midpoint of the next
        edge, cell centroid, midpoint of the previous edge.  3D: vertex,
        three edge midpoints, three face centroids, cell centroid.
    area : ndarray, shape (npieces,)
        Area (2D) or volume (3D) of every piece.
    segment_points : ndarray, shape (dim, nsegments, nq)
        Quadrature points of every distinct segment (2D: half edges, then
        spokes) or triangle (3D).
    segment_weights : ndarray, shape (nq,)
        Weights on the reference segment or triangle, summing to 1.
    segment_ends : ndarray, shape (dim, 2 or 3, nsegments)
        Start and end point of every segment, corners of every triangle.
    incidence : scipy.sparse.csr_matrix, shape (npieces, nsegments)
        ``±1``: the piece boundary runs along (against) the segment, or the
        triangle's normal points out of (into) the piece.
    nparticles : int
    segment_area : ndarray, shape (dim, nsegments)
        ``∫ n dΓ`` over every segment or triangle as stored: 2D ``(Δy, -Δx)``
        (segment traversed with the domain on its left), 3D half the cross
        product of two sides.
    """

    owner: np.ndarray
    corners: np.ndarray
    area: np.ndarray
    segment_points: np.ndarray
    segment_weights: np.ndarray
    segment_ends: np.ndarray
    incidence: sp.csr_matrix
    nparticles: int
    segment_area: np.ndarray

    @property
    def npieces(self):
        return len(self.owner)

    @property
    def cell_area(self):
        """``A_L``: area (volume in 3D) of each particle's smoothing cell."""
        return np.bincount(self.owner, self.area, minlength=self.nparticles)

    @property
    def to_cells(self):
        """Sparse sum over the pieces of each cell, shape (nparticles, npieces)."""
        return sp.csr_matrix((np.ones(self.npieces), (self.owner, np.arange(self.npieces))),
                             shape=(self.nparticles, self.npieces))

    def merged(self):
        """The same cells with one piece each: the whole smoothing cell.

        Segments (triangles) inside a smoothing cell, shared by two of its
        pieces with opposite signs, cancel exactly and are dropped: what is
        left bounds the cells.  For schemes that need no piece gradients
        (SCNI without stabilization), about half the points in 3D.
        """
        incidence = (self.to_cells @ self.incidence).tocsc()
        incidence.eliminate_zeros()
        keep = np.flatnonzero(np.diff(incidence.indptr))
        return SmoothingCells(np.arange(self.nparticles), None, self.cell_area,
                              self.segment_points[:, keep], self.segment_weights,
                              self.segment_ends[:, :, keep], incidence[:, keep].tocsr(),
                              self.nparticles, self.segment_area[:, keep])

    def segment_normals(self, weight=None):
        """``∫_seg f n dΓ`` as weights of the segment points: (dim, nsegments, nq).

        The normal is constant on a straight segment or planar triangle:
        ``n dΓ = segment_area · w_q``.  ``weight`` (nsegments, nq) multiplies
        the integrand (``R`` for axisymmetric cells).
        """
        ndg = self.segment_area[:, :, None] * self.segment_weights
        return ndg if weight is None else ndg * weight

    def piece_rule(self, npoints):
        """Gauss points and weights (with Jacobian) inside every piece.

        Tensor rule on the bilinear map of the quadrilateral piece: exact for
        the integral of linear functions (and of ``R`` times them).

        Returns
        -------
        x : ndarray, shape (dim, npieces, nq)
        w : ndarray, shape (npieces, nq)
        """
        t, w1 = _gauss01(npoints)
        s, r = np.meshgrid(t, t, indexing="ij")
        s, r, w = s.ravel(), r.ravel(), np.outer(w1, w1).ravel()
        c = self.corners  # (dim, npieces, 4): bilinear in (s, r)
        shape = np.stack([(1 - s) * (1 - r), s * (1 - r), s * r, (1 - s) * r])  # (4, nq)
        ds = np.stack([-(1 - r), 1 - r, r, -r])
        dr = np.stack([-(1 - s), -s, s, 1 - s])
        x = np.einsum("dpk,kq->dpq", c, shape)
        xs = np.einsum("dpk,kq->dpq", c, ds)
        xr = np.einsum("dpk,kq->dpq", c, dr)
        jac = xs[0] * xr[1] - xs[1] * xr[0]
        return x, jac * w


def smoothing_cells(mesh, npoints=2, kind="median_dual"):
    """The median dual cells of a triangle, quadrilateral, tetrahedron or
    hexahedron mesh, or the Voronoi cells of its vertices clipped to a
    triangle or quadrilateral mesh (``kind="voronoi"``, :mod:`.voronoi_cells`).

    Parameters
    ----------
    mesh : skfem.MeshTri, skfem.MeshQuad, skfem.MeshTet or skfem.MeshHex
        Its vertices are the particles.
    npoints : int
        Gauss points on every segment (half edge or spoke); in 3D it selects
        the rule on every triangle (:func:`~.median_dual_3d.triangle_rule`).
    kind : {"median_dual", "voronoi"}

    Raises
    ------
    ValueError
        For other cells, for cells of zero area (volume) and, in 3D, for
        pieces of non-positive volume (names the cell).
    """
    if kind not in SMOOTHING_CELLS:
        raise ValueError(f"smoothing cells are one of {SMOOTHING_CELLS}, not {kind!r}")
    if kind == "voronoi":
        d = voronoi_cells(mesh)
        ends = d["ends"]
        tq, wq = _gauss01(npoints)
        delta = ends[:, 1] - ends[:, 0]
        return SmoothingCells(d["owner"], d["corners"], d["area"],
                              ends[:, 0, :, None] + delta[:, :, None] * tq, wq, ends,
                              d["incidence"], mesh.nvertices, np.stack([delta[1], -delta[0]]))
    if mesh.dim() == 3:
        d = median_dual_3d(mesh, npoints)
        return SmoothingCells(d["owner"], d["corners"], d["volume"], d["points"],
                              d["weights"], d["ends"], d["incidence"], mesh.nvertices,
                              d["area_vectors"])
    if mesh.dim() != 2:
        raise ValueError(f"nodal integration builds smoothing cells on 2D and 3D meshes "
                         f"(this mesh is {mesh.dim()}D); use integration='vci'")
    p, t = mesh.p, mesh.t.copy()
    nv, ne = t.shape
    signed = 0.5 * sum(p[0, t[j]] * p[1, t[(j + 1) % nv]] - p[0, t[(j + 1) % nv]] * p[1, t[j]]
                       for j in range(nv))
    bad = np.flatnonzero(~(np.abs(signed) > 0))
    if bad.size:
        raise ValueError(f"mesh cell {bad[0]} (vertices {t[:, bad[0]].tolist()}) has zero "
                         f"area ({bad.size} such cells): it cannot carry smoothing cells; "
                         "remove the degenerate cells from the mesh")
    t[:, signed < 0] = t[::-1, signed < 0]  # counter-clockwise
    centroid = p[:, t].mean(axis=1)  # (2, ne)
    # the distinct half edges: facet f from a to b gives a->m (2f) and m->b (2f+1)
    fa, fb = mesh.facets
    keys = np.minimum(fa, fb).astype(np.int64) * mesh.nvertices + np.maximum(fa, fb)
    order = np.argsort(keys)
    start = np.stack([p[:, fa], 0.5 * (p[:, fa] + p[:, fb])], axis=1)  # (2, 2, nf)
    end = np.stack([0.5 * (p[:, fa] + p[:, fb]), p[:, fb]], axis=1)
    half_start = start.transpose(0, 2, 1).reshape(2, -1)
    half_end = end.transpose(0, 2, 1).reshape(2, -1)
    nhalf = half_start.shape[1]
    owner, corners, rows, cols, signs = [], [], [], [], []
    npieces = 0
    for j in range(nv):
        v, nxt, prv = t[j], t[(j + 1) % nv], t[(j - 1) % nv]
        f_next = order[np.searchsorted(keys[order], np.minimum(v, nxt).astype(np.int64)
                                       * mesh.nvertices + np.maximum(v, nxt))]
        f_prev = order[np.searchsorted(keys[order], np.minimum(v, prv).astype(np.int64)
                                       * mesh.nvertices + np.maximum(v, prv))]
        m_next, m_prev = 0.5 * (p[:, v] + p[:, nxt]), 0.5 * (p[:, v] + p[:, prv])
        corners.append(np.stack([p[:, v], m_next, centroid, m_prev], axis=-1))
        owner.append(v)
        piece = npieces + np.arange(ne)
        # v -> m_next: half a->m of f_next if v = a, else m->b reversed
        first = fa[f_next] == v
        rows += [piece]
        cols += [np.where(first, 2 * f_next, 2 * f_next + 1)]
        signs += [np.where(first, 1.0, -1.0)]
        # m_next -> centroid: spoke j of the cell; centroid -> m_prev: spoke j-1 reversed
        rows += [piece, piece]
        cols += [nhalf + j * ne + np.arange(ne), nhalf + ((j - 1) % nv) * ne + np.arange(ne)]
        signs += [np.ones(ne), -np.ones(ne)]
        # m_prev -> v: half m->b of f_prev if v = b, else a->m reversed
        last = fb[f_prev] == v
        rows += [piece]
        cols += [np.where(last, 2 * f_prev + 1, 2 * f_prev)]
        signs += [np.where(last, 1.0, -1.0)]
        npieces += ne
    spoke_start = np.concatenate([0.5 * (p[:, t[j]] + p[:, t[(j + 1) % nv]])
                                  for j in range(nv)], axis=1)
    spoke_end = np.tile(centroid, (1, nv))
    ends = np.stack([np.hstack([half_start, spoke_start]),
                     np.hstack([half_end, spoke_end])], axis=1)  # (2, 2, nseg)
    tq, wq = _gauss01(npoints)
    points = ends[:, 0, :, None] + (ends[:, 1] - ends[:, 0])[:, :, None] * tq
    corners = np.concatenate(corners, axis=1)
    x, y = corners[0], corners[1]
    area = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    incidence = sp.csr_matrix((np.concatenate(signs),
                               (np.concatenate(rows), np.concatenate(cols))),
                              shape=(npieces, ends.shape[2]))
    delta = ends[:, 1] - ends[:, 0]
    return SmoothingCells(np.concatenate(owner), corners, area, points, wq, ends,
                          incidence, mesh.nvertices, np.stack([delta[1], -delta[0]]))


def smoothed_gradients(cells, segment_values, axisymmetric=False, piece_values=None,
                       piece_x=None, piece_w=None):
    """Boundary integrals of the shape functions over pieces (SCNI).

    Parameters
    ----------
    cells : SmoothingCells
    segment_values : scipy.sparse matrix, shape (nsegments * nq, nnodes)
        ``Ψ_I`` at the segment points (segment-major).
    axisymmetric : bool
        Smooth in the measure ``R dA`` (see the module docstring); then give
        ``piece_values`` (npieces * nq, nnodes) with ``piece_x``, ``piece_w``
        from :meth:`SmoothingCells.piece_rule`.

    Returns
    -------
    G : list of scipy.sparse.csr_matrix, shape (npieces, nnodes)
        ``∮_{∂Ω_k} Ψ_I n_d dΓ`` (times ``R`` for axisymmetric) per direction.
    M : scipy.sparse.csr_matrix or None
        ``∫_{Ω_k} Ψ_I dA`` (axisymmetric only).
    measure : ndarray, shape (npieces,)
        ``A_k`` (plane) or ``V_k = ∫_{Ω_k} R dA`` (axisymmetric).
    """
    nseg, nq = cells.segment_points.shape[1:]
    weight = cells.segment_points[0] if axisymmetric else None
    ndg = cells.segment_normals(weight)  # (dim, nseg, nq)
    point_rows = np.arange(nseg * nq)
    G = []
    for d in range(ndg.shape[0]):
        W = sp.csr_matrix((ndg[d].ravel(), (np.repeat(np.arange(nseg), nq), point_rows)),
                          shape=(nseg, nseg * nq))
        G.append((cells.incidence @ (W @ segment_values)).tocsr())
    if not axisymmetric:
        return G, None, cells.area
    npieces, nqa = piece_w.shape
    Wa = sp.csr_matrix((piece_w.ravel(), (np.repeat(np.arange(npieces), nqa),
                                          np.arange(npieces * nqa))),
                       shape=(npieces, npieces * nqa))
    M = (Wa @ piece_values).tocsr()
    G[0] = (G[0] - M).tocsr()
    volume = np.sum(piece_x[0] * piece_w, axis=1)
    return G, M, volume


def _aligned(pattern, matrix):
    """Entries of ``matrix`` at the (sorted CSR) positions of ``pattern``."""
    n = pattern.shape[1]
    rows = np.repeat(np.arange(pattern.shape[0]), np.diff(pattern.indptr))
    keys = rows.astype(np.int64) * n + pattern.indices
    coo = matrix.tocoo()
    out = np.zeros(len(keys))
    np.add.at(out, np.searchsorted(keys, coo.row.astype(np.int64) * n + coo.col), coo.data)
    return out


def nodal_table(values, grads, nnodes):
    """A :class:`ShapeTable` with one point per particle from sparse matrices.

    ``values`` and every ``grads[d]`` are sparse (npoints, nnodes); the pairs
    are the union of their patterns.
    """
    pattern = abs(values).tocsr()
    for g in grads:
        pattern = pattern + abs(g)
    pattern = pattern.tocsr()
    pattern.sum_duplicates()
    pattern.sort_indices()
    return ShapeTable(pattern.indptr.copy(), pattern.indices.copy(),
                      _aligned(pattern, values),
                      np.stack([_aligned(pattern, g) for g in grads]), nnodes)


def scale_rows(matrix, factor):
    """``diag(factor) @ matrix`` as CSR."""
    return (sp.diags(factor) @ matrix).tocsr()


class NodalGeometry:
    """Quadrature of nodal integration in scikit-fem's basis terms.

    Every particle is one "element" with one point at ``x`` and ``dx`` its
    weight, so forms, assembly and material state run per particle.
    """

    def __init__(self, x, weight):
        self.x = np.asarray(x, float)
        self.nelems = self.x.shape[1]
        self.X = np.zeros((self.x.shape[0], 1))
        self.W = np.ones(1)
        self.dx = np.asarray(weight, float).reshape(self.nelems, 1)
        self.mapping = None

    def global_coordinates(self):
        return DiscreteField(self.x[:, :, None])

    def mesh_parameters(self):
        return DiscreteField(np.abs(self.dx) ** (1.0 / self.x.shape[0]))

    def default_parameters(self):
        return {"x": self.global_coordinates(), "h": self.mesh_parameters()}


@dataclass
class NodalQuadrature:
    """What a nodal scheme gives an RK basis.

    Attributes
    ----------
    table : ShapeTable
        One point per particle: values and (smoothed or exact) gradients.
    geometry : NodalGeometry
    jumps : list of scipy.sparse.csr_matrix or None
        SCNI: ``b_I(k) - b_I(L)`` per direction, shape (npieces, nnodes),
        the piece gradients minus those of their cell.
    piece_weight : ndarray or None
        ``A_k`` (``2π V_k`` axisymmetric) of every piece.
    piece_owner : ndarray or None
        The particle ``L`` whose smoothing cell holds each piece.
    """

    table: ShapeTable
    geometry: NodalGeometry
    jumps: list
    piece_weight: np.ndarray
    piece_owner: np.ndarray = None


def nodal_quadrature(mesh, scheme, shape_table, nodal, npoints=2, axisymmetric=False,
                     pieces=True, smoothing="median_dual"):
    """Nodal quadrature of an RK basis whose particles are the mesh vertices.

    Parameters
    ----------
    mesh : skfem.Mesh
    scheme : {"scni", "dni"}
    shape_table : callable
        ``x -> ShapeTable`` of the basis (values only are used for SCNI).
    nodal : ShapeTable
        Values and exact gradients at the particles.
    npoints : int
        Gauss points per segment (and per direction in the pieces).
    axisymmetric : bool
        ``x`` is the radius (see the module docstring).
    pieces : bool
        Keep the piece gradients (``jumps``) for the stabilization; without
        them (and not axisymmetric) the shape functions are evaluated on the
        boundaries of the whole smoothing cells only
        (:meth:`SmoothingCells.merged`), and ``jumps`` is None.
    smoothing : {"median_dual", "voronoi"}
        The smoothing cells (:func:`smoothing_cells`).

    Returns
    -------
    NodalQuadrature
    """
    if mesh.p.shape[1] != mesh.nvertices:
        raise ValueError(
            f"integration={scheme!r} builds its smoothing cells from the straight "
            f"edges of a linear mesh, but this {type(mesh).__name__} has "
            f"{mesh.p.shape[1] - mesh.nvertices} nodes besides its {mesh.nvertices} "
            f"vertices; pass the linear mesh of its vertices, "
            f"{linear_mesh_class(mesh).__name__}(mesh.p[:, :mesh.nvertices], mesh.t), "
            "or use a cell scheme "
            "(integration='vci'), which integrates over the curved cells")
    cells = smoothing_cells(mesh, npoints, smoothing)
    nnodes = mesh.nvertices
    area = cells.cell_area
    if scheme == "dni":
        return NodalQuadrature(nodal, NodalGeometry(mesh.p, area), None, None)
    pieces = pieces or axisymmetric
    if not pieces:
        cells = cells.merged()
    dim, nseg, nq = cells.segment_points.shape
    points = [cells.segment_points.reshape(dim, -1)]
    if axisymmetric:
        px, pw = cells.piece_rule(npoints)
        points.append(px.reshape(dim, -1))
    table = shape_table(np.hstack(points))
    values = table.matrix()
    seg_values = values[:nseg * nq] if axisymmetric else values
    piece_values = values[nseg * nq:] if axisymmetric else None
    G, M, measure = smoothed_gradients(cells, seg_values, axisymmetric, piece_values,
                                       *((px, pw) if axisymmetric else (None, None)))
    Q = cells.to_cells
    cell_measure = Q @ measure
    cell_grads = [scale_rows(Q @ g, 1.0 / cell_measure) for g in G]
    jumps = [(scale_rows(g, 1.0 / measure) - Q.T @ cg).tocsr()
             for g, cg in zip(G, cell_grads)] if pieces else None
    if axisymmetric:
        # one point per particle at the centroid radius R̄ = V/A with value
        # Ψ̄ = (1/A) ∫ Ψ dA and dx = A: the hoop Ψ̄/R̄ and the weight 2π R̄ A
        # are h_I and 2π V_L
        mean_values = scale_rows(Q @ M, 1.0 / area)
        x = np.vstack([cell_measure / area, (Q @ np.sum(px[1] * pw, axis=1)) / area])
        geometry = NodalGeometry(x, area)
        return NodalQuadrature(nodal_table(mean_values, cell_grads, nnodes), geometry,
                               jumps, 2 * np.pi * measure, cells.owner)
    geometry = NodalGeometry(mesh.p, area)
    table = nodal_table(_as_csr(nodal, nnodes), cell_grads, nnodes)
    return NodalQuadrature(table, geometry, jumps, measure if pieces else None,
                           cells.owner if pieces else None)


def _as_csr(table, nnodes):
    return sp.csr_matrix((table.values, table.indices, table.indptr),
                         shape=(table.npoints, nnodes))


def jump_operator(quadrature, ncomp):
    """The piece gradient jumps ``B_k - B_L`` as one sparse operator.

    Row ``(k ncomp + c) dim + l`` holds ``∂u_c/∂X_l`` on piece ``k`` minus
    that of its cell for the coefficients ``d`` (dofs ``ncomp*I + c``).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (npieces * ncomp * dim, ncomp * nnodes)
    """
    D = quadrature.jumps
    dim = len(D)
    npieces, nnodes = D[0].shape
    rows, cols, data = [], [], []
    for c in range(ncomp):
        for l in range(dim):
            P = D[l].tocoo()
            rows.append((P.row * ncomp + c) * dim + l)
            cols.append(ncomp * P.col + c)
            data.append(P.data)
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(npieces * ncomp * dim, ncomp * nnodes))


def stabilization_matrix(quadrature, C, ncomp, jumps=None):
    """Modified SCNI stabilization ``Σ_k w_k (B_k - B_L)ᵀ C (B_k - B_L)``.

    Puso, Chen, Zywicz & Elmer (2008), IJNME 74, with the piece
    (sub-cell) gradients of the smoothing cells; the factor ``α`` is applied
    by the caller.  Only the in-plane gradient enters (no hoop row in
    axisymmetric models).

    Parameters
    ----------
    quadrature : NodalQuadrature
        SCNI quadrature (with ``jumps``).
    C : ndarray, shape (dim, dim, dim, dim) or (nparticles, dim, dim, dim, dim)
        Tangent moduli ``C_{c l d m}`` (see :func:`skfem_rkpm.isotropic_tangent`),
        the same for every piece or one set per particle, used on the pieces of
        its smoothing cell (``quadrature.piece_owner``).
    ncomp : int
        Field components (dofs ``ncomp*I + c``).
    jumps : scipy.sparse.csr_matrix, optional
        :func:`jump_operator` of the quadrature, when the caller keeps it
        (moduli per particle only).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (ncomp * nnodes, ncomp * nnodes)
    """
    C = np.asarray(C, float)
    dim = len(quadrature.jumps)
    one = (ncomp, dim, ncomp, dim)
    if C.shape != one and C.shape[1:] != one:
        raise ValueError(f"stabilization moduli of shape {C.shape}: give C_(c l d m) as "
                         f"{one}, or one set per particle, (nparticles,) + {one}")
    if C.ndim == 5:
        B = jump_operator(quadrature, ncomp) if jumps is None else jumps
        m = ncomp * dim
        blocks = (quadrature.piece_weight[:, None, None]
                  * C[quadrature.piece_owner].reshape(-1, m, m))
        W = sp.bsr_matrix((blocks, np.arange(len(blocks)), np.arange(len(blocks) + 1)),
                          shape=(len(blocks) * m, len(blocks) * m)).tocsr()
        return (B.T @ (W @ B)).tocsr()
    D = quadrature.jumps
    nnodes = D[0].shape[1]
    W = sp.diags(quadrature.piece_weight)
    products = {(l, m): (D[l].T @ W @ D[m]).tocoo()
                for l in range(dim) for m in range(dim)}
    rows, cols, data = [], [], []
    for c in range(ncomp):
        for d in range(ncomp):
            for (l, m), P in products.items():
                if C[c, l, d, m] == 0.0:
                    continue
                rows.append(ncomp * P.row + c)
                cols.append(ncomp * P.col + d)
                data.append(C[c, l, d, m] * P.data)
    n = ncomp * nnodes
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(rows),
                                                 np.concatenate(cols))), shape=(n, n))
