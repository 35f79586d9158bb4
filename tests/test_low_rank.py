"""A solve with a tangent changed in a few rows from the factors of the old
tangent (``solve_updated``, Sherman-Morrison-Woodbury) against factoring
the changed tangent (``solve_constrained``), on each path that keeps its
factors: no conditions, conditions that select unknowns (FEM nodal values)
and general conditions eliminated into a dense system (RK).

Bounds: each solution is the exact one of a system perturbed by its
backward error, at most ``FACTOR`` ε for the direct solve and
``BACKWARD_ERROR`` + ``FACTOR`` ε for the formula (it refines until its
backward error is below ``BACKWARD_ERROR``), so they differ by at most
the sum of the two :func:`constrained_solve_bound`\\ s; that bound is
loose where ``ΔK`` is a large penalty, so the residual of the changed
system is checked as well: a normwise backward error of at most
``BACKWARD_ERROR`` + ``FACTOR`` ε.  The solution of the unchanged
system leaves a residual 1e6 times larger (checked)."""

import numpy as np
import pytest
import scipy.sparse as sp

from _roundoff import EPS, FACTOR, assert_within, constrained_solve_bound, inf_norm
from skfem_rkpm.solvers.constrained import solve_constrained
from skfem_rkpm.solvers.linear import make_solver
from skfem_rkpm.solvers.low_rank import BACKWARD_ERROR, MAX_ROWS, solve_updated


def _norm(A):
    return inf_norm(A) if A.shape[0] and A.shape[1] else 0.0


def _tangent(rng, n):
    """A sparse non-symmetric, nonsingular matrix with a banded pattern
    (the coupling of neighbouring nodes) and a dominant diagonal."""
    K = sp.diags([rng.uniform(-1, 1, n - k) for k in (3, 1)] + [rng.uniform(4, 6, n)]
                 + [rng.uniform(-1, 1, n - k) for k in (1, 3)], [-3, -1, 0, 1, 3])
    return sp.csr_matrix(K) * 1e3


def _conditions(rng, n, kind):
    if kind == "none":
        return sp.csr_matrix((0, n)), np.zeros(0)
    if kind == "selection":  # nodal values of some unknowns
        rows = np.arange(0, n, 7)
        C = sp.csr_matrix((np.ones(len(rows)), (np.arange(len(rows)), rows)), shape=(len(rows), n))
    else:  # a combination of two unknowns per row (RK nodal values, oblique planes)
        rows = np.arange(0, n - 1, 9)
        k = np.arange(len(rows))
        C = sp.csr_matrix((np.concatenate([np.ones(len(rows)), 0.5 * np.ones(len(rows))]),
                           (np.concatenate([k, k]), np.concatenate([rows, rows + 1]))),
                          shape=(len(rows), n))
    return C, rng.uniform(-1, 1, C.shape[0])


def _change(rng, n, rows, scale):
    """``ΔK`` nonzero in ``rows``, coupling each to a few columns (a penalty
    stiffness of contact nodes)."""
    cols = np.concatenate([rows, (rows + 1) % n, (rows + 5) % n])
    r = np.concatenate([rows, rows, rows])
    return sp.csr_matrix((scale * rng.uniform(0.5, 1.0, len(r)), (r, cols)), shape=(n, n))


@pytest.mark.parametrize("kind", ["none", "selection", "general"])
@pytest.mark.parametrize("scale", [1e2, 1e8])
def test_updated_solve_equals_factoring_the_changed_tangent(kind, scale):
    rng = np.random.default_rng(3)
    n = 120
    K = _tangent(rng, n)
    C, g = _conditions(rng, n, kind)
    f = rng.uniform(-1, 1, n) * 1e3
    dK = _change(rng, n, np.array([4, 5, 6, 40, 41, 90]), scale * 1e3)
    solver = make_solver("auto")
    solve_constrained(K, rng.uniform(-1, 1, n), C, g, solver=solver)
    factored = solver.factored
    assert factored is not None and factored.holds(K, C)
    if kind == "selection":
        assert factored.elimination.selection
    if kind == "general":
        assert not factored.elimination.selection
    backend = solver.current
    count = backend.stats["factorizations"]
    d, lam = solve_updated(K, dK, f, C, g, solver)
    assert backend.stats["factorizations"] == count  # nothing factored again
    d_ref, lam_ref = solve_constrained(K + dK, f, C, g, solver=make_solver("auto"))
    bound = (constrained_solve_bound(K + dK, f, C, g)
             + constrained_solve_bound(K + dK, f, C, g, factor=FACTOR + BACKWARD_ERROR / EPS))
    assert_within(d, d_ref, bound)
    # the changed system is solved to round-off: its normwise backward error
    A = K + dK
    residual = np.abs(A @ d - f - C.T @ lam).max()
    size = (_norm(A) * np.abs(d).max() + _norm(C.T) * np.abs(lam).max(initial=0)
            + np.abs(f).max())
    assert residual <= (FACTOR * EPS + BACKWARD_ERROR) * size
    assert np.abs(C @ d - g).max(initial=0) <= (FACTOR * EPS + BACKWARD_ERROR) * (
        _norm(C) * np.abs(d).max() + np.abs(g).max(initial=0))
    # the change matters: without it the residual is far above that
    d_old, lam_old = solve_constrained(K, f, C, g)
    assert np.abs(A @ d_old - f - C.T @ lam_old).max() > 1e6 * (FACTOR * EPS + BACKWARD_ERROR) * size


