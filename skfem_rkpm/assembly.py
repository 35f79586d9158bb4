"""Vectorized assembly of gradient forms for RK and FEM bases alike.

scikit-fem's assembly loops in Python over every pair of local functions,
which is fine for FEM (4-9 functions per cell) and slow for RK bases
(30-130).  The built-in mechanics only need forms in which test and trial
functions enter through their gradients,

    K[(a,c), (b,d)] = ∫ ∂_l Ñ_a  C_{c l d m}  ∂_m N_b  dΩ,      f[(a,c)] = ∫ ∂_l Ñ_a P_{c l} dΩ,

(``Ñ``: test functions, VCI-corrected for RK; ``N``: trial functions) plus
the mass-type form ``∫ Ñ_a s N_b``.  The :class:`Assembler` reads any basis
as per-cell scalar local functions, computes all local matrices with
``einsum`` and batched matrix products, and scatters them into a CSR matrix
whose sparsity pattern and scatter map are computed once.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import FacetBasis
from skfem.element import ElementVector

__all__ = ["Layout", "layout", "axisymmetric_layout", "Assembler", "isotropic_tangent",
           "facet_basis"]

#: most cells per block of the local computations
CELLS_PER_BLOCK = 256
#: entries of the largest per-block temporary (fewer cells per block when a
#: cell has many local functions): keeps the blocks in cache
BLOCK_ENTRIES = 2**18
#: the gradient tables are also kept cell by cell (in the layouts of the
#: batched products) when they have at most this many entries
CACHE_ENTRIES = 2**22


@dataclass
class Layout:
    """A basis seen as scalar local functions per cell.

    Attributes
    ----------
    element_nodes : ndarray, shape (nloc, nelems)
        Scalar function (particle / scalar dof) of each local slot.
    values : ndarray, shape (nloc, nelems, nqp)
    trial_grads, test_grads : ndarray, shape (dim, nloc, nelems, nqp)
    dx : ndarray, shape (nelems, nqp)
        Quadrature weights times Jacobians.
    ncomp : int
        Field components; dof of (slot node I, component c) is ``ncomp*I + c``.
    nscalar : int
        Number of scalar functions.
    """

    element_nodes: np.ndarray
    values: np.ndarray
    trial_grads: np.ndarray
    test_grads: np.ndarray
    dx: np.ndarray
    ncomp: int
    nscalar: int

    @property
    def N(self):
        return self.ncomp * self.nscalar

    @property
    def dim(self):
        """Rows of the (possibly extended) gradient."""
        return self.trial_grads.shape[0]


def layout(basis):
    """The :class:`Layout` of an RK basis or of a scikit-fem ``CellBasis``.

    scikit-fem vector bases must use ``ElementVector``, whose dof ``dim*s + c``
    belongs to scalar dof ``s`` and component ``c``.
    """
    if hasattr(basis, "element_nodes"):  # RKBasis
        return Layout(basis.element_nodes, basis.values, basis.trial.grads,
                      basis.grads, basis.dx, basis.ncomp, basis.nnodes)
    ncomp = basis.elem.dim if isinstance(basis.elem, ElementVector) else 1
    first = basis.element_dofs[::ncomp]
    for c in range(1, ncomp):
        if not np.array_equal(basis.element_dofs[c::ncomp], first + c):
            raise ValueError("vector basis dofs are not interleaved (dim*s + c); "
                             "use skfem.ElementVector")
    if np.any(first % ncomp):
        raise ValueError("vector basis dofs are not interleaved (dim*s + c)")
    fields = [basis.basis[ncomp * k][0] for k in range(first.shape[0])]
    if ncomp > 1:
        values = np.array([f[0] for f in fields])
        grads = np.array([f.grad[0] for f in fields]).transpose(1, 0, 2, 3)
    else:
        values = np.array([np.asarray(f) for f in fields])
        grads = np.array([f.grad for f in fields]).transpose(1, 0, 2, 3)
    return Layout(first // ncomp, values, grads, grads, basis.dx, ncomp,
                  basis.N // ncomp)


def isotropic_tangent(lam, mu, dim):
    """``C_{c l d m} = λ δ_cl δ_dm + μ (δ_cd δ_lm + δ_cm δ_ld)``, shape (dim,)*4."""
    I = np.eye(dim)
    return (lam * np.einsum("cl,dm->cldm", I, I)
            + mu * (np.einsum("cd,lm->cldm", I, I) + np.einsum("cm,ld->cldm", I, I)))


def axisymmetric_layout(L, radius):
    """Append the hoop row ``N/R`` to the gradients and weigh ``dx`` by ``2πR``.

    The extended gradient of a vector field then holds ``u_r/R`` (the hoop
    strain) at row ``(c=0, l=dim)``; volumes and forces refer to the full ring.
    """
    R = np.asarray(radius)
    if np.any(R <= 0):
        raise ValueError("axisymmetric model: quadrature points need radius > 0 "
                         f"(smallest is {R.min():.3g}); the axis is x = 0")
    hoop = (L.values / R)[None]
    return Layout(L.element_nodes, L.values,
                  np.concatenate([L.trial_grads, hoop]),
                  np.concatenate([L.test_grads, hoop]),
                  2.0 * np.pi * R * L.dx, L.ncomp, L.nscalar)


class Assembler:
    """Assemble gradient forms on one basis with a cached sparsity pattern.

    Parameters
    ----------
    basis : RKBasis or skfem CellBasis
    axisymmetric : bool
        Add the hoop row ``N/R`` (see :func:`axisymmetric_layout`); x is the
        radius.
    """

    def __init__(self, basis, axisymmetric=False):
        self.layout = L = layout(basis)
        if axisymmetric:
            radius = np.asarray(basis.global_coordinates())[0]
            self.layout = L = axisymmetric_layout(L, radius)
        c, nloc, nelems = L.ncomp, *L.element_nodes.shape
        self.element_dofs = (c * L.element_nodes[:, None, :]
                             + np.arange(c)[None, :, None]).reshape(nloc * c, nelems)
        self._cache = {}
        self._build_pattern()

    def _build_pattern(self):
        """CSR pattern of the vector matrix and the scatter map of local entries.

        The scalar pattern (particle x particle) comes from a sparse product
        of the cell-particle incidence; each local entry finds its place by
        binary search in the sorted scalar keys, and scalar entries expand to
        ``c x c`` blocks analytically.  The scatter map follows the local
        matrices cell by cell, in the order (cell, a, c, d, b): test slot
        ``a``, its component ``c``, the trial component ``d``, trial slot ``b``.
        """
        L = self.layout
        c, (nloc, nelems), n = L.ncomp, L.element_nodes.shape, L.nscalar
        cells = np.broadcast_to(np.arange(nelems), (nloc, nelems))
        incidence = sp.csr_matrix((np.ones(cells.size), (cells.ravel(),
                                   L.element_nodes.ravel())), shape=(nelems, n))
        pattern = (incidence.T @ incidence).tocsr()
        pattern.sort_indices()
        indptr_s, cols_s = pattern.indptr, pattern.indices
        rows_s = np.repeat(np.arange(n), np.diff(indptr_s))
        keys = rows_s.astype(np.int64) * n + cols_s
        nodes = np.ascontiguousarray(L.element_nodes.T)  # (nelems, nloc)
        I = nodes[:, :, None].astype(np.int64)
        J = nodes[:, None, :]
        position = np.searchsorted(keys, (I * n + J).ravel()).reshape(nelems, nloc, nloc)
        # vector CSR: scalar row I becomes rows cI..cI+c-1, each holding the
        # c x c blocks of the scalar row in column order
        length = np.diff(indptr_s)
        start = indptr_s[:-1]
        # entry (cell, a, c_a, c_b, b) goes to c² start_I + c_a c length_I
        # + c (position - start_I) + c_b, with I the particle of slot a
        first = start[nodes].astype(np.intp)[:, :, None]
        block = c * c * first + c * (position - first)  # (E, a, b)
        row = (c * length[nodes]).astype(np.intp)[:, :, None]  # (E, a, 1)
        scatter = np.empty((nelems, nloc, c, c, nloc), dtype=np.intp)
        for c_a in range(c):
            for c_b in range(c):
                np.add(block, c_a * row + c_b, out=scatter[:, :, c_a, c_b, :])
        self._scatter = scatter.reshape(-1)
        self.nnz = c * c * len(keys)
        self.indptr = np.concatenate([[0], np.cumsum(np.repeat(c * length, c))])
        # column indices: vector row cI+a repeats the block columns of row I
        block_cols = (c * cols_s[:, None] + np.arange(c)[None, :]).ravel()
        row_length = np.repeat(c * length, c)
        row_source = np.repeat(c * start, c)
        offset = np.arange(self.nnz) - np.repeat(self.indptr[:-1], row_length)
        self._pattern_cols = block_cols[np.repeat(row_source, row_length) + offset]

    @property
    def N(self):
        return self.layout.N

    def _blocks(self, entries_per_cell=1):
        """Slices of cells, each block's temporaries at most ``BLOCK_ENTRIES``."""
        nelems = self.layout.element_nodes.shape[1]
        step = max(1, min(CELLS_PER_BLOCK, BLOCK_ENTRIES // entries_per_cell))
        for start in range(0, nelems, step):
            yield slice(start, min(start + step, nelems))

    def matrix(self, local):
        """Sum local matrices into the cached CSR pattern.

        ``local`` holds one matrix per cell in the order of the scatter map,
        (nelems, nloc, c, c, nloc) or any shape with as many entries
        (:meth:`local_bilinear`, :meth:`local_outer`).
        """
        data = np.bincount(self._scatter, weights=local.ravel(), minlength=self.nnz)
        return sp.csr_matrix((data, self._pattern_cols, self.indptr),
                             shape=(self.N, self.N))

    def bilinear(self, C):
        """``∫ ∂_l Ñ_a C_{c l d m} ∂_m N_b``.

        Parameters
        ----------
        C : ndarray, shape (c, dim, c, dim) or (c, dim, c, dim, nelems, nqp)
            Tangent (scalar fields: ``c = 1``).
        """
        return self.matrix(self.local_bilinear(C))

    def local_bilinear(self, C, out=None):
        """Local matrices of :meth:`bilinear`, shape (nelems, nloc, c, c, nloc).

        Per block of cells, ``R = C ∂N`` of the trial functions is formed
        first (a 3-term product per quadrature point), then one batched
        matrix product with the weighted test gradients gives the local
        matrices.  A tangent per point is read in the layout
        (nelems, nqp, dim, c, c, dim), without a copy if ``C`` is a
        transposed view of an array stored that way.  ``out`` (an earlier
        result) is overwritten instead of allocating new local matrices.
        """
        L = self.layout
        c, nloc, nelems = L.ncomp, *L.element_nodes.shape
        C = np.asarray(C, dtype=float)
        dim, nqp = L.dim, L.dx.shape[1]
        if C.ndim == 6:  # (E, q, l, c, d, m) as a matrix (l c d) x m per point
            C = np.ascontiguousarray(C.transpose(4, 5, 1, 0, 2, 3)).reshape(
                nelems, nqp, dim * c * c, dim)
        else:
            C = C.transpose(1, 0, 2, 3).reshape(dim * c * c, dim)
        local = np.empty((nelems, nloc, c, c, nloc)) if out is None else out
        for s in self._blocks(dim * nqp * c * c * nloc):  # size of R
            E = s.stop - s.start
            # R[E, q, (l c d), b] = Σ_m C[E, q, (l c d), m] ∂_m N_b
            R = np.matmul(C[s] if C.ndim == 4 else C, self._trial_grads(s))
            # local[E, a, (c d b)] = Σ_(q l) T[E, a, (q l)] R[E, (q l), (c d b)]
            np.matmul(self._weighted_test_grads(s), R.reshape(E, nqp * dim, c * c * nloc),
                      out=local[s].reshape(E, nloc, c * c * nloc))
        return local

    def _cached(self, key, s, compute):
        """``compute(s)``, from a copy for all cells kept if small enough."""
        full = self._cache.get(key)
        if full is None:
            if self.layout.trial_grads.size > CACHE_ENTRIES:
                return compute(s)
            full = self._cache[key] = np.ascontiguousarray(compute(slice(None)))
        return full[s]

    def _trial_grads(self, s):
        """``∂_m N_b`` on cells ``s``, shape (cells, nqp, dim, nloc)."""
        return self._cached("trial", s, lambda s: self.layout.trial_grads[:, :, s]
                            .transpose(2, 3, 0, 1))

    def _weighted_test_grads(self, s):
        """``∂_l Ñ_a dΩ`` on cells ``s``, shape (cells, nloc, nqp * dim)."""
        return self._cached("test", s,
                            lambda s: self._weighted_grads(s, self.layout.test_grads))

    def _weighted_trial_grads(self, s):
        """``∂_l N_a dΩ`` on cells ``s``, shape (cells, nloc, nqp * dim)."""
        return self._cached("weighted trial", s,
                            lambda s: self._weighted_grads(s, self.layout.trial_grads))

    def _weighted_grads(self, s, grads):
        """``grads`` (dim, nloc, nelems, nqp) times ``dΩ`` on cells ``s``, shape
        (cells, nloc, nqp * dim)."""
        T = (grads[:, :, s] * self.layout.dx[s]).transpose(2, 1, 3, 0)  # (E, a, q, l)
        return T.reshape(T.shape[0], T.shape[1], -1)

    def mass(self, density=1.0):
        """``∫ Ñ_a ρ N_b δ_cd`` (values are not corrected by VCI)."""
        L = self.layout
        c, nloc, nelems = L.ncomp, *L.element_nodes.shape
        rho = np.broadcast_to(np.asarray(density, dtype=float), L.dx.shape)
        scalar = np.empty((nelems, nloc, nloc))
        for s in self._blocks():
            V = L.values[:, s].transpose(1, 0, 2)  # (E, a, q)
            np.matmul(V * (rho[s] * L.dx[s])[:, None, :], V.transpose(0, 2, 1),
                      out=scalar[s])
        local = np.zeros((nelems, nloc, c, c, nloc))
        for comp in range(c):  # δ_cd: the same scalar block on each component
            local[:, :, comp, comp, :] = scalar
        return self.matrix(local)

    def cell_vectors(self, P, test=True):
        """Per-cell vectors ``∫_e ∂_l N_a P_{c l}``, shape (nloc * c, nelems).

        ``test=False`` uses the trial gradients instead of the test gradients.
        """
        L = self.layout
        c, nloc, nelems = L.ncomp, *L.element_nodes.shape
        P = np.asarray(P, dtype=float).reshape(c, L.dim, nelems, -1)
        everything = slice(None)
        grads = (self._weighted_test_grads(everything) if test
                 else self._weighted_trial_grads(everything))
        # local[E, a, c] = Σ_(q l) ∂_l N_a dΩ [E, a, (q l)] P[E, (q l), c]
        local = grads @ P.transpose(2, 3, 1, 0).reshape(nelems, -1, c)
        return local.reshape(nelems, nloc * c).T

    def scatter(self, local):
        """Sum per-cell vectors (nloc * c, nelems) into a global vector."""
        return np.bincount(self.element_dofs.ravel(), weights=local.ravel(),
                           minlength=self.N)

    def linear(self, P):
        """``f[(a,c)] = ∫ ∂_l Ñ_a P_{c l}``; ``P`` has shape (c, dim, nelems, nqp)."""
        return self.scatter(self.cell_vectors(P))

    def outer(self, u, w):
        """Matrix of the per-cell rank-one blocks ``u_e ⊗ w_e`` (nloc * c, nelems)."""
        return self.matrix(self.local_outer(u, w))

    def local_outer(self, u, w):
        """Local matrices of :meth:`outer`, shape (nelems, nloc, c, c, nloc)."""
        U, W = self._outer_factors(u, w)
        return U * W

    def add_outer(self, local, u, w):
        """Add the blocks of :meth:`local_outer` to ``local`` in place, block by
        block of cells (no temporary as large as ``local``)."""
        U, W = self._outer_factors(u, w)
        L = self.layout
        for s in self._blocks(L.ncomp**2 * L.element_nodes.shape[0]**2):
            local[s] += U[s] * W[s]
        return local

    def _outer_factors(self, u, w):
        """``u`` as (nelems, nloc, c, 1, 1) and ``w`` as (nelems, 1, 1, c, nloc)."""
        L = self.layout
        c, nloc, nelems = L.ncomp, *L.element_nodes.shape
        U = u.T.reshape(nelems, nloc, c, 1, 1)
        W = w.T.reshape(nelems, nloc, c).transpose(0, 2, 1)[:, None, None]
        return U, W

    def gradient(self, u):
        """``∂_m u_c`` at the quadrature points, shape (c, dim, nelems, nqp)."""
        L = self.layout
        U = np.asarray(u).reshape(L.nscalar, L.ncomp)[L.element_nodes]  # (nloc, nelems, c)
        # H[E, q, m, c] = Σ_a ∂_m N_a [E, q, m, a] U[E, a, c]
        H = self._trial_grads(slice(None)) @ U.transpose(1, 0, 2)[:, None]
        return H.transpose(3, 2, 0, 1)


def facet_basis(basis, facets=None):
    """The facet basis matching ``basis`` on a named boundary (default: all)."""
    if hasattr(basis, "element_nodes"):
        return basis.boundary(facets)
    if isinstance(facets, str):
        facets = basis.mesh.boundaries[facets]
    return FacetBasis(basis.mesh, basis.elem, facets=facets,
                      intorder=2 * basis.elem.maxdeg + 2)
