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
whose sparsity pattern and scatter map are computed once.  Trial and test
functions may come from different bases on the same cells (``test=``), and
the "gradient" rows may be any table of the functions: :mod:`skfem_rkpm.forms`
stacks values on gradients to assemble any scikit-fem form this way.
"""

import copy
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
#: the scatter map finds matrix positions in a dense (test x trial particle)
#: table of positions if it has at most this many entries, else by binary search
DENSE_POSITIONS = 2**24
#: a scatter map with at most this many local entries is stored (intp) even
#: when the dense table of positions could find them again: a matrix is then
#: one bincount (measured on the RK billet_3d tangent, 5.4e6 local entries:
#: 11 ms against 26 ms with the places looked up again at every call); the
#: local matrices it sums have as many entries, in float64
STORED_ENTRIES = 2**24
#: above ``STORED_ENTRIES`` and up to this many local entries the scatter map
#: is stored as int32 (half the bytes of the local matrices) and widened block
#: by block when a matrix is summed (16 ms on the same tangent), instead of
#: being looked up again in the table of positions; beyond, nothing as large
#: as the local matrices is stored
COMPACT_ENTRIES = 2**27
#: local matrix entries summed per call of bincount when the places of local
#: entries are looked up block by block (dense table of positions)
SCATTER_ENTRIES = 2**21
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
    """The :class:`Layout` of an RK basis or of a scikit-fem ``CellBasis``
    (a :class:`Layout` is returned as it is).

    scikit-fem vector bases must use ``ElementVector``, whose dof ``dim*s + c``
    belongs to scalar dof ``s`` and component ``c``.
    """
    if isinstance(basis, Layout):
        return basis
    if hasattr(basis, "element_nodes"):  # RKBasis
        return Layout(basis.element_nodes, basis.values,
                      getattr(basis, "trial", basis).grads,
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
    """Assemble gradient forms with a cached sparsity pattern.

    Parameters
    ----------
    basis : RKBasis, skfem CellBasis or Layout
        The trial basis (the only one unless ``test`` is given).
    axisymmetric : bool
        Add the hoop row ``N/R`` (see :func:`axisymmetric_layout`); x is the
        radius.
    test : RKBasis, skfem CellBasis or Layout, optional
        A different test basis on the same cells and quadrature points: the
        matrices of :meth:`bilinear` then have its dofs as rows and those of
        ``basis`` as columns.  Only :meth:`bilinear`, :meth:`local_bilinear`,
        :meth:`matrix`, :meth:`linear` and :meth:`cell_vectors` (test side)
        serve a rectangular pair.
    pattern : bool
        Build the sparsity pattern now (default); ``False`` defers it to the
        first matrix, e.g. for an assembler of vectors only.
    """

    def __init__(self, basis, axisymmetric=False, test=None, pattern=True):
        self.layout = L = layout(basis)
        if axisymmetric:
            radius = np.asarray(basis.global_coordinates())[0]
            self.layout = L = axisymmetric_layout(L, radius)
        self.test_layout = L if test is None else layout(test)
        if self.test_layout.element_nodes.shape[1] != L.element_nodes.shape[1]:
            raise ValueError(
                f"the test basis has {self.test_layout.element_nodes.shape[1]} cells, "
                f"the trial basis {L.element_nodes.shape[1]}: they must share the cells")
        T = self.test_layout
        c, nloc, nelems = T.ncomp, *T.element_nodes.shape
        self.element_dofs = (c * T.element_nodes[:, None, :]
                             + np.arange(c)[None, :, None]).reshape(nloc * c, nelems)
        self._cache = {}
        self._pattern = None
        if pattern:
            self._build_pattern()

    @property
    def square(self):
        """Trial and test functions are the same scalar functions."""
        return self.test_layout is self.layout

    def with_layouts(self, trial, test=None):
        """The same sparsity pattern for other tables of the same functions.

        ``trial`` and ``test`` (default ``trial``) are :class:`Layout` objects
        with the element nodes and components of this assembler's trial and
        test layouts, and any rows in their gradient tables (e.g. values and
        gradients stacked, see :mod:`skfem_rkpm.forms`).  The pattern and
        scatter map are shared, not recomputed.
        """
        test = trial if test is None else test
        for new, old in ((trial, self.layout), (test, self.test_layout)):
            if new.ncomp != old.ncomp or new.element_nodes is not old.element_nodes and not \
                    np.array_equal(new.element_nodes, old.element_nodes):
                raise ValueError("with_layouts needs the element nodes and components "
                                 "of the original layouts")
        self._pattern_parts()  # built once, here, for all the copies
        other = copy.copy(self)
        other.layout, other.test_layout = trial, test
        other._cache = {}
        return other

    def _build_pattern(self):
        """CSR pattern of the vector matrix and how local entries find their place.

        The scalar pattern (test particle x trial particle) comes from a
        sparse product of the cell-particle incidences.  The places of the
        local entries in the CSR data (the scatter map) are found in a dense
        table of positions if the scalar matrix has at most
        ``DENSE_POSITIONS`` entries, else by binary search in the sorted
        scalar keys.  The map is kept, except when the table is used and
        there are more than ``STORED_ENTRIES`` local entries: then the
        places are looked up block by block of cells each time a matrix is
        summed, and nothing as large as the local matrices is stored.
        """
        U, V = self.layout, self.test_layout
        cu, cv = U.ncomp, V.ncomp
        nelems = U.element_nodes.shape[1]
        nu, nv = U.nscalar, V.nscalar

        def incidence(L):
            nloc = L.element_nodes.shape[0]
            cells = np.broadcast_to(np.arange(nelems), (nloc, nelems))
            return sp.csr_matrix((np.ones(cells.size), (cells.ravel(),
                                  L.element_nodes.ravel())), shape=(nelems, L.nscalar))

        pattern = (incidence(V).T @ incidence(U)).tocsr()
        pattern.sort_indices()
        indptr_s, cols_s = pattern.indptr, pattern.indices
        rows_s = np.repeat(np.arange(nv), np.diff(indptr_s))
        self._nodes_v = np.ascontiguousarray(V.element_nodes.T)  # (nelems, nloc_v)
        self._nodes_u = np.ascontiguousarray(U.element_nodes.T)
        self._length, self._start = np.diff(indptr_s), indptr_s[:-1]
        self._table = scatter = self._compact = None
        entries = nelems * self._nodes_v.shape[1] * self._nodes_u.shape[1] * cu * cv
        nnz = cu * cv * len(cols_s)
        if nu * nv <= DENSE_POSITIONS:
            self._table = np.empty((nv, nu), dtype=np.intp)
            self._table[rows_s, cols_s] = np.arange(len(cols_s))
            if entries <= STORED_ENTRIES:  # small: keep the scatter map too
                scatter = self._table_places(slice(None))
            elif entries <= COMPACT_ENTRIES and nnz < 2**31:
                self._compact = self._compact_places(entries)
        else:
            keys = rows_s.astype(np.int64) * nu + cols_s
            position = np.searchsorted(keys, (self._nodes_v[:, :, None].astype(np.int64)
                                              * nu + self._nodes_u[:, None, :]))
            scatter = self._expand(position.astype(np.intp), slice(None)).reshape(-1)
        length, start = self._length, self._start
        indptr = np.concatenate([[0], np.cumsum(np.repeat(cu * length, cv))])
        # column indices: vector row c_v I + a repeats the block columns of row I
        block_cols = (cu * cols_s[:, None] + np.arange(cu)[None, :]).ravel()
        row_length = np.repeat(cu * length, cv)
        row_source = np.repeat(cu * start, cv)
        offset = np.arange(nnz) - np.repeat(indptr[:-1], row_length)
        cols = block_cols[np.repeat(row_source, row_length) + offset]
        self._pattern = (scatter, nnz, indptr, cols)

    def _expand(self, position, s):
        """Places in the vector CSR data of the local entries of cells ``s``.

        ``position`` (cells, nloc_v, nloc_u) holds the places of the scalar
        entries.  Scalar row ``I`` becomes rows ``c_v I + c_a``, each holding
        the ``c_u``-blocks of the scalar row in column order: entry (cell, a,
        c_a, c_b, b) goes to ``c_u (position + (c_v - 1) start_I) + c_a c_u
        length_I + c_b``, with ``I`` the particle of slot ``a``.  The result
        has the order of the local matrices, (cells, nloc_v, c_v, c_u, nloc_u).
        """
        cu, cv = self.layout.ncomp, self.test_layout.ncomp
        if cu == cv == 1:
            return position
        nodes_v = self._nodes_v[s]
        block = cu * (position + (cv - 1) * self._start[nodes_v][:, :, None])
        row = (cu * self._length[nodes_v]).astype(np.intp)[:, :, None]  # (E, a, 1)
        out = np.empty(position.shape[:2] + (cv, cu, position.shape[2]), dtype=np.intp)
        for c_a in range(cv):
            for c_b in range(cu):
                np.add(block, c_a * row + c_b, out=out[:, :, c_a, c_b, :])
        return out

    def _compact_places(self, entries):
        """The scatter map as int32, looked up block by block of cells."""
        nelems = self.layout.element_nodes.shape[1]
        compact = np.empty(entries, dtype=np.int32).reshape(nelems, -1)
        for s in self._blocks(compact.shape[1], SCATTER_ENTRIES):
            compact[s] = self._table_places(s).reshape(s.stop - s.start, -1)
        return compact

    def _places(self, s):
        """Places in the CSR data of the local entries of cells ``s``, flat."""
        scatter = self._pattern_parts()[0]
        nelems = self.layout.element_nodes.shape[1]
        if scatter is not None:
            return scatter.reshape(nelems, -1)[s].reshape(-1)
        if self._compact is not None:
            return self._compact[s].reshape(-1).astype(np.intp)
        return self._table_places(s)

    def _table_places(self, s):
        """:meth:`_places` looked up in the dense table of positions."""
        flat = self._nodes_v[s][:, :, None] * self._table.shape[1]
        position = np.take(self._table, flat + self._nodes_u[s][:, None, :])
        return self._expand(position, s).reshape(-1)

    def _pattern_parts(self):
        if self._pattern is None:
            self._build_pattern()
        return self._pattern

    @property
    def nnz(self):
        """Stored entries of the assembled matrices."""
        return self._pattern_parts()[1]

    @property
    def N(self):
        return self.layout.N

    @property
    def shape(self):
        """(test dofs, trial dofs) of the assembled matrices."""
        return (self.test_layout.N, self.layout.N)

    def _block_step(self, entries_per_cell=1, entries=BLOCK_ENTRIES):
        """Cells per block so that a block's temporaries hold at most ``entries``."""
        cap = CELLS_PER_BLOCK if entries == BLOCK_ENTRIES else self.layout.dx.shape[0]
        return max(1, min(cap, entries // entries_per_cell))

    def _blocks(self, entries_per_cell=1, entries=BLOCK_ENTRIES):
        """Slices of cells, each block's temporaries at most ``entries``."""
        nelems = self.layout.element_nodes.shape[1]
        step = self._block_step(entries_per_cell, entries)
        for start in range(0, nelems, step):
            yield slice(start, min(start + step, nelems))

    def matrix(self, local):
        """Sum local matrices into the cached CSR pattern.

        ``local`` holds one matrix per cell in the order of the scatter map,
        (nelems, nloc_v, c_v, c_u, nloc_u) or any shape with as many entries
        (:meth:`local_bilinear`, :meth:`local_outer`).
        """
        scatter, nnz, indptr, cols = self._pattern_parts()
        if scatter is not None:
            data = np.bincount(scatter, weights=local.ravel(), minlength=nnz)
        else:
            nelems = self.layout.element_nodes.shape[1]
            local = local.reshape(nelems, -1)
            data = np.zeros(nnz)
            for s in self._blocks(local.shape[1], SCATTER_ENTRIES):
                data += np.bincount(self._places(s), weights=local[s].ravel(),
                                    minlength=nnz)
        return sp.csr_matrix((data, cols, indptr), shape=self.shape)

    def bilinear(self, C):
        """``∫ ∂_l Ñ_a C_{c l d m} ∂_m N_b``.

        Parameters
        ----------
        C : ndarray, shape (c_v, dim_v, c_u, dim_u) or (c_v, dim_v, c_u, dim_u, nelems, nqp)
            Tangent (scalar fields: ``c = 1``).
        """
        if self._pattern_parts()[0] is not None:
            return self.matrix(self.local_bilinear(C))
        C, width = self._tangent_matrix(C)
        nloc_v = self.test_layout.element_nodes.shape[0]
        step = self._block_step(self.test_layout.dim * self.layout.dx.shape[1] * width)

        def local_of(s):
            local = np.empty((s.stop - s.start, nloc_v, width))
            for start in range(s.start, s.stop, step):
                b = slice(start, min(start + step, s.stop))
                self._local_block(C, b, local[b.start - s.start:b.stop - s.start])
            return local

        return self.streamed(local_of, nloc_v * width)

    def streamed(self, local_of, entries_per_cell):
        """Sum local matrices formed block by block of cells, none kept:
        ``local_of(s)`` returns those of the cells ``s`` (a slice), in the
        order of :meth:`matrix` (any shape with ``entries_per_cell`` entries
        per cell).  The blocks follow each other in cell order."""
        _, nnz, indptr, cols = self._pattern_parts()
        data = np.zeros(nnz)
        for s in self._blocks(entries_per_cell, SCATTER_ENTRIES):
            data += np.bincount(self._places(s), weights=local_of(s).ravel(), minlength=nnz)
        return sp.csr_matrix((data, cols, indptr), shape=self.shape)

    def local_bilinear(self, C, out=None, rank_one=None):
        """Local matrices of :meth:`bilinear`, shape (nelems, nloc_v, c_v, c_u, nloc_u).

        Per block of cells, ``R = C ∂N`` of the trial functions is formed
        first (a 3-term product per quadrature point), then one batched
        matrix product with the weighted test gradients gives the local
        matrices.  A tangent per point is read in the layout
        (nelems, nqp, dim_v, c_v, c_u, dim_u), without a copy if ``C`` is a
        transposed view of an array stored that way.  ``out`` (an earlier
        result) is overwritten instead of allocating new local matrices.
        ``rank_one = (u, w)`` (each (nloc * c, nelems)) adds the per-cell
        blocks ``u_e ⊗ w_e`` of :meth:`local_outer` inside the same product:
        ``u`` as ``c_v`` more columns of the test gradients, ``w`` as
        ``c_v`` more rows of ``R``, so no further pass over the local
        matrices is needed (square assemblers only).
        """
        U, V = self.layout, self.test_layout
        nloc_v, nelems = V.element_nodes.shape
        C, width = self._tangent_matrix(C)
        local = (np.empty((nelems, nloc_v, V.ncomp, U.ncomp, U.element_nodes.shape[0]))
                 if out is None else out)
        flat = local.reshape(nelems, nloc_v, width)
        factors = None
        if rank_one is not None:
            u, w = self._outer_factors(*rank_one)
            factors = (self._test_grads_with(u[..., 0, 0]), w.reshape(nelems, -1))
        for s in self._blocks(V.dim * U.dx.shape[1] * width):  # size of R
            self._local_block(C, s, flat[s], factors)
        return local

    def _test_grads_with(self, u):
        """The weighted test gradients (nelems, nloc, nqp * dim) with the
        columns ``u`` (nelems, nloc, c) appended, in a buffer kept between
        calls when the gradients are cached."""
        T = self._weighted_test_grads(slice(None))
        buffer = self._cache.get("test with rank one")
        if buffer is None or buffer.shape[2] != T.shape[2] + u.shape[2]:
            buffer = np.concatenate([T, u], axis=2)
            if "test" in self._cache:
                self._cache["test with rank one"] = buffer
        else:
            buffer[:, :, T.shape[2]:] = u
        return buffer

    def _tangent_matrix(self, C):
        """``C`` as a matrix (l c d) x m, per point (nelems, nqp, ., .) or one,
        and the width c_v c_u nloc_u of a row of the local matrices."""
        U, V = self.layout, self.test_layout
        cu, cv, nelems = U.ncomp, V.ncomp, U.element_nodes.shape[1]
        C = np.asarray(C, dtype=float)
        dim_u, dim_v, nqp = U.dim, V.dim, U.dx.shape[1]
        if C.shape[:4] != (cv, dim_v, cu, dim_u) or C.ndim not in (4, 6):
            raise ValueError(f"tangent has shape {C.shape}; this assembler needs "
                             f"{(cv, dim_v, cu, dim_u)} (+ (nelems, nqp) per point)")
        if C.ndim == 6:  # (E, q, l, c, d, m) as a matrix (l c d) x m per point
            C = np.ascontiguousarray(C.transpose(4, 5, 1, 0, 2, 3)).reshape(
                nelems, nqp, dim_v * cv * cu, dim_u)
        else:
            C = C.transpose(1, 0, 2, 3).reshape(dim_v * cv * cu, dim_u)
        return C, cv * cu * U.element_nodes.shape[0]

    def _local_block(self, C, s, out, rank_one=None):
        """Local matrices of cells ``s`` into ``out`` (cells, nloc_v, width),
        with the rank-one factors of :meth:`local_bilinear` if given
        (test gradients with ``u`` appended, ``w`` as (nelems, c * nloc))."""
        E, nqp, dim_v = s.stop - s.start, self.layout.dx.shape[1], self.test_layout.dim
        grads = self._trial_grads(s)
        if rank_one is None:
            # R[E, q, (l c d), b] = Σ_m C[E, q, (l c d), m] ∂_m N_b
            R = np.matmul(C[s] if C.ndim == 4 else C, grads)
            # local[E, a, (c d b)] = Σ_(q l) T[E, a, (q l)] R[E, (q l), (c d b)]
            np.matmul(self._weighted_test_grads(s),
                      R.reshape(E, nqp * dim_v, out.shape[-1]), out=out)
            return
        T, w = rank_one
        rows, c = nqp * dim_v, self.test_layout.ncomp
        R = np.empty((E, rows + c, out.shape[-1]))
        product = R[:, :rows].reshape(E, nqp, -1, grads.shape[-1])
        np.matmul(C[s] if C.ndim == 4 else C, grads, out=product)
        # rows (rows + c'): δ_(c c') w[E, d, b], so that local += u[E, a, c] w[E, d, b]
        extra = R[:, rows:].reshape(E, c, c, -1)
        extra[...] = 0.0
        for comp in range(c):
            extra[:, comp, comp] = w[s]
        np.matmul(T[s], R, out=out)

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

    def _test_grads(self, s):
        """``∂_m Ñ_b`` on cells ``s``, shape (cells, nqp, dim, nloc)."""
        if self.same_gradients:
            return self._trial_grads(s)
        return self._cached("test grads", s, lambda s: self.test_layout.test_grads[:, :, s]
                            .transpose(2, 3, 0, 1))

    def _weighted_test_grads(self, s):
        """``∂_l Ñ_a dΩ`` on cells ``s``, shape (cells, nloc, nqp * dim)."""
        return self._cached("test", s,
                            lambda s: self._weighted_grads(s, self.test_layout.test_grads))

    def _weighted_trial_grads(self, s):
        """``∂_l N_a dΩ`` on cells ``s``, shape (cells, nloc, nqp * dim)."""
        return self._cached("weighted trial", s,
                            lambda s: self._weighted_grads(s, self.layout.trial_grads))

    def _weighted_grads(self, s, grads):
        """``grads`` (dim, nloc, nelems, nqp) times ``dΩ`` on cells ``s``, shape
        (cells, nloc, nqp * dim).  ``dΩ`` is the trial layout's, as in
        scikit-fem's bilinear forms."""
        T = (grads[:, :, s] * self.layout.dx[s]).transpose(2, 1, 3, 0)  # (E, a, q, l)
        return T.reshape(T.shape[0], T.shape[1], -1)

    def _require_square(self, what):
        if not self.square:
            raise ValueError(f"Assembler.{what} needs one basis; this assembler has "
                             "different trial and test bases")

    def mass(self, density=1.0):
        """``∫ Ñ_a ρ N_b δ_cd`` (values are not corrected by VCI)."""
        self._require_square("mass")
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
        if not test:
            self._require_square("cell_vectors(test=False)")
        L = self.test_layout
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
                           minlength=self.test_layout.N)

    def linear(self, P):
        """``f[(a,c)] = ∫ ∂_l Ñ_a P_{c l}``; ``P`` has shape (c, dim, nelems, nqp)."""
        return self.scatter(self.cell_vectors(P))

    def outer(self, u, w):
        """Matrix of the per-cell rank-one blocks ``u_e ⊗ w_e`` (nloc * c, nelems)."""
        return self.matrix(self.local_outer(u, w))

    def local_outer(self, u, w):
        """Local matrices of :meth:`outer`, shape (nelems, nloc, c, c, nloc)."""
        self._require_square("outer")
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

    def gradient(self, u, test=False):
        """``∂_m u_c`` at the quadrature points, shape (c, dim, nelems, nqp);
        ``test=True`` takes the test gradients ``∂_m Ñ`` (VCI-corrected)."""
        self._require_square("gradient")
        L = self.layout
        U = np.asarray(u).reshape(L.nscalar, L.ncomp)[L.element_nodes]  # (nloc, nelems, c)
        grads = self._test_grads(slice(None)) if test else self._trial_grads(slice(None))
        # H[E, q, m, c] = Σ_a ∂_m N_a [E, q, m, a] U[E, a, c]
        H = grads @ U.transpose(1, 0, 2)[:, None]
        return H.transpose(3, 2, 0, 1)

    def gradient_table(self, test=False):
        """``∂_m N_a`` of every cell as (nelems, nqp * dim, nloc) (rows in the
        order (q, m)); ``test=True``: the test gradients ``∂_m Ñ_a``."""
        G = self._test_grads(slice(None)) if test else self._trial_grads(slice(None))
        return G.reshape(G.shape[0], -1, G.shape[-1])

    def weighted_table(self, test=True):
        """``∂_l Ñ_a dΩ`` of every cell as (nelems, nloc, nqp * dim) (columns in
        the order (q, l)); ``test=False``: the trial gradients."""
        everything = slice(None)
        return (self._weighted_test_grads(everything) if test
                else self._weighted_trial_grads(everything))

    @property
    def same_gradients(self):
        """Test and trial gradients are equal (no VCI correction): the
        bilinear forms of a symmetric tangent are then symmetric."""
        same = self._cache.get("same gradients")
        if same is None:
            L = self.layout
            same = self._cache["same gradients"] = self.square and (
                L.test_grads is L.trial_grads or np.array_equal(L.test_grads, L.trial_grads))
        return same


def facet_basis(basis, facets=None):
    """The facet basis matching ``basis`` on a named boundary (default: all)."""
    if hasattr(basis, "element_nodes"):
        return basis.boundary(facets)
    if isinstance(facets, str):
        facets = basis.mesh.boundaries[facets]
    return FacetBasis(basis.mesh, basis.elem, facets=facets,
                      intorder=2 * basis.elem.maxdeg + 2)
