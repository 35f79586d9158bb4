"""Newton tangents solved with the last factorization: GMRES preconditioned by
it, and a refactorization when GMRES stalls.

Between two Newton iterations (and between a tangent and the touching or
stick prediction that adds a few contact stiffnesses to it) the tangent
changes little, while its sparse LU grows fastest of all the parts of an
iteration: on the billet's Hex1 tangent at 40k unknowns SuperLU takes 6.7-7.3
s, GMRES on the next iteration's matrix preconditioned by the last LU 1.57 s
(21 iterations; docs/forming_3d.md, "The linear solver at real size").  A
:class:`Reusing` backend therefore keeps the last factorization ``M`` of its
``inner`` (direct) backend; the next matrix ``A`` is not factored: each solve
runs GMRES on ``A M⁻¹ y = b``, ``x = M⁻¹ y`` (right preconditioning, so that
GMRES's residual is the true one, ``|b - A x|``).  When GMRES does not reach
the relative residual ``rtol`` within ``maxiter`` iterations (40), ``A`` is
factored after all (a *fallback*, counted in ``stats``) and solved directly; that
factorization is the preconditioner of the next matrices.

The tolerance follows the Newton tolerance (:meth:`Reusing.follow_newton`):
``rtol = NEWTON_FRACTION · tol``.  Newton's next residual is ``r - K δ`` plus
terms of second order in ``δ``; a linear residual of at most ``rtol |r|``
(``|r| ≤ 2 ref`` for the reference force ``ref`` of the convergence test)
moves the relative residual Newton tests by at most ``2 · NEWTON_FRACTION ·
tol`` = 0.2 % of ``tol``: the converged steps and their iteration counts
stay those of the direct solves, and the converged answer moves by less
than the Newton tolerance does.

Under constraints solved by the augmented Lagrangian (``K_ρ = K + ρ CᵀC``,
:func:`~skfem_rkpm.solvers.constrained.solve_saddle_point`), one GMRES on
the whole saddle-point system replaces the GMRES on the multipliers with an
exact ``K_ρ⁻¹`` inside (:func:`saddle_point`).
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, gmres, splu

from .backend import Solver, _canonical

__all__ = ["Reusing", "reusing", "REUSE_MODES", "REUSE_LIMIT", "REUSE_ENTRIES",
           "NEWTON_FRACTION",
           "MAX_ITERATIONS", "preconditioned_gmres", "saddle_point"]

#: ``reuse_factorization``: ``"off"`` (factor every matrix), ``"on"`` (reuse
#: the last factorization at every size), ``"auto"`` (from :data:`REUSE_LIMIT`
#: unknowns or :data:`REUSE_ENTRIES` stored entries on)
REUSE_MODES = ("off", "on", "auto")

#: ``"auto"`` reuses the last factorization for matrices of at least this
#: order.  Measured on the billet (CPU, one core, load 7-10): at 802 (FEM,
#: whole run) reuse costs 11.1 s against 8.2 s direct; at 5,476 (FEM, first 3
#: steps) 406 against 594 ms per iteration, at 5,967 (RKPM, first 8 tangents)
#: 4.8 against 5.9 s per tangent, at 42,075 (FEM, first 4 tangents) 21.1
#: against 24.5 s per tangent (docs/forming_3d.md)
REUSE_LIMIT = 5000

#: ``"auto"`` also reuses it for smaller matrices with at least this many
#: stored entries: what a factorization costs against a GMRES iteration
#: grows with the entries per row, not with the order alone.  The RK
#: tangents in 3D have about 600 a row (FEM Hex1 at most 81): the ring
#: sector's ``K + ρCᵀC`` (3,696 unknowns, 2.27 M entries) factors in 1.1-1.5
#: s against 12 ms for a solve with the factors, about 70 GMRES iterations
#: (FEM at 5,476 unknowns, where reuse pays: 17), and reuse pays there
#: (docs/forming_3d.md, "The ring sector's linear solves").  The thin sheet
#: of ``stretch_3d`` (3,969 unknowns, 1.15 M entries in ``K``), whose
#: conditions need 80-90 GMRES iterations on the multipliers even with
#: exact factors, is not measured with reuse and stays below the limit.
REUSE_ENTRIES = 2_000_000

#: the linear relative residual over the Newton tolerance
NEWTON_FRACTION = 1e-3

#: GMRES iterations of one reused solve before the matrix is factored.
#: Measured on the billet (CPU per iteration or tangent, load 8-11): RKPM at
#: 5,967 unknowns, first 8 tangents, 4.8 s with a cap of 40 against 5.7 s
#: with one of 100 (about a factorization's cost: 33 ms per GMRES iteration,
#: 2.7 s per factorization); FEM at 5,967, first 3 steps, 406 ms with 40
#: against 417 ms with 16 (half a factorization's cost)
MAX_ITERATIONS = 40

#: a reused solve that needs more than this fraction of its cap of GMRES
#: iterations makes the next matrix factored (a fresh preconditioner)
REFRESH = 0.5

#: backends whose factorization can be kept: the sparse direct ones (dense LU
#: of the small systems it is chosen for costs no more than a few solves)
REUSABLE = ("superlu", "pardiso", "umfpack", "cholmod")


def preconditioned_gmres(matvec, precondition, b, rtol, maxiter):
    """``x`` with ``|b - A x| ≤ rtol |b|`` by GMRES on ``A M⁻¹`` (no restart),
    ``x = M⁻¹ y``; returns ``(x, iterations, converged)``.  ``matvec``
    applies ``A``, ``precondition`` ``M⁻¹``."""
    n = len(b)
    nb = np.linalg.norm(b)
    if nb == 0:
        return np.zeros_like(b), 0, True
    count = [0]

    def counted(_):
        count[0] += 1

    operator = LinearOperator((n, n), matvec=lambda y: matvec(precondition(y)), dtype=float)
    y, _ = gmres(operator, b, rtol=rtol, atol=0.0, restart=min(maxiter, n), maxiter=1,
                 callback=counted, callback_type="pr_norm")
    x = precondition(y)
    converged = bool(np.all(np.isfinite(x)) and np.linalg.norm(b - matvec(x)) <= rtol * nb)
    return x, count[0], converged


class Reusing(Solver):
    """A direct backend ``inner`` whose last factorization serves the next
    matrices through GMRES (see the module docstring).

    ``min_size``: smaller matrices are factored every time, unless they have
    at least ``min_entries`` stored entries (0: no such exception).  ``stats`` adds
    ``reused`` (matrices not factored), ``gmres_iterations`` and
    ``fallbacks`` (reused matrices factored after all because GMRES stalled)
    to the counts of ``inner.stats`` (its ``factorizations`` are all the
    factorizations done).
    """

    def __init__(self, inner, min_size=0, rtol=1e-9, maxiter=MAX_ITERATIONS, min_entries=0):
        super().__init__(inner.symmetric, **inner.options)
        self.inner, self.min_size, self.rtol, self.maxiter = inner, min_size, rtol, maxiter
        self.min_entries = min_entries
        self.name = inner.name
        self.stale = self.refresh = False
        self.stats = inner.stats
        self.stats.update(reused=0, gmres_iterations=0, fallbacks=0)
        self.iterations = []  # GMRES iterations of each reused solve

    @property
    def spd_only(self):
        return self.inner.spd_only

    def follow_newton(self, tol):
        """Tie the linear tolerance to the Newton tolerance ``tol``."""
        self.rtol = NEWTON_FRACTION * float(tol)

    def factor(self, A, reuse=True):
        """Keep ``A``; factor it only when there is no factorization of a
        matrix of its order to reuse, it is below ``min_size`` (and has fewer
        than ``min_entries`` entries) or ``reuse`` is False."""
        A = _canonical(A)
        kept = self.inner.A
        if self.refresh:  # the last reused solve was slow: a new preconditioner
            reuse, self.refresh = False, False
        large = A.shape[0] >= self.min_size or 0 < self.min_entries <= A.nnz
        if reuse and kept is not None and kept.shape == A.shape and large:
            self.A, self.stale = A, True
            self.stats["reused"] += 1
            return self
        self._factor_inner(A)
        self.A, self.stale = A, False
        return self

    def _factor_inner(self, A):
        try:
            self.inner.factor(A)
        except BaseException:
            self.inner.reset()  # no factorization of A to keep
            raise

    def refactor(self):
        """Factor the kept matrix after all (GMRES stalled on it)."""
        self.stats["fallbacks"] += 1
        self._factor_inner(self.A)
        self.stale = self.refresh = False

    def precondition(self, b):
        """``M⁻¹ b`` with the kept factorization."""
        return self.inner.solve(b)

    def gmres(self, matvec, precondition, b):
        """:func:`preconditioned_gmres` with this backend's tolerance and
        ``maxiter``, counted; more than ``REFRESH`` of ``maxiter`` make the
        next matrix factored.  Returns ``x`` or None when GMRES stalls."""
        cap = self.maxiter
        x, its, converged = preconditioned_gmres(matvec, precondition, b, self.rtol, cap)
        self.iterations.append(its)
        self.stats["gmres_iterations"] += its
        self.refresh = its > REFRESH * cap
        return x if converged else None

    def solve(self, b):
        """Solve ``A x = b`` (the solves are counted in ``inner.stats``)."""
        if self.A is None:
            raise RuntimeError("call factor(A) before solve(b)")
        return self._solve(np.asarray(b, dtype=float))

    def _solve(self, b):
        if self.stale:
            columns = b.T if b.ndim == 2 else [b]
            solved = []
            for column in columns:
                x = self.gmres(self.A.dot, self.precondition, column)
                if x is None:
                    break
                solved.append(x)
            else:
                return np.column_stack(solved) if b.ndim == 2 else solved[0]
            self.refactor()
        return self.inner.solve(b)

    def reset(self):
        super().reset()
        self.inner.reset()
        self.stale = False

    def describe(self):
        return (f"{self.inner.describe()}; the last factorization reused by GMRES "
                f"(relative residual {self.rtol:.0e}, at most {self.maxiter} iterations)"
                + (f" from {self.min_size} unknowns" if self.min_size else "")
                + (f" or {self.min_entries:,} entries" if self.min_entries else "")
                + (" on" if self.min_size or self.min_entries else ""))


def reusing(inner, mode, name):
    """``inner`` wrapped in :class:`Reusing` for ``mode`` (one of
    :data:`REUSE_MODES`), or ``inner`` itself for ``"off"`` and the backends
    not in :data:`REUSABLE`."""
    if mode not in REUSE_MODES:
        raise ValueError(f"reuse_factorization must be one of {', '.join(REUSE_MODES)}, "
                         f"not {mode!r}")
    if mode == "off" or name not in REUSABLE:
        return inner
    if mode == "auto":
        return Reusing(inner, min_size=REUSE_LIMIT, min_entries=REUSE_ENTRIES)
    return Reusing(inner)


def saddle_point(backend, K, rho, f, C, g):
    """``d, λ`` of ``K d = f + Cᵀ λ``, ``C d = g`` by GMRES with the kept
    factorization of an earlier ``K_ρ`` (``backend``, a stale
    :class:`Reusing`), or None when GMRES stalls.

    With ``d = d₀ + e``, ``d₀ = Cᵀ (CCᵀ)⁻¹ g`` (``CCᵀ`` factored once per
    set of rows), ``e`` solves the system with ``C e = 0``; in the augmented
    form with its second row scaled by ``ρ`` (forces in both rows),
    ``[[K_ρ, Cᵀ], [ρC, 0]] [e; μ] = [f - K d₀; 0]`` with ``μ = -λ``.  It is
    preconditioned from the right by the block triangle ``P = [[M, Cᵀ],
    [0, -1]]``, ``M`` the kept factorization: with ``M = K_ρ`` the
    preconditioned matrix is ``[[1, 0], [ρ C K_ρ⁻¹, ρ C K_ρ⁻¹ Cᵀ]]``, whose
    eigenvalues are 1 and those of the Schur complement operator the direct
    path iterates on (:func:`~skfem_rkpm.solvers.constrained.
    _schur_complement_solve`), so GMRES needs about as many iterations as
    that one, each with one solve by ``M``.  ``e`` is then projected onto
    ``C e = 0`` (``C d = g`` to round-off, as Newton's test of the prescribed
    values needs), and the residual of the first row, ``|f - K d + Cᵀ λ|``,
    must be at most ``rtol |f - K d₀|``.
    """
    N, m = K.shape[0], C.shape[0]
    Krho, CT = backend.A, sp.csr_matrix(C.T)

    def matvec(x):
        d, mu = x[:N], x[N:]
        return np.concatenate([Krho @ d + CT @ mu, rho * (C @ d)])

    def precondition(y):
        u, v = y[:N], y[N:]
        return np.concatenate([backend.precondition(u + CT @ v), -v])

    d0 = CT @ _rows_solve(backend, C, g)  # C d0 = g
    f0 = f - K @ d0
    b = np.concatenate([f0, np.zeros(m)])
    x = backend.gmres(matvec, precondition, b)
    if x is None:
        return None
    e, lam = x[:N], -x[N:]
    d = d0 + e - CT @ _rows_solve(backend, C, C @ e)
    if not np.linalg.norm(f - K @ d + CT @ lam) <= backend.rtol * np.linalg.norm(f0):
        return None
    return d, lam


def _rows_solve(backend, C, r):
    """``(CCᵀ)⁻¹ r``, the factorization of ``CCᵀ`` kept on ``backend`` for the
    rows ``C``."""
    kept = getattr(backend, "_rows", None)
    if kept is None or not (kept[0].shape == C.shape and kept[0].nnz == C.nnz
                            and np.array_equal(kept[0].indptr, C.indptr)
                            and np.array_equal(kept[0].indices, C.indices)
                            and np.array_equal(kept[0].data, C.data)):
        kept = backend._rows = (C.copy(), splu(sp.csc_matrix(C @ C.T)))
    return kept[1].solve(r)
