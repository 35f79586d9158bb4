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

from .nodal_integration import boundary_rule

__all__ = ["transformation", "direction", "Constraint", "ConstraintSet",
           "nodal_constraint", "weak_constraint"]


def transformation(basis, N=None):
    """Λᵀ of a basis: its ``nodal_matrix`` or, for FEM bases, the identity.

    For a system of ``N > basis.N`` unknowns (rows added to the basis's
    matrix, e.g. a Lagrange multiplier of ``∫ u = c``) the unknowns after the
    basis's coefficients are their own values: Λᵀ gets identity rows for them.
    """
    nodal = getattr(basis, "nodal_matrix", None)
    T = sp.identity(basis.N, format="csr") if nodal is None else sp.csr_matrix(nodal)
    extra = (basis.N if N is None else N) - basis.N
    if extra < 0:
        raise ValueError(f"the system has {N} unknowns, fewer than the {basis.N} "
                         f"coefficients of the basis: pass the matrix of this basis")
    return sp.block_diag([T, sp.identity(extra)], format="csr") if extra else T


class Constraint:
    """Linear constraints ``C d = R g`` on the coefficients of one basis.

    ``g`` holds the prescribed displacement of each constrained node
    (``nodes``, component ``component``: a number, or a direction ``n`` of a
    skew condition); ``weights`` are such that the resultant of the
    multipliers ``λ`` along the constrained direction is ``Σ λ · weights``:
    the row sums of ``C`` for a component, ``C (n, n, ...)`` for a direction
    (the reaction force ``Cᵀ λ`` projected on ``n``; the coefficients of a
    vector basis are interleaved by component).
    """

    def __init__(self, C, R, nodes, coordinates, component):
        self.C = sp.csr_matrix(C)
        self.R = sp.csr_matrix(R)
        self.nodes = nodes
        self.coordinates = coordinates
        self.component = component
        if isinstance(component, (int, np.integer)):
            self.weights = np.asarray(self.C.sum(axis=1)).ravel()
        else:
            n = np.asarray(component, dtype=float)
            n = n / np.linalg.norm(n)
            self.weights = self.C @ np.tile(n, self.C.shape[1] // len(n))

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


def direction(component, ncomp):
    """The unit row ``n`` (ncomp,) of a constrained displacement ``n·u``:
    ``component`` is a component number or a direction (a skew condition,
    e.g. the normal of a symmetry plane not aligned with the axes)."""
    if isinstance(component, (int, np.integer)):
        if not 0 <= component < ncomp:
            raise ValueError(f"component {component} does not exist: the basis has "
                             f"{ncomp} component(s)")
        return np.eye(ncomp)[component]
    n = np.asarray(component, dtype=float)
    if n.shape != (ncomp,) or not np.all(np.isfinite(n)) or not np.any(n):
        raise ValueError(f"a constrained direction must be {ncomp} finite numbers, not all "
                         f"zero, not {component!r}")
    return n / np.linalg.norm(n)


def _component_dofs(basis, facets, component):
    """Dofs of one displacement component on ``facets``, with their nodes and
    coordinates: a particle's for RK bases; for FEM every dof on the facets
    (vertices and higher-order nodes)."""
    mesh, ncomp = basis.mesh, _ncomp(basis)
    if hasattr(basis, "element_nodes"):
        nodes = np.unique(mesh.facets[:, facets])
        return ncomp * nodes + component, nodes, mesh.p[:, nodes]
    dofs = np.sort(basis.get_dofs(facets).all(f"u^{component + 1}")
                   if ncomp > 1 else basis.get_dofs(facets).all())
    return dofs, dofs // ncomp, basis.doflocs[:, dofs]


def nodal_constraint(basis, facets, component):
    """Prescribe nodal values on the nodes of ``facets`` (Eq. 3.37): of one
    displacement component (the rows of ``Λᵀ``), or of ``n·u`` for a
    direction ``n`` (the rows ``Σ_c n_c Λᵀ[c]``)."""
    find = _named_facets(basis.mesh, facets)
    n = direction(component, _ncomp(basis))
    T = transformation(basis)
    components = np.flatnonzero(n)
    _, nodes, x = _component_dofs(basis, find, components[0])
    C = sum(n[c] * T[_component_dofs(basis, find, c)[0]] for c in components)
    return Constraint(C, sp.identity(len(nodes)), nodes, x,
                      component if isinstance(component, (int, np.integer)) else tuple(n))


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
    """Prescribe displacements weakly along ``facets`` (boundary multipliers):
    one component, or ``n·u`` for a direction ``n`` (``component``).

    The multiplier is piecewise linear on the boundary facets, one hat
    function ``N_K`` per boundary node, and the constraints read
    ``∫_Γ N_K (u_c - g_c) dΓ = 0``.  Unlike nodal prescription, the reaction
    ``Σ_K λ_K N_K`` is a traction field: a uniform traction is represented
    exactly and homogeneous states stay exact for RK bases.  For linear
    elements with linear data it prescribes exactly the nodal values.  With
    nodal integration the default rule is that of the smoothing cells'
    boundary segments, on which the integration constraint holds.
    """
    from skfem import FacetBasis

    mesh = basis.mesh
    find = _named_facets(mesh, facets)
    quadrature = None
    if intorder is None and getattr(basis, "nodal_quadrature", None) is not None:
        quadrature = boundary_rule(basis.segment_points, mesh)
    if intorder is None:
        intorder = getattr(basis, "intorder", None) or 2 * basis.elem.maxdeg
    hats = FacetBasis(mesh, type(mesh).elem(), facets=find, intorder=intorder,
                      quadrature=quadrature)
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
    pick = sp.csr_matrix(direction(component, ncomp)[None])
    return Constraint(sp.kron(B, pick, format="csr"), M, nodes, mesh.p[:, nodes],
                      component)


class ConstraintSet:
    """The rows of several :class:`Constraint` stacked, dependent rows removed.

    Two conditions that prescribe the same component at a shared node (two
    boundaries meeting at a corner, both fixing ``x``) give the same row of
    ``Λᵀ`` twice; weak conditions on such boundaries give rows that are
    dependent for FEM bases.  The stacked ``C`` is then rank deficient and
    neither the saddle-point system nor the reaction fit ``C Cᵀ`` can be
    factored.  The rows of the conditions that share a column with another
    condition are tested in the order given; a row dependent on the rows
    kept before it is removed, and its prescribed value is checked against
    the same combination of the kept rows' values.

    The multipliers of the removed rows are zero, so at a shared node the
    reaction counts in the condition listed first, and the resultants of all
    conditions add up to the total reaction force.

    Parameters
    ----------
    constraints : sequence of Constraint
    N : int
        Number of coefficients (columns).
    names : sequence of str, optional
        A name per constraint, for error messages.
    tol : float
        A row is dependent when its part orthogonal to the kept rows is
        below ``tol`` times its norm (``C Cᵀ`` would otherwise have a
        condition number near ``tol⁻²``).
    """

    def __init__(self, constraints, N, names=None, tol=1e-8):
        self.constraints = list(constraints)
        self.names = list(names) if names is not None else [
            f"condition {k}" for k in range(len(self.constraints))]
        sizes = [len(c) for c in self.constraints]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        full = sp.vstack([c.C for c in self.constraints] or [sp.csr_matrix((0, N))],
                         format="csr")
        owner = np.repeat(np.arange(len(sizes)), sizes)
        self.keep, self.removed, self.combination = _independent_rows(full, owner, tol)
        self.owner = owner
        self.C = full[self.keep]

    def __len__(self):
        return len(self.keep)

    def values(self, g):
        """The kept entries of the stacked prescribed values ``g`` (one per
        row of all constraints); raises ValueError where a removed row's
        value contradicts the kept rows'."""
        g = np.asarray(g, dtype=float)
        if len(self.removed):
            implied = self.combination @ g[self.keep]
            scale = np.abs(self.combination) @ np.abs(g[self.keep]) + np.abs(g[self.removed])
            bad = np.flatnonzero(np.abs(g[self.removed] - implied) > 1e-8 * scale)
            if bad.size:
                self._conflict(self.removed[bad[0]], g[self.removed[bad[0]]],
                               implied[bad[0]])
        return g[self.keep]

    def _conflict(self, row, value, implied):
        k = int(self.owner[row])
        c = self.constraints[k]
        local = row - self.offsets[k]
        where = ", ".join(f"{x:.6g}" for x in c.coordinates[:, local])
        column = np.flatnonzero(self.combination[np.searchsorted(self.removed, row)])
        others = sorted({self.names[int(self.owner[self.keep[j]])] for j in column})
        raise ValueError(
            f"{self.names[k]} and {', '.join(others)} prescribe different values of "
            f"component {c.component} at the shared node X = ({where}): {value:.6g} and "
            f"{implied:.6g}; give both the same value there or prescribe it once")

    def expand(self, lam):
        """Multipliers of every stacked row: ``lam`` on the kept rows, 0 elsewhere."""
        full = np.zeros(self.offsets[-1])
        full[self.keep] = lam
        return full

    def split(self, lam):
        """The multipliers of each constraint (a list), from those of the kept rows."""
        full = self.expand(lam)
        return [full[a:b] for a, b in zip(self.offsets[:-1], self.offsets[1:])]


def _independent_rows(C, owner, tol):
    """Rows of ``C`` to keep, rows removed and their combination of the kept.

    Only conditions that share a column with another condition can have
    dependent rows (the rows of one condition are independent: rows of the
    invertible ``Λᵀ``, or boundary integrals against independent hats).
    Their rows are taken in order (within a condition, those at shared
    columns last) and a row is removed when its part
    orthogonal to the rows kept before it is below ``tol`` times its norm
    (:func:`_in_order_independent`).  A whole condition is taken, not only
    its rows near the shared columns, because a dependency can reach along
    it (the weak rows ``∫ N_K u`` of a linear FEM edge combine to the value
    at its end).

    Returns ``keep`` (sorted row indices), ``removed`` (sorted) and a
    (len(removed), len(keep)) matrix ``A`` with ``C[removed] = A C[keep]``.
    """
    m = C.shape[0]
    everything = np.arange(m)
    nothing = (everything, np.zeros(0, np.int64), np.zeros((0, m)))
    if m == 0 or owner.max(initial=0) == 0:
        return nothing
    pattern = abs(C).astype(bool).astype(np.int64).tocsr()
    ngroups = owner.max() + 1
    groups = sp.csr_matrix((np.ones(m), (owner, everything)), shape=(ngroups, m))
    touches = ((groups @ pattern) > 0).astype(np.int64)
    shared = np.asarray(touches.sum(axis=0)).ravel() >= 2
    involved = np.asarray(touches[:, shared].sum(axis=1)).ravel() > 0
    candidates = np.flatnonzero(involved[owner])
    if candidates.size == 0:
        return nothing
    # within each condition the rows at the shared columns come last, so
    # that a dependency removes a row at a shared node, not one far from it
    at_shared = (pattern[candidates] @ shared.astype(np.int64)) > 0
    candidates = candidates[np.lexsort((at_shared, owner[candidates]))]
    block = C[candidates]
    rows = block[:, np.unique(block.indices)].toarray()
    kept, removed_local, coef = _in_order_independent(rows, tol)
    order = np.argsort(candidates[removed_local])
    removed = candidates[removed_local][order]
    keep = np.setdiff1d(everything, removed)
    A = np.zeros((len(removed), len(keep)))
    A[:, np.searchsorted(keep, candidates[kept])] = coef[order]
    return keep, removed, A


def _in_order_independent(rows, tol):
    """Rows of the dense ``rows`` independent of the rows kept before them.

    Classical Gram-Schmidt with a second pass (orthogonal to round-off): a
    row whose part orthogonal to the kept ones is below ``tol`` times its
    norm is removed.  Returns the kept and removed positions and the
    combination ``rows[removed] = coef @ rows[kept]`` (least squares).
    """
    Q = np.zeros_like(rows)
    kept, removed = [], []
    for i, v in enumerate(rows):
        n = len(kept)
        w = v - Q[:n].T @ (Q[:n] @ v)
        w -= Q[:n].T @ (Q[:n] @ w)
        size = np.linalg.norm(w)
        if size > tol * np.linalg.norm(v):
            Q[n] = w / size
            kept.append(i)
        else:
            removed.append(i)
    coef = np.zeros((len(removed), len(kept)))
    if removed:
        coef = np.linalg.lstsq(rows[kept].T, rows[removed].T, rcond=None)[0].T
    return np.array(kept, np.int64), np.array(removed, np.int64), coef
