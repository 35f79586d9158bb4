"""Symmetric VCI (integration="vci_symmetric"): symmetric matrices, patch test kept.

The corrected gradients reproduce the gradients of linear fields, so they
serve as trial and test gradients: the stiffness is symmetric to round-off
(1e-14 of its largest entry), the linear patch test passes to round-off
(1e-10: a solve with condition numbers of 1e3-1e4), conjugate gradients
converge and ``eigsh`` agrees with a dense eigensolver.
"""

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg as sla
from skfem import LinearForm, MeshTet, MeshTri
from skfem.helpers import dot
from skfem.models import laplace, linear_elasticity, mass

import skfem_rkpm
from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.meshes import rectangle

# results exact but for round-off of dense and sparse solves
pytestmark = pytest.mark.roundoff

LAM, MU = 1.2, 0.8


def asymmetry(K):
    return abs(K - K.T).max() / abs(K).max()


@pytest.fixture(scope="module", params=["quad", "tri"])
def perturbed(request):
    return rectangle(2.0, 1.0, 12, 6, perturb=0.25, kind=request.param)


def test_default_vci_is_not_symmetric_and_symmetric_vci_is(perturbed):
    vci = RKBasis(perturbed)
    sym = RKBasis(perturbed, integration="vci_symmetric")
    assert sym.trial is sym
    assert asymmetry(skfem_rkpm.asm(laplace, vci.trial, vci)) > 1e-5
    assert asymmetry(skfem_rkpm.asm(laplace, sym)) < 1e-14
    v = RKBasis(perturbed, vector=True, integration="vci_symmetric")
    assert asymmetry(Assembler(v).bilinear(isotropic_tangent(LAM, MU, 2))) < 1e-14


def test_corrected_gradients_reproduce_linear_fields(perturbed):
    basis = RKBasis(perturbed, integration="vci_symmetric")
    # RK functions reproduce linear fields from their nodal values
    d = 1.0 + 2.0 * basis.nodes[0] - 3.0 * basis.nodes[1]
    grads = np.einsum("kanq,an->knq", basis.grads, d[basis.element_nodes])
    assert np.abs(grads - np.array([2.0, -3.0])[:, None, None]).max() < 1e-12


def test_linear_patch_test_elasticity(perturbed):
    """Traction loads of a linear displacement field; all boundary values fixed
    to it: the solution is that field to round-off, everywhere."""
    basis = RKBasis(perturbed, vector=True, integration="vci_symmetric")
    G = np.array([[0.01, 0.02], [-0.03, 0.015]])

    def exact(x):
        return np.array([0.1 + G[0] @ x[:2], -0.2 + G[1] @ x[:2]])

    eps = 0.5 * (G + G.T)
    sigma = LAM * np.trace(eps) * np.eye(2) + 2 * MU * eps

    @LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", sigma, w.n), v)

    K = skfem_rkpm.asm(linear_elasticity(LAM, MU), basis)
    f = skfem_rkpm.asm(traction, basis.boundary())
    D = basis.get_dofs()
    d = skfem_rkpm.solve(K, f, basis, D=D, x=exact(basis.nodes).T.ravel()[D])
    x = np.random.default_rng(0).uniform([0, 0], [2, 1], size=(50, 2)).T
    values = (basis.probes(x) @ d).reshape(2, -1)
    assert np.abs(values - exact(x)).max() < 1e-10
    assert np.abs(basis.interpolate(d).grad - G[:, :, None, None]).max() < 1e-10


def test_patch_test_3d():
    basis = RKBasis(MeshTet().refined(1), integration="vci_symmetric")
    K = skfem_rkpm.asm(laplace, basis)
    assert asymmetry(K) < 1e-14
    g = np.array([1.0, -2.0, 0.5])

    @LinearForm
    def flux(v, w):
        return dot(g, w.n) * v

    f = skfem_rkpm.asm(flux, basis.boundary())
    D = basis.get_dofs()
    d = skfem_rkpm.solve(K, f, basis, D=D, x=1.0 + g @ basis.nodes)
    assert np.abs(basis.interpolate(d).grad - g[:, None, None]).max() < 1e-10


def test_conjugate_gradients_converge():
    """(-Δ + 1) u = f, natural boundary: symmetric positive definite."""
    basis = RKBasis(rectangle(1.0, 1.0, 16, 16, perturb=0.2), integration="vci_symmetric")
    A = (skfem_rkpm.asm(laplace, basis) + skfem_rkpm.asm(mass, basis)).tocsr()
    f = skfem_rkpm.asm(LinearForm(lambda v, w: np.cos(np.pi * w.x[0]) * v), basis)
    iterations = []
    u, info = sla.cg(A, f, rtol=1e-12, maxiter=2000,
                     callback=lambda xk: iterations.append(1))
    assert info == 0, f"CG did not converge ({len(iterations)} iterations)"
    direct = sla.spsolve(A.tocsc(), f)
    assert np.abs(u - direct).max() <= 1e-8 * np.abs(direct).max()


