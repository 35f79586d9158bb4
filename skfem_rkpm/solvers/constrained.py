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

import weakref

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.linalg import LinearOperator, gmres

from ..approximation.constraints import transformation
from .backend import _canonical
from .linear import Auto, DenseLU, NotPositiveDefinite, SuperLU, make_solver
from .nullspace import for_rows, kept_for_rows
from .reuse import Reusing, saddle_point as _reused_saddle_point

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
    d, reactions = solve_constrained(K, f, transformation(basis, N)[D], g)
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


def solve_saddle_point(solver, K, f, C, g, rtol=1e-12, maxiter=200):
    """Solve ``K d = f + Cᵀ λ``, ``C d = g`` with ``solver``; return ``d``, ``λ``.

    The saddle-point system is ``[[K, Cᵀ], [C, 0]] [d; -λ] = [f; g]``.
    ``"auto"`` first eliminates the conditions by a null-space basis ``Z``
    (:mod:`skfem_rkpm.solvers.nullspace`, built once per set of rows) where
    that pays: when ``Zᵀ K Z`` is a selection of ``K`` (FEM rows of one
    component) or ``K`` is small and dense enough for dense LU (3D RK).
    One factorization of ``Zᵀ K Z`` and one solve then replace the
    multiplier iteration below (billet_3d, FEM, 945 unknowns, 143 weak
    symmetry rows, CPU under cProfile: 9 ms per solve against 28 ms for
    ``K + ρCᵀC`` and GMRES on the multipliers).  Otherwise, and for a
    backend asked for by name, as follows.
    Dense LU, UMFPACK, PARDISO and PETSc (MUMPS) factor it as it is.

    SuperLU and the SPD-only backends (CHOLMOD, AMG) use the augmented
    Lagrangian instead: with ``K_ρ = K + ρ CᵀC`` the system becomes
    ``K_ρ d = f + ρ Cᵀ g + Cᵀ λ`` and ``λ`` solves the Schur complement
    system ``C K_ρ⁻¹ Cᵀ λ = g - C K_ρ⁻¹ (f + ρ Cᵀ g)`` (``len(C)`` rows) by
    GMRES, one solve with the factored ``K_ρ`` per iteration
    (:func:`_schur_complement_solve`).  ``K_ρ`` has the sparsity class of
    ``K``, and it is nonsingular (positive definite for symmetric positive
    semi-definite ``K``) whenever the saddle-point system is, also when
    ``K`` alone is singular because only the constraints remove its
    rigid-body modes.  If ``K`` is invertible, the eigenvalues of
    ``(C K_ρ⁻¹ Cᵀ)⁻¹`` are ``ρ`` plus those of ``(C K⁻¹ Cᵀ)⁻¹``; with
    ``ρ = 10 |K| / |CᵀC|`` most lie near ``ρ`` and GMRES needs about ten
    iterations on the coarse 3D RK scenes (9-19 on the ring sector's 464
    weak rows), more where rows nearly cancel (80-90 on the thin sheet of
    ``stretch_3d``).  SuperLU's minimum-degree ordering of the
    saddle-point matrix itself reaches the zero diagonal of the multipliers
    half-way and must pivot off the diagonal there (2675 of 4160 pivots on
    a coarse 3D RK ring sector with weak symmetry planes), which undoes the
    ordering: 14.0 million factor entries against 6.8 million for ``K_ρ``,
    3.3 s against 0.7 s under load (docs/benchmarks/linear_solvers.md).

    ``rtol`` is the backward error of the saddle-point system
    (:func:`_backward_error`) that iterative refinement goes for (1e-12,
    about 5000 units of round-off; SuperLU's direct solves of the 3D
    scenes' systems leave 2e-14 to 2e-8), at most three corrections from
    the residual; below :data:`ACCEPTED_BACKWARD_ERROR` the solve is
    accepted, else, or when ``K_ρ`` is singular, SuperLU factors the
    saddle-point matrix itself; an SPD-only backend asked for by name
    raises instead.  ``maxiter`` bounds the GMRES iterations of one solve.
    The shares of a partitioned tangent (``K.partial``,
    :class:`~skfem_rkpm.solvers.partitioned.PartialMatrix`) go to the
    saddle-point solve of their own.
    """
    solver.factored = None  # set below where the factors can solve again
    if getattr(K, "partial", False):  # the ranks' shares of a partitioned tangent
        return K.solve_saddle_point(solver, f, C, g)
    N = K.shape[0]
    given, K = K, _canonical(K)
    m = C.shape[0]
    if m == 0:
        _factor(solver, K, spd=True)
        solver.system = "K"
        solver.factored = Factored(given, C, K, solver, None)
        return solver.factored.solve(f, g)
    f = np.asarray(f, dtype=float)
    g = np.asarray(g, dtype=float)
    if isinstance(solver, Auto):
        solution = _eliminated(solver, K, f, C, g)
        if solution is not None:
            solver.factored = Factored(given, C, K, solver, solver.null_space)
            return solution
    given_C, C = C, sp.csr_matrix(C)
    backend = solver
    if isinstance(solver, Auto):
        name = solver.choose(sp.csr_matrix((N + m, N + m)))
        if name == "superlu" and solver.choose(K, spd=True) == "cholmod":
            name = "cholmod"  # CHOLMOD on K + ρCᵀC beats SuperLU on the KKT matrix
        backend = solver.backend(name)
    direct = backend.inner if isinstance(backend, Reusing) else backend
    if backend.spd_only or isinstance(direct, SuperLU):
        rho = _penalty(K, C)
        Krho = _canonical(K + rho * _gram(given_C, C))
        solution = _augmented_lagrangian(solver, backend, K, Krho, rho, f, C, g, rtol,
                                         maxiter)
        if solution is not None:
            solver.system = "K + ρCᵀC (constraints by the augmented Lagrangian)"
            factors = getattr(solver, "current", None) if isinstance(solver, Auto) else solver
            if solver.A is Krho and not getattr(factors, "stale", False):
                solver.factored = AugmentedFactored(given, given_C, K, solver, factors,
                                                    (rho, C, rtol, maxiter))
            return solution
        backend = solver.backend("superlu") if isinstance(solver, Auto) else backend
    A = _saddle_matrix(K, C, dense=isinstance(direct, DenseLU))
    if isinstance(backend, Reusing):  # GMRES would not keep C d = g to round-off
        backend.factor(A, reuse=False)
    else:
        backend.factor(A)
    solver.A = A
    solver.system = "the saddle-point matrix [[K, Cᵀ], [C, 0]]"
    sol = backend.solve(np.concatenate([f, g]))
    return sol[:N], -sol[N:]


