"""What every linear solver backend shares: the registry of backends by name
(with the package and the extra each needs), the :class:`Solver` interface
with its reuse of the symbolic analysis, and small helpers (symmetry check,
iterative refinement).

:mod:`skfem_rkpm.solvers.linear` and :mod:`skfem_rkpm.solvers.petsc` build
their backends on it; the scene schema reads the names of :data:`BACKENDS`.
"""

import importlib
import time

import numpy as np
import scipy.sparse as sp

__all__ = ["BACKENDS", "BackendUnavailable", "available", "installed", "is_symmetric", "Solver"]

#: the backends, the Python module each needs and the extra that installs it
BACKENDS = {
    "dense": (None, None),
    "superlu": (None, None),
    "pardiso": ("pypardiso", "pardiso"),
    "cholmod": ("sksparse.cholmod", "cholmod"),
    "umfpack": ("cvxopt", "umfpack"),
    "amg": ("pyamg", "amg"),
    "petsc": ("petsc4py", "petsc"),
    "petsc-gamg": ("petsc4py", "petsc"),
}

_INSTALL_NOTES = {
    "cholmod": " (scikit-sparse compiles against SuiteSparse: first "
               "`apt-get install libsuitesparse-dev`; on Debian 12 pin "
               "`scikit-sparse==0.4.16`)",
    "pardiso": " (installs MKL, about 1 GB)",
    "petsc": " (petsc4py has no wheel: pip builds PETSc from source, about 20 minutes; "
             "for MPI put an MPI compiler wrapper (mpicc) on PATH before the build, and "
             "for MUMPS pass a MUMPS installation in PETSC_CONFIGURE_OPTIONS; see "
             "docs/benchmarks/partitioned.md, \"PETSc and MPI\"; on Debian 12 `bash .ci/run-mpi` "
             "installs it all)",
}
_INSTALL_NOTES["petsc-gamg"] = _INSTALL_NOTES["petsc"]


class BackendUnavailable(ImportError):
    """An optional solver backend is not installed."""


def _import_backend(name):
    module, extra = BACKENDS[name]
    if module is None:
        return None
    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise BackendUnavailable(
            f"the linear solver {name!r} needs the Python package {module.split('.')[0]!r}, "
            f"which is not installed ({err}); install it with "
            f"`pip install skfem-rkpm[{extra}]`{_INSTALL_NOTES.get(name, '')}, or choose "
            f"another solver: {', '.join(available())} are installed") from err


def available():
    """Names of the backends that can be used here (``"auto"`` not included)."""
    return [name for name in BACKENDS if installed(name)]


def installed(name):
    """Whether backend ``name`` can be used here: its package imports (only
    that one is imported, so that a run does not pay for the optional
    packages it never uses: pyamg and cvxopt take 0.07 s CPU)."""
    module = BACKENDS[name][0]
    if module is None:
        return True
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


def is_symmetric(A, rtol=1e-12):
    """True if ``|A - Aᵀ| ≤ rtol · |A|`` entrywise in the max norm."""
    if sp.issparse(A):
        A = sp.csr_matrix(A)
        diff = abs(A - A.T)
        scale = abs(A).max() if A.nnz else 0.0
        return (diff.max() if diff.nnz else 0.0) <= rtol * scale
    A = np.asarray(A)
    return np.abs(A - A.T).max(initial=0.0) <= rtol * np.abs(A).max(initial=0.0)


class Solver:
    """Factor a square matrix, then solve with it.

    Subclasses implement ``_analyze(A)`` (symbolic work, pattern only),
    ``_factor(A)`` (numeric work) and ``_solve(b)``.  ``stats`` counts the
    analyses and factorizations and records the seconds spent.
    """

    name = "?"
    #: the backend needs a symmetric positive definite matrix
    spd_only = False

    def __init__(self, symmetric=None, **options):
        self.symmetric = symmetric
        self.options = options
        self.A = None
        self._pattern = None
        self.stats = dict(analyses=0, factorizations=0, solves=0,
                          analyze_seconds=0.0, factor_seconds=0.0, solve_seconds=0.0)

    # -- interface -----------------------------------------------------
    def factor(self, A):
        """Factor ``A``; reuse the symbolic analysis if the pattern is unchanged."""
        A = _canonical(A)
        if A.shape[0] != A.shape[1]:
            raise ValueError(f"the matrix must be square, it is {A.shape[0]} x {A.shape[1]}")
        if not self._same_pattern(A):
            self._analyze_timed(A)
        return self._factor_timed(A)

    def _analyze_timed(self, A, analyze=None):
        """``_analyze(A)`` (or ``analyze()``), counted in ``stats``; ``A``'s
        pattern is the one kept."""
        clock = time.perf_counter()
        if analyze is None:
            self._analyze(A)
        else:
            analyze()
        self.stats["analyses"] += 1
        self.stats["analyze_seconds"] += time.perf_counter() - clock
        self._pattern = (A.shape, A.indptr.copy(), A.indices.copy())

    def _factor_timed(self, A):
        """``_factor(A)``, kept as the factored matrix and counted in ``stats``."""
        clock = time.perf_counter()
        self.A = A
        self._factor(A)
        self.stats["factorizations"] += 1
        self.stats["factor_seconds"] += time.perf_counter() - clock
        return self

    def solve(self, b):
        """Solve ``A x = b`` with the last factored ``A`` (``b`` 1-D or 2-D)."""
        if self.A is None:
            raise RuntimeError("call factor(A) before solve(b)")
        b = np.asarray(b, dtype=float)
        if b.shape[0] != self.A.shape[0]:
            raise ValueError(f"the right-hand side has {b.shape[0]} rows, the matrix "
                             f"{self.A.shape[0]}")
        clock = time.perf_counter()
        x = self._solve(b)
        self.stats["solves"] += 1
        self.stats["solve_seconds"] += time.perf_counter() - clock
        return x

    def describe(self):
        """One line: the backend and its settings."""
        return self.name

    def reset(self):
        """Forget the stored analysis and factor."""
        self.A = None
        self._pattern = None

    # -- helpers -------------------------------------------------------
    def _same_pattern(self, A):
        if self._pattern is None:
            return False
        shape, indptr, indices = self._pattern
        return (shape == A.shape and len(indices) == len(A.indices)
                and np.array_equal(indptr, A.indptr) and np.array_equal(indices, A.indices))

    def _analyze(self, A):
        pass

    def __repr__(self):
        return f"<{type(self).__name__}: {self.describe()}>"


def _canonical(A):
    if not sp.issparse(A):
        A = sp.csr_matrix(np.asarray(A, dtype=float))
    A = sp.csr_matrix(A, dtype=float)
    A.sum_duplicates()
    A.sort_indices()
    return A


def _refine(A, b, x, solve, steps=2, rtol=1e-13):
    """Iterative refinement: at most ``steps`` corrections while the residual is large."""
    nb = np.linalg.norm(b)
    for _ in range(steps):
        r = b - A @ x
        if np.linalg.norm(r) <= rtol * nb:
            break
        x = x + solve(r)
    return x
