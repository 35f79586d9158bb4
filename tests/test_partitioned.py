"""Partitioned assembly (skfem_rkpm.solvers.partitioned) on threads.

Each thread plays one MPI rank: it builds its part of the basis on its own
cells and runs the Newton loop on its share, and the sums over the ranks
go through a barrier (:class:`ThreadReduction`).  The parts must give the
whole-domain basis, forces, tangents and solutions: the VCI sums, the
internal force and the tangent shares are sums over cells, which only the
order of the additions distinguishes, so the tolerances are round-off.
The MPI counterpart (PETSc, mpiexec) is in tests/test_petsc.py.
"""

import threading

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, ElementHex1, ElementQuad1, ElementVector, MeshHex, MeshQuad

from skfem_rkpm import RKBasis
from skfem_rkpm.approximation.basis_views import BasisIdiomError
from skfem_rkpm.mechanics.materials import J2Material, linear
from skfem_rkpm.mechanics.problem import InvertedElementError, SolidProblem
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.backend import Solver
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from skfem_rkpm.solvers.partitioned import (PartialMatrix, PartitionedSolid, RankFailure,
                                            partition)

E, NU = 200e3, 0.3
VECTOR = ElementVector(ElementQuad1())


class ThreadReduction:
    """Sums over ``parts`` threads: each deposits its array, waits for the
    others, and adds all of them in part order (the same sum on every part)."""

    def __init__(self, parts):
        self.parts = parts
        # a part that fails alone leaves the others waiting: they time out
        self._barrier = threading.Barrier(parts, timeout=120)
        self._box = {}

    def of(self, rank):
        shared = self

        class Part:
            parts = shared.parts

            def sum(self, array):
                return shared._sum(rank, np.asarray(array), lambda xs: sum(xs[1:], xs[0].copy()))

            def sum_sparse(self, matrix):
                return shared._sum(rank, matrix.tocsr(), lambda xs: sum(xs[1:], xs[0]).tocsr())

            def gather(self, values, rows, total):
                def place(pieces):
                    whole = np.zeros((total,) + np.shape(values)[1:])
                    for piece_rows, piece in pieces:
                        whole[piece_rows] = piece
                    return whole

                whole = shared._sum(rank, (rows, np.asarray(values)), place)
                return whole if rank == 0 else None

        return Part()

    def _sum(self, rank, value, add):
        self._box[rank] = value
        self._barrier.wait()
        total = add([self._box[r] for r in range(self.parts)])
        self._barrier.wait()
        return total


class SummedLU(Solver):
    """The shares summed on every part and factored by SuperLU."""

    name = "summed superlu"
    sums_shares = True

    def __init__(self):
        super().__init__()
        self.system = None

    def factor(self, A, constraint_rows=None):
        self.A = A
        self._lu = splu(A.reduction.sum_sparse(A.local).tocsc())
        return self

    def _solve(self, b):
        return self._lu.solve(b)


