"""The transformation method (Eq. 3.32-3.37) without a dense Λ⁻¹."""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector, LinearForm, MeshQuad, asm, condense
from skfem import solve as skfem_solve
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent, solve

# results exact but for round-off of dense and sparse solves
pytestmark = pytest.mark.roundoff

LAM, MU = lame_parameters(1000.0, 0.25)


@LinearForm
def gravity(v, w):
    return dot(np.array([0.3, -1.0])[:, None, None] + 0 * w.x, v)


@pytest.fixture(params=["gauss", "vci"])
def model(request):
    m = MeshQuad.init_tensor(np.linspace(0, 2, 7), np.linspace(0, 1, 5)).with_defaults()
    b = RKBasis(m, vector=True, support=2.5, integration=request.param)
    K = Assembler(b).bilinear(isotropic_tangent(LAM, MU, 2))
    return b, K, asm(gravity, b)


def test_equals_the_papers_dense_transformation(model):
    b, K, f = model
    D = b.get_dofs("left")
    g = 1e-3 * np.sin(np.arange(len(D)))  # prescribed nodal values
    # the paper: K̂ = Λ⁻¹ K Λ⁻ᵀ, f̂ = Λ⁻¹ f, d̂_D = g, d = Λ⁻ᵀ d̂
    LT = b.nodal_matrix.toarray()
    L_inv = np.linalg.inv(LT.T)
    K_hat = L_inv @ K.toarray() @ L_inv.T
    f_hat = L_inv @ f
    free = np.setdiff1d(np.arange(b.N), D)
    d_hat = np.zeros(b.N)
    d_hat[D] = g
    d_hat[free] = np.linalg.solve(K_hat[np.ix_(free, free)],
                                  f_hat[free] - K_hat[np.ix_(free, D)] @ g)
    d_paper = np.linalg.solve(LT, d_hat)

    d, reactions = solve(K, f, b, D=D, x=g, return_reactions=True)
    np.testing.assert_allclose(d, d_paper, rtol=0, atol=1e-10 * np.abs(d_paper).max())
    np.testing.assert_allclose(b.nodal_values(d)[D], g, atol=1e-15)
    # the reactions are the paper's nodal forces K̂ d̂ - f̂ on D ...
    np.testing.assert_allclose(reactions, (K_hat @ d_hat - f_hat)[D],
                               atol=1e-9 * np.abs(reactions).max())
    # ... and balance the applied load; exactly for the symmetric Gauss
    # scheme, to the integration error for the Petrov-Galerkin VCI scheme
    # (its test gradients do not sum to zero pointwise)
    tol = 1e-10 if b.integration == "gauss" else 1e-3
    np.testing.assert_allclose(reactions.reshape(-1, 2).sum(0),
                               -f.reshape(-1, 2).sum(0), rtol=tol)


def test_full_vector_of_values_and_fem_identity():
    m = MeshQuad.init_tensor(np.linspace(0, 2, 7), np.linspace(0, 1, 5)).with_defaults()
    fb = Basis(m, ElementVector(ElementQuad1()))
    K = asm(linear_elasticity(LAM, MU), fb)
    f = asm(gravity, fb)
    D = fb.get_dofs("left").all()
    x = np.zeros(fb.N)
    x[D] = 1e-3
    expected = skfem_solve(*condense(K, f, x=x, D=D))
    np.testing.assert_allclose(solve(K, f, fb, D=D, x=x), expected, atol=1e-14)


def test_wrong_number_of_values(model):
    b, K, f = model
    with pytest.raises(ValueError, match="one value per constrained dof"):
        solve(K, f, b, D=b.get_dofs("left"), x=np.zeros(3))


@pytest.mark.parametrize("kind, method", [("fem", "nodal"), ("fem", "weak"), ("rk", "weak")])
def test_skew_conditions_compress_a_rotated_block_homogeneously(kind, method):
    """A unit block turned by 30°, held by ``n·u = 0`` on two faces whose
    normals ``n`` are not axis-aligned and pressed by ``n·u = -δ`` on a
    third: the plane-strain compression of the unturned block, turned
    (Hencky elastic closed form); its stress in the turned frame is uniaxial
    to round-off (1e-9 of the axial stress).  Nodal conditions on an RK
    basis cannot carry the uniform reaction traction exactly (their
    reactions are Σ_K Ψ_I(X_K) λ_K), as for axis-aligned components."""
    from skfem_rkpm.mechanics.materials import J2Material
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import rectangle
    from skfem_rkpm.solvers.newton import Prescribed, newton_steps

    E, nu, delta = 200e3, 0.3, 0.02
    a = np.radians(30.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    mesh = rectangle(1.0, 1.0, 4, 4)
    mesh = type(mesh)(R @ mesh.p, mesh.t, _boundaries=mesh.boundaries)
    basis = (RKBasis(mesh, vector=True, support=2.0) if kind == "rk"
             else Basis(mesh, ElementVector(ElementQuad1()), intorder=2))
    problem = SolidProblem(basis, J2Material(E, nu, None), "plane_strain")
    ex, ey = R[:, 0], R[:, 1]
    conditions = [Prescribed("left", ex, method=method), Prescribed("bottom", ey, method=method),
                  Prescribed("top", ey, -delta, method=method)]
    result = newton_steps(problem, conditions, steps=2, tol=1e-12)
    assert result.completed, result.message
    lam, G = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    eyy = np.log(1.0 - delta)
    exx = -lam * eyy / (lam + 2 * G)
    sigma = (lam * (exx + eyy) + 2 * G * eyy) / np.exp(exx + eyy)
    stress = problem.cauchy_stress(problem.evaluate(result.d, tangent=False))[:, :2, :2]
    turned = np.einsum("ia,nij,jb->nab", R, stress, R)
    np.testing.assert_allclose(turned[:, 1, 1], sigma, rtol=1e-9)
    np.testing.assert_allclose(turned[:, 0, 0], 0.0, atol=1e-9 * abs(sigma))
    np.testing.assert_allclose(turned[:, 0, 1], 0.0, atol=1e-9 * abs(sigma))
