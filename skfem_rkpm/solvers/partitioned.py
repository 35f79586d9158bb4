"""Partitioned assembly: each MPI rank integrates over its own cells.

Under ``mpiexec -n P`` the background cells are split among the ranks by
recursive coordinate bisection of their centres (:func:`partition`), and
every rank builds its part of the basis (``RKBasis(..., elements=cells,
reduction=...)``): shape functions only at its own quadrature points, for
the particles these reach, with the VCI sums added up over the ranks
(:class:`MPIReduction`).  A :class:`~skfem_rkpm.mechanics.problem.SolidProblem`
on that part updates only its own material points and assembles only its
own cells, so the memory of the basis, the material state and the local
matrices falls as ``1/P``.

:class:`PartitionedSolid` puts the parts together for the Newton loop of
:func:`~skfem_rkpm.solvers.newton.newton_steps`, which runs unchanged on
every rank:

- the internal force is summed over the ranks (``MPI_Allreduce`` of a
  vector of the dofs), so every rank holds the same residual and takes the
  same decisions (convergence, line search, cut-backs);
- a failure at a material point of one rank (inverted cell, return map,
  NaN) is raised on every rank;
- the tangent stays distributed: each rank's share is a
  :class:`PartialMatrix`, to which the terms every rank computes alike
  (contact, the penalty of the constraints) are added on rank 0 only, and
  :class:`DistributedLU` sums the shares into a PETSc MPIAIJ matrix (COO
  assembly: each rank sends only the entries of rows it does not own) and
  factors it with MUMPS.

Vectors of the dofs (coefficients, forces) are replicated: ``16 N`` bytes
per rank for ``N`` dofs, small beside the shape tables.  The VCI balancing
matrix (particles × particles) is summed and solved on every rank alike.
What rank 0 writes (the material state of a checkpoint, the fields of an
output step) is gathered on rank 0 only.
"""


import numpy as np
import scipy.sparse as sp

from ..mechanics.materials import MaterialState, ReturnMapError
from ..mechanics.problem import InvertedElementError, NonFiniteError
from .petsc import PETScLU, bisection

__all__ = ["RankFailure", "MPIReduction", "partition", "Partition", "PartialMatrix", "PartitionedSolid",
           "DistributedLU"]

#: errors of a material point that stop an evaluation: raised on every rank
_POINT_ERRORS = (InvertedElementError, NonFiniteError, ReturnMapError)
#: bytes of a failing rank's message passed to the others
_MESSAGE_BYTES = 1024


class RankFailure(Exception):
    """An error that is not a material point's stopped one rank: every rank
    stops (not a ``RuntimeError``, which Newton would retry)."""


class MPIReduction:
    """Sums over the MPI ranks (:mod:`skfem_rkpm.approximation.reduction`).

    Parameters
    ----------
    comm : mpi4py communicator, optional
        Default ``MPI.COMM_WORLD``.
    """

    def __init__(self, comm=None):
        if comm is None:
            try:
                from mpi4py import MPI
            except ImportError as err:
                raise ImportError(f"a run partitioned over MPI ranks sums over them with "
                                  f"mpi4py, which is not installed ({err}): `pip install "
                                  f"mpi4py` (part of skfem-rkpm[petsc])") from err
            comm = MPI.COMM_WORLD
        self.comm = comm
        self.rank, self.parts = comm.Get_rank(), comm.Get_size()

    def sum(self, array):
        """The elementwise sum over the ranks, the same bits on every rank:
        summed on rank 0 and broadcast (an allreduce may round differently
        on different ranks, and every Newton decision compares sums)."""
        array = np.ascontiguousarray(array)
        out = np.empty_like(array)
        self.comm.Reduce(array, out, root=0)
        self.comm.Bcast(out, root=0)
        return out

    def sum_sparse(self, matrix):
        """All ranks' COO entries gathered on every rank, in rank order, and
        summed: every rank gets the same matrix, bit for bit."""
        coo = matrix.tocoo()
        counts = np.array(self.comm.allgather(coo.nnz), dtype=np.int64)
        rows, cols, data = (self._gather(np.ascontiguousarray(a, dtype=t), counts)
                            for a, t in ((coo.row, np.int64), (coo.col, np.int64),
                                         (coo.data, np.float64)))
        return sp.csr_matrix((data, (rows, cols)), shape=matrix.shape)

    def _gather(self, local, counts):
        out = np.empty(int(counts.sum()), dtype=local.dtype)
        self.comm.Allgatherv(local, (out, counts))
        return out

    def gather(self, values, rows, total):
        """The ranks' ``values`` at their ``rows`` of a (total, ...) array,
        on rank 0 only (``MPI_Gatherv``; None on the others)."""
        values = np.ascontiguousarray(values, dtype=float)
        width = int(np.prod(values.shape[1:], dtype=np.int64))
        counts = np.array(self.comm.gather(len(rows), root=0) or [], dtype=np.int64)
        root = self.rank == 0
        all_rows = np.empty(int(counts.sum()), dtype=np.int64) if root else None
        flat = np.empty(int(counts.sum()) * width) if root else None
        self.comm.Gatherv(np.ascontiguousarray(rows, dtype=np.int64),
                          (all_rows, counts) if root else None, root=0)
        self.comm.Gatherv(values.ravel(), (flat, counts * width) if root else None, root=0)
        if not root:
            return None
        whole = np.zeros((total,) + values.shape[1:])
        whole[all_rows] = flat.reshape((-1,) + values.shape[1:])
        return whole