def on_threads(parts, run):
    """``run(rank, reduction)`` on ``parts`` threads; their results in rank
    order (an exception in one is raised here)."""
    reduction = ThreadReduction(parts)
    results, errors = [None] * parts, [None] * parts

    def target(rank):
        try:
            results[rank] = run(rank, reduction.of(rank))
        except BaseException as err:  # noqa: BLE001 - handed to the caller
            errors[rank] = err

    threads = [threading.Thread(target=target, args=(r,)) for r in range(parts)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results, errors


def block(n=8):
    return rectangle(1.0, 1.0, n, n)


@pytest.mark.parametrize("axisymmetric", [False, True])
def test_the_parts_of_a_vci_basis_are_the_whole_basis_on_their_cells(axisymmetric):
    """3 parts of a distorted mesh: the corrected test gradients of each
    part equal those of the whole basis restricted to its cells (the VCI
    sums added over the parts), to 1e-13 of their size."""
    mesh = MeshQuad.init_tensor(np.linspace(0.5, 1.5, 11), np.linspace(0, 2, 15))
    rng = np.random.default_rng(3)
    interior = ~np.isin(np.arange(mesh.nvertices), mesh.boundary_nodes())
    p = mesh.p.copy()
    p[:, interior] += 0.02 * rng.uniform(-1, 1, (2, interior.sum()))
    mesh = MeshQuad(p, mesh.t)
    whole = RKBasis(mesh, VECTOR, support=2.5, axisymmetric=axisymmetric)
    parts = partition(mesh, 3)
    bases, errors = on_threads(3, lambda r, red: RKBasis(
        mesh, VECTOR, support=2.5, axisymmetric=axisymmetric,
        elements=parts.cells_of(r), reduction=red))
    assert errors == [None] * 3
    scale = np.abs(whole.grads).max()
    for rank, part in enumerate(bases):
        restricted = whole.with_elements(parts.cells_of(rank))
        np.testing.assert_array_equal(part.element_nodes, restricted.element_nodes)
        np.testing.assert_allclose(part.grads, restricted.grads, atol=1e-13 * scale, rtol=0)
        np.testing.assert_allclose(part.trial.grads, restricted.trial.grads,
                                   atol=1e-13 * scale, rtol=0)
    assert sum(b.nelems for b in bases) == mesh.nelements
    with pytest.raises(BasisIdiomError, match="one part of a partitioned basis"):
        bases[0].with_elements([0])


def test_the_parts_of_a_3d_vci_basis_are_the_whole_basis_on_their_cells():
    """The same on hexahedra (2 parts of a 4 x 3 x 3 block)."""
    mesh = MeshHex.init_tensor(np.linspace(0, 1, 5), np.linspace(0, 1, 4),
                               np.linspace(0, 1, 4))
    element = ElementVector(ElementHex1())
    whole = RKBasis(mesh, element, support=2.0, intorder=3)
    parts = partition(mesh, 2)
    bases, errors = on_threads(2, lambda r, red: RKBasis(
        mesh, element, support=2.0, intorder=3, elements=parts.cells_of(r), reduction=red))
    assert errors == [None] * 2
    scale = np.abs(whole.grads).max()
    for rank, part in enumerate(bases):
        restricted = whole.with_elements(parts.cells_of(rank))
        np.testing.assert_allclose(part.grads, restricted.grads, atol=1e-13 * scale, rtol=0)


def test_partition_splits_the_cells_evenly_and_gives_rows_to_a_cell_of_theirs():
    mesh = block(12)
    parts = partition(mesh, 4)
    assert np.bincount(parts.cells, minlength=4).tolist() == [36] * 4
    for I in range(mesh.nvertices):
        cells = np.flatnonzero((mesh.t == I).any(axis=0))
        assert parts.particles[I] == parts.cells[cells].min()
    with pytest.raises(ValueError, match="at most one rank per cell"):
        partition(block(2), 5)


def test_a_part_needs_its_cells_and_vci_or_gauss():
    mesh = block(4)
    reduction = ThreadReduction(1).of(0)
    with pytest.raises(ValueError, match="give elements="):
        RKBasis(mesh, VECTOR, reduction=reduction)
    with pytest.raises(ValueError, match="'vci' or 'gauss'"):
        RKBasis(mesh, VECTOR, integration="scni", elements=[0], reduction=reduction)


def test_a_partial_matrix_counts_a_replicated_term_once():
    rng = np.random.default_rng(0)
    shares = [sp.random(6, 6, 0.4, random_state=r, format="csr") for r in range(3)]
    extra = sp.csr_matrix(rng.standard_normal((6, 6)))
    x = rng.standard_normal(6)

    def run(rank, reduction):
        K = sum([extra], PartialMatrix(shares[rank], reduction, rank == 0))
        return K @ x, K.diagonal()

    results, errors = on_threads(3, run)
    assert errors == [None] * 3
    total = sum(shares) + extra
    for Kx, diagonal in results:
        np.testing.assert_allclose(Kx, total @ x, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(diagonal, total.diagonal(), rtol=1e-14, atol=1e-14)


def upsetting(basis):
    """Plastic upsetting of a block between rough platens (F-bar): the top
    moves down 8 % with no slip, the bottom is held, so that the flow is
    not homogeneous."""
    problem = SolidProblem(basis, J2Material(E, NU, linear(250.0, 1000.0)),
                           "plane_strain", locking="fbar")
    conditions = [Prescribed("bottom", 0), Prescribed("bottom", 1),
                  Prescribed("top", 0), Prescribed("top", 1, -0.08)]
    return problem, conditions


def rk_or_fem(method, mesh, cells=None, reduction=None):
    if method == "fem":
        return Basis(mesh, VECTOR, intorder=2, elements=cells)
    return RKBasis(mesh, VECTOR, support=2.5, elements=cells, reduction=reduction)


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_newton_on_three_parts_follows_the_whole_run(method):
    """The same iterations, residuals and solution as the unpartitioned
    run: every part sees the summed force and the summed tangent."""
    mesh = block(8)
    whole, conditions = upsetting(rk_or_fem(method, mesh))
    serial = newton_steps(whole, conditions, steps=4, tol=1e-10)
    assert serial.completed, serial.message
    parts = partition(mesh, 3)

    def run(rank, reduction):
        basis = rk_or_fem(method, mesh, parts.cells_of(rank), reduction)
        problem, conditions = upsetting(basis)
        return newton_steps(PartitionedSolid(problem, reduction, rank), conditions,
                            steps=4, tol=1e-10, linear_solver=SummedLU())

    results, errors = on_threads(3, run)
    assert errors == [None] * 3
    scale = np.abs(serial.d).max()
    for result in results:
        assert result.completed, result.message
        assert [r.iterations for r in result.history] == [
            r.iterations for r in serial.history]
        np.testing.assert_allclose(result.d, serial.d, atol=1e-10 * scale, rtol=0)
        np.testing.assert_allclose(result.history[-1].reactions["top[1]"],
                                   serial.history[-1].reactions["top[1]"], rtol=1e-9)
    assert serial.history[-1].reactions["top[1]"] < -250.0  # plastic: beyond yield


def test_a_failure_on_one_part_stops_every_part():
    """An inverted cell on part 1 raises InvertedElementError on all parts,
    naming the rank where it happened."""
    mesh = block(4)
    parts = partition(mesh, 2)
    d = np.zeros(2 * mesh.nvertices)
    corner = np.flatnonzero(parts.particles == 1)[-1]
    d[2 * corner:2 * corner + 2] = -5.0  # folds the cells around one particle

    def run(rank, reduction):
        basis = RKBasis(mesh, VECTOR, support=2.0, elements=parts.cells_of(rank),
                        reduction=reduction)
        problem, _ = upsetting(basis)
        PartitionedSolid(problem, reduction, rank).evaluate(d)

    _, errors = on_threads(2, run)
    assert all(isinstance(e, InvertedElementError) for e in errors), errors
    assert all("on rank " in str(e) for e in errors)
    # the cell named is the mesh's: the point named lies in it
    message = str(errors[0])
    cell = int(message.split("in cell ")[1].split()[0])
    X = np.array([float(v) for v in message.split("X = (")[1].split(")")[0].split(",")])
    corners = mesh.p[:, mesh.t[:, cell]]
    assert np.all(corners.min(axis=1) <= X) and np.all(X <= corners.max(axis=1))


def test_the_gathered_state_is_the_whole_state_and_restores_each_part():
    """After a plastic step, the whole-domain state gathered on part 0 from
    2 parts is the unpartitioned run's (cell-major points), and restoring
    the whole state gives each part its own points."""
    mesh = block(6)
    whole, conditions = upsetting(RKBasis(mesh, VECTOR, support=2.5))
    assert newton_steps(whole, conditions, steps=1, tol=1e-10).completed
    parts = partition(mesh, 2)

    def run(rank, reduction):
        basis = RKBasis(mesh, VECTOR, support=2.5, elements=parts.cells_of(rank),
                        reduction=reduction)
        problem, conditions = upsetting(basis)
        solid = PartitionedSolid(problem, reduction, rank)
        newton_steps(solid, conditions, steps=1, tol=1e-10, linear_solver=SummedLU())
        gathered = solid.gathered_state()
        own = solid.problem.state.copy()
        solid.problem.state = None
        solid.restore_state(whole.state)  # as every rank reads it from a checkpoint
        return gathered, own, solid.problem.state, solid.whole_dx

    results, errors = on_threads(2, run)
    assert errors == [None] * 2
    assert whole.state.alpha.max() > 1e-3  # the state is plastic
    gathered, _, _, dx = results[0]
    np.testing.assert_allclose(gathered.alpha, whole.state.alpha, atol=1e-12)
    np.testing.assert_allclose(gathered.Cp_inv, whole.state.Cp_inv, atol=1e-12)
    np.testing.assert_allclose(dx, whole.assembler.layout.dx, rtol=1e-15)
    assert results[1][0] is None and results[1][3] is None  # rank 0 only
    for _, own, restored, _ in results:
        np.testing.assert_allclose(restored.alpha, own.alpha, atol=1e-12)
        np.testing.assert_allclose(restored.Cp_inv, own.Cp_inv, atol=1e-12)


def test_any_other_failure_on_one_part_stops_every_part():
    """An error that is not a material point's (here a KeyError on part 1)
    becomes a RankFailure on every part: Newton must not retry it on some."""
    mesh = block(4)
    parts = partition(mesh, 2)

    def run(rank, reduction):
        basis = RKBasis(mesh, VECTOR, support=2.0, elements=parts.cells_of(rank),
                        reduction=reduction)
        problem, _ = upsetting(basis)
        if rank == 1:
            def broken(*args, **kwargs):
                raise KeyError("a missing entry")
            problem.evaluate = broken
        PartitionedSolid(problem, reduction, rank).evaluate(np.zeros(problem.N))

    _, errors = on_threads(2, run)
    assert all(isinstance(e, RankFailure) for e in errors), errors
    assert all("rank 1 failed" in str(e) and "a missing entry" in str(e) for e in errors)
    assert isinstance(errors[1].__cause__, KeyError)
