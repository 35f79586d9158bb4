"""Linear solves under constraints: nodal values prescribed by the
transformation method (Eq. 3.37), and the saddle-point systems behind it.

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
nodal values directly.  The rows ``C`` come from
:mod:`skfem_rkpm.approximation.constraints`.
"""

import numpy as np
import scipy.sparse as sp

from ..approximation.constraints import transformation
from .backend import _canonical
from .linear import Auto, NotPositiveDefinite, make_solver

__all__ = ["solve", "solve_constrained", "linear_solve", "solve_saddle_point"]


def linear_solve(A, b, solver="auto"):
    """Solve ``A x = b``; ``solver`` is a name or a :class:`~skfem_rkpm.solvers.linear.Solver`.

    The default picks dense LU when small and sparse LU (SuperLU, minimum
    degree ordering of ``Aᵀ + A``, symmetric mode, COLAMD fallback) or an
    installed faster backend otherwise; see :mod:`skfem_rkpm.solvers.linear`.
    """
    return make_solver(solver).factor(A).solve(b)


def _prescribed_values(D, x, N, columns=None):
    """``g`` of shape (len(D),), or (len(D), columns) for several right-hand sides."""
    shape = (len(D),) if columns is None else (len(D), columns)
    if x is None:
        return np.zeros(shape)
    x = np.asarray(x, dtype=float)
    if x.shape[:1] == (N,) and x.ndim <= len(shape):
        x = x[D]
    elif not (x.shape[:1] == (len(D),) or x.ndim == 0):
        raise ValueError(f"prescribed values have shape {x.shape}; give one value per "
                         f"constrained dof ({len(D)}) or a full vector ({N})"
                         + ("" if columns is None else f", with {columns} columns or one"))
    if x.ndim == 2 and columns is None:
        raise ValueError(f"prescribed values have shape {x.shape} for one right-hand "
                         f"side; give a vector")
    try:
        return np.array(np.broadcast_to(x if x.ndim != 1 or columns is None
                                        else x[:, None], shape), dtype=float)
    except ValueError:
        raise ValueError(f"prescribed values have shape {x.shape}, the right-hand sides "
                         f"{columns} columns: give one column or {columns}") from None


def solve(K, f, basis, D=None, x=None, return_reactions=False):
    """Solve ``K d = f`` with prescribed *nodal values* on dofs ``D``.

    Parameters
    ----------
    K : sparse matrix, shape (N, N)
        Stiffness in generalized coordinates (as assembled on the basis).
    f : ndarray, shape (N,) or (N, k)
        Load vector in generalized coordinates, or ``k`` of them (one
        factorization serves all).
    basis : RKBasis or skfem basis
        Supplies the transformation Λᵀ.
    D : array of int, optional
        Dofs whose nodal values are prescribed (``basis.get_dofs(...)``).
    x : ndarray, optional
        The prescribed nodal values: a full vector (N,) read at ``D``, one
        value per entry of ``D``, or a scalar.  Default zero.  With ``k``
        right-hand sides also (N, k) or (len(D), k): one column per load.
    return_reactions : bool
        Also return the nodal reactions ``λ`` on ``D``.

    Returns
    -------
    d : ndarray, shape (N,) or (N, k)
        Generalized coefficients; ``basis.nodal_values(d)[D]`` equals ``x``.
    """
    N = K.shape[0]
    f = np.asarray(f, dtype=float)
    if f.ndim not in (1, 2) or f.shape[0] != N:
        raise ValueError(f"the load has shape {f.shape}; give ({N},) or ({N}, k) for "
                         f"k right-hand sides")
    D = np.zeros(0, dtype=np.int64) if D is None else np.asarray(D, dtype=np.int64)
    g = _prescribed_values(D, x, N, None if f.ndim == 1 else f.shape[1])
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


def _penalty(K, C):
    """Penalty factor ρ of the augmented Lagrangian: 10 × diag(K) / diag(CᵀC)."""
    kd = np.abs(K.diagonal()).max(initial=0.0)
    cd = np.asarray(C.multiply(C).sum(axis=0)).ravel().max(initial=0.0)
    return 10.0 * (kd if kd > 0 else 1.0) / (cd if cd > 0 else 1.0)