def test_eigsh_agrees_with_dense_eigensolver():
    basis = RKBasis(MeshTri().refined(3), integration="vci_symmetric")
    K, M = skfem_rkpm.asm(laplace, basis), skfem_rkpm.asm(mass, basis)
    dense = scipy.linalg.eigh(K.toarray(), M.toarray(), eigvals_only=True)[:6]
    sparse = np.sort(sla.eigsh(K, k=6, M=M, sigma=-1.0, which="LM")[0])
    assert np.abs(sparse - dense).max() <= 1e-9 * dense[-1]
    # Neumann Laplacian of the unit square: 0, π², π², 2π², ...
    assert abs(dense[0]) < 1e-10 and dense[1] == pytest.approx(np.pi ** 2, rel=0.05)


def test_refuses_what_it_does_not_build():
    mesh = MeshTri().refined(2)
    with pytest.raises(ValueError, match="order 1"):
        RKBasis(mesh, order=2, support=3.0, intorder=6, integration="vci_symmetric")
    with pytest.raises(ValueError, match="axisymmetric"):
        RKBasis(mesh, integration="vci_symmetric", axisymmetric=True)


@pytest.mark.parametrize("options", [{}, {"support_shape": "box"},
                                     {"kernel": "quartic", "support": 2.5}])
def test_patch_test_on_two_separate_bodies(options):
    """Each body has its own linear null space in the constraint system: the
    patch test passes on both, for other supports and kernels too."""
    from skfem import MeshQuad

    left = MeshQuad.init_tensor(np.linspace(0, 1, 7), np.linspace(0, 1, 7))
    right = MeshQuad.init_tensor(np.linspace(3, 4, 7), np.linspace(0, 1, 7))
    basis = RKBasis(left + right, integration="vci_symmetric", **options)
    g = np.array([2.0, -3.0])

    @LinearForm
    def flux(v, w):
        return dot(g, w.n) * v

    K = skfem_rkpm.asm(laplace, basis)
    assert asymmetry(K) < 1e-14
    d = skfem_rkpm.solve(K, skfem_rkpm.asm(flux, basis.boundary()), basis,
                         D=basis.get_dofs(), x=1.0 + g @ basis.nodes)
    assert np.abs(basis.interpolate(d).grad - g[:, None, None]).max() < 1e-10


def test_elasticity_patch_test_3d():
    """A linear displacement field on tetrahedra: symmetric stiffness, the
    field reproduced to round-off with tractions on the whole boundary."""
    basis = RKBasis(MeshTet().refined(1), vector=True, integration="vci_symmetric")
    G = np.array([[0.01, 0.02, -0.01], [-0.03, 0.015, 0.02], [0.005, -0.01, 0.01]])
    eps = 0.5 * (G + G.T)
    sigma = LAM * np.trace(eps) * np.eye(3) + 2 * MU * eps

    @LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", sigma, w.n), v)

    K = skfem_rkpm.asm(linear_elasticity(LAM, MU), basis)
    assert asymmetry(K) < 1e-14
    D = basis.get_dofs()
    exact = (G @ basis.nodes + np.array([[0.1], [-0.2], [0.3]])).T.ravel()
    d = skfem_rkpm.solve(K, skfem_rkpm.asm(traction, basis.boundary()), basis,
                         D=D, x=exact[D])
    assert np.abs(basis.interpolate(d).grad - G[:, :, None, None]).max() < 1e-10


@pytest.mark.parametrize("interpolating", [False, True])
def test_exact_gradients_computed_again_equal_those_of_the_build(interpolating):
    """A symmetric VCI basis keeps only its corrected gradients; the exact
    ones (``basis.table``, ``interpolate``, ``with_elements``) are computed
    again when asked: they equal those of the same basis with plain Gauss
    integration (the same shape functions, to round-off of their solves),
    on all cells and on a subset, and the corrected gradients are not the
    exact ones."""
    import copy

    from skfem_rkpm.approximation.rk_base import EXACT_ON_DEMAND

    mesh = MeshTet.init_tensor(*(np.linspace(0, 1, 5),) * 3)
    sym = RKBasis(mesh, interpolating=interpolating, integration="vci_symmetric")
    gauss = RKBasis(mesh, interpolating=interpolating, integration="gauss")
    assert sym._exact_grads is EXACT_ON_DEMAND
    assert copy.deepcopy(sym)._exact_grads is EXACT_ON_DEMAND  # the same marker
    cells = np.arange(1, mesh.nelements, 3)[::-1]  # a subset, not in order
    for a, b in ((sym.with_elements(cells), gauss.with_elements(cells)), (sym, gauss)):
        ta, tb = a.table, b.table
        np.testing.assert_array_equal(ta.indptr, tb.indptr)
        np.testing.assert_array_equal(ta.indices, tb.indices)
        scale = np.abs(tb.grads).max()
        assert np.abs(ta.grads - tb.grads).max() <= 1e-12 * scale
        assert np.abs(a.test_grads - ta.grads).max() > 1e-6 * scale  # corrected
    assert not isinstance(sym._exact_grads, type(EXACT_ON_DEMAND))  # kept once computed
    u = mesh.p[0] ** 2 - mesh.p[1] * mesh.p[2]
    grad, expected = sym.interpolate(u).grad, gauss.interpolate(u).grad
    assert np.abs(grad - expected).max() <= 1e-12 * np.abs(expected).max()
