"""The transformation Λ of the nodal values (Eq. 3.32-3.34) and the
constraint rows built from it: nodal values prescribed on a boundary (the
rows of Eq. 3.37) or weak boundary multipliers.

RK coefficients ``d`` are not nodal values; the nodal values are
``d̂ = Λᵀ d``.  This module builds rows ``C`` of ``Λᵀ`` (or of a boundary
integral against ``Λ``) and solves nothing: the constrained solves are in
:mod:`skfem_rkpm.solvers.constrained`.  For a scikit-fem (FEM) basis ``Λ``
is the identity.
"""

import numpy as np
import scipy.sparse as sp
from skfem.element import ElementVector

__all__ = ["transformation", "Constraint", "nodal_constraint", "weak_constraint"]


def transformation(basis):
    """Λᵀ of a basis: its ``nodal_matrix`` or, for FEM bases, the identity."""
    nodal = getattr(basis, "nodal_matrix", None)
    if nodal is None:
        return sp.identity(basis.N, format="csr")
    return nodal


class Constraint:
    """Linear constraints ``C d = R g`` on the coefficients of one basis.

    ``g`` holds the prescribed displacement of each constrained node
    (``nodes``, component ``component``); ``weights`` are the row sums of
    ``C`` so that the resultant of the multipliers ``λ`` is ``Σ λ · weights``.
    """

    def __init__(self, C, R, nodes, coordinates, component):
        self.C = sp.csr_matrix(C)
        self.R = sp.csr_matrix(R)
        self.nodes = nodes
        self.coordinates = coordinates
        self.component = component
        self.weights = np.asarray(self.C.sum(axis=1)).ravel()

    def __len__(self):
        return self.C.shape[0]


def _ncomp(basis):
    if hasattr(basis, "ncomp"):
        return basis.ncomp
    return basis.elem.dim if isinstance(basis.elem, ElementVector) else 1


def _named_facets(mesh, facets):
    if isinstance(facets, str):
        if facets not in (mesh.boundaries or {}):
            raise ValueError(f"the mesh has no boundary named {facets!r}; it has "
                             f"{sorted(mesh.boundaries or {})}")
        return np.asarray(mesh.boundaries[facets])
    return np.asarray(facets)


def nodal_constraint(basis, facets, component):
    """Prescribe nodal values on the nodes of ``facets`` (Eq. 3.37)."""
    mesh = basis.mesh
    find = _named_facets(mesh, facets)
    ncomp = _ncomp(basis)
    if hasattr(basis, "element_nodes"):
        nodes = np.unique(mesh.facets[:, find])
        dofs = ncomp * nodes + component
        x = mesh.p[:, nodes]
    else:  # FEM: every dof on the facets, vertices and higher-order nodes
        dofs = np.sort(basis.get_dofs(find).all(f"u^{component + 1}")
                       if ncomp > 1 else basis.get_dofs(find).all())
        nodes, x = dofs // ncomp, basis.doflocs[:, dofs]
    return Constraint(transformation(basis)[dofs], sp.identity(len(dofs)),
                      nodes, x, component)


def _facet_values(fb):
    """Sparse (facet quadrature points x dofs) matrix of a scalar FacetBasis."""
    nq = fb.X.shape[-1]
    rows = np.arange(fb.nelems * nq).reshape(fb.nelems, nq)
    data, r, c = [], [], []
    for i in range(fb.Nbfun):
        data.append(np.asarray(fb.basis[i][0]).ravel())
        r.append(rows.ravel())
        c.append(np.repeat(fb.element_dofs[i], nq))
    return sp.csr_matrix((np.concatenate(data), (np.concatenate(r), np.concatenate(c))),
                         shape=(fb.nelems * nq, fb.N))


def weak_constraint(basis, facets, component, intorder=None):
    """Prescribe displacements weakly along ``facets`` (boundary multipliers).

    The multiplier is piecewise linear on the boundary facets, one hat
    function ``N_K`` per boundary node, and the constraints read
    ``∫_Γ N_K (u_c - g_c) dΓ = 0``.  Unlike nodal prescription, the reaction
    ``Σ_K λ_K N_K`` is a traction field: a uniform traction is represented
    exactly and homogeneous states stay exact for RK bases.  For linear
    elements with linear data it prescribes exactly the nodal values.
    """
    from skfem import FacetBasis

    mesh = basis.mesh
    find = _named_facets(mesh, facets)
    if intorder is None:
        intorder = getattr(basis, "intorder", None) or 2 * basis.elem.maxdeg
    hats = FacetBasis(mesh, type(mesh).elem(), facets=find, intorder=intorder)
    Nhat = _facet_values(hats)
    W = sp.diags(np.asarray(hats.dx).ravel())
    if hasattr(basis, "element_nodes"):  # RK: shape functions at the same points
        xq = np.asarray(hats.global_coordinates()).reshape(mesh.dim(), -1)
        trial = basis._shape_table(xq, gradients=False).matrix()
    else:
        scalar = basis.elem.elem if hasattr(basis.elem, "elem") else basis.elem
        trial = _facet_values(FacetBasis(mesh, scalar, facets=find, intorder=intorder))
    nodes = np.unique(mesh.facets[:, find])
    B = (Nhat.T @ W @ trial).tocsr()[nodes]
    M = (Nhat.T @ W @ Nhat).tocsr()[nodes][:, nodes]
    ncomp = _ncomp(basis)
    pick = sp.csr_matrix((np.ones(1), ([0], [component])), shape=(1, ncomp))
    return Constraint(sp.kron(B, pick, format="csr"), M, nodes, mesh.p[:, nodes],
                      component)
