"""RK bases on 3D background meshes (hexahedra and tetrahedra)."""

import numpy as np
import pytest
from skfem import LinearForm, MeshHex, MeshTet, asm
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent, solve


def perturbed_cube(mesh_type, n=5, amplitude=0.2, seed=0):
    t = np.linspace(0.0, 1.0, n + 1)
    m = mesh_type.init_tensor(t, t, t)
    rng = np.random.default_rng(seed)
    p = m.p.copy()
    inner = ~np.isin(np.arange(m.nvertices), m.boundary_nodes())
    p[:, inner] += amplitude / n * rng.uniform(-1, 1, (3, inner.sum()))
    return mesh_type(p, m.t)


@pytest.mark.parametrize("mesh_type", [MeshHex, MeshTet])
def test_laplace_patch_3d(mesh_type):
    """Linear potential with its exact flux on the boundary, one value fixed."""
    m = perturbed_cube(mesh_type)
    grad = np.array([0.3, -0.7, 0.2])
    b = RKBasis(m, support=2.0, intorder=2)
    K = Assembler(b).bilinear(np.eye(3)[None, :, None, :])

    @LinearForm
    def flux(v, w):
        return np.einsum("i,i...->...", grad, w.n) * v

    f = asm(flux, b.boundary())
    exact = grad @ b.nodes + 1.0
    d = solve(K, f, b, D=[0], x=exact[0])
    np.testing.assert_allclose(d, exact, atol=1e-12)
    gauss = RKBasis(m, support=2.0, intorder=2, integration="gauss")
    K = Assembler(gauss).bilinear(np.eye(3)[None, :, None, :])
    d = solve(K, asm(flux, gauss.boundary()), gauss, D=[0], x=exact[0])
    assert np.abs(d - exact).max() > 1e-5


def test_vector_basis_3d_with_skfem_forms():
    m = perturbed_cube(MeshHex, n=3)
    b = RKBasis(m, vector=True, support=2.0, intorder=2)
    lam, mu = lame_parameters(1.0, 0.3)
    K = asm(linear_elasticity(lam, mu), b.trial, b)
    K2 = Assembler(b).bilinear(isotropic_tangent(lam, mu, 3))
    assert abs(K - K2).max() < 1e-12 * abs(K).max()
    # a linear displacement field is reproduced with its exact gradient
    A = np.array([[0.1, 0.2, 0.0], [0.0, -0.1, 0.3], [0.2, 0.0, 0.05]])
    d = (A @ b.nodes).T.ravel()
    u = b.interpolate(d)
    np.testing.assert_allclose(u.grad, np.broadcast_to(A[:, :, None, None], u.grad.shape),
                               atol=1e-12)
    assert asm(LinearForm(lambda v, w: dot(np.ones(3)[:, None, None] + 0 * w.x, v)),
               b).sum() == pytest.approx(3.0)
