"""The closed-form symmetric 3x3 eigen-decomposition against LAPACK's ``eigh``,
and the 3D J2 return map built on it against the same map built on ``eigh``.

Bounds: both decompositions are backward stable, so by Weyl's theorem their
eigenvalues differ by at most a few ``ε ‖b‖`` whatever the gaps, and an
isotropic function ``Σ f(λ_A) n_A ⊗ n_A`` with Lipschitz ``f`` differs by
a few ``ε ‖b‖`` times its Lipschitz constant, also where eigenvalues are
repeated (the choice of vectors within a repeated pair does not enter).
``C = 64`` such units are allowed; a wrong vector or a mixed-up pairing of
values and vectors gives errors of the size of the eigenvalue gaps
(1e-2 here)."""

import numpy as np
import pytest

from skfem_rkpm.mechanics import materials
from skfem_rkpm.mechanics.eigen3 import symmetric_eigen
from skfem_rkpm.mechanics.materials import J2Material, MaterialState, linear

EPS = np.finfo(float).eps
C = 64.0


def _rotations(rng, n):
    q, r = np.linalg.qr(rng.standard_normal((n, 3, 3)))
    return q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]


def _matrices(rng, lam):
    Q = _rotations(rng, len(lam))
    b = (Q * lam[:, None, :]) @ Q.transpose(0, 2, 1)
    return 0.5 * (b + b.transpose(0, 2, 1))


def _spectra(rng, n=400):
    """Eigenvalues: distinct, a repeated pair (upper and lower), nearly
    repeated at 1e-9 and 1e-15, three equal and nearly equal."""
    u = rng.uniform(0.5, 1.0, (n, 1))
    return {
        "distinct": np.exp(rng.uniform(-0.3, 0.3, (n, 3))),
        "pair above": 1.0 + np.hstack([0 * u, 0 * u, 0.05 * u]),
        "pair below": 1.0 + np.hstack([0 * u, -0.05 * u, -0.05 * u]),
        "near 1e-9": 1.0 + np.hstack([0 * u, 1e-9 * u, 0.05 * u]),
        "near 1e-15": 1.0 + np.hstack([0 * u, 1e-15 + 0 * u, -0.05 * u]),
        "triple": np.ones((n, 3)) * 1.3,
        "near triple": 1.0 + rng.uniform(-1e-13, 1e-13, (n, 3)),
    }


@pytest.mark.parametrize("case", list(_spectra(np.random.default_rng(0))))
def test_decomposition_equals_lapack(case):
    rng = np.random.default_rng(1)
    lam_exact = _spectra(rng)[case]
    b = _matrices(rng, lam_exact)
    lam, vec = symmetric_eigen(b)
    L, V = np.linalg.eigh(b)
    scale = np.abs(L).max(axis=1)
    unit = C * EPS * scale
    # orthonormal vectors, eigenpairs, the same spectrum as LAPACK's
    assert np.all(np.abs(vec.transpose(0, 2, 1) @ vec - np.eye(3)).max(axis=(1, 2)) <= C * EPS)
    residual = np.linalg.norm(b @ vec - vec * lam[:, None, :], axis=1).max(axis=1)
    assert np.all(residual <= unit)
    assert np.all(np.abs(np.sort(lam, axis=1) - L).max(axis=1) <= unit)
    # isotropic functions: b itself, ln b (Lipschitz 1/λ_min) and exp(2 ln b / 2)

    def iso(f, lam, vec):
        return (vec * f(lam)[:, None, :]) @ vec.transpose(0, 2, 1)

    for f, lipschitz in ((lambda x: x, 1.0), (np.log, 1.0 / L.min(axis=1)),
                         (np.sqrt, 0.5 / np.sqrt(L.min(axis=1)))):
        diff = np.abs(iso(f, lam, vec) - iso(f, L, V)).max(axis=(1, 2))
        assert np.all(diff <= lipschitz * unit), (case, diff.max() / unit.max())


