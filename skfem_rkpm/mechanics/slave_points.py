"""The slave points of a contact boundary, where gaps are measured and
contact forces applied (Sec. 4 of Chen, Pan, Roque & Wang 1998).

The contact law acts at the boundary particles (contact nodes ``K``); the
slave points depend on ``collocation``:

``"nodal"``
    The paper's choice: the boundary particles themselves, at their current
    positions ``x = X + û`` with the nodal displacements ``û = Λᵀ d``
    (Eq. 3.32).  The nodal contact forces ``f̂`` (Eq. 4.27) and stiffness
    ``K̂`` (Eq. 4.28-4.29), weighted by the tributary area
    ``W_K = ∫_Γ N_K dΓ`` of the particle (hat functions ``N_K`` on the
    boundary facets, with ``2πR`` for axisymmetric models), go back to the
    coefficients as ``f = Λ f̂``, ``K = Λ K̂ Λᵀ``.
``"quadrature"``
    The Gauss points ``x_q`` of the boundary facets, with
    ``u(x_q) = Σ_I Ψ_I(x_q) d_I``.  The particle ``K`` sees the hat-weighted
    averages ``ĝ_K = Σ_q N_K(x_q) w_q g_q / W_K`` of the gaps and slips (a
    mortar-type weighted gap), and its tractions are interpolated back,
    ``t(x_q) = Σ_K N_K(x_q) t_K``, and integrated as
    ``f_I = Σ_q w_q Ψ_I(x_q) t(x_q)``.  A uniform traction is then
    integrated exactly, so a homogeneous compression stays exact for RK
    bases, which nodal forces ``Σ_K Ψ_I(X_K) f̂_K`` cannot achieve; and
    there is one law per particle, as in the nodal case.  At a corner of
    the slave surface the particle carries one law per side, so that a
    weighted gap never mixes two faces.
``"gauss"``
    The law at every Gauss point.  Exact for homogeneous states too, but
    with three Gauss points per facet the boundary is over-constrained and
    friction converges badly (measured in ``docs/contact.md``).

All are written as ``u_points = G d`` with a sparse ``G`` (rows of ``Λᵀ``,
or shape function values at boundary Gauss points) so that
``f = Gᵀ f_points`` and ``K = Gᵀ K_points G``; for a finite element basis
``Λ`` is the identity.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..approximation.constraints import transformation

__all__ = ["SlavePoints", "slave_points"]

_TWO_PI = 2.0 * np.pi
# slave points
# ---------------------------------------------------------------------------


@dataclass
class SlavePoints:
    """Slave points on the workpiece boundary and the contact nodes that
    carry the contact law.

    Attributes
    ----------
    X : ndarray (dim, n)
        Reference positions of the points.
    weights : ndarray (n,)
        Boundary area of each point (``2πR`` included for axisymmetric
        models).
    G : sparse (dim·n, N)
        Displacements of the points, interleaved ``(u_x, u_y[, u_z])`` per
        point, are ``G @ d``.
    spacing : float
        Mean length ``h_c`` of the slave boundary facets (in 3D the square
        root of their mean area).
    hats : sparse (n, m)
        Values ``N_K(x_q)`` of the boundary hat function of contact node
        ``K`` at the points (the identity for nodal collocation).
    node_weights : ndarray (m,)
        ``W_K = Σ_q N_K(x_q) w_q = ∫_Γ N_K dΓ``.
    nodes : ndarray (m,) or None
        Mesh vertex of each contact node.
    """

    X: np.ndarray
    weights: np.ndarray
    G: object
    spacing: float
    hats: object
    node_weights: np.ndarray
    nodes: np.ndarray = None

    @property
    def n(self):
        return self.X.shape[1]

    @property
    def dim(self):
        return self.X.shape[0]

    @property
    def m(self):
        return self.node_weights.shape[0]

    @cached_property
    def weighted_hats(self):
        """``M = Nᵀ diag(w)`` (m × n): nodal integrals of point values."""
        return (self.hats.T @ sp.diags(self.weights)).tocsr()

    def displacements(self, d):
        """Displacements (dim, n) of the points for coefficients ``d``."""
        return (self.G @ d).reshape(-1, self.dim).T

    @cached_property
    def hats_T(self):
        """``Nᵀ`` (m × n) in compressed rows, formed once (``hats.T`` is a new
        matrix object at every use, whose set-up costs more than the product)."""
        hats_T = sp.csr_matrix(self.hats.T)
        hats_T.sort_indices()
        return hats_T

    def average(self, values):
        """Hat-weighted nodal averages ``Σ_q N_K(x_q) w_q v_q / W_K``."""
        return (self.hats_T @ (self.weights * values)) / self.node_weights


def _facets(mesh, boundaries):
    """Facet indices of boundary names (or of the whole boundary)."""
    named = mesh.boundaries or {}
    if boundaries is None:
        return np.asarray(mesh.boundary_facets())
    if isinstance(boundaries, str):
        boundaries = [boundaries]
    if isinstance(boundaries, np.ndarray) and boundaries.dtype.kind in "iu":
        return np.unique(boundaries)
    out = []
    for b in boundaries:
        if isinstance(b, str):
            if b not in named:
                raise ValueError(f"the mesh has no boundary named {b!r}; it has "
                                 f"{sorted(named)}")
            out.append(np.asarray(named[b]))
        else:
            out.append(np.atleast_1d(np.asarray(b, dtype=np.int64)))
    if not out:
        raise ValueError("no slave boundary given")
    return np.unique(np.concatenate(out))


def _facet_spacing(mesh, facets):
    """The spacing ``h_c``: the mean reference length of the facets, in 3D
    the square root of their mean area."""
    if mesh.dim() == 3:
        from skfem import FacetBasis

        fb = FacetBasis(mesh, type(mesh).elem(), facets=facets, intorder=1)
        return float(np.sqrt(np.asarray(fb.dx).sum() / len(facets)))
    e = mesh.p[:, mesh.facets[1, facets]] - mesh.p[:, mesh.facets[0, facets]]
    return float(np.mean(np.linalg.norm(e, axis=0)))


def _scalar_value_matrix(fb):
    """Sparse (facet quadrature points × scalar dofs) values of a FacetBasis."""
    nq = fb.X.shape[-1]
    rows = np.arange(fb.nelems * nq).reshape(fb.nelems, nq)
    fields = getattr(fb, "local_fields", None) or fb.basis  # RK: without the loop warning
    data = [np.asarray(fields[i][0]).ravel() for i in range(fb.Nbfun)]
    cols = [np.repeat(fb.element_dofs[i], nq) for i in range(fb.Nbfun)]
    return sp.csr_matrix((np.concatenate(data),
                          (np.tile(rows.ravel(), fb.Nbfun), np.concatenate(cols))),
                         shape=(fb.nelems * nq, fb.N))


def _boundary_quadrature(mesh, facets, intorder, axisymmetric):
    """Gauss points (dim, nq) and weights (with ``2πR``) on the facets, and
    the facet hat functions there (sparse nq × nvertices)."""
    from skfem import FacetBasis

    fb = FacetBasis(mesh, type(mesh).elem(), facets=facets, intorder=intorder)
    x = np.asarray(fb.global_coordinates()).reshape(mesh.dim(), -1)
    w = np.asarray(fb.dx).ravel()
    if axisymmetric:
        w = _TWO_PI * x[0] * w
    return x, w, _scalar_value_matrix(fb)


def _is_rk(basis):
    return hasattr(basis, "element_nodes") and hasattr(basis, "nodal_matrix")


def _check_model(basis, model):
    if model not in ("plane_strain", "axisymmetric", "3d"):
        raise ValueError(f"model must be 'plane_strain', 'axisymmetric' or '3d', "
                         f"not {model!r}")
    dim = basis.mesh.dim()
    if (dim == 3) != (model == "3d"):
        raise ValueError(f"a {dim}D mesh with model {model!r}: 3D meshes need "
                         f"model='3d', 2D meshes 'plane_strain' or 'axisymmetric'")


def _vertex_dof_check(basis):
    mesh = basis.mesh
    if _is_rk(basis):
        if basis.nodes is not mesh.p and not (basis.nodes.shape == mesh.p.shape
                                              and np.allclose(basis.nodes, mesh.p)):
            raise ValueError("nodal collocation needs the particles at the mesh "
                             "vertices; use collocation='quadrature'")
    elif basis.N != mesh.dim() * mesh.nvertices:
        raise ValueError("nodal collocation needs one dof per vertex and component "
                         "(linear elements); use collocation='quadrature'")


def _interleaved(nodes, dim=2):
    """Vector dofs ``dim·K + c`` of nodes ``K``, point-major."""
    return (dim * np.asarray(nodes)[:, None] + np.arange(dim)[None]).ravel()


def _element_nodal_points(basis, facets, axisymmetric):
    """The nodes of a higher-order FEM basis (Q2, T6, ...) on the facets, with
    the weights ``w_K = ∫_Γ N_K dΓ`` of the element's own facet shape
    functions (for quadratic facets 1/6 and 2/3 of the facet: all positive)
    and ``G`` the rows of their dofs; the spacing is that of the nodes."""
    from skfem import FacetBasis

    mesh = basis.mesh
    scalar = basis.elem.elem if hasattr(basis.elem, "elem") else basis.elem
    fb = FacetBasis(mesh, scalar, facets=facets, intorder=2 * scalar.maxdeg + 1)
    dim = mesh.dim()
    x = np.asarray(fb.global_coordinates()).reshape(dim, -1)
    w = np.asarray(fb.dx).ravel()
    if axisymmetric:
        w = _TWO_PI * x[0] * w
    values = _scalar_value_matrix(fb)
    nodes = np.unique(fb.element_dofs[:, :])
    nodes = nodes[np.asarray(abs(values[:, nodes]).sum(axis=0)).ravel() > 0]
    weights = np.asarray(values.T @ w).ravel()[nodes]
    if np.any(weights < -1e-12 * weights.max()):
        raise ValueError(f"nodal collocation needs nodal weights ∫N_K dΓ ≥ 0; the "
                         f"{type(scalar).__name__} facets have {np.sum(weights < 0)} "
                         f"negative ones: use collocation='quadrature'")
    # a node on the axis of an axisymmetric model carries no area (∫N_K 2πR dR
    # vanishes there for quadratic facets): it has no contact law
    keep = weights > 1e-12 * weights.max()
    nodes, weights = nodes[keep], weights[keep]
    per_facet = len(nodes) / max(len(facets), 1)  # ~ nodes per facet beyond the first
    G = sp.identity(basis.N, format="csr")[_interleaved(nodes, dim)]
    return SlavePoints(basis.doflocs[:, dim * nodes], weights, G,
                       _facet_spacing(mesh, facets) / max(per_facet, 1.0),
                       sp.identity(len(nodes), format="csr"), weights, nodes)


def _nodal_points(basis, facets, axisymmetric):
    """Boundary particles with hat-function weights ``w_K = ∫_Γ N_K dΓ`` and
    ``G`` = the rows of ``Λᵀ`` (Eq. 3.33) of their nodal values."""
    mesh = basis.mesh
    if not _is_rk(basis) and basis.N != mesh.dim() * mesh.nvertices:
        return _element_nodal_points(basis, facets, axisymmetric)
    _vertex_dof_check(basis)
    _, w, hats = _boundary_quadrature(mesh, facets, 2, axisymmetric)
    nodes = np.unique(mesh.facets[:, facets])
    weights = np.asarray(hats.T @ w).ravel()[nodes]
    G = transformation(basis)[_interleaved(nodes, mesh.dim())]
    return SlavePoints(mesh.p[:, nodes], weights, sp.csr_matrix(G),
                       _facet_spacing(mesh, facets), sp.identity(len(nodes), format="csr"),
                       weights, nodes)


def _quadrature_points(basis, facets, axisymmetric, intorder, pointwise=False):
    """Gauss points of the boundary facets, with ``G`` built from the shape
    functions there: ``Ψ_I(x_q)`` (RK) or the element's facet values (FEM);
    the contact nodes are the boundary vertices with their hat functions
    (or, ``pointwise``, every Gauss point is its own contact node)."""
    from skfem import FacetBasis

    mesh = basis.mesh
    if intorder is None:
        intorder = getattr(basis, "intorder", None) or 2 * basis.elem.maxdeg
    x, w, hats = _boundary_quadrature(mesh, facets, intorder, axisymmetric)
    if _is_rk(basis):
        S = basis._shape_table(x, gradients=False).matrix()
    else:
        scalar = basis.elem.elem if hasattr(basis.elem, "elem") else basis.elem
        S = _scalar_value_matrix(FacetBasis(mesh, scalar, facets=facets,
                                            intorder=intorder))
    G = sp.kron(S, sp.identity(mesh.dim()), format="csr")
    spacing = _facet_spacing(mesh, facets)
    if pointwise:
        return SlavePoints(x, w, G, spacing, sp.identity(len(w), format="csr"), w)
    hats, nodes = _split_by_normals(mesh, facets, hats)
    return SlavePoints(x, w, G, spacing, hats, np.asarray(hats.T @ w).ravel(), nodes)


#: facets meeting at more than this angle make a corner of the slave surface
CORNER_ANGLE = 30.0


def _facet_groups(vertex, normal, cos_corner, rounds=8):
    """Group the (vertex, facet) incidences of every vertex by facet normal:
    in each round the first ungrouped incidence of a vertex opens a group,
    which every ungrouped incidence of that vertex within the corner angle
    joins.  ``vertex`` (k,) sorted, ``normal`` (k, dim); returns the group
    number (k,) of every incidence."""
    group = np.full(len(vertex), -1)
    for g in range(rounds):
        idx = np.flatnonzero(group < 0)
        if len(idx) == 0:
            return group
        v = vertex[idx]
        leads = idx[np.r_[True, v[1:] != v[:-1]]]
        lead_of = leads[np.searchsorted(vertex[leads], v)]
        close = np.einsum("kd,kd->k", normal[idx], normal[lead_of]) >= cos_corner
        group[idx[close]] = g
    if (group < 0).any():
        k = int(vertex[np.flatnonzero(group < 0)[0]])
        raise ValueError(f"slave vertex {k} joins more than {rounds} faces of distinct "
                         "normals; use collocation='nodal'")
    return group


def _split_by_normals(mesh, facets, hats):
    """Contact nodes: one per slave vertex and face of the slave surface
    meeting there (facets whose normals differ by more than
    :data:`CORNER_ANGLE` degrees make distinct faces: the corners of a 2D
    section, the edges and corners of a box), each with the part of its hat
    function on that face, so that a weighted gap never mixes two faces.

    Returns the hat values at the Gauss points (sparse nq × m; the rows of
    ``hats`` are facet-major) and the vertex of every contact node."""
    from skfem import FacetBasis

    fb = FacetBasis(mesh, type(mesh).elem(), facets=facets, intorder=1)
    normal = np.asarray(fb.normals)[:, :, 0].T  # (nf, dim), one per (flat) facet
    fv = mesh.facets[:, facets]
    vertex = fv.T.ravel()
    facet = np.repeat(np.arange(len(facets)), fv.shape[0])
    order = np.argsort(vertex, kind="stable")
    vertex, facet = vertex[order], facet[order]
    group = _facet_groups(vertex, normal[facet], np.cos(np.radians(CORNER_ANGLE)))
    nodes = np.unique(vertex)
    extra = group > 0
    keys = np.unique(vertex[extra].astype(np.int64) * 8 + group[extra])
    column_of = np.full(len(vertex), -1)
    column_of[~extra] = np.searchsorted(nodes, vertex[~extra])
    column_of[extra] = len(nodes) + np.searchsorted(
        keys, vertex[extra].astype(np.int64) * 8 + group[extra])
    coo = sp.coo_matrix(hats)
    keep = np.isin(coo.col, nodes) & (coo.data != 0)
    row, col, data = coo.row[keep], coo.col[keep], coo.data[keep]
    row_facet = row // (hats.shape[0] // len(facets))
    # the incidence (vertex col, facet row_facet) in the sorted list
    incidence = np.lexsort((facet, vertex))
    pairs = vertex[incidence].astype(np.int64) * len(facets) + facet[incidence]
    at = incidence[np.searchsorted(pairs, col.astype(np.int64) * len(facets) + row_facet)]
    out = sp.csr_matrix((data, (row, column_of[at])),
                        shape=(hats.shape[0], len(nodes) + len(keys)))
    return out, np.concatenate([nodes, keys // 8])


def slave_points(basis, boundaries=None, collocation="nodal", model="plane_strain",
                 intorder=None):
    """The slave points of the named boundaries of a basis.

    Parameters
    ----------
    basis : RKBasis or skfem vector basis
    boundaries : str, sequence of str, facet indices, or None
        Named boundaries (``mesh.boundaries``), facet indices, or the whole
        boundary.
    collocation : {"nodal", "quadrature", "gauss"}
        ``"nodal"``: the boundary particles (Eq. 4.26-4.29).
        ``"quadrature"``: the boundary Gauss points, with the contact law
        applied at the boundary particles to hat-weighted averages of the
        Gauss point gaps and slips.  ``"gauss"``: the contact law at every
        Gauss point (over-constrains the boundary; kept for comparison).
    model : {"plane_strain", "axisymmetric"}
        Axisymmetric weights include ``2πR`` (forces for the full ring).
    intorder : int, optional
        Facet quadrature degree (``"quadrature"``); default that of the RK
        basis (so that a uniform traction is integrated like the VCI
        boundary terms) or twice the FEM element degree.

    Returns
    -------
    SlavePoints
    """
    _check_model(basis, model)
    facets = _facets(basis.mesh, boundaries)
    if len(facets) == 0:
        raise ValueError("the slave boundary has no facets")
    axisymmetric = model == "axisymmetric"
    if collocation == "nodal":
        return _nodal_points(basis, facets, axisymmetric)
    if collocation in ("quadrature", "gauss"):
        return _quadrature_points(basis, facets, axisymmetric, intorder,
                                  pointwise=collocation == "gauss")
    raise ValueError("collocation must be 'nodal', 'quadrature' or 'gauss', "
                     f"not {collocation!r}")


# ---------------------------------------------------------------------------
