"""Linear constraints ``C d = g`` eliminated by a null-space basis.

The saddle-point system ``K d = f + Cᵀ λ``, ``C d = g`` of
:func:`~skfem_rkpm.solvers.constrained.solve_saddle_point` is solved on the
``N - m`` unknowns that the ``m`` conditions leave free, as
:func:`~skfem_rkpm.solvers.idioms.condense` does for nodal values: with
``m`` columns ``D`` of ``C`` whose block ``C_D`` is nonsingular (the pivots
of a column-pivoted QR of the columns ``C`` touches) and ``I`` the others,

    d = d₀ + Z z,   Z = [1 ; W],   W = -C_D⁻¹ C_I,   d₀ = [0 ; C_D⁻¹ g],

so ``C Z = 0`` and ``C d₀ = g``; then ``Zᵀ K Z z = Zᵀ (f - K d₀)`` and the
multipliers follow from the rows ``D`` of the first equation,
``λ = C_D⁻ᵀ (K d - f)_D``.  ``W`` is nonzero only in the columns of ``I``
that ``C`` touches.

For linear FEM bases the weak symmetry rows ``∫ N_K u_c`` and nodal rows
touch only the constrained dofs: ``W`` is empty, ``Z`` a selection and
``Zᵀ K Z = K_II``, a sparse matrix like ``K`` (positive definite where
``K`` is on the conditions' null space), with no multiplier iteration.
For RK bases ``W`` is a dense block (the boundary particles' coupling to
their neighbours) and ``Zᵀ K Z`` is formed densely, for a dense
factorization (:class:`~skfem_rkpm.solvers.linear.Auto` picks dense LU for
small dense tangents).
"""

import weakref

import numpy as np
import scipy.linalg
import scipy.sparse as sp

__all__ = ["NullSpace", "null_space", "for_rows", "QR_ENTRIES", "QR_FLOPS"]

#: most entries ``m x touched columns`` of the dense block of ``C`` whose
#: pivoted QR picks the columns ``D`` (larger sets of conditions keep the
#: saddle-point solve)
QR_ENTRIES = 2**22
#: most ``m² x touched columns`` (the flops of that QR, done once per set of
#: conditions: about 10 ms)
QR_FLOPS = 2**28
#: ``C_D`` is refused (the saddle-point solve is kept) when its pivots fall
#: below this fraction of the largest: the conditions are nearly dependent
PIVOT_RATIO = 1e-10