class Partition:
    """Which rank integrates each cell and owns each particle's rows.

    Attributes
    ----------
    cells : ndarray, shape (ncells,)
        The rank of every background cell.
    particles : ndarray, shape (nparticles,)
        The rank owning the rows (dofs) of every particle: the lowest rank
        among the cells it is a vertex of, so that its rows sit on a rank
        that assembles some of their entries.
    parts : int
    """

    def __init__(self, cells, particles, parts):
        self.cells, self.particles, self.parts = cells, particles, int(parts)

    def cells_of(self, rank):
        """The cells rank ``rank`` integrates."""
        return np.flatnonzero(self.cells == rank)

    def dof_owners(self, ncomp):
        """The owner of every dof ``ncomp * I + c``."""
        return np.repeat(self.particles, ncomp)


def partition(mesh, parts, nodes=None):
    """Split the cells of ``mesh`` into ``parts`` by recursive coordinate
    bisection of the cell centres (equal numbers of cells, compact parts).

    ``nodes`` (dim x n): the particles, if they are not the mesh vertices;
    they are then assigned by bisection of their own positions.
    """
    parts = int(parts)
    if not 1 <= parts <= mesh.nelements:
        raise ValueError(f"cannot split {mesh.nelements} cells into {parts} parts: "
                         "use at most one rank per cell")
    centres = mesh.p[:, mesh.t].mean(axis=1)
    cells = bisection(centres, parts)
    if nodes is None:
        particles = np.full(mesh.nvertices, parts, dtype=np.int64)
        np.minimum.at(particles, mesh.t.ravel(), np.tile(cells, mesh.t.shape[0]))
        particles[particles == parts] = 0  # vertices without cells
    else:
        particles = bisection(np.asarray(nodes, dtype=float), parts)
    return Partition(cells, particles, parts)


class PartialMatrix:
    """One rank's share of a matrix that is the sum of all ranks' shares.

    Adding a matrix that every rank computes alike (a replicated term)
    adds it to rank 0's share only, so the sum counts it once; adding
    another share adds the shares.  ``A @ x`` and ``A.diagonal()`` are
    those of the summed matrix (collective).
    """

    partial = True

    def __init__(self, local, reduction, root):
        self.local = sp.csr_matrix(local)
        self.reduction, self.root = reduction, root
        self.shape = self.local.shape

    def _like(self, local):
        return PartialMatrix(local, self.reduction, self.root)

    def __add__(self, other):
        if isinstance(other, PartialMatrix):
            return self._like(self.local + other.local)
        if np.isscalar(other) and other == 0:
            return self
        return self._like(self.local + other) if self.root else self

    __radd__ = __add__

    def __matmul__(self, x):
        return self.reduction.sum(self.local @ x)

    def diagonal(self):
        return self.reduction.sum(self.local.diagonal())

    def solve_saddle_point(self, solver, f, C, g):
        """``K d = f + Cᵀ λ``, ``C d = g`` by ``solver`` (a solver of
        shares, ``sums_shares``: :class:`DistributedLU`) on the summed
        saddle-point matrix."""
        if not getattr(solver, "sums_shares", False):
            raise TypeError(f"a partitioned problem is solved by DistributedLU, not "
                            f"{type(solver).__name__}: run newton_steps with "
                            "linear_solver=DistributedLU(partition, reduction)")
        N, m = self.shape[0], C.shape[0]
        if m == 0:
            solver.factor(self)
            solver.system = "K"
            return solver.solve(f), np.zeros((0,) + np.shape(f)[1:])
        C = sp.csr_matrix(C)
        if self.root:
            local = sp.bmat([[self.local, C.T], [C, None]], format="csr")
        else:
            local = sp.bmat([[self.local, None], [None, sp.csr_matrix((m, m))]],
                            format="csr")
        solver.factor(self._like(local), constraint_rows=C)
        solver.system = "the saddle-point matrix [[K, Cᵀ], [C, 0]]"
        sol = solver.solve(np.concatenate([f, g]))
        return sol[:N], -sol[N:]