def _eliminated(solver, K, f, C, g):
    """``d, λ`` with the conditions eliminated by a null-space basis
    (:mod:`skfem_rkpm.solvers.nullspace`), or None where that does not pay:
    when the reduced matrix ``Zᵀ K Z`` is neither a selection of ``K`` (FEM)
    nor small and dense enough for dense LU (``Auto.choose`` on ``K``).  The
    basis is built once per set of conditions
    (:func:`~skfem_rkpm.solvers.nullspace.for_rows`)."""
    elimination = solver.null_space = for_rows(C)
    if elimination is None:
        return None
    dense = solver.choose(K) == "dense"
    if not (dense or elimination.selection):
        return None
    d0 = elimination.particular(g)
    if dense:
        reduced = elimination.reduce_dense(K)
        solver.backend("dense").factor(reduced)
    else:
        reduced = elimination.reduce(K)
        solver.factor(reduced, spd=True)
    solver.A = reduced
    solver.system = "Zᵀ K Z (constraints eliminated by a null-space basis)"
    return _eliminated_solve(solver, elimination, K, f, d0)


def _eliminated_solve(solver, elimination, K, f, d0):
    """``d, λ`` from the factored ``Zᵀ K Z`` and the particular ``d₀``."""
    z = solver.solve(elimination.reduced_load(K, f, d0))
    d = elimination.expand(z, d0)
    return d, elimination.multipliers((K @ d - f)[elimination.D])


