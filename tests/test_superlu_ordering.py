"""SuperLU reuses the MMD ordering of a pattern: the later factorizations of
the same pattern factor the permuted matrix in its natural order and solve
as a fresh MMD factorization does, to the round-off of a backward-stable
solve (:func:`_roundoff.solve_bound`, both solutions against the exact one)."""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from _roundoff import solve_bound
from skfem_rkpm.solvers.linear import SuperLU


def _matrix(rng, n=14):
    """A non-symmetric sparse matrix on the pattern of a 2D 5-point stencil
    (a friction-like skew part), with values drawn anew for each call."""
    L = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    A = sp.kron(L, sp.identity(n)) + sp.kron(sp.identity(n), L)
    A = sp.csr_matrix(A)
    A.data *= 1.0 + 0.2 * rng.random(A.nnz)  # same pattern, new values
    A.sort_indices()
    return A


def test_reused_ordering_solves_as_a_fresh_factorization():
    rng = np.random.default_rng(0)
    solver = SuperLU()
    for k in range(3):
        A = _matrix(rng)
        x_exact = rng.normal(size=A.shape[0])
        b = A @ x_exact
        solver.factor(A)
        x = solver.solve(b)
        fresh = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                     options=dict(SymmetricMode=True)).solve(b)
        bound = solve_bound(A, x_exact, b)
        assert np.abs(x - x_exact).max() <= bound
        assert np.abs(fresh - x_exact).max() <= bound
        assert solver._lu_permuted == (k > 0)  # the ordering of the first is reused
        # the same fill as MMD's own
        lu = solver._lu
        mmd = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                   options=dict(SymmetricMode=True))
        assert lu.L.nnz + lu.U.nnz == mmd.L.nnz + mmd.U.nnz
    assert solver.stats["analyses"] == 1 and solver.stats["factorizations"] == 3


def test_new_pattern_orders_again():
    rng = np.random.default_rng(1)
    solver = SuperLU()
    solver.factor(_matrix(rng, 10))
    solver.factor(_matrix(rng, 10))
    assert solver._lu_permuted
    A = _matrix(rng, 12)
    b = A @ np.ones(A.shape[0])
    solver.factor(A)
    assert not solver._lu_permuted and solver.stats["analyses"] == 2
    assert np.abs(solver.solve(b) - 1.0).max() <= solve_bound(A, np.ones(A.shape[0]), b)
