"""The mass of a solid (Eq. 3.38's M̂) and the stable step of central
differences, against closed forms: the total mass of the body, the exact
acceleration of a uniform load, the spectrum of a free-free bar."""

import numpy as np
import pytest
from skfem import (Basis, ElementHex1, ElementLineP1, ElementQuad1, ElementVector,
                   MeshHex, MeshLine, MeshQuad)
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.mechanics.mass import (consistent_mass, critical_time_step,
                                       dilatational_wave_speed, gershgorin_time_step,
                                       largest_eigenvalue, lumped_mass, nodal_lumped_mass,
                                       nodal_mass_matrix)
from skfem_rkpm.mechanics.materials import J2Material

EPS = np.finfo(float).eps
LAM, MU = lame_parameters(1.0, 0.3)


def square(n):
    t = np.linspace(0.0, 1.0, n + 1)
    return MeshQuad.init_tensor(t, t).with_defaults()


def bases(mesh, dim):
    element = ElementQuad1() if dim == 2 else ElementHex1()
    return {"fem": Basis(mesh, ElementVector(element), intorder=2),
            "rk": RKBasis(mesh, vector=True, support=2.0, integration="gauss")}


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", ["fem", "rk"])
def test_every_mass_carries_the_mass_of_the_body(dim, method):
    """1ᵀ M e_c = ρ V for each component c (the functions sum to one): the
    consistent mass, the generalized row sums and the nodal row sums."""
    mesh = square(4) if dim == 2 else MeshHex.init_tensor(*[np.linspace(0, 1, 4)] * 3)
    mesh = mesh.scaled([2.0] + [1.0] * (dim - 1))  # volume 2
    basis = bases(mesh, dim)[method]
    A, rho = Assembler(basis), 7.5
    M = consistent_mass(A, rho)
    m = lumped_mass(A, rho)
    m_hat = nodal_lumped_mass(basis, A, rho)
    # sums of N ~ 1e2-1e3 terms of one sign (Ψ ≥ 0 on most of the body): a few
    # hundred ulps of ρV; a missing cell or component would be off by ≥ 1/64
    tol = 1e3 * EPS * rho * 2.0
    for c in range(dim):
        e = np.zeros(basis.N)
        e[c::dim] = 1.0
        assert abs(e @ M @ e - 2.0 * rho) < tol
        assert abs(m[c::dim].sum() - 2.0 * rho) < tol
        assert abs(m_hat[c::dim].sum() - 2.0 * rho) < tol
    # the generalized row sums are M's: Σ_J Ψ_J = 1 at every point
    np.testing.assert_allclose(m, M @ np.ones(basis.N), rtol=0, atol=1e3 * EPS * m.max())


def test_axisymmetric_mass_is_that_of_the_full_ring():
    """With the 2πR measure the mass of a ring section r ∈ [1, 2], z ∈ [0, 1]
    is ρ π (2² − 1²)."""
    mesh = square(4).translated([1.0, 0.0])
    basis = RKBasis(mesh, vector=True, axisymmetric=True, integration="gauss")
    A = Assembler(basis, axisymmetric=True)
    m = lumped_mass(A, 2.0)
    assert m[0::2].sum() == pytest.approx(2.0 * np.pi * 3.0, rel=1e3 * EPS)


def test_uniform_load_gives_uniform_acceleration_with_either_mass():
    """A body force ρ g gives the acceleration g everywhere: exactly with the
    consistent mass (M a = f for the coefficients a = g, since Σ_J Ψ_J = 1)
    and with the generalized row sums (m_I a_I = g ∫ ρ Ψ_I)."""
    basis = RKBasis(square(6), vector=True, support=2.5, integration="gauss")
    A, rho, g = Assembler(basis), 3.0, np.array([0.0, -9.81])
    m = lumped_mass(A, rho)
    f = m * np.tile(g, basis.nnodes)  # ∫ ρ g Ψ_I: the load vector of ρ g
    M = consistent_mass(A, rho)
    from scipy.sparse.linalg import spsolve
    a = spsolve(M.tocsc(), f)
    # the consistent mass of a support-2.5 basis has cond ~ 1e3-1e4
    np.testing.assert_allclose(a, np.tile(g, basis.nnodes), atol=1e-9 * 9.81)
    np.testing.assert_allclose(f / m, np.tile(g, basis.nnodes), atol=10 * EPS * 9.81)


