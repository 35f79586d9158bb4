"""The order-1 VCI balancing system is a weighted graph Laplacian, solved
semidefinite by conjugate gradients with a two-level preconditioner
(``approximation.laplacian``): the same corrections as the pinned
factorization, on one body and on two."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import LinearForm, MeshHex, MeshQuad
from skfem.helpers import dot
from skfem.models import laplace

import skfem_rkpm
import skfem_rkpm.approximation.integration as integration
from skfem_rkpm.approximation.laplacian import laplacian_solve, two_level_preconditioner
from skfem_rkpm import RKBasis
from skfem_rkpm.approximation.shape import ShapeTable
from skfem_rkpm.meshes import rectangle

# results exact but for round-off of dense and sparse solves
pytestmark = pytest.mark.roundoff


def _random_laplacian(sizes, seed=0):
    """A weighted graph Laplacian with one connected block per entry of
    ``sizes`` (a path keeps each block connected, random edges are added)."""
    rng = np.random.default_rng(seed)
    blocks = []
    for n in sizes:
        W = sp.random(n, n, density=0.2, random_state=rng)
        W = W + sp.diags(np.ones(n - 1), 1)
        W = (W + W.T).tocsr()
        W.setdiag(0.0)
        blocks.append(sp.diags(np.asarray(W.sum(1)).ravel()) - W)
    return sp.block_diag(blocks, format="csr")


def test_laplacian_solve_matches_the_pseudoinverse():
    """Two bodies: the solution is the minimum-norm one (zero mean per body)
    of the consistent part of ``b``, as from the dense pseudoinverse."""
    sizes = [40, 25]
    M = _random_laplacian(sizes)
    body = np.repeat([0, 1], sizes)
    rng = np.random.default_rng(1)
    b = rng.standard_normal((M.shape[0], 2))
    # particles scattered at random: aggregates of any shape still precondition
    nodes = rng.random((2, M.shape[0]))
    x = laplacian_solve(M, b, body, 2, nodes, np.full(M.shape[0], 0.2), 1e-13)
    expected = np.linalg.pinv(M.toarray()) @ b
    # rtol 1e-13 on the residual, condition number of M on its range ~1e2
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    for k in range(2):
        assert abs(x[body == k].mean(axis=0)).max() < 1e-14 * np.abs(x).max()


def test_laplacian_solve_reports_no_convergence():
    M = _random_laplacian([60])
    b = np.random.default_rng(2).standard_normal((60, 1))
    with pytest.raises(RuntimeError, match="did not reach a relative residual"):
        laplacian_solve(M, b, np.zeros(60, dtype=int), 1,
                        np.linspace(0, 1, 120).reshape(2, 60), np.full(60, 0.01), 1e-13,
                        maxiter=2)


def _two_bodies():
    left = rectangle(1.0, 1.0, 9, 9, kind="quad", perturb=0.2, seed=5)
    right = MeshQuad.init_tensor(np.linspace(2, 3, 8), np.linspace(0, 1, 6))
    return left + right


@pytest.mark.parametrize("case", ["two bodies", "axisymmetric", "3D"])
def test_corrections_match_the_pinned_factorization(monkeypatch, case):
    """Conjugate gradients on the Laplacian (forced at every size) against
    the factorization of the pinned system (the default at these sizes):
    the corrected gradients agree to 1e-9 of the correction (M's condition
    number here is ~1e3, CG stops at a relative residual of 1e-13, the
    factorization at round-off), and sum to zero at every point."""
    mesh, options = _two_bodies(), {"support": 2.0, "intorder": 3}
    if case == "axisymmetric":
        mesh, options["axisymmetric"] = mesh.translated([0.5, 0.0]), True
    elif case == "3D":
        mesh = MeshHex.init_tensor(*[np.linspace(0, 1, 6)] * 3)
        mesh = MeshHex(mesh.p + 0.03 * np.sin(7 * mesh.p[[1, 2, 0]]), mesh.t)

    direct = RKBasis(mesh, vector=True, **options)
    assert mesh.nvertices <= integration.LAPLACIAN_DIRECT_MAX_UNKNOWNS
    monkeypatch.setattr(integration, "LAPLACIAN_DIRECT_MAX_UNKNOWNS", 0)
    called = []

    def counted(*args, **kw):
        called.append(1)
        return laplacian_solve(*args, **kw)
    monkeypatch.setattr(integration, "laplacian_solve", counted)
    iterative = RKBasis(mesh, vector=True, **options)
    assert called
    scale = np.abs(direct.test_grads - direct.table.grads).max()
    assert scale > 1e-4 * np.abs(direct.table.grads).max()  # a correction to check
    assert np.abs(iterative.test_grads - direct.test_grads).max() < 1e-9 * scale
    dim, nq, rows = mesh.dim(), iterative.table.npoints, iterative.table.rows
    sums = np.stack([np.bincount(rows, iterative.test_grads[k], minlength=nq)
                     for k in range(dim)])
    assert np.abs(sums).max() < 1e-12 * np.abs(iterative.test_grads).max()


def test_patch_test_on_two_separate_bodies(monkeypatch):
    """Each body has its own constant null space: with the CG solve, the
    linear patch test of the (Petrov-Galerkin) VCI basis passes on both to
    round-off."""
    monkeypatch.setattr(integration, "LAPLACIAN_DIRECT_MAX_UNKNOWNS", 0)
    left = MeshQuad.init_tensor(np.linspace(0, 1, 7), np.linspace(0, 1, 7))
    right = MeshQuad.init_tensor(np.linspace(3, 4, 7), np.linspace(0, 1, 7))
    basis = RKBasis(left + right)
    g = np.array([2.0, -3.0])

    @LinearForm
    def flux(v, w):
        return dot(g, w.n) * v

    K = skfem_rkpm.asm(laplace, basis.trial, basis)
    d = skfem_rkpm.solve(K, skfem_rkpm.asm(flux, basis.boundary()), basis,
                         D=basis.get_dofs(), x=1.0 + g @ basis.nodes)
    # a solve with condition numbers of 1e3-1e4 at round-off
    assert np.abs(basis.interpolate(d).grad - g[:, None, None]).max() < 1e-10


def test_two_level_preconditioner_is_symmetric_positive_definite_on_the_range():
    """The preconditioner as a matrix (applied to the unit vectors), on two
    bodies: symmetric to round-off, positive on vectors of zero mean per body."""
    sizes = [30, 20]
    M = _random_laplacian(sizes, seed=3)
    n = M.shape[0]
    body = np.repeat([0, 1], sizes)
    nodes = np.random.default_rng(4).random((2, n))
    apply = two_level_preconditioner(M, body, 2, nodes, 0.3)
    P = np.stack([apply(e) for e in np.eye(n)], axis=1)
    assert abs(P - P.T).max() < 1e-12 * abs(P).max()
    centred = np.eye(n) - np.stack([np.where(body == body[i], 1 / np.array(sizes)[body],
                                             0.0) for i in range(n)])
    eigenvalues = np.linalg.eigvalsh(centred.T @ P @ centred)
    # the range has n - 2 dimensions: n - 2 positive eigenvalues
    assert np.sum(eigenvalues > 1e-10 * eigenvalues.max()) == n - 2
    assert eigenvalues.min() > -1e-12 * eigenvalues.max()


def test_rows_of_points_without_pairs():
    """``ShapeTable.rows`` counts points with no pairs (first, middle, last)."""
    counts = np.array([0, 2, 0, 0, 3, 1, 0])
    indptr = np.concatenate([[0], np.cumsum(counts)])
    table = ShapeTable(indptr, np.zeros(6, dtype=int), np.zeros(6), None, 1)
    np.testing.assert_array_equal(table.rows, np.repeat(np.arange(7), counts))
    empty = ShapeTable(np.zeros(4, dtype=int), np.zeros(0, dtype=int), np.zeros(0),
                       None, 1)
    assert empty.rows.shape == (0,)
