"""Nodal essential conditions by the transformation method, Eq. (3.31)-(3.37).

RK coefficients ``d`` are not nodal values; the nodal values are
``d̂ = Λᵀ d`` (Eq. 3.32-3.34).  The paper solves ``K̂ d̂ = f̂`` with
``K̂ = Λ⁻¹ K Λ⁻ᵀ`` and ``f̂ = Λ⁻¹ f`` and prescribes entries of ``d̂``
(Eq. 3.37).  That is the minimum of ``½ dᵀ K d - fᵀ d`` over ``d`` subject to
the sparse linear constraints ``(Λᵀ d)_D = g``, so we solve the equivalent
saddle-point system

    [ K   Cᵀ ] [ d ]   [ f ]
    [ C   0  ] [ -λ] = [ g ],     C = rows D of Λᵀ,

which never forms ``Λ⁻¹``.  ``λ`` are the nodal reaction forces.  For a
scikit-fem (FEM) basis ``Λ`` is the identity and the same call prescribes
nodal values directly.
"""

import numpy as np
import scipy.sparse as sp
from skfem.element import ElementVector

from ..solvers.linear import make_solver, solve_saddle_point

__all__ = ["transformation", "solve", "solve_constrained", "linear_solve",
           "Constraint", "nodal_constraint", "weak_constraint"]

def transformation(basis):
    """Λᵀ of a basis: its ``nodal_matrix`` or, for FEM bases, the identity."""
    nodal = getattr(basis, "nodal_matrix", None)
    if nodal is None:
        return sp.identity(basis.N, format="csr")
    return nodal


def linear_solve(A, b, solver="auto"):
    """Solve ``A x = b``; ``solver`` is a name or a :class:`~skfem_rkpm.solvers.linear.Solver`.

    The default picks dense LU when small and sparse LU (SuperLU, minimum
    degree ordering of ``Aᵀ + A``, symmetric mode, COLAMD fallback) or an
    installed faster backend otherwise; see :mod:`skfem_rkpm.solvers.linear`.
    """
    return make_solver(solver).factor(A).solve(b)


def _prescribed_values(D, x, N):
    if x is None:
        return np.zeros(len(D))
    x = np.asarray(x, dtype=float)
    if x.shape == (N,):
        return x[D]
    if x.shape == (len(D),) or x.ndim == 0:
        return np.broadcast_to(x, (len(D),)).astype(float)
    raise ValueError(f"prescribed values have shape {x.shape}; give one value per "
                     f"constrained dof ({len(D)}) or a full vector ({N})")


def solve(K, f, basis, D=None, x=None, return_reactions=False):
    """Solve ``K d = f`` with prescribed *nodal values* on dofs ``D``.

    Parameters
    ----------
    K : sparse matrix, shape (N, N)
        Stiffness in generalized coordinates (as assembled on the basis).
    f : ndarray, shape (N,)
        Load vector in generalized coordinates.
    basis : RKBasis or skfem basis
        Supplies the transformation Λᵀ.
    D : array of int, optional
        Dofs whose nodal values are prescribed (``basis.get_dofs(...)``).
    x : ndarray, optional
        The prescribed nodal values: a full vector (N,) read at ``D``, one
        value per entry of ``D``, or a scalar.  Default zero.
    return_reactions : bool
        Also return the nodal reactions ``λ`` on ``D``.

    Returns
    -------
    d : ndarray, shape (N,)
        Generalized coefficients; ``basis.nodal_values(d)[D]`` equals ``x``.
    """
    N = K.shape[0]
    D = np.zeros(0, dtype=np.int64) if D is None else np.asarray(D, dtype=np.int64)
    g = _prescribed_values(D, x, N)
    d, reactions = solve_constrained(K, f, transformation(basis)[D], g)
    return (d, reactions) if return_reactions else d


def solve_constrained(K, f, C, g, solver="auto"):
    """Solve ``K d = f + Cᵀ λ`` subject to ``C d = g``; return ``d`` and ``λ``.

    ``λ`` are the reactions: the forces the constraints exert, conjugate to
    the constrained nodal values.  ``solver`` is a backend name or a
    :class:`~skfem_rkpm.solvers.linear.Solver` kept across calls (to reuse its
    analysis); see :func:`~skfem_rkpm.solvers.linear.solve_saddle_point`.
    """
    return solve_saddle_point(make_solver(solver), K, f, C, g)


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