def test_other_systems_are_factored_anew():
    """Another K than the one factored, or a change in too many rows: the
    changed tangent is factored, and the answer is the same."""
    rng = np.random.default_rng(5)
    n = 2000  # sparse LU (SuperLU), its factorizations counted
    K, other = _tangent(rng, n), _tangent(rng, n)
    C, g = _conditions(rng, n, "selection")
    f = rng.uniform(-1, 1, n)
    solver = make_solver("auto")
    few, many = np.array([3, 7]), np.arange(0, 2 * (MAX_ROWS + 1), 2)
    for factored, rows in ((other, few), (K, many)):
        dK = _change(rng, n, rows, 1e4)
        solve_constrained(factored, f, C, g, solver=solver)
        count = solver.current.stats["factorizations"]
        d, _ = solve_updated(K, dK, f, C, g, solver)
        assert solver.current.stats["factorizations"] == count + 1
        d_ref, _ = solve_constrained(K + dK, f, C, g)
        assert np.abs(d - d_ref).max() <= 2 * FACTOR * EPS * 1e3 * np.abs(d_ref).max()


@pytest.mark.parametrize("scale", [1e2, 1e8])
def test_updated_augmented_lagrangian_solve_equals_factoring_the_changed_tangent(scale):
    """Conditions that SuperLU meets by the augmented Lagrangian (sparse
    ``K``, rows that are neither a selection nor small enough for dense
    LU): the factors of ``K + ρCᵀC`` solve the changed system by the
    formula on ``K + ρCᵀC + ΔK``, and no factorization is done.  Both
    answers are refined until their backward error in the changed system is
    at most ``ACCEPTED_BACKWARD_ERROR`` (1e-12 sought), so they differ by at
    most twice :func:`constrained_solve_bound` with that backward error."""
    from skfem_rkpm.solvers.constrained import ACCEPTED_BACKWARD_ERROR, AugmentedFactored
    rng = np.random.default_rng(7)
    n = 800  # above the dense limit: SuperLU
    K = _tangent(rng, n)
    C, g = _conditions(rng, n, "general")
    f = rng.uniform(-1, 1, n) * 1e3
    dK = _change(rng, n, np.array([4, 5, 6, 40, 41, 90, 500]), scale * 1e3)
    solver = make_solver("auto")
    solve_constrained(K, rng.uniform(-1, 1, n), C, g, solver=solver)
    assert isinstance(solver.factored, AugmentedFactored) and solver.factored.holds(K, C)
    backend = solver.current
    count, solves = backend.stats["factorizations"], backend.stats["solves"]
    d, lam = solve_updated(K, dK, f, C, g, solver)
    assert backend.stats["factorizations"] == count  # nothing factored again
    assert backend.stats["solves"] > solves
    d_ref, lam_ref = solve_constrained(K + dK, f, C, g, solver=make_solver("auto"))
    accepted = ACCEPTED_BACKWARD_ERROR / EPS
    assert_within(d, d_ref, 2 * constrained_solve_bound(K + dK, f, C, g, factor=accepted))
    A = K + dK
    residual = np.abs(A @ d - f - C.T @ lam).max()
    size = (_norm(A) * np.abs(d).max() + _norm(C.T) * np.abs(lam).max() + np.abs(f).max())
    assert residual <= ACCEPTED_BACKWARD_ERROR * size
    assert np.abs(C @ d - g).max() <= ACCEPTED_BACKWARD_ERROR * (
        _norm(C) * np.abs(d).max() + np.abs(g).max())
    d_old, lam_old = solve_constrained(K, f, C, g)
    assert np.abs(A @ d_old - f - C.T @ lam_old).max() > 1e3 * ACCEPTED_BACKWARD_ERROR * size