class PartitionedSolid:
    """A :class:`~skfem_rkpm.mechanics.problem.SolidProblem` on this rank's
    cells, seen by the Newton loop as the whole solid.

    ``evaluate(d)`` returns the evaluation of this rank's material points
    with the internal force summed over the ranks and the tangent as a
    :class:`PartialMatrix`; the committed state is this rank's.
    """

    #: a partitioned solid has no SCNI stabilization (a cell scheme)
    stabilization = None
    partitioned = True

    def __init__(self, problem, reduction, rank):
        self.problem, self.reduction, self.rank = problem, reduction, int(rank)
        self.basis, self.material, self.model = problem.basis, problem.material, problem.model
        self.assembler = problem.assembler
        nqp = problem.shape[1]
        cells = np.asarray(self.basis.tind, dtype=np.int64)
        #: the material points of the whole domain (all cells x nqp)
        self.whole_points = self.basis.mesh.nelements * nqp
        self._points = (cells[:, None] * nqp + np.arange(nqp)).ravel()
        dx = self.gather_points(problem.assembler.layout.dx.ravel())
        #: the quadrature weights of the whole domain (nelements, nqp), on rank 0
        self.whole_dx = None if dx is None else dx.reshape(-1, nqp)
        #: the whole domain's state at the last :meth:`gathered_state`, on rank 0
        self.whole_state = None

    @property
    def N(self):
        return self.problem.N

    @property
    def state(self):
        return self.problem.state

    def evaluate(self, d, state=None, tangent=True):
        error = None
        try:
            evaluation = self.problem.evaluate(d, state, tangent)
        except Exception as err:  # noqa: BLE001 - raised on every rank below
            error = err
        self._raise_together(error)
        evaluation.f_int = self.reduction.sum(evaluation.f_int)
        form = evaluation._form_tangent
        if form is not None:
            evaluation._form_tangent = lambda: PartialMatrix(form(), self.reduction,
                                                             self.rank == 0)
        return evaluation

    def _raise_together(self, error):
        """Raise the error of the lowest failing rank on every rank, with
        the rank named: a material point's error as its own type (Newton
        cuts the step back on every rank alike), any other as a
        :class:`RankFailure`, which stops every rank."""
        failed = np.zeros(self.reduction.parts)
        failed[self.rank] = error is not None
        failed = np.flatnonzero(self.reduction.sum(failed))
        if not failed.size:
            return
        first = int(failed[0])
        code = np.zeros(_MESSAGE_BYTES + 1)
        if self.rank == first:
            text = str(error).encode()[:_MESSAGE_BYTES]
            code[0] = 1 + next((k for k, kind in enumerate(_POINT_ERRORS)
                                if isinstance(error, kind)), -1)
            code[1:1 + len(text)] = np.frombuffer(text, dtype=np.uint8)
        code = self.reduction.sum(code)
        text = bytes(code[1:].astype(np.uint8)).rstrip(b"\0").decode(errors="replace")
        if code[0] == 0:
            raise RankFailure(f"rank {first} failed in the evaluation of the solid: "
                              f"{text}") from error
        points = error.points if self.rank == first else np.zeros(0, dtype=np.int64)
        raise _POINT_ERRORS[int(code[0]) - 1](f"on rank {first}: {text}", points)

    def commit(self, evaluation):
        self.problem.commit(evaluation)

    def gather_points(self, values):
        """Values at this rank's material points (n, ...) placed among those
        of all ranks: the whole domain's (cell-major, as an unpartitioned
        problem numbers its points), on rank 0, None on the others
        (collective)."""
        return self.reduction.gather(values, self._points, self.whole_points)

    def gathered_state(self):
        """The committed material state of the whole domain on rank 0 (None
        on the others; collective), kept there as ``whole_state``."""
        state = self.problem.state
        Cp_inv, alpha = self.gather_points(state.Cp_inv), self.gather_points(state.alpha)
        if Cp_inv is not None:
            self.whole_state = MaterialState(Cp_inv, alpha)
        return self.whole_state

    def restore_state(self, whole):
        """Take this rank's points of a whole-domain material state (rank 0
        keeps the whole one, as after :meth:`gathered_state`)."""
        if self.rank == 0:
            self.whole_state = whole
        self.problem.state = MaterialState(whole.Cp_inv[self._points].copy(),
                                           whole.alpha[self._points].copy())

    def cauchy_stress(self, evaluation):
        return self.problem.cauchy_stress(evaluation)


