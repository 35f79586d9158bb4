"""The distributed linear solve: PETSc (petsc4py) KSP on MPI ranks.

A run started with ``mpiexec -n P`` runs the same Python program on every
rank: the model, its assembly and the Newton loop are replicated, and the
linear system of every Newton iteration is distributed.  Each rank owns a
contiguous block of rows of a PETSc MPIAIJ matrix; the particles are split
among the ranks by recursive coordinate bisection, with every dof of a
particle on the same rank, and the rows are renumbered so that each rank's
rows are contiguous.  KSP solves (MUMPS LU by default, smoothed-aggregation
AMG (GAMG) with CG or GMRES as an option) and the solution is gathered back
to every rank, so that all ranks continue with bit-identical iterates.

Without ``mpiexec`` the same backends run on one process (sequential AIJ
matrix, sequential MUMPS).

Backends (``make_solver(name)`` in :mod:`skfem_rkpm.solvers.linear`):

``"petsc"``
    MUMPS LU through PETSc (``KSPPREONLY`` + ``PCLU``), any nonsingular
    matrix, the symbolic analysis kept while the pattern stays; two steps
    of iterative refinement against the replicated matrix.
``"petsc-gamg"``
    GAMG preconditioning CG (symmetric matrices) or GMRES, relative
    residual ``rtol`` (1e-12); positive definite matrices only, so the
    constraints go through the augmented Lagrangian of
    :func:`~skfem_rkpm.solvers.constrained.solve_saddle_point`.

Both take ``points`` (dim x N, the location of every dof, e.g.
``basis.doflocs``) to partition by coordinates; without them the rows are
split into contiguous blocks.  PETSc options from the environment
(``PETSC_OPTIONS``, e.g. ``-mat_mumps_icntl_14 50``) are applied.
"""

import os

import numpy as np
import scipy.sparse as sp

from .backend import Solver, _import_backend, _refine, is_symmetric

__all__ = ["world", "is_root", "bisection", "row_owners", "PETScLU", "PETScGAMG"]

#: environment variables that MPI launchers set: (size, rank)
_LAUNCHER_VARIABLES = (("OMPI_COMM_WORLD_SIZE", "OMPI_COMM_WORLD_RANK"),  # Open MPI
                       ("PMI_SIZE", "PMI_RANK"),  # MPICH (hydra), Intel MPI
                       ("PMIX_SIZE", "PMIX_RANK"))


def world():
    """``(rank, size)`` of this process in MPI_COMM_WORLD; ``(0, 1)`` when it
    was not started by an MPI launcher.

    Read from the launcher's environment variables, so that nothing
    initializes MPI in a plain serial run.
    """
    for size_key, rank_key in _LAUNCHER_VARIABLES:
        if size_key in os.environ and rank_key in os.environ:
            try:
                return int(os.environ[rank_key]), int(os.environ[size_key])
            except ValueError:
                continue
    return 0, 1


def is_root():
    """True on rank 0 (and in a serial run): the rank that writes and prints."""
    return world()[0] == 0