class Factored:
    """The system that :func:`solve_saddle_point` factored last with a
    solver (``solver.factored``), where its factors solve it again for new
    right-hand sides: ``K`` without conditions, or with the conditions
    eliminated by a null-space basis.  ``K`` and ``C`` are the objects
    given (:func:`~skfem_rkpm.solvers.low_rank.solve_updated` recognizes
    the system by them; ``K`` is referenced weakly); the other paths leave
    ``solver.factored`` None."""

    def __init__(self, K, C, canonical, solver, elimination):
        # K only by weak reference: a tangent is not kept alive for this
        self._K, self._canonical = weakref.ref(K), weakref.ref(canonical)
        self._copy = None if canonical is K else canonical  # lives only here
        self.C, self.solver, self.elimination = C, solver, elimination
        self.A = solver.A  # the matrix factored: another factorization replaces it

    @property
    def canonical(self):
        """``K`` in canonical CSR form."""
        return self._canonical()

    def holds(self, K, C):
        """Whether the solver's factors are still those of ``K`` and ``C``."""
        return self._K() is K and self.C is C and self.solver.A is self.A

    def solve(self, f, g):
        """``d, λ`` of ``K d = f + Cᵀ λ``, ``C d = g`` (``f``, ``g`` 1-D or
        with a column per right-hand side), without factoring again."""
        f, g = np.asarray(f, dtype=float), np.asarray(g, dtype=float)
        if self.elimination is None:
            return self.solver.solve(f), np.zeros((0,) + f.shape[1:])
        return _eliminated_solve(self.solver, self.elimination, self.canonical, f,
                                 self.elimination.particular(g))


class AugmentedFactored(Factored):
    """The factors of ``K_ρ = K + ρ CᵀC`` that the augmented Lagrangian of
    :func:`solve_saddle_point` solved with last (``solver.factored``): they
    solve the system again for new right-hand sides, and that of ``K + ΔK``
    with ``ΔK`` nonzero in a few rows (:meth:`solve_changed`).
    ``factors`` is the backend holding them; ``augmented`` is ``(ρ, C
    (CSR), rtol, maxiter)`` of the solve."""

    def __init__(self, K, C, canonical, solver, factors, augmented):
        super().__init__(K, C, canonical, solver, None)
        self.factors = factors
        self.rho, self.rows, self.rtol, self.maxiter = augmented

    def solve(self, f, g, apply=None, K=None):
        """``d, λ`` of ``K d = f + Cᵀ λ``, ``C d = g`` by the augmented
        Lagrangian (:func:`_refined_solve`, to the same backward error as
        the first solve) with ``apply`` for ``K_ρ⁻¹`` (default: the
        factors) and the system's ``K`` (default: the one factored).
        Raises LinAlgError where the backward error is not reached."""
        f, g = np.asarray(f, dtype=float), np.asarray(g, dtype=float)
        apply = self.factors.solve if apply is None else apply
        K = self.canonical if K is None else K
        return _per_column(lambda fj, gj: _refined_solve(apply, K, self.rho, fj, self.rows,
                                                         gj, self.rtol, self.maxiter), f, g)

    def solve_changed(self, dK, rows, f, g):
        """``d, λ`` of ``(K + ΔK) d = f + Cᵀ λ``, ``C d = g`` with ``ΔK``
        (CSR) nonzero only in ``rows``: ``K_ρ + ΔK`` is the augmented matrix
        of the changed system, and its inverse is applied from the factors
        of ``K_ρ`` by the Sherman-Morrison-Woodbury formula,
        ``(K_ρ + E M)⁻¹ b = y - X (I + M X)⁻¹ M y`` with ``y = K_ρ⁻¹ b``,
        ``X = K_ρ⁻¹ E`` (one solve with ``len(rows)`` columns) and ``M =
        ΔK[rows]``.  The refined solve measures its backward error in the
        changed system itself, so the answer meets the bound a
        factorization of ``K_ρ + ΔK`` would; raises LinAlgError where it
        does not (then factor the changed system)."""
        if not len(rows):
            return self.solve(f, g)
        N, s = self.canonical.shape[0], len(rows)
        M = dK[rows]
        E = np.zeros((N, s))
        E[rows, np.arange(s)] = 1.0
        X = self.factors.solve(E)
        capacitance = scipy.linalg.lu_factor(np.eye(s) + M @ X, check_finite=False)

        def apply(b):
            y = self.factors.solve(b)
            return y - X @ scipy.linalg.lu_solve(capacitance, M @ y, check_finite=False)

        return self.solve(f, g, apply, self.canonical + dK)