class DistributedLU(PETScLU):
    """MUMPS LU through PETSc of a matrix given as the ranks' shares
    (:class:`PartialMatrix`).

    Each rank owns the rows of its particles (``partition.particles``;
    multiplier rows go with the particle of their largest constraint
    entry).  The shares are summed by PETSc's COO assembly into an MPIAIJ
    matrix; the pattern (and MUMPS's analysis) is kept until a share's
    pattern changes on some rank.  The solve, the gathered solution and
    its refinement against the summed matrix are :class:`PETScLU`'s.
    """

    #: factors the sum of the ranks' :class:`PartialMatrix` shares
    sums_shares = True

    def __init__(self, partition, reduction, factor_solver="mumps"):
        super().__init__(symmetric=False, factor_solver=factor_solver)
        self.parts, self.reduction = partition, reduction
        self._owner = None
        self.system = None

    def factor(self, A, constraint_rows=None):
        """Factor the sum of the shares ``A``; the matrix and MUMPS's
        analysis are made again only when some rank's share changes its
        pattern or the rows change owners (collective)."""
        n = A.shape[0]
        m = 0 if constraint_rows is None else constraint_rows.shape[0]
        owner = self._owners(n, (n - m) // len(self.parts.particles), constraint_rows)
        changed = not (self._same_pattern(A.local) and np.array_equal(owner, self._owner))
        if self.reduction.sum(np.array([float(changed)]))[0] > 0:
            self._analyze_timed(A.local, lambda: self._analyze_shares(owner, A.local.tocoo()))
            self._owner = owner
        return self._factor_timed(A)

    def _set_values(self, A):
        """The share's values, in the order of its CSR entries (that of the
        COO entries the matrix was preallocated with)."""
        self._mat.setValuesCOO(A.local.data, addv=self.PETSc.InsertMode.INSERT_VALUES)
        self._mat.assemble()

    def _owners(self, n, ncomp, C):
        """The rank of every row: the particle's, then the multipliers'."""
        owner = np.zeros(n, dtype=np.int64)
        dofs = self.parts.dof_owners(max(ncomp, 1))
        owner[:len(dofs)] = dofs
        if C is not None and C.shape[0]:
            big = np.abs(sp.csr_matrix(C)).argmax(axis=1)
            owner[len(dofs):] = dofs[np.asarray(big).ravel()]
        return owner

    def _analyze_shares(self, owner, coo):
        """The MPIAIJ matrix of the rows ``owner`` gives each rank (renumbered
        to be contiguous), preallocated for the entries of ``coo``."""
        PETSc = self.PETSc
        n = len(owner)
        order, new, bounds = self._contiguous_rows(owner)
        r0, r1 = int(bounds[self.rank]), int(bounds[self.rank + 1])
        self._order, self._rows = order, (r0, r1)
        self._destroy()
        mat = PETSc.Mat().create(comm=self.comm)
        mat.setSizes(((r1 - r0, n), (r1 - r0, n)))
        mat.setType(PETSc.Mat.Type.AIJ)
        mat.setPreallocationCOO(new[coo.row].astype(PETSc.IntType),
                                new[coo.col].astype(PETSc.IntType))
        self._attach(mat)

    def describe(self):
        return (f"PETSc {self.options['factor_solver'].upper()} LU of the ranks' summed "
                f"shares ({self._ranks()})")
