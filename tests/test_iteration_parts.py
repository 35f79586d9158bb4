"""The parts of a Newton iteration agree with their plain definitions."""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector

from skfem_rkpm import RKBasis, assembly
from skfem_rkpm.assembly import Assembler
from skfem_rkpm.mechanics.kinematics import entries, from_entries, to_assembler
from skfem_rkpm.mechanics.materials import J2Material, MaterialState, perfect
from skfem_rkpm.meshes import rectangle

E, NU = 200e3, 0.3


def reference_tangent(mat, F, state):
    """``A = ½ (D:L:B) F⁻¹ F⁻¹ - τ F⁻¹ F⁻¹`` with the 4th-order tensors formed."""
    I3 = np.eye(3)
    I_sym = 0.5 * (np.einsum("ik,jl->ijkl", I3, I3) + np.einsum("il,jk->ijkl", I3, I3))
    one_one = np.einsum("ij,kl->ijkl", I3, I3)
    I_dev = I_sym - one_one / 3
    G, K = mat.G, mat.K
    Finv = np.linalg.inv(F)
    b = F @ state.Cp_inv @ F.transpose(0, 2, 1)
    lam, vec = np.linalg.eigh(0.5 * (b + b.transpose(0, 2, 1)))
    eps = 0.5 * np.log(lam)
    _, _, _, dgamma, q_trial, H = mat.return_map(eps, state.alpha)
    dev = eps - eps.mean(axis=1, keepdims=True)
    N = np.einsum("niA,nA,njA->nij", vec, dev / np.linalg.norm(dev, axis=1)[:, None], vec)
    theta1 = np.where(dgamma > 0, 1 - 3 * G * dgamma / q_trial, 1.0)
    theta_bar = np.where(dgamma > 0, 3 * G / (3 * G + H) - (1 - theta1), 0.0)
    D = (K * one_one + 2 * G * theta1[:, None, None, None, None] * I_dev
         - 2 * G * theta_bar[:, None, None, None, None] * np.einsum("nij,nkl->nijkl", N, N))
    la, lb = lam[:, :, None], lam[:, None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.where(np.abs(la - lb) > 1e-12 * lb, (np.log(la) - np.log(lb)) / (la - lb),
                         1 / lb)
    outer = np.einsum("niA,njB->nijAB", vec, vec)
    L = np.einsum("nAB,nijAB,nklAB->nijkl", theta, outer, outer)
    L = 0.5 * (L + L.transpose(0, 1, 2, 4, 3))
    B = np.einsum("ik,njl->nijkl", I3, b) + np.einsum("jk,nil->nijkl", I3, b)
    DLB = np.einsum("nijab,nabcd,ncdkl->nijkl", D, L, B)
    tau = mat.update(F, state, tangent=False)[1]
    return (0.5 * np.einsum("nijkl,nJj,nLl->niJkL", DLB, Finv, Finv)
            - np.einsum("nil,nJk,nLl->niJkL", tau, Finv, Finv))


@pytest.mark.parametrize("plastic", [False, True])
def test_principal_frame_tangent_equals_the_tensor_products(plastic):
    rng = np.random.default_rng(3)
    n = 12
    F = np.eye(3) + (0.2 if plastic else 1e-4) * rng.normal(size=(n, 3, 3))
    mat = J2Material(E, NU, perfect(300.0))
    state = MaterialState.virgin(n)
    A = mat.update(F, state)[3]
    assert (mat.update(F, state)[2].alpha > 0).any() == plastic
    ref = reference_tangent(mat, F, state)
    assert np.abs(A - ref).max() < 1e-12 * np.abs(ref).max()


@pytest.mark.parametrize("model", ["plane_strain", "axisymmetric", "3d"])
def test_tangent_at_entries_is_the_block_of_the_full_tangent(model):
    rng = np.random.default_rng(4)
    F = np.eye(3) + 0.1 * rng.normal(size=(6, 3, 3))
    mat = J2Material(E, NU, perfect(300.0))
    chosen = [e for _, e in entries(model)]
    full = mat.update(F, MaterialState.virgin(6))[3]
    part = mat.update(F, MaterialState.virgin(6), entries=chosen)[3]
    i, J = np.array(chosen).T
    np.testing.assert_array_equal(part.shape, (6, len(chosen), len(chosen)))
    expected = full[:, i[:, None], J[:, None], i[None, :], J[None, :]]
    assert np.abs(part - expected).max() < 1e-13 * np.abs(full).max()


@pytest.mark.parametrize("model", ["plane_strain", "axisymmetric", "3d"])
def test_from_entries_equals_to_assembler(model):
    rng = np.random.default_rng(5)
    shape = (4, 3)
    n = 12
    P, A = rng.normal(size=(n, 3, 3)), rng.normal(size=(n, 3, 3, 3, 3))
    i, J = np.array([e for _, e in entries(model)]).T
    P_ext, A_ext = from_entries(P[:, i, J], A[:, i[:, None], J[:, None], i, J], model, shape)
    P_ref, A_ref = to_assembler(P, A, model, shape)
    np.testing.assert_array_equal(P_ext, P_ref)
    np.testing.assert_array_equal(A_ext, A_ref)


@pytest.fixture(params=["rk", "fem"])
def basis(request):
    mesh = rectangle(2.0, 1.0, 5, 3)
    if request.param == "rk":
        return RKBasis(mesh, vector=True, support=2.0)
    return Basis(mesh, ElementVector(ElementQuad1()), intorder=3)


@pytest.mark.parametrize("cache", [True, False])
def test_local_tangent_with_rank_one_blocks_equals_the_sum_of_matrices(basis, cache,
                                                                       monkeypatch):
    if not cache:
        monkeypatch.setattr(assembly, "CACHE_ENTRIES", 0)
    asm = Assembler(basis)
    L = asm.layout
    rng = np.random.default_rng(6)
    C = rng.normal(size=(2, 2, 2, 2) + L.dx.shape)
    u, w = rng.normal(size=(2, *asm.element_dofs.shape))
    expected = (asm.bilinear(C) + asm.outer(u, w)).toarray()
    buffer = asm.local_bilinear(np.zeros_like(C))
    local = asm.local_bilinear(C, out=buffer)
    assert local is buffer
    got = asm.matrix(asm.add_outer(local, u, w)).toarray()
    assert np.abs(got - expected).max() < 1e-13 * np.abs(expected).max()
    assert bool(asm._cache) == cache


@pytest.mark.parametrize("cache", [True, False])
def test_rank_one_blocks_inside_the_local_product_equal_the_sum_of_matrices(
        basis, cache, monkeypatch):
    """``local_bilinear(C, rank_one=(u, w))`` folds the blocks ``u_e ⊗ w_e``
    into its batched product; the result is the sum of the two matrices
    assembled separately, to round-off (a few summation orders of products
    of O(1) random numbers: 1e-13 of the largest entry), also on the second
    call, which reuses the kept buffer of the test gradients with ``u``."""
    if not cache:
        monkeypatch.setattr(assembly, "CACHE_ENTRIES", 0)
    asm = Assembler(basis, axisymmetric=True)
    L = asm.layout
    rng = np.random.default_rng(7)
    for _ in range(2):
        C = rng.normal(size=(2, 3, 2, 3) + L.dx.shape)
        u, w = rng.normal(size=(2, *asm.element_dofs.shape))
        expected = (asm.bilinear(C) + asm.outer(u, w)).toarray()
        got = asm.matrix(asm.local_bilinear(C, rank_one=(u, w))).toarray()
        assert np.abs(got - expected).max() < 1e-13 * np.abs(expected).max()
    assert ("test with rank one" in asm._cache) == cache


def test_inverse_and_determinant_by_cofactors_equal_lapack():
    """Cofactor inverse and determinant against ``np.linalg`` on deformation
    gradients near the identity (det F in [0.5, 2]): both are backward
    stable there, so they agree to a few ulps (1e-14 relative)."""
    from skfem_rkpm.mechanics.kinematics import inverse_and_determinant

    rng = np.random.default_rng(8)
    F = np.eye(3) + 0.2 * rng.uniform(-1, 1, size=(500, 3, 3))
    Finv, J = inverse_and_determinant(F)
    np.testing.assert_allclose(J, np.linalg.det(F), rtol=1e-14)
    assert np.abs(Finv - np.linalg.inv(F)).max() < 1e-14 * np.abs(Finv).max()
    assert np.abs(F @ Finv - np.eye(3)).max() < 1e-14


def test_closed_form_spectral_decomposition_of_planar_b_equals_eigh():
    """Plane ``b`` (no coupling with the third axis) is diagonalized in closed
    form: the eigenvalues equal LAPACK's (sorted; 1e-15 for entries of
    order 1), the eigenvectors are orthonormal and rebuild ``b``, also for
    equal in-plane eigenvalues (the isotropic point) and for ``b_33`` equal
    to one of them."""
    from skfem_rkpm.mechanics.materials import _spectral

    rng = np.random.default_rng(9)
    F = np.eye(3) + 0.3 * rng.uniform(-1, 1, size=(400, 3, 3))
    F[:, 2, :2] = F[:, :2, 2] = 0.0
    F[:3] = np.diag([1.1, 1.1, 0.9])  # equal in-plane eigenvalues
    F[3] = np.diag([1.0, 1.2, 1.0])  # b_33 equal to an in-plane one
    b = F @ F.transpose(0, 2, 1)
    lam, vec = _spectral(b)
    np.testing.assert_allclose(np.sort(lam, axis=1), np.linalg.eigvalsh(b), atol=1e-15,
                               rtol=1e-15)
    assert np.abs(vec @ vec.transpose(0, 2, 1) - np.eye(3)).max() < 1e-15
    assert np.abs((vec * lam[:, None, :]) @ vec.transpose(0, 2, 1) - b).max() < 1e-14
    coupled = b.copy()
    coupled[0, 0, 2] = coupled[0, 2, 0] = 0.1  # one coupled point: the 3D path for all
    lam, vec = _spectral(coupled)
    np.testing.assert_allclose(np.sort(lam, axis=1), np.linalg.eigvalsh(coupled),
                               atol=1e-14, rtol=0)
    assert np.abs((vec * lam[:, None, :]) @ vec.transpose(0, 2, 1) - coupled).max() < 1e-14