#: ``CᵀC`` of the last sets of rows given to :func:`_gram`
_GRAMS = []


def _gram(given, C):
    """``CᵀC`` (CSR) of the rows ``C``, ``given`` the object they came in:
    formed once while the same unchanged rows come again (a Newton run
    passes one matrix of conditions to every solve; 25 ms a tangent for the
    ring sector's 464 rows), as :func:`~skfem_rkpm.solvers.nullspace.for_rows`
    keeps its null spaces."""
    return kept_for_rows(_GRAMS, given, C, lambda rows: sp.csr_matrix(rows.T @ rows))


def _saddle_matrix(K, C, dense=False):
    """``[[K, Cᵀ], [C, 0]]``, sparse, or a dense array for dense LU."""
    if not dense:
        return _canonical(sp.bmat([[K, C.T], [C, None]]))
    N, m = K.shape[0], C.shape[0]
    A = np.zeros((N + m, N + m))
    A[:N, :N] = K.toarray()
    A[N:, :N] = C.toarray()
    A[:N, N:] = A[N:, :N].T
    return A


def _augmented_lagrangian(solver, backend, K, Krho, rho, f, C, g, rtol, maxiter):
    """``d, λ`` from the factored ``K_ρ`` (see :func:`solve_saddle_point`),
    or None when SuperLU should factor the saddle-point matrix instead."""
    explicit = backend is solver and backend.spd_only
    try:
        backend.factor(Krho)
    except (NotPositiveDefinite, RuntimeError):
        # CHOLMOD: K_ρ is not positive definite; SuperLU: K_ρ is singular
        if explicit:
            raise
        if backend.spd_only:  # auto: SuperLU on the (indefinite) K_ρ
            return _augmented_lagrangian(solver, solver.backend("superlu"), K, Krho,
                                         rho, f, C, g, rtol, maxiter)
        return None
    solver.A = Krho
    if getattr(backend, "stale", False):  # the last factorization of an earlier K_ρ
        solution = _reused(backend, K, rho, f, C, g)
        if solution is not None:
            return solution
        try:
            backend.refactor()
        except (NotPositiveDefinite, RuntimeError):
            if explicit:
                raise
            return None
    try:
        return _per_column(lambda fj, gj: _refined_solve(backend.solve, K, rho, fj, C, gj,
                                                         rtol, maxiter), f, g)
    except np.linalg.LinAlgError:
        if explicit:
            raise
        return None


def _per_column(solve_one, f, g):
    """``solve_one(f, g)`` -> ``(d, λ)`` (or None) for a 1-D ``f``; for 2-D
    ``f`` and ``g`` once per column, the answers stacked as columns, or None
    when one column's answer is None."""
    if f.ndim == 1:
        return solve_one(f, g)
    pairs = [solve_one(f[:, j], g[:, j]) for j in range(f.shape[1])]
    if any(p is None for p in pairs):
        return None
    return (np.column_stack([p[0] for p in pairs]), np.column_stack([p[1] for p in pairs]))


#: the backward error of the saddle-point system (:func:`_backward_error`) at
#: which an augmented Lagrangian solve is accepted after its refinements
#: (SuperLU's direct solves of the saddle point of the 3D scenes leave 2e-14
#: to 2e-8; its own check accepts a residual of 1e-10 |b|)
ACCEPTED_BACKWARD_ERROR = 1e-10


def _reused(backend, K, rho, f, C, g):
    """:func:`skfem_rkpm.solvers.reuse.saddle_point` for each column of ``f``
    and ``g``, or None when GMRES stalls on one of them."""
    return _per_column(lambda fj, gj: _reused_saddle_point(backend, K, rho, fj, C, gj), f, g)