def solve_saddle_point(solver, K, f, C, g, rtol=1e-13, maxiter=200):
    """Solve ``K d = f + Cᵀ λ``, ``C d = g`` with ``solver``; return ``d``, ``λ``.

    Backends that factor indefinite matrices (dense, SuperLU, PARDISO) solve
    the saddle-point system ``[[K, Cᵀ], [C, 0]] [d; -λ] = [f; g]`` directly.

    SPD-only backends (CHOLMOD, AMG) use the augmented Lagrangian: with
    ``K_ρ = K + ρ CᵀC``, symmetric positive definite whenever the
    constraints remove the rigid-body modes of ``K``, the system becomes
    ``K_ρ d = f + ρ Cᵀ g + Cᵀ λ`` and ``λ`` solves the Schur complement
    system ``C K_ρ⁻¹ Cᵀ λ = g - C K_ρ⁻¹ (f + ρ Cᵀ g)`` by conjugate
    gradients, one solve with the factored ``K_ρ`` per iteration.  The
    eigenvalues of ``(C K_ρ⁻¹ Cᵀ)⁻¹`` lie in ``[ρ, ρ + μ]`` with ``μ`` of
    the order of ``|K|``, so with ``ρ = 10 |K| / |CᵀC|`` CG needs a handful
    of iterations, independent of the mesh.  ``λ`` converges to ``rtol``
    relative to ``|f| + ρ |g|``.
    """
    N = K.shape[0]
    K = _canonical(K)
    m = C.shape[0]
    if m == 0:
        _factor(solver, K, spd=True)
        return solver.solve(f), np.zeros((0,) + np.shape(f)[1:])
    C = sp.csr_matrix(C)
    backend = solver
    if isinstance(solver, Auto):
        name = solver.choose(sp.csr_matrix((N + m, N + m)))
        if name == "superlu" and solver.choose(K, spd=True) == "cholmod":
            name = "cholmod"  # CHOLMOD on K + ρCᵀC beats SuperLU on the KKT matrix
        backend = solver.backend(name)
    if backend.spd_only:
        rho = _penalty(K, C)
        Krho = _canonical(K + rho * (C.T @ C))
        try:
            backend.factor(Krho)
        except NotPositiveDefinite:
            if backend is solver:
                raise
            backend = solver.backend("superlu")  # auto: the tangent is indefinite
        else:
            solver.A = Krho
            if np.ndim(f) == 2:  # one Schur complement iteration per load
                pairs = [_augmented_lagrangian(backend, Krho, rho, f[:, j], C, g[:, j],
                                               rtol, maxiter) for j in range(f.shape[1])]
                return (np.column_stack([p[0] for p in pairs]),
                        np.column_stack([p[1] for p in pairs]))
            return _augmented_lagrangian(backend, Krho, rho, f, C, g, rtol, maxiter)
    A = _canonical(sp.bmat([[K, C.T], [C, None]]))
    backend.factor(A)
    solver.A = A
    sol = backend.solve(np.concatenate([f, g]))
    return sol[:N], -sol[N:]


def _augmented_lagrangian(solver, Krho, rho, f, C, g, rtol, maxiter):
    """CG on the Schur complement ``C K_ρ⁻¹ Cᵀ λ = g - C K_ρ⁻¹ (f + ρ Cᵀ g)``."""
    m = C.shape[0]
    rhs = f + rho * (C.T @ g)
    d0 = solver.solve(rhs)
    lam = np.zeros(m)
    r = g - C @ d0
    stop = rtol * max(np.linalg.norm(g), np.linalg.norm(C @ d0), 1e-300)
    p = r.copy()
    rr = r @ r
    for _ in range(maxiter):
        if np.sqrt(rr) <= stop:
            break
        Sp = C @ solver.solve(C.T @ p)
        alpha = rr / (p @ Sp)
        lam += alpha * p
        r -= alpha * Sp
        rr_new = r @ r
        p = r + (rr_new / rr) * p
        rr = rr_new
    else:
        raise np.linalg.LinAlgError(
            f"the augmented Lagrangian iterations did not converge in {maxiter} "
            f"iterations (constraint residual {np.sqrt(rr):.2e}, wanted {stop:.2e}); the "
            f"tangent may not be positive definite on the constrained space: use solver "
            f"'superlu' or 'pardiso'")
    return solver.solve(rhs + C.T @ lam), lam


def _factor(solver, A, spd):
    if isinstance(solver, Auto):
        solver.factor(A, spd=spd)
    else:
        solver.factor(A)