def test_free_free_bar_has_the_step_h_over_c():
    """Linear elements with lumped mass on a free-free bar of n elements:
    ω²_k = (4 c²/h²) sin²(kπ/2n), k = 0..n, so ω_max = 2c/h and the stable
    step is h/c exactly; Gershgorin's bound is sharp there too."""
    n, E, rho = 25, 210e3, 7.85e-9
    mesh = MeshLine(np.linspace(0.0, 2.0, n + 1))
    A = Assembler(Basis(mesh, ElementLineP1()))
    K = A.bilinear(np.full((1, 1, 1, 1), E))
    m = lumped_mass(A, rho)
    h, c = 2.0 / n, np.sqrt(E / rho)
    assert critical_time_step(K, m) == pytest.approx(h / c, rel=1e-10)
    assert gershgorin_time_step(K, m) == pytest.approx(h / c, rel=1e-10)
    # the consistent mass of the bar: ω_max = 2√3 c/h (the step shrinks by √3)
    ratio = critical_time_step(K, consistent_mass(A, rho)) / (h / c)
    assert ratio == pytest.approx(1.0 / np.sqrt(3.0), rel=1e-2)


@pytest.mark.parametrize("support", [1.5, 2.0, 3.0])
def test_gershgorin_step_is_safe_and_rk_steps_grow_with_support(support):
    """The Gershgorin step never exceeds the exact one; an RK basis with the
    generalized row-sum mass is stable at steps above FEM Q1's on the same
    spacing, more so with a larger support (smoother functions)."""
    mesh = square(8)
    cd = np.sqrt(LAM + 2 * MU)  # ρ = 1
    fem = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    A = Assembler(fem)
    K, m = A.bilinear(isotropic_tangent(LAM, MU, 2)), lumped_mass(A, 1.0)
    fem_step = critical_time_step(K, m)
    assert gershgorin_time_step(K, m) <= fem_step
    rk = RKBasis(mesh, vector=True, support=support, integration="gauss")
    A = Assembler(rk)
    K, m = A.bilinear(isotropic_tangent(LAM, MU, 2)), lumped_mass(A, 1.0)
    step = critical_time_step(K, m)
    assert gershgorin_time_step(K, m) <= step
    # measured 1.09, 1.31 and 1.79 h/c_d at supports 1.5, 2 and 3 (FEM: 0.99)
    assert step > fem_step * (1.0 + (support - 1.0) / 10.0)
    assert step * cd * 8 < 2.0  # and below twice the spacing over c_d


def test_nodal_lumping_implies_the_mass_lambda_diag_lambda_t():
    """The kinetic energy of nodal velocities with the nodal lumped mass is
    that of the coefficients with Λ diag(m̂) Λᵀ; it has the body's mass."""
    basis = RKBasis(square(5), vector=True, support=2.0, integration="gauss")
    A = Assembler(basis)
    m_hat = nodal_lumped_mass(basis, A, 1.0)
    Mn = nodal_mass_matrix(basis, m_hat)
    v = np.random.default_rng(1).normal(size=basis.N)
    v_hat = basis.nodal_values(v)
    assert v @ Mn @ v == pytest.approx(v_hat @ (m_hat * v_hat), rel=1e3 * EPS)
    translation = np.tile([1.0, 0.0], basis.nnodes)
    assert translation @ Mn @ translation == pytest.approx(1.0, rel=1e3 * EPS)


def test_bad_masses_and_densities_are_refused():
    A = Assembler(Basis(square(2), ElementVector(ElementQuad1())))
    with pytest.raises(ValueError, match="point 0 of cell 0"):
        lumped_mass(A, np.nan)
    K = A.bilinear(isotropic_tangent(LAM, MU, 2))
    m = lumped_mass(A, 1.0)
    m[3] = -1.0
    with pytest.raises(ValueError, match="dof 3"):
        largest_eigenvalue(K, m)
    with pytest.raises(ValueError, match="density"):
        dilatational_wave_speed(J2Material(1.0, 0.3), 0.0)


def test_wave_speed_is_that_of_lambda_plus_two_mu():
    material = J2Material(117e3, 0.35)
    lam, mu = lame_parameters(117e3, 0.35)
    assert dilatational_wave_speed(material, 8.93e-9) == pytest.approx(
        np.sqrt((lam + 2 * mu) / 8.93e-9), rel=1e-14)