def _refined_solve(solve, K, rho, f, C, g, rtol, maxiter, refinements=3):
    """:func:`_schur_complement_solve`, then corrections from the residual of
    the saddle-point system (iterative refinement) while its backward error
    is above ``rtol``; raises LinAlgError when it ends above
    :data:`ACCEPTED_BACKWARD_ERROR`."""
    norms = (spla.norm(K, np.inf), spla.norm(C, np.inf), spla.norm(C, 1))
    d, lam = _schur_complement_solve(solve, rho, f, C, g, maxiter)
    for k in range(refinements + 1):
        r_f = f - K @ d + C.T @ lam
        r_g = g - C @ d
        error = _backward_error(norms, f, g, d, lam, r_f, r_g)
        if error <= rtol or k == refinements:
            break
        dd, dlam = _schur_complement_solve(solve, rho, r_f, C, r_g, maxiter)
        d, lam = d + dd, lam + dlam
    if not error <= ACCEPTED_BACKWARD_ERROR:
        raise np.linalg.LinAlgError(
            f"the augmented Lagrangian solve left a backward error {error:.2e} in the "
            f"saddle-point system (accepted: {ACCEPTED_BACKWARD_ERROR:g}); it may be "
            f"singular: use solver 'superlu' or 'pardiso'")
    return d, lam


def _backward_error(norms, f, g, d, lam, r_f, r_g):
    """The normwise backward error of ``d, λ`` in each block row of the
    saddle-point system (max norms): ``|r_f| / (|K| |d| + |Cᵀ| |λ| + |f|)``
    and ``|r_g| / (|C| |d| + |g|)``, the larger of the two.  Each block row
    is measured in its own units (forces, displacements).  A backward-stable
    direct solve makes both of the order of the unit round-off times the
    growth of its pivots.  ``norms``: ``|K|``, ``|C|`` and ``|Cᵀ|``."""
    def size(v):
        return np.abs(v).max(initial=0.0)

    norm_K, norm_C, norm_Ct = norms
    force = norm_K * size(d) + norm_Ct * size(lam) + size(f)
    value = norm_C * size(d) + size(g)
    return max(size(r_f) / force if force > 0 else 0.0,
               size(r_g) / value if value > 0 else 0.0)


#: relative residual of GMRES on the Schur complement before a refinement
SCHUR_RTOL = 1e-10


def _schur_complement_solve(solve, rho, f, C, g, maxiter):
    """GMRES on ``ρ C K_ρ⁻¹ Cᵀ λ = ρ (g - C K_ρ⁻¹ (f + ρ Cᵀ g))``; ``solve``
    applies ``K_ρ⁻¹``.  Returns ``d = K_ρ⁻¹ (f + ρ Cᵀ g + Cᵀ λ)`` and ``λ``.

    The factor ``ρ`` scales the operator to eigenvalues of at most 1.
    GMRES (restarted after 50 iterations, at most ``maxiter`` in all) to
    the relative residual :data:`SCHUR_RTOL`, which is all the iteration
    needs to do: :func:`_refined_solve` corrects the rest.  The eigenvalues
    near zero belong to combinations of the condition rows that nearly
    cancel (``|C|`` over its smallest singular value: 140 for the weak
    rows of the ring sector, 3e4 on the thin sheet of ``stretch_3d``), and
    the residual attainable in ``λ`` is limited by them.
    """
    m = C.shape[0]
    rhs = f + rho * (C.T @ g)
    d0 = solve(rhs)
    b = rho * (g - C @ d0)
    if not np.any(b):
        return d0, np.zeros(m)

    def schur(lam):
        return rho * (C @ solve(C.T @ lam))

    restart = min(m, 50)
    lam, _ = gmres(LinearOperator((m, m), matvec=schur, dtype=float), b, rtol=SCHUR_RTOL,
                   atol=0.0, restart=restart, maxiter=-(-maxiter // restart))
    if not np.all(np.isfinite(lam)):
        raise np.linalg.LinAlgError("GMRES on the Schur complement of the constraints "
                                    "gave non-finite multipliers (a singular K + ρCᵀC?)")
    return solve(rhs + C.T @ lam), lam


def _factor(solver, A, spd):
    if isinstance(solver, Auto):
        solver.factor(A, spd=spd)
    else:
        solver.factor(A)
