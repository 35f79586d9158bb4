"""A solve with a tangent changed in a few rows, from the factors of the
tangent before the change (the Sherman-Morrison-Woodbury formula).

The touching and stick predictions of a Newton update
(:func:`skfem_rkpm.solvers.newton._update`) add the penalty stiffness of
the contact nodes they find to the tangent ``K`` just factored and solve
again: ``ΔK`` is nonzero in the rows of those nodes only (1 to 9 rows on
``billet_3d``, against 802 unknowns), so ``ΔK = E M`` with ``E`` the
columns of the identity of its ``s`` rows and ``M = ΔK[rows, :]``.  With
the conditions ``C d = g``, the saddle-point matrix ``𝒜`` changes by
``[E; 0] [M, 0]``, and

    (𝒜 + U V)⁻¹ b = x - X (I + M X_d)⁻¹ M x_d,

with ``x = 𝒜⁻¹ b`` and ``X = 𝒜⁻¹ U``: one solve with ``s + 1``
right-hand sides by the factors at hand and an ``s x s`` dense solve,
where a new factorization of the FEM billet's tangent costs 3-5 ms and of
the RK one 20 ms.  The result is checked by the backward error of the
changed system (:func:`~skfem_rkpm.solvers.constrained._backward_error`),
refined from its residual by the same formula, and factored anew where
that does not reach round-off.
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .constrained import _backward_error, solve_constrained

__all__ = ["solve_updated", "MAX_ROWS", "BACKWARD_ERROR"]

#: changes in more rows than this (or than 5 % of the unknowns) are factored anew
MAX_ROWS = 64

#: the backward error the formula must reach, else the changed system is
#: factored: 100 units of round-off (the direct solves leave 1-20)
BACKWARD_ERROR = 100 * np.finfo(float).eps


def solve_updated(K, dK, f, C, g, solver, refinements=2):
    """``d, λ`` of ``(K + ΔK) d = f + Cᵀ λ``, ``C d = g``, as
    :func:`~skfem_rkpm.solvers.constrained.solve_constrained` gives them.

    If the last :func:`~skfem_rkpm.solvers.constrained.solve_constrained`
    with ``solver`` factored ``K`` (the same object) under the same ``C``
    in a form that can solve again (``solver.factored``) and ``ΔK`` is
    nonzero in at most ``MAX_ROWS`` rows, the factors of ``K`` solve the
    changed system (see the module); otherwise ``K + ΔK`` is factored.
    """
    record = getattr(solver, "factored", None)
    dK = sp.csr_matrix(dK)
    rows = np.flatnonzero(np.diff(dK.indptr))
    N = K.shape[0]
    if (record is None or not record.holds(K, C) or len(rows) > MAX_ROWS
            or len(rows) > 0.05 * N):
        return solve_constrained(K + dK, f, C, g, solver=solver)
    f, g = np.asarray(f, dtype=float), np.asarray(g, dtype=float)
    if hasattr(record, "solve_changed"):  # the factors of K + ρCᵀC (augmented Lagrangian)
        try:
            return record.solve_changed(dK, rows, f, g)
        except np.linalg.LinAlgError:
            return solve_constrained(K + dK, f, C, g, solver=solver)
    if not len(rows):
        return record.solve(f, g)
    s = len(rows)
    M = dK[rows]
    U = np.zeros((N, s))
    U[rows, np.arange(s)] = 1.0
    X, X_lam = record.solve(U, np.zeros((C.shape[0], s)))
    capacitance = scipy.linalg.lu_factor(np.eye(s) + M @ X, check_finite=False)

    def apply(f, g):
        """``(𝒜 + U V)⁻¹ [f; g]`` by the formula."""
        x, x_lam = record.solve(f, g)
        y = scipy.linalg.lu_solve(capacitance, M @ x, check_finite=False)
        return x - X @ y, x_lam - X_lam @ y

    A = record.canonical + dK
    norms = (spla.norm(A, np.inf), spla.norm(C, np.inf), spla.norm(C, 1)) if C.shape[0] \
        else (spla.norm(A, np.inf), 0.0, 0.0)
    d, lam = apply(f, g)
    for k in range(refinements + 1):
        r_f = f - A @ d + (C.T @ lam if C.shape[0] else 0.0)
        r_g = g - C @ d
        if _backward_error(norms, f, g, d, lam, r_f, r_g) <= BACKWARD_ERROR:
            return d, lam
        if k < refinements:
            dd, dlam = apply(r_f, r_g)
            d, lam = d + dd, lam + dlam
    return solve_constrained(K + dK, f, C, g, solver=solver)
