"""``"auto"`` factors small dense tangents (3D RK) with dense LU: the rule
(size and fill) and the solution, equal to SuperLU's to round-off."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.meshes import box
from skfem_rkpm.solvers import linear
from skfem_rkpm.solvers.linear import make_solver


def filled(n, fraction, seed=0):
    """A diagonally dominant n x n matrix with about ``fraction`` of its entries set."""
    R = sp.random(n, n, density=fraction, random_state=np.random.default_rng(seed))
    return (R + sp.diags(np.asarray(abs(R).sum(axis=1)).ravel() + 1.0)).tocsr()


@pytest.mark.parametrize("n, fraction, expected", [
    (linear.DENSE_LIMIT, 0.01, "dense"),         # small: dense at any fill
    (945, 0.42, "dense"),                        # the 3D RK billet tangent's fill
    (945, 0.06, "superlu"),                      # FEM Hex1 on the same mesh
    (linear.DENSE_SIZE, 0.3, "dense"),
    (linear.DENSE_SIZE + 10, 0.3, "superlu"),    # dense LU grows as n³
])
def test_auto_takes_dense_lu_for_small_dense_systems(n, fraction, expected):
    auto = make_solver("auto")
    auto.installed = ["dense", "superlu"]
    assert auto.choose(filled(n, fraction)) == expected


def rk_tangent():
    """The RK elasticity tangent of an 8 x 4 x 5 box (9 x 5 x 6 particles,
    810 unknowns, 41 % nonzero, not symmetric: VCI) plus a small
    multiple of the identity that removes the rigid motions."""
    basis = RKBasis(box(2.0, 1.0, 1.25, 8, 4, 5), vector=True, support=2.0, intorder=2)
    lam, mu = lame_parameters(200e3, 0.3)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 3)).tocsr()
    return (K + 1e-3 * abs(K).max() * sp.identity(K.shape[0])).tocsr()


def test_dense_and_sparse_lu_solve_alike():
    """The dense path (chosen by ``auto``) against SuperLU by name: the
    difference of the two backward-stable solves is bounded by the
    condition number times a few hundred units of round-off."""
    K = rk_tangent()
    n = K.shape[0]
    assert n > linear.DENSE_LIMIT and K.nnz > linear.DENSE_FRACTION * n * n
    auto = make_solver("auto")
    b = np.random.default_rng(2).normal(size=(n, 2))
    x = auto.factor(K).solve(b)
    assert auto.current.name == "dense"
    y = make_solver("superlu").factor(K).solve(b)
    kappa = np.linalg.cond(K.toarray())
    assert np.linalg.norm(x - y) / np.linalg.norm(y) <= 500 * kappa * np.finfo(float).eps
    # and each is a solution: residual at round-off of |K| |x|
    assert np.abs(K @ x - b).max() <= 1e-12 * abs(K).sum(axis=1).max() * np.abs(x).max()
