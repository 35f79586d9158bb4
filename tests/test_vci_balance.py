"""VCI keeps the partition-of-unity derivative: Σ_I ∇̃Ψ_I = 0 at every
quadrature point, so internal forces are self-equilibrated for any stress."""

import numpy as np
import pytest

from skfem_rkpm import Assembler, RKBasis
from skfem_rkpm.meshes import rectangle


def _basis(kind, order):
    m = rectangle(2.0, 1.0, 8, 5, kind=kind, perturb=0.2 if kind == "quad" else 0.15,
                  seed=3)
    return RKBasis(m, vector=True, support=2.0 if order == 1 else 3.0, order=order,
                   intorder=2 if order == 1 else 4, integration="vci")


@pytest.mark.parametrize("kind", ["quad", "tri"])
@pytest.mark.parametrize("order", [1, 2])
def test_test_gradients_sum_to_zero_pointwise(kind, order):
    b = _basis(kind, order)
    dim, nq, rows = b.nodes.shape[0], b.table.npoints, b.table.rows
    sums = np.stack([np.bincount(rows, b.test_grads[k], minlength=nq)
                     for k in range(dim)])
    scale = np.abs(b.test_grads).max()
    # the correction itself is far from round-off ...
    assert np.abs(b.test_grads - b.table.grads).max() > 1e-4 * scale
    # ... but sums to zero at every point
    assert np.abs(sums).max() < 1e-12 * scale


@pytest.mark.parametrize("kind", ["quad", "tri"])
@pytest.mark.parametrize("order", [1, 2])
def test_internal_force_of_nonuniform_stress_is_balanced(kind, order):
    b = _basis(kind, order)
    x = np.asarray(b.global_coordinates())
    # a quadratic, non-symmetric stress field (c, l, nelems, nqp)
    P = np.array([[1.0 + 3 * x[0] ** 2 - x[1], 0.5 * x[0] * x[1]],
                  [2.0 - x[0] + x[1] ** 2, -1.0 + 4 * x[0] * x[1]]])
    f = Assembler(b).linear(P).reshape(-1, 2)
    magnitude = np.abs(f).sum(0)
    np.testing.assert_array_less(np.abs(f.sum(0)), 1e-12 * magnitude)


@pytest.mark.parametrize("integration, order", [("vci", 1), ("vci_symmetric", 1)])
def test_iterative_vci_solve_matches_the_factorization(monkeypatch, integration, order):
    """AMG-preconditioned CG (used above DIRECT_MAX_UNKNOWNS) gives the
    corrections of the sparse LU factorization, and keeps their balance."""
    pytest.importorskip("pyamg")
    import skfem_rkpm.approximation.integration as integration_module

    mesh = rectangle(2.0, 1.0, 36, 18, kind="quad", perturb=0.2, seed=5)

    def build():
        return RKBasis(mesh, vector=True, support=2.0 if order == 1 else 3.0,
                       order=order, intorder=2 if order == 1 else 4,
                       integration=integration)

    direct = build()
    monkeypatch.setattr(integration_module, "DIRECT_MAX_UNKNOWNS", 0)
    iterative = build()
    scale = np.abs(direct.test_grads - direct.table.grads).max()
    # both solve M ξ = r to a relative residual of ~1e-13 (CG) or round-off
    # (LU); M's condition number here is ~1e3, so the corrections agree to
    # ~1e-10 of their size
    assert np.abs(iterative.test_grads - direct.test_grads).max() < 1e-9 * scale
    dim, nq, rows = mesh.dim(), iterative.table.npoints, iterative.table.rows
    sums = np.stack([np.bincount(rows, iterative.test_grads[k], minlength=nq)
                     for k in range(dim)])
    assert np.abs(sums).max() < 1e-12 * np.abs(iterative.test_grads).max()


def test_a_stalled_iterative_vci_solve_falls_back_to_the_factorization(monkeypatch):
    """Where AMG + CG do not reach the tolerance (as on order 2 above 20,000
    unknowns: 1e-3 after 500 iterations, so order 2 is always factored), the
    correction system is factored instead of the build failing: the
    corrections are those of the factorization."""
    pytest.importorskip("pyamg")
    import skfem_rkpm.approximation.integration as integration_module

    mesh = rectangle(2.0, 1.0, 24, 12, kind="quad", perturb=0.2, seed=5)

    def build():
        return RKBasis(mesh, vector=True, support=2.0, intorder=2,
                       integration="vci_symmetric")

    direct = build()
    stalled = []
    amg_cg = integration_module._amg_cg

    def one_iteration(M, b, rtol, maxiter):
        stalled.append(amg_cg(M, b, rtol, 1))
        return stalled[-1]

    monkeypatch.setattr(integration_module, "DIRECT_MAX_UNKNOWNS", 0)
    monkeypatch.setattr(integration_module, "_amg_cg", one_iteration)
    fallen_back = build()
    assert stalled == [None]  # one iteration does not reach 1e-13
    # the same factorization, after pyamg has set up on the matrix: round-off
    # (measured 3.6e-15 of gradients of size 1)
    np.testing.assert_allclose(fallen_back.test_grads, direct.test_grads, rtol=0,
                               atol=1e-13 * np.abs(direct.test_grads).max())