class NullSpace:
    """The elimination of the rows ``C`` (m x N, independent).

    Attributes
    ----------
    D, I : ndarray of int
        Eliminated and free unknowns (a partition of ``0..N-1``).
    near : ndarray of int
        Positions in ``I`` of the free unknowns ``C`` touches (the columns of ``W``).
    W : ndarray, shape (m, len(near))
        ``-C_D⁻¹ C_I`` on those columns.
    selection : bool
        ``W`` is empty: ``Z`` picks the unknowns ``I``.
    """

    def __init__(self, C, D, touched):
        C = sp.csr_matrix(C)  # not kept: for_rows keeps the basis while C lives
        self.N = N = C.shape[1]
        self.D = D
        free = np.ones(N, dtype=bool)
        rest = np.setdiff1d(touched, D)
        free[D] = False
        free[rest] = False
        # the free unknowns C touches last, so that W acts on a slice
        self.I = np.concatenate([np.flatnonzero(free), rest])
        self.near = np.arange(N - len(D) - len(rest), N - len(D))
        C_D = C[:, D].toarray()
        self._lu = scipy.linalg.lu_factor(C_D, check_finite=False)
        self.W = (-scipy.linalg.lu_solve(self._lu, C[:, rest].toarray(), check_finite=False)
                  if len(rest) else np.zeros((len(D), 0)))
        self.selection = self.W.shape[1] == 0
        # the unknowns in the order [I, D], for the dense reduction
        self._order = np.concatenate([self.I, self.D])
        self._Z = None
        self._buffers = None
        self._selected = None  # (indptr, indices of K, the positions picked, pattern)

    @property
    def n(self):
        """Free unknowns."""
        return len(self.I)

    @property
    def Z(self):
        """The sparse null-space basis (N x n), ``C Z = 0``."""
        if self._Z is None:
            n, m = self.n, len(self.D)
            rows = np.concatenate([self.I, np.repeat(self.D, len(self.near))])
            cols = np.concatenate([np.arange(n), np.tile(self.near, m)])
            data = np.concatenate([np.ones(n), self.W.ravel()])
            self._Z = sp.csr_matrix((data, (rows, cols)), shape=(self.N, n))
        return self._Z

    def particular(self, g):
        """``d₀``: zero on ``I``, ``C d₀ = g``."""
        g = np.asarray(g, dtype=float)
        d0 = np.zeros((self.N,) + g.shape[1:])
        d0[self.D] = scipy.linalg.lu_solve(self._lu, g, check_finite=False)
        return d0

    def reduce(self, K):
        """``Zᵀ K Z``, sparse (``K`` sparse)."""
        K = sp.csr_matrix(K)
        if self.selection:
            return self._select(K)
        return (self.Z.T @ K @ self.Z).tocsr()

    def _select(self, K):
        """``K[I][:, I]``: the entries of ``K`` it picks are found once per
        sparsity pattern of ``K`` (by picking the entry numbers of a copy of
        the pattern) and then copied, which gives the same matrix as the
        fancy indexing (the same entries in the same places) in a third of
        its time (FEM billet_3d, 945 unknowns: 0.14 against 0.46 ms)."""
        kept = self._selected
        if not (kept is not None and np.array_equal(kept[0], K.indptr)
                and np.array_equal(kept[1], K.indices)):
            if not K.has_canonical_format:  # duplicates: indexing sums them
                return K[self.I][:, self.I].tocsr()
            numbers = sp.csr_matrix((np.arange(1.0, K.nnz + 1.0), K.indices, K.indptr),
                                    shape=K.shape)[self.I][:, self.I].tocsr()
            kept = self._selected = (K.indptr.copy(), K.indices.copy(),
                                     numbers.data.astype(np.int64) - 1, numbers)
        pattern = kept[3]
        # copies: a caller may sort or change the indices of the matrix in place
        return sp.csr_matrix((K.data[kept[2]], pattern.indices.copy(),
                              pattern.indptr.copy()), shape=pattern.shape)

    def reduce_dense(self, K):
        """``Zᵀ K Z`` as a dense array: a view of a buffer kept for the next
        call (``K`` made dense in the order ``[I, D]``), so it is valid
        until then.  6 ms for the RK billet_3d tangent (945 unknowns,
        143 rows, 143 columns of ``W``), against 12 ms for its LU."""
        if self._buffers is None:  # fresh pages of this size cost as much as the work
            self._buffers = (np.empty((self.N, self.N)), np.empty((self.N, self.N)))
        dense, Kp = self._buffers
        if sp.issparse(K):
            dense.fill(0.0)  # toarray adds into out
            sp.csr_matrix(K).toarray(out=dense)
        else:
            dense = np.asarray(K, dtype=float)
        np.take(dense, self._order, axis=0, out=Kp)
        if dense is self._buffers[0]:
            np.take(Kp, self._order, axis=1, out=dense)
            Kp = dense
        else:
            Kp = Kp.take(self._order, axis=1)
        n, W = self.n, self.W
        if not self.selection:
            # Zᵀ K Z = K_II + K_ID W + Wᵀ K_DI + Wᵀ K_DD W, W nonzero in the
            # last columns J of I; K_II is updated in place
            J = slice(n - W.shape[1], n)
            right = Kp[:n, n:] @ W
            below = W.T @ Kp[n:, :n]
            Kp[:n, J] += right
            Kp[J, :n] += below
            Kp[J, J] += W.T @ (Kp[n:, n:] @ W)
        return Kp[:n, :n]

    def reduced_load(self, K, f, d0):
        """``Zᵀ (f - K d₀)``."""
        return self.transpose_apply(f - K @ d0)

    def transpose_apply(self, v):
        """``Zᵀ v`` (``v`` of length N, or N x k)."""
        out = np.array(v[self.I])
        if not self.selection:
            out[self.near] += self.W.T @ v[self.D]
        return out

    def expand(self, z, d0):
        """``d₀ + Z z``."""
        d = np.array(d0)
        d[self.I] += z
        if not self.selection:
            d[self.D] += self.W @ z[self.near]
        return d

    def multipliers(self, residual_D):
        """``λ = C_D⁻ᵀ (K d - f)_D`` from the rows ``D`` of ``K d - f``."""
        return scipy.linalg.lu_solve(self._lu, residual_D, trans=1, check_finite=False)


def null_space(C):
    """A :class:`NullSpace` of the rows ``C``, or None when the pivoted QR
    finds them nearly dependent or they are too many (``QR_ENTRIES``)."""
    C = sp.csr_matrix(C)
    m = C.shape[0]
    touched = np.unique(C.indices)
    if (m == 0 or len(touched) < m or m * len(touched) > QR_ENTRIES
            or m * m * len(touched) > QR_FLOPS):
        return None
    block = C[:, touched].toarray()
    R, pivots = scipy.linalg.qr(block, mode="r", pivoting=True, check_finite=False)
    diagonal = np.abs(np.diag(R))
    if not diagonal.size or not diagonal[-1] > PIVOT_RATIO * diagonal[0]:
        return None
    return NullSpace(C, np.sort(touched[pivots[:m]]), touched)


#: the null spaces of the last sets of rows given to :func:`for_rows`
_KEPT = []
#: how many are kept
KEPT = 4


def for_rows(C):
    """:func:`null_space` of ``C``, built once while the same rows come
    again: a Newton run passes one matrix of conditions to every solve,
    also where each solve makes its own solver.  The rows are known by the
    object (a weak reference) and checked to be unchanged."""
    return kept_for_rows(_KEPT, C, C, null_space)


def kept_for_rows(store, given, C, make):
    """``make(C)``, kept in ``store`` (a list, at most ``KEPT`` entries)
    while the same object ``given`` comes again with the rows ``C``
    unchanged; known by a weak reference, so the rows' own lifetime frees it."""
    store[:] = [entry for entry in store if entry[0]() is not None]  # rows gone: freed
    for rows, data, value in store:
        if rows() is given and _unchanged(C, data):
            return value
    value = make(C)
    try:
        store.insert(0, (weakref.ref(given), _fingerprint(C), value))
    except TypeError:  # not weakly referable: not kept
        return value
    del store[KEPT:]
    return value


def _fingerprint(C):
    C = sp.csr_matrix(C)
    return C.shape, C.indptr.copy(), C.indices.copy(), C.data.copy()


def _unchanged(C, data):
    C = sp.csr_matrix(C)
    shape, indptr, indices, values = data
    return (C.shape == shape and np.array_equal(C.indptr, indptr)
            and np.array_equal(C.indices, indices) and np.array_equal(C.data, values))
