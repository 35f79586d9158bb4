"""Sparse linear solvers behind one small interface.

Every Newton iteration ends in a factorization of the tangent (or of the
saddle-point matrix with the constraints), and RK tangents have 90-150
nonzeros per row, so the solver decides how large a model can be.  The
Newton loop calls::

    solver = make_solver("auto")      # once per run
    solver.factor(A)                  # every iteration
    x = solver.solve(b)

``factor`` keeps the symbolic analysis (fill-reducing ordering, elimination
tree) of the last matrix and reuses it when the next matrix has the same
sparsity pattern and the backend allows it.

Backends (``make_solver(name)``):

``"dense"``
    LAPACK LU of the dense matrix.  Best for small systems (the paper's ring,
    352 unknowns with 43 % nonzeros).
``"superlu"``
    scipy's SuperLU in symmetric mode, pivoting off the diagonal only where a
    pivot is below 1 % of its column, on the METIS nested dissection ordering
    of ``Aᵀ + A`` (``pymetis``, a default dependency) above ``ND_LIMIT``
    unknowns and its minimum-degree ordering below; COLAMD with partial
    pivoting if the residual is poor.  Always available; handles any
    nonsingular matrix; factors the 1e5-particle RK tangent in 1.5-2.0× the
    time and 1.7× the memory of PARDISO, refactors it in 2.5-2.7× the time
    (docs/benchmarks/linear_solvers.md).
``"pardiso"``
    MKL PARDISO through ``pypardiso`` (``pip install skfem-rkpm[pardiso]``,
    about 1 GB with MKL).  Any nonsingular matrix; analysis reused.
``"umfpack"``
    UMFPACK multifrontal LU (SuiteSparse) through the ``cvxopt`` wheel
    (``pip install skfem-rkpm[umfpack]``, 21 MB, 65 MB installed, no
    compiler needed).  Any nonsingular matrix; analysis reused.  Only by
    name: on the RK tangents measured it is no faster than SuperLU with
    nested dissection and its solves are 10× slower (docs/benchmarks/linear_solvers.md).
``"cholmod"``
    CHOLMOD supernodal Cholesky through ``scikit-sparse``
    (``pip install skfem-rkpm[cholmod]`` after
    ``apt-get install libsuitesparse-dev``).  Symmetric positive definite
    matrices only; analysis reused.
``"amg"``
    Smoothed-aggregation AMG (``pyamg``, ``pip install skfem-rkpm[amg]``)
    as the preconditioner of CG (symmetric) or GMRES (non-symmetric),
    iterated to a relative residual of ``rtol`` (1e-12).  Symmetric positive
    definite matrices; the hierarchy is rebuilt at every ``factor``.
``"petsc"``, ``"petsc-gamg"``
    PETSc KSP through ``petsc4py`` (``pip install skfem-rkpm[petsc]``, a
    source build): MUMPS LU, or GAMG + CG/GMRES (positive definite only),
    distributed over the ranks of a run started with ``mpiexec``; see
    :mod:`skfem_rkpm.solvers.petsc`.
``"auto"``
    Picks one of the above (never PETSc) at every ``factor`` from the size, the symmetry
    and what is installed; :meth:`Solver.describe` says what it picked.

SPD-only backends (``cholmod``, ``amg``) cannot factor the symmetric
indefinite saddle-point matrix of
:func:`~skfem_rkpm.solvers.constrained.solve_saddle_point`, and SuperLU's
orderings do it badly (pivots off the zero diagonal undo them); with these
three the constraints are handled by an augmented Lagrangian instead (see
that function).
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .backend import (BACKENDS, BackendUnavailable, Solver, _canonical, _import_backend,
                      _refine, available, installed, is_symmetric)
from .petsc import PETScGAMG, PETScLU
from .reuse import REUSE_MODES, reusing

__all__ = ["make_solver", "available", "Solver", "BackendUnavailable",
           "is_symmetric", "DENSE_LIMIT", "DENSE_FRACTION", "DENSE_SIZE", "ND_LIMIT",
           "BACKENDS"]

#: systems up to this size are solved with dense LU by ``"auto"`` (measured:
#: SuperLU wins from about 600 unknowns on, even for RK tangents with 200
#: nonzeros per row)
DENSE_LIMIT = 500

#: ``"auto"`` also takes dense LU for systems up to ``DENSE_SIZE`` unknowns
#: with at least ``DENSE_FRACTION`` of their entries nonzero (3D RK
#: tangents).  Measured on one core, LAPACK LU of the dense matrix against
#: SuperLU (MMD, symmetric mode) on the billet_3d tangents: RK 945 unknowns,
#: 42 % nonzero, 20 ms against 36 ms; RK 1782, 27 %, 99 against 131 ms;
#: RK 2730, 19 %, 347 against 285 ms; FEM Hex1 945, 6 %, 18 against 6 ms
DENSE_FRACTION = 0.25
DENSE_SIZE = 3000

#: ``"auto"`` takes PARDISO (if installed) only above this size: measured on one
#: core, SuperLU is faster up to about 1e4 unknowns, and PARDISO with several
#: threads is not bitwise reproducible from run to run
PARDISO_LIMIT = 20000

#: SuperLU orders systems above this size by nested dissection (if ``pymetis``
#: is installed), smaller ones by MMD: measured on one core on the 2D RK
#: tangents (support 3), MMD is faster at 2e4 unknowns (2.0 s against 2.9 s),
#: nested dissection at 3.4e4 (5.4 s against 6.2 s; docs/benchmarks/linear_solvers.md)
ND_LIMIT = 30000


class DenseLU(Solver):
    """LAPACK LU with partial pivoting of the dense matrix."""

    name = "dense"

    def factor(self, A):
        """Factor ``A``, sparse or a dense array (then used as it is: a small
        system needs no sparse bookkeeping, which costs as much as its LU)."""
        if sp.issparse(A):
            return super().factor(A)
        A = np.asarray(A, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1]:
            raise ValueError(f"the matrix must be square, it is {A.shape}")
        return self._factor_timed(A)

    def _factor(self, A):
        dense = A.toarray() if sp.issparse(A) else A
        self._lu = scipy.linalg.lu_factor(dense, check_finite=False)

    def _solve(self, b):
        return scipy.linalg.lu_solve(self._lu, b, check_finite=False)

    def describe(self):
        n = self.A.shape[0] if self.A is not None else "?"
        return f"dense LU (LAPACK, n = {n})"


class SuperLU(Solver):
    """SuperLU in symmetric mode (pivot threshold 0.01) with a fill-reducing
    ordering of ``A + Aᵀ``: METIS nested dissection above ``ND_LIMIT``
    unknowns (``pymetis``), MMD below it or without ``pymetis``; COLAMD with
    partial pivoting if the residual is poor.

    Measured on an RK elasticity saddle-point matrix with 8.5k unknowns and
    217 nonzeros per row: 0.45 s, against 14 s with SuperLU's default partial
    pivoting, whose row exchanges destroy the ordering (38M instead of 7M
    factor entries).  On the 3D RK saddle points of weak symmetry planes
    the zero diagonal forces such exchanges in symmetric mode too (2675 of
    4160 pivots on the coarse ring sector, 14M factor entries against 6.8M
    for ``K + ρCᵀC``), so
    :func:`~skfem_rkpm.solvers.constrained.solve_saddle_point` gives SuperLU
    ``K + ρCᵀC`` instead.  MMD's fill grows too fast for 2D RK tangents of
    1e5 particles (SuperLU fails with "gstrf was called with invalid
    arguments" after minutes); nested dissection factors them
    (docs/benchmarks/linear_solvers.md).  The nested dissection ordering
    and the permutation of the pattern are the symbolic analysis, reused
    while the pattern stays; scipy exposes no other symbolic phase.  Below
    ``ND_LIMIT`` the first factorization of a pattern orders it by MMD and
    the later ones of the same pattern reuse that ordering (SuperLU's
    ``perm_c``, its postorder included) on the permuted matrix: the same
    factors, without MMD each time (FEM billet_3d, 802 unknowns: 3.9 against
    4.8 ms per factorization).
    """

    name = "superlu"

    def _analyze(self, A):
        self._perm = nested_dissection(A) if A.shape[0] > ND_LIMIT else None
        self._nested, self._permuted = self._perm is not None, None
        if self._perm is not None:
            self._permutation_map(A)

    def _permutation_map(self, A):
        """Where each entry of the permuted matrix (compressed columns) comes from."""
        where = sp.csr_matrix((np.arange(1, A.nnz + 1, dtype=np.int64), A.indices, A.indptr),
                              shape=A.shape)
        where = where[self._perm][:, self._perm].tocsc()
        self._permuted = (where.data - 1, where.indices, where.indptr)

    def _factor(self, A):
        self.fallback = False
        self._csc = A.tocsc()
        if self._permuted is None:  # the first factorization of an MMD-ordered pattern
            self._lu = splu(self._csc, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                            options=dict(SymmetricMode=True))
            self._lu_permuted = False
            self._perm = np.argsort(self._lu.perm_c)
            self._permutation_map(A)
            return
        source, indices, indptr = self._permuted
        P = sp.csc_matrix((A.data[source], indices, indptr), shape=A.shape)
        self._lu = splu(P, permc_spec="NATURAL", diag_pivot_thresh=0.01,
                        options=dict(SymmetricMode=True))
        self._lu_permuted = True

    def _substitute(self, b):
        if not self._lu_permuted or self.fallback:
            return self._lu.solve(b)
        x = np.empty_like(b)
        x[self._perm] = self._lu.solve(b[self._perm])
        return x

    def _solve(self, b):
        x = self._substitute(b)
        res = np.linalg.norm(self._csc @ x - b)
        if np.isfinite(res) and res <= 1e-10 * np.linalg.norm(b):
            return x
        if not self.fallback:  # a poor pivot sequence: partial pivoting instead
            self._lu = splu(self._csc, permc_spec="COLAMD")
            self.fallback = True
        return self._lu.solve(b)

    def describe(self):
        if getattr(self, "fallback", False):
            return "SuperLU (COLAMD, partial pivoting)"
        order = "METIS nested dissection" if getattr(self, "_nested", False) else "MMD"
        return f"SuperLU ({order} of Aᵀ+A, symmetric mode, pivot threshold 0.01)"


def nested_dissection(A):
    """METIS nested dissection ordering of the graph of ``A + Aᵀ`` (``pymetis``),
    or None when ``pymetis`` is not installed.

    Rows come in blocks of ``b`` unknowns of one particle or node (the
    components of a vector field, numbered together) when consecutive rows
    have equal lengths; the graph of the blocks is ordered (``b``² times
    fewer edges) and each block kept together.  ``b`` is the largest of 3,
    2, 1 for which 99 % of the blocks have rows of equal length.
    """
    try:
        import pymetis
    except ImportError:
        return None
    n = A.shape[0]
    lengths = np.diff(A.indptr)
    block = 1
    for b in (3, 2):
        m = n // b
        rows = lengths[:m * b].reshape(m, b)
        if m and np.mean(np.all(rows == rows[:, :1], axis=1)) >= 0.99:
            block = b
            break
    coarse = -(-n // block)
    rows = np.repeat(np.arange(n) // block, lengths)
    G = sp.csr_matrix((np.ones(A.nnz), (rows, A.indices // block)), shape=(coarse, coarse))
    G = (G + G.T).tocsr()
    G.setdiag(0)
    G.eliminate_zeros()
    order, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(G.indptr, G.indices))
    perm = (block * np.asarray(order)[:, None] + np.arange(block)).ravel()
    return perm[perm < n]


class Pardiso(Solver):
    """MKL PARDISO (``pypardiso``): analysis (phase 11) once per pattern,
    numeric factorization (phase 22) per matrix, solve (phase 33).

    Uses the real unsymmetric mode (``mtype = 11``, the one pypardiso is
    tested with) for every matrix, with pypardiso's defaults: nested
    dissection ordering, scaling and weighted matching, pivot perturbation
    1e-13.  Perturbed pivots are corrected by two steps of iterative
    refinement in double precision.
    """

    name = "pardiso"

    def __init__(self, symmetric=None, **options):
        super().__init__(symmetric, **options)
        self._pypardiso = _import_backend("pardiso")
        self._ps = None

    def _analyze(self, A):
        if self._ps is not None:
            self._ps.free_memory(everything=True)
        self._ps = self._pypardiso.PyPardisoSolver(mtype=11)
        self._ps._check_A(A)
        self._ps.set_phase(11)
        self._ps._call_pardiso(A, np.zeros((A.shape[0], 1)))

    def _factor(self, A):
        self._ps._check_A(A)
        self._ps.set_phase(22)
        self._ps._call_pardiso(A, np.zeros((A.shape[0], 1)))

    def _phase33(self, b):
        self._ps.set_phase(33)
        return self._ps._call_pardiso(self.A, self._ps._check_b(self.A, b))

    def _solve(self, b):
        return _refine(self.A, b, self._phase33(b), self._phase33)

    def describe(self):
        return "MKL PARDISO (pypardiso, real unsymmetric mode, analysis reused)"

    def __del__(self):
        try:
            if self._ps is not None:
                self._ps.free_memory(everything=True)
        except Exception:
            pass


class UMFPACK(Solver):
    """UMFPACK multifrontal LU (SuiteSparse, through the ``cvxopt`` wheel);
    symbolic analysis (ordering, elimination tree) reused per pattern.

    UMFPACK takes compressed columns; the CSR arrays of ``A`` are the
    compressed columns of ``Aᵀ``, so ``Aᵀ`` is factored without a copy of
    the pattern and every solve is a transposed solve.  UMFPACK's automatic
    strategy (AMD ordering of ``A + Aᵀ`` and diagonal pivots for matrices
    with a nearly symmetric pattern and a nonzero diagonal, COLAMD and
    threshold partial pivoting otherwise) handles any nonsingular matrix,
    the non-symmetric RK and friction tangents included.  Two steps of
    iterative refinement from the residual.
    """

    name = "umfpack"

    def __init__(self, symmetric=None, **options):
        super().__init__(symmetric, **options)
        self._cvxopt = _import_backend("umfpack")
        from cvxopt import umfpack
        self._umfpack = umfpack

    def _analyze(self, A):
        n = A.shape[0]
        rows = np.repeat(np.arange(n), np.diff(A.indptr))
        # the transpose in compressed columns: column i holds row i of A
        self._At = self._cvxopt.spmatrix(A.data, A.indices.astype(int), rows, (n, n))
        self._symbolic = self._umfpack.symbolic(self._At)

    def _factor(self, A):
        self._At.V = self._cvxopt.matrix(A.data)  # same pattern: new values in place
        try:
            self._numeric = self._umfpack.numeric(self._At, self._symbolic)
        except ArithmeticError as err:
            raise RuntimeError(f"UMFPACK: the matrix ({A.shape[0]} unknowns) is singular "
                               f"({err}); check the supports and constraints") from err

    def _substitute(self, b):
        B = self._cvxopt.matrix(np.asfortranarray(b.reshape(len(b), -1)))
        self._umfpack.solve(self._At, self._numeric, B, trans="T")
        return np.array(B).reshape(b.shape)

    def _solve(self, b):
        return _refine(self.A, b, self._substitute(b), self._substitute)

    def describe(self):
        return "UMFPACK LU (cvxopt, SuiteSparse; analysis reused)"


class NotPositiveDefinite(np.linalg.LinAlgError):
    """An SPD-only backend met a matrix that is not positive definite."""


class Cholmod(Solver):
    """CHOLMOD supernodal Cholesky (``scikit-sparse``); analysis reused.

    Needs a symmetric positive definite matrix: friction tangents (not
    symmetric) and saddle-point matrices (indefinite) are refused.
    """

    name = "cholmod"
    spd_only = True

    def __init__(self, symmetric=None, **options):
        super().__init__(symmetric, **options)
        self._cholmod = _import_backend("cholmod")

    def _analyze(self, A):
        self._symbolic = self._cholmod.analyze(A.tocsc())

    def _check_symmetric(self, A):
        if self.symmetric is None and not is_symmetric(A):
            asym = abs(A - A.T).max() / abs(A).max()
            raise NotPositiveDefinite(
                f"CHOLMOD needs a symmetric matrix; this one has |A - Aᵀ| / |A| = "
                f"{asym:.1e} (RK bases with VCI integration and frictional contact give "
                f"non-symmetric tangents); use solver 'superlu', 'pardiso' or 'auto'")

    def _factor(self, A):
        self._check_symmetric(A)
        try:
            self._symbolic.cholesky_inplace(A.tocsc())
        except self._cholmod.CholmodNotPositiveDefiniteError as err:
            raise NotPositiveDefinite(
                f"CHOLMOD needs a symmetric positive definite matrix ({err}); use "
                f"solver 'superlu', 'pardiso' or 'auto' for indefinite or "
                f"non-symmetric systems") from err
        self._L = self._symbolic

    def _solve(self, b):
        return _refine(self.A, b, self._L(b), self._L, steps=1)

    def describe(self):
        return "CHOLMOD Cholesky (scikit-sparse, analysis reused)"


class AMG(Solver):
    """Smoothed-aggregation AMG (pyamg) preconditioning CG or GMRES.

    CG for symmetric matrices, GMRES otherwise (symmetry is checked unless
    declared).  Options: ``rtol`` (relative residual, default 1e-12), ``maxiter``
    (default 2000), ``near_nullspace`` (columns of rigid-body modes, e.g. for
    elasticity; default constants).  The hierarchy is rebuilt at every
    ``factor``: pyamg has no separate symbolic phase.
    """

    name = "amg"
    spd_only = True

    def __init__(self, symmetric=None, **options):
        super().__init__(symmetric, **options)
        self._pyamg = _import_backend("amg")
        self.iterations = []

    def _factor(self, A):
        B = self.options.get("near_nullspace")
        self._sym = self.symmetric if self.symmetric is not None else is_symmetric(A)
        self._ml = self._pyamg.smoothed_aggregation_solver(
            A, B=B, symmetry="symmetric" if self._sym else "nonsymmetric", max_coarse=500)

    def _solve(self, b):
        rtol = self.options.get("rtol", 1e-12)
        maxiter = self.options.get("maxiter", 2000)
        accel = "cg" if self._sym else "gmres"
        if b.ndim == 2:
            return np.column_stack([self._solve(col) for col in b.T])
        nb = np.linalg.norm(b)
        if nb == 0:
            return np.zeros_like(b)
        if accel == "gmres":
            maxiter = min(maxiter, len(b))  # pyamg's limit for GMRES
        x = np.zeros_like(b)
        its = 0
        for _ in range(4):  # restarts on the true residual (GMRES reports a preconditioned one)
            r = b - self.A @ x
            true = np.linalg.norm(r)
            if true <= 10 * rtol * nb:
                break
            residuals = []
            x = x + self._ml.solve(r, tol=rtol * nb / true, maxiter=maxiter, accel=accel,
                                   residuals=residuals)
            its += len(residuals) - 1
        else:
            raise np.linalg.LinAlgError(
                f"AMG-{accel.upper()} did not reach the relative residual {rtol:g} "
                f"(reached {true / nb:.2e} after {its} iterations); the matrix may not be "
                f"positive definite: use solver 'superlu' or 'pardiso'")
        self.iterations.append(its)
        return x

    def describe(self):
        accel = "CG" if getattr(self, "_sym", True) else "GMRES"
        its = f", last solve {self.iterations[-1]} iterations" if self.iterations else ""
        return (f"smoothed-aggregation AMG + {accel} (pyamg, rtol "
                f"{self.options.get('rtol', 1e-12):g}{its})")


_CLASSES = {"dense": DenseLU, "superlu": SuperLU, "pardiso": Pardiso,
            "cholmod": Cholmod, "umfpack": UMFPACK, "amg": AMG, "petsc": PETScLU, "petsc-gamg": PETScGAMG}


class Auto(Solver):
    """Chooses a backend at every :meth:`factor`.

    * ``n ≤ DENSE_LIMIT``, or ``n ≤ DENSE_SIZE`` with at least
      ``DENSE_FRACTION`` of the entries nonzero: dense LU;
    * above ``PARDISO_LIMIT`` unknowns, PARDISO if installed;
    * otherwise, for symmetric matrices known to be positive definite
      (``spd=True``, as in :func:`solve_saddle_point`), CHOLMOD if installed;
    * otherwise SuperLU.

    AMG is never picked: it is an iterative method whose cost depends on
    the problem; ask for it by name.  Nor is UMFPACK: it is no faster than
    SuperLU with nested dissection on the RK tangents measured, and it did
    not factor the 1e5-particle one in 300 s (docs/benchmarks/linear_solvers.md).  Backends are kept between calls so
    that each reuses its analysis.  ``reuse_factorization`` (``"off"``,
    ``"on"``, ``"auto"``) makes the sparse direct ones keep their last
    factorization as the preconditioner of GMRES on the next matrices
    (:mod:`skfem_rkpm.solvers.reuse`).
    """

    name = "auto"

    def __init__(self, symmetric=None, reuse_factorization="off", **options):
        super().__init__(symmetric, **options)
        if reuse_factorization not in REUSE_MODES:
            raise ValueError(f"reuse_factorization must be one of {', '.join(REUSE_MODES)}, "
                             f"not {reuse_factorization!r}")
        self.reuse = reuse_factorization
        self.newton_tol = None
        self._backends = {}
        self.current = None
        self._installed = None  # the backends installed, listed at the first need

    @property
    def installed(self):
        """Names of the backends installed (:func:`available`), listed when
        first asked for (:meth:`choose` asks only for the ones it may pick)."""
        if self._installed is None:
            self._installed = available()
        return self._installed

    @installed.setter
    def installed(self, names):
        self._installed = list(names)

    def _has(self, name):
        """Backend ``name`` is installed (the list if known, else its package)."""
        return name in self._installed if self._installed is not None else installed(name)

    def choose(self, A, spd=False):
        """The backend name for the matrix ``A`` (``spd``: the caller knows it
        is positive definite if it is symmetric)."""
        n = A.shape[0]
        if n <= DENSE_LIMIT or (n <= DENSE_SIZE and A.nnz >= DENSE_FRACTION * n * n):
            return "dense"
        if n > PARDISO_LIMIT and self._has("pardiso"):
            return "pardiso"
        if spd and self._has("cholmod"):
            sym = self.symmetric if self.symmetric is not None else is_symmetric(A)
            if sym:
                return "cholmod"
        return "superlu"

    def backend(self, name):
        """The kept instance of backend ``name``; it becomes the current one."""
        if name not in self._backends:
            backend = reusing(_CLASSES[name](self.symmetric, **self.options), self.reuse, name)
            if self.newton_tol is not None and hasattr(backend, "follow_newton"):
                backend.follow_newton(self.newton_tol)
            self._backends[name] = backend
        self.current = self._backends[name]
        return self.current

    def factor(self, A, spd=False):
        """Factor ``A`` with the chosen backend; if CHOLMOD finds ``A`` not
        positive definite, SuperLU instead."""
        A = _canonical(A)
        try:
            self.backend(self.choose(A, spd)).factor(A)
        except NotPositiveDefinite:
            self.backend("superlu").factor(A)
        self.A = A
        return self

    def _solve(self, b):
        try:
            return self.current.solve(b)
        except NotPositiveDefinite:  # a reused CHOLMOD's fallback factorization
            return self.backend("superlu").factor(self.current.A).solve(b)

    @property
    def spd_only(self):
        return self.current is not None and self.current.spd_only

    def follow_newton(self, tol):
        """Tie the tolerance of the reused factorizations to the Newton tolerance."""
        self.newton_tol = tol
        for backend in self._backends.values():
            if hasattr(backend, "follow_newton"):
                backend.follow_newton(tol)

    @property
    def reuse_stats(self):
        """Reused matrices, GMRES iterations and fallbacks, over all backends."""
        keys = ("reused", "gmres_iterations", "fallbacks", "factorizations")
        return {k: sum(b.stats.get(k, 0) for b in self._backends.values()) for k in keys}

    def describe(self):
        if self.current is None:
            return "auto (nothing factored yet)"
        return f"auto: {self.current.describe()}"


def make_solver(name="auto", symmetric=None, reuse_factorization="off", **options):
    """A :class:`Solver` by name.

    Parameters
    ----------
    name : str or Solver
        ``"auto"`` or one of :data:`BACKENDS` (``"dense"``, ``"superlu"``,
        ``"pardiso"``, ``"cholmod"``, ``"amg"``, ``"petsc"``,
        ``"petsc-gamg"``); a :class:`Solver` is returned as it is.  ``None``
        means ``"auto"``.
    symmetric : bool, optional
        What the caller knows of the matrices to come: ``False`` for
        frictional contact tangents, ``True`` for symmetric ones; ``None``
        lets ``auto`` check when it matters.
    reuse_factorization : {"off", "on", "auto"}
        Keep the last factorization and solve the next matrices by GMRES
        preconditioned by it, factoring again only when GMRES stalls
        (:mod:`skfem_rkpm.solvers.reuse`); ``"auto"`` from
        :data:`~skfem_rkpm.solvers.reuse.REUSE_LIMIT` unknowns or
        :data:`~skfem_rkpm.solvers.reuse.REUSE_ENTRIES` stored entries on.  Sparse
        direct backends only (``superlu``, ``pardiso``, ``umfpack``,
        ``cholmod``, and those ``auto`` picks).
    **options
        Backend options (``amg``: ``rtol``, ``maxiter``, ``near_nullspace``;
        ``petsc``, ``petsc-gamg``: ``points``, the dof locations used to
        partition the rows among MPI ranks, and ``rtol``, ``maxiter`` for
        GAMG).

    Raises
    ------
    BackendUnavailable
        The backend's package is missing; the message names the extra to
        install, e.g. ``pip install skfem-rkpm[pardiso]``.
    """
    if isinstance(name, Solver):
        return name
    name = "auto" if name is None else str(name).lower()
    if name == "auto":
        return Auto(symmetric, reuse_factorization, **options)
    if name not in _CLASSES:
        raise ValueError(f"unknown linear solver {name!r}; choose one of "
                         f"auto, {', '.join(_CLASSES)}")
    if symmetric is False and _CLASSES[name].spd_only and name not in ("amg", "petsc-gamg"):
        raise ValueError(f"the linear solver {name!r} needs symmetric positive definite "
                         f"matrices, and these are declared non-symmetric; use "
                         f"'superlu', 'pardiso' or 'auto'")
    return reusing(_CLASSES[name](symmetric, **options), reuse_factorization, name)
