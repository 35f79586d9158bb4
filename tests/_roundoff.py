"""Round-off bounds for tests that expect an exact answer "to round-off".

An answer that is exact in exact arithmetic (a patch test, a reproduced
polynomial, an identity between two assembly paths) differs from the
computed one by round-off whose size depends on the BLAS kernel that ran
(AVX-512, AVX2 or SSE kernels of OpenBLAS sum in different orders).  A fixed
threshold such as ``1e-12`` tuned on one kernel fails on another; the bounds
here follow from the problem instead: machine epsilon times the size of the
terms, and for a linear solve the condition of the matrix.

Solves.  A backward-stable solve of ``A x = b`` (LU with partial pivoting)
returns the exact solution of a system perturbed by a relative ``c ε`` in
``A`` and ``b``; the assembly of ``A`` and ``b`` from the terms of a
quadrature adds a perturbation of the same kind.  With ``ω`` their sum, the
forward error of the entries ``rows`` of ``x`` is at most (Higham, Accuracy
and Stability of Numerical Algorithms, Thm. 7.2, normwise in ∞-norms)

    |δx[rows]|∞ ≤ ω ‖A⁻¹[rows, :]‖∞ (‖A‖∞ ‖x‖∞ + ‖b‖∞),     ω = FACTOR ε,

:func:`solve_bound`.  ``FACTOR`` = 16 covers the normwise backward errors
measured on the suite's patch-test systems under the SkylakeX, Haswell,
Sandybridge and Nehalem kernels of OpenBLAS: 0.1 to 0.4 ε for the dense LU
of prescribed nodal values, 5 to 15 ε for the iteratively refined
saddle-point solve of weakly prescribed values (LU's worst case, ``n ε``
times the growth factor, is not seen in practice).  Solves through the
augmented Lagrangian of :func:`skfem_rkpm.solvers.constrained.solve_saddle_point`
(SuperLU, large systems) accept a backward error up to its
``ACCEPTED_BACKWARD_ERROR`` and need ``factor`` = that / ε.  The bound is a
worst case: the errors measured are 1e-7 to 1e-2 of it.  What a real defect
gives is still far above it: the tests that use it state both numbers.

Sums of ``n`` terms: :func:`sum_bound`.  :func:`assert_within` prints each
error's fraction of its bound when ``ROUNDOFF_REPORT`` is set (``pytest -s``).
"""

import os

import numpy as np
import scipy.sparse as sp

EPS = np.finfo(float).eps

#: backward error of an assembled and LU-solved system, in units of ε
FACTOR = 16.0


def _dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)


def inf_norm(A):
    """‖A‖∞ (largest row sum of absolute values) of a dense or sparse matrix."""
    if sp.issparse(A):
        return float(abs(A).sum(axis=1).max())
    A = np.asarray(A, dtype=float)
    return float(np.abs(A).sum(axis=-1).max()) if A.ndim > 1 else float(np.abs(A).max())


def inverse_norm(A, rows=None):
    """‖A⁻¹[rows, :]‖∞ of a nonsingular matrix (dense inverse: a few
    thousand unknowns at most)."""
    inverse = np.linalg.inv(_dense(A))
    return inf_norm(inverse if rows is None else inverse[rows])


def solve_bound(A, x, b=None, rows=None, factor=FACTOR):
    """Worst-case round-off ``|δx[rows]|∞`` of the solution ``x`` of the
    assembled system ``A x = b`` (module docstring): ``factor ε
    ‖A⁻¹[rows]‖∞ (‖A‖∞ ‖x‖∞ + ‖b‖∞)``."""
    bnorm = 0.0 if b is None else float(np.abs(b).max())
    return factor * EPS * inverse_norm(A, rows) * (
        inf_norm(A) * float(np.abs(x).max()) + bnorm)


def sum_bound(magnitude, count):
    """Round-off of a sum of ``count`` terms whose absolute values add up
    to ``magnitude``: a recursive sum (``np.bincount``, sparse products, a
    dot product in any order or blocking) errs by at most
    ``(count - 1) ε Σ|terms|`` (Higham, Eq. 4.4); ``count ε magnitude``
    also covers a relative ε in each term."""
    return count * EPS * np.asarray(magnitude)


def lebesgue(matrix):
    """max_q Σ_I |A[q, I]|: how much an error of the coefficients can grow
    on evaluation through ``A`` (shape functions at points)."""
    return inf_norm(matrix)


def constrained_solve_bound(K, f, C, g, factor=FACTOR):
    """:func:`solve_bound` of ``d`` from ``K d = f + Cᵀ λ``, ``C d = g``: the
    saddle-point matrix ``[[K, Cᵀ], [C, 0]]``, the rows of ``d`` (the
    multipliers' own round-off does not count).  Prescribed nodal values
    (the transformation method) are ``C = Λᵀ[D]``."""
    A = sp.bmat([[sp.csr_matrix(K), C.T], [C, None]]).tocsr()
    b = np.concatenate([np.asarray(f, dtype=float), np.asarray(g, dtype=float)])
    x = np.linalg.solve(A.toarray(), b)  # its norm only
    return solve_bound(A, x, b, rows=slice(0, K.shape[0]), factor=factor)


def field_bounds(basis, coefficient_error, coefficients, factor=FACTOR):
    """Bounds on the errors of ``u`` and ``∇u`` at the quadrature points of
    an RK ``basis``: a coefficient error ``δd`` grows by at most the
    :func:`lebesgue` constants of the shape functions (``L``, about 1) and of
    their gradients (``G``, about 1/h), and the evaluation ``Ψ d`` adds
    ``factor ε L ‖d‖∞``: ``L (δd + factor ε ‖d‖∞)``, ``G (...)``."""
    table = basis.table
    L = lebesgue(table.matrix())
    G = max(lebesgue(table.gradient_matrix(k)) for k in range(basis.mesh.dim()))
    delta = coefficient_error + factor * EPS * float(np.abs(coefficients).max())
    return L * delta, G * delta


def assert_within(actual, expected, bound):
    """``|actual - expected| ≤ bound`` entry by entry (``bound`` broadcast),
    naming the worst entry and its error in units of the bound."""
    error = np.abs(np.asarray(actual, dtype=float) - expected)
    bound = np.broadcast_to(np.asarray(bound, dtype=float), error.shape)
    ratio = np.divide(error, bound, out=np.full(error.shape, np.inf), where=bound > 0)
    ratio[error == 0] = 0.0
    worst = np.unravel_index(np.argmax(ratio), ratio.shape) if ratio.size else ()
    if os.environ.get("ROUNDOFF_REPORT") and ratio.size:  # margins, for retuning
        print(f"\nround-off: error {ratio[worst]:.3g} of the bound {bound[worst]:.3g}")
    assert not ratio.size or ratio[worst] <= 1.0, (
        f"entry {tuple(int(i) for i in worst)}: error {error[worst]:.3g} is "
        f"{ratio[worst]:.3g} times the round-off bound {bound[worst]:.3g}")


def assert_errors_within(errors, bounds, names):
    """Each named error below its bound (with ``ROUNDOFF_REPORT`` set, print
    the fraction of the bound each error reaches)."""
    for name, error, bound in zip(names, errors, bounds):
        if os.environ.get("ROUNDOFF_REPORT"):
            print(f"\nround-off: error {error / bound:.3g} of the bound {bound:.3g} ({name})")
        assert error < bound, f"{name}: error {error:.3g} above the round-off bound {bound:.3g}"