def test_identity_and_diagonal_matrices_exact():
    """``b = c I`` and diagonal ``b``: the eigenvalues are the diagonal."""
    b = np.zeros((3, 3, 3))
    b[0] = 2.0 * np.eye(3)
    b[1] = np.diag([1.0, 3.0, 3.0])
    b[2] = np.diag([0.5, 0.7, 0.9])
    lam, vec = symmetric_eigen(b)
    assert np.allclose(np.sort(lam, axis=1), np.sort(np.diagonal(b, axis1=1, axis2=2)),
                       rtol=0, atol=4 * EPS * 3)
    assert np.allclose(vec.transpose(0, 2, 1) @ vec, np.eye(3), rtol=0, atol=4 * EPS)


def _deformations(rng, n=300):
    """3D deformation gradients of a plastic step: random stretches and
    rotations, uniaxial ones (a repeated pair of b), and the identity."""
    F = np.empty((3 * n, 3, 3))
    stretch = np.exp(rng.uniform(-0.05, 0.05, (n, 3)))
    F[:n] = _rotations(rng, n) @ (stretch[:, :, None] * _rotations(rng, n))
    s = np.exp(rng.uniform(-0.05, 0.05, n))
    uni = np.zeros((n, 3, 3))
    uni[:, 0, 0], uni[:, 1, 1], uni[:, 2, 2] = s, s ** -0.5, s ** -0.5
    Q = _rotations(rng, n)
    F[n:2 * n] = Q @ uni @ Q.transpose(0, 2, 1)
    F[2 * n:] = np.eye(3)
    return F


def test_return_map_equals_lapack_path(monkeypatch):
    """Stress, state and consistent tangent of the 3D J2 model: the closed-form
    decomposition against ``eigh``, from a virgin and from a plastically
    deformed state.  ``C ε E`` is allowed for the stresses, ``C ε`` for
    ``C_p⁻¹`` and ``ε̄ᵖ``.  The plastic tangent holds ``2G θ̄ ν ⊗ ν`` with the
    flow direction ``ν = e/|e|`` of the deviatoric elastic strain ``e``, whose
    round-off is ``ε/|e|``; on the plastic branch ``|e| ≥ e_y = √(2/3) σ_y / 2G``,
    so the tangent is allowed ``C ε E (1 + 1/e_y)``."""
    rng = np.random.default_rng(2)
    material = J2Material(200e3, 0.3, linear(250.0, 1e3))
    F = _deformations(rng)
    plastic = MaterialState.virgin(len(F))
    P0, _, plastic, _ = material.update(_deformations(np.random.default_rng(3)), plastic,
                                        tangent=False)
    for state in (MaterialState.virgin(len(F)), plastic):
        P, tau, new, A = material.update(F, state)
        with monkeypatch.context() as patch:
            patch.setattr(materials, "symmetric_eigen", np.linalg.eigh)
            P_ref, tau_ref, new_ref, A_ref = material.update(F, state)
        assert np.any(new.alpha > state.alpha)  # some points on the plastic branch
        unit = C * EPS * material.E
        assert np.abs(P - P_ref).max() <= unit
        assert np.abs(tau - tau_ref).max() <= unit
        e_y = np.sqrt(2.0 / 3.0) * 250.0 / (2.0 * material.G)
        assert np.abs(A - A_ref).max() <= unit * (1.0 + 1.0 / e_y)
        assert np.abs(new.Cp_inv - new_ref.Cp_inv).max() <= C * EPS
        assert np.abs(new.alpha - new_ref.alpha).max() <= C * EPS


def test_full_tangent_equals_the_tangent_at_listed_entries():
    """The nine entries in row-major order take a broadcast path; listed in
    another order they take the general one: the same sums, to round-off."""
    rng = np.random.default_rng(4)
    material = J2Material(200e3, 0.3, linear(250.0, 1e3))
    F = _deformations(rng, 50)
    _, _, _, point = material.stress(F, MaterialState.virgin(len(F)))
    order = [(i, J) for J in range(3) for i in range(3)]  # column-major
    full = material.tangent(point)  # (n, 3, 3, 3, 3)
    listed = material.tangent(point, order)
    rows, cols = np.array(order).T
    again = full[:, rows, cols][:, :, rows, cols]
    assert np.abs(listed - again).max() <= C * EPS * np.abs(full).max()
    assert np.abs(full).max() > 1e4