def bisection(points, parts, weights=None):
    """Recursive coordinate bisection of ``points`` (dim x n) into ``parts``
    sets of about equal weight; returns the part of every point.

    Each cut is normal to the longest side of the bounding box of the
    points it splits, at the weighted quantile ``⌊parts/2⌋ / parts``, so
    any number of parts works.  Ties in the coordinate are broken by the
    point index, which makes the result deterministic.
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    n = points.shape[1]
    weights = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    owner = np.zeros(n, dtype=np.int64)

    def split(index, first, count):
        if count == 1 or len(index) == 0:
            owner[index] = first
            return
        x = points[:, index]
        axis = int(np.argmax(x.max(axis=1) - x.min(axis=1)))
        order = index[np.lexsort((index, x[axis]))]
        left = count // 2
        cumulative = np.cumsum(weights[order])
        cut = int(np.searchsorted(cumulative, cumulative[-1] * left / count, side="right"))
        cut = min(max(cut, 1), len(order) - 1) if len(order) > 1 else len(order)
        split(order[:cut], first, left)
        split(order[cut:], first + left, count - left)

    split(np.arange(n), 0, int(parts))
    return owner


def row_owners(A, parts, points=None):
    """The rank owning every row of ``A`` (n x n).

    With ``points`` (dim x N, N ≤ n, the location of the first N unknowns)
    the distinct locations (the particles or nodes) are bisected, so that
    all dofs at one location share a rank; each further row (Lagrange
    multipliers of constraints) goes to the owner of its largest entry
    among the first N columns.  Without ``points``: contiguous blocks.
    """
    n = A.shape[0]
    if parts == 1:
        return np.zeros(n, dtype=np.int64)
    if points is None:
        return np.minimum(np.arange(n) * parts // n, parts - 1)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    N = points.shape[1]
    if N > n:
        raise ValueError(f"{N} dof locations for a matrix of {n} rows")
    unique, inverse, counts = np.unique(points.T, axis=0, return_inverse=True,
                                        return_counts=True)
    owner = np.empty(n, dtype=np.int64)
    owner[:N] = bisection(unique.T, parts, counts)[inverse.ravel()]
    if N < n:
        extra = sp.csr_matrix(A)[N:, :N].tocsr()
        extra.data = np.abs(extra.data)
        has = np.diff(extra.indptr) > 0
        big = np.asarray(extra.argmax(axis=1)).ravel()
        owner[N:] = np.where(has, owner[big], 0)
    return owner


class _PETScSolver(Solver):
    """Common part: partition, distributed matrix, KSP, gathered solution."""

    def __init__(self, symmetric=None, **options):
        super().__init__(symmetric, **options)
        _import_backend(self.name)
        from petsc4py import PETSc

        self.PETSc = PETSc
        self.comm = PETSc.COMM_WORLD
        self.rank, self.size = self.comm.getRank(), self.comm.getSize()
        self._mat = self._ksp = None

    # -- symbolic: partition and matrix structure ------------------------
    def _analyze(self, A):
        PETSc = self.PETSc
        n = A.shape[0]
        owner = row_owners(A, self.size, self.options.get("points"))
        order, new, bounds = self._contiguous_rows(owner)
        r0, r1 = int(bounds[self.rank]), int(bounds[self.rank + 1])
        # the local rows in the new numbering, sorted columns; `take` maps
        # their entries to positions in A.data (the pattern is fixed)
        position = sp.csr_matrix((np.arange(A.nnz, dtype=float), A.indices, A.indptr),
                                 shape=A.shape)
        local = position[order[r0:r1]].tocsr()
        local.indices = new[local.indices].astype(local.indices.dtype)
        local.has_sorted_indices = False
        local.sort_indices()
        self._take = local.data.astype(np.int64)
        self._indptr = local.indptr.astype(PETSc.IntType)
        self._indices = local.indices.astype(PETSc.IntType)
        self._order, self._rows = order, (r0, r1)
        self.partition = np.diff(bounds)
        self._destroy()
        nlocal = r1 - r0
        mat = PETSc.Mat().createAIJ(size=((nlocal, n), (nlocal, n)),
                                    csr=(self._indptr, self._indices, A.data[self._take]),
                                    comm=self.comm)
        mat.assemble()
        self._attach(mat)
        self._fresh = True

    def _contiguous_rows(self, owner):
        """The renumbering that makes each rank's rows contiguous: ``order``
        (new row k is old row ``order[k]``), ``new`` (its inverse) and the
        bounds of the ranks' blocks of new rows."""
        order = np.argsort(owner, kind="stable")
        new = np.empty(len(owner), dtype=np.int64)
        new[order] = np.arange(len(owner))
        bounds = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=self.size))])
        return order, new, bounds

    def _attach(self, mat):
        """Solve with ``mat``: its vectors, the gather of the solution to
        every rank and the KSP (:meth:`_configure`)."""
        PETSc = self.PETSc
        self._mat = mat
        self._b, self._x = mat.createVecs()
        self._gather, self._xall = PETSc.Scatter.toAll(self._x)
        self._ksp = PETSc.KSP().create(comm=self.comm)
        self._ksp.setOperators(mat)
        self._configure(self._ksp)

    def _factor(self, A):
        PETSc = self.PETSc
        self._set_values(A)
        try:
            self._setup(A)
        except PETSc.Error as err:
            raise np.linalg.LinAlgError(f"{self.describe()}: PETSc error {err.ierr} in "
                                        f"the factorization or set-up") from err

    def _set_values(self, A):
        """Put the values of ``A`` into the PETSc matrix (its pattern is
        the analysed one): numeric work only."""
        if not self._fresh:  # the matrix was created with these values
            self._mat.setValuesCSR(self._indptr, self._indices, A.data[self._take])
            self._mat.assemble()
        self._fresh = False

    def _setup(self, A):
        self._ksp.setUp()

    def _solve_one(self, b):
        PETSc = self.PETSc
        r0, r1 = self._rows
        self._b.setArray(b[self._order[r0:r1]])
        try:
            self._ksp.solve(self._b, self._x)
        except PETSc.Error as err:
            raise np.linalg.LinAlgError(f"{self.describe()}: PETSc error {err.ierr} in "
                                        f"the solve") from err
        reason = self._ksp.getConvergedReason()
        if reason < 0:
            raise np.linalg.LinAlgError(self._diverged(reason))
        self._gather.scatter(self._x, self._xall, addv=PETSc.InsertMode.INSERT,
                             mode=PETSc.ScatterMode.FORWARD)
        x = np.empty(len(b))
        x[self._order] = self._xall.getArray(readonly=True)
        return x

    def _diverged(self, reason):
        return f"{self.describe()}: KSP did not converge (reason {reason})"

    def _solve(self, b):
        if b.ndim == 2:
            return np.column_stack([self._solve(col) for col in b.T])
        return _refine(self.A, b, self._solve_one(b), self._solve_one)

    def _ranks(self):
        if self.size == 1:
            return "1 process"
        return f"{self.size} MPI ranks"

    def _destroy(self):
        for name in ("_ksp", "_mat", "_b", "_x", "_xall", "_gather"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
            setattr(self, name, None)

    def reset(self):
        super().reset()
        self._destroy()

    def __del__(self):
        try:
            self._destroy()
        except Exception:
            pass


class PETScLU(_PETScSolver):
    """MUMPS LU through PETSc, distributed over the MPI ranks."""

    name = "petsc"

    def _configure(self, ksp):
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType(self.options.get("factor_solver", "mumps"))
        ksp.setErrorIfNotConverged(True)
        ksp.setFromOptions()

    def describe(self):
        kind = self.options.get("factor_solver", "mumps").upper()
        return f"PETSc {kind} LU ({self._ranks()}, analysis reused)"


class PETScGAMG(_PETScSolver):
    """GAMG (smoothed aggregation) + CG or GMRES through PETSc."""

    name = "petsc-gamg"
    spd_only = True

    def _configure(self, ksp):
        ksp.setTolerances(rtol=self.options.get("rtol", 1e-12), atol=0.0,
                          max_it=self.options.get("maxiter", 2000))
        ksp.getPC().setType("gamg")
        ksp.setInitialGuessNonzero(False)

    def _setup(self, A):
        sym = self.symmetric if self.symmetric is not None else is_symmetric(A)
        self._sym = sym
        self._ksp.setType("cg" if sym else "gmres")
        if not sym:
            self._ksp.setGMRESRestart(200)
        self._ksp.setFromOptions()
        self._ksp.setUp()

    def _solve(self, b):
        if b.ndim == 2:
            return np.column_stack([self._solve(col) for col in b.T])
        return self._solve_one(b)  # iterated to rtol: no refinement

    def _diverged(self, reason):
        its = self._ksp.getIterationNumber()
        return (f"{self.describe()}: KSP did not reach the relative residual "
                f"{self.options.get('rtol', 1e-12):g} (reason {reason}, {its} iterations); "
                f"the matrix may not be positive definite: use solver 'petsc'")

    def describe(self):
        accel = "CG" if getattr(self, "_sym", True) else "GMRES"
        return (f"PETSc GAMG + {accel} ({self._ranks()}, rtol "
                f"{self.options.get('rtol', 1e-12):g})")
