"""The consistent tangent of the J2 material as ``Z (Ŝ - T) Zᵀ`` against the
outer-product form it replaced, formed here independently:

    A = X Yᵀ - P_iL F⁻¹_Jk,   X = [Z_AA D, Z_AB + Z_BA],
                              Y = [Z_AA, g_AB Z_AB + g_BA Z_BA],

with ``Z_(iJ),(AB) = Q_iA (F⁻¹ Q)_JB``.  Both are sums of at most 81
products of entries of size ``|F⁻¹|² max(|D|, |g|, |τ|)``, so they agree
to ``C = 64`` units of round-off of that size; a wrong sign or a misplaced
entry of ``T`` (the geometric term) changes ``A`` by ``|τ| |F⁻¹|²``,
1e-3 of that size here and 1e13 units."""

import numpy as np
import pytest

from skfem_rkpm.mechanics.materials import J2Material, MaterialState, linear

EPS = np.finfo(float).eps
C = 64.0
PAIR_A, PAIR_B = np.array([0, 0, 1]), np.array([1, 2, 2])


def _outer_product_tangent(material, point, rows, cols):
    """``A`` at the entries (rows, cols) by the outer-product form."""
    D, g = _principal_parts(material, point)
    vec, Finv, P = point.vec, point.Finv, point.P
    W = Finv @ vec
    a, b = PAIR_A, PAIR_B
    Q, WJ = vec[:, rows], W[:, cols]
    Zd, Zab, Zba = Q * WJ, Q[:, :, a] * WJ[:, :, b], Q[:, :, b] * WJ[:, :, a]
    X = np.concatenate([Zd @ D, Zab + Zba], axis=2)
    Y = np.concatenate([Zd, g[:, None, a, b] * Zab + g[:, None, b, a] * Zba], axis=2)
    # P_iL F⁻¹_Jk at (iJ, kL)
    geometric = P[:, rows[:, None], cols[None, :]] * Finv[:, cols[:, None], rows[None, :]]
    return X @ Y.transpose(0, 2, 1) - geometric, geometric, (D, g)


def _principal_parts(material, point):
    dev = point.eps_trial - point.eps_trial.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(dev, axis=1)
    direction = np.where(norm[:, None] > 0, dev / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
    return material._principal_tangent(point.lam, direction, point.dgamma,
                                       point.q_trial, point.H)


def _deformations(rng, n, planar):
    F = np.eye(3) + 0.2 * rng.standard_normal((n, 3, 3))
    if planar:  # no coupling of the third axis
        F[:, :2, 2] = F[:, 2, :2] = 0.0
    F[0] = np.eye(3)  # three equal eigenvalues, elastic
    F[1] = np.diag([1.1, 1.1, 0.9])  # a repeated pair
    F[2] = np.diag([1.0, 1.0, 1.0 + 1e-4])  # elastic, nearly repeated
    return F * np.sign(np.linalg.det(F))[:, None, None] ** (1 / 3)


@pytest.mark.parametrize("entries", ["3d", "axisymmetric", "plane_strain"])
def test_tangent_equals_the_outer_product_form(entries):
    rng = np.random.default_rng(7)
    material = J2Material(200e3, 0.3, linear(250.0, 1e3))
    F = _deformations(rng, 300, planar=entries != "3d")
    state = MaterialState.virgin(len(F))
    _, _, new, point = material.stress(F, state)
    plastic = new.alpha > state.alpha
    assert 0 < plastic.sum() < len(F)  # both branches are checked
    listed = {"3d": [(i, J) for i in range(3) for J in range(3)],
              "axisymmetric": [(0, 0), (0, 1), (1, 0), (1, 1), (2, 2)],
              "plane_strain": [(0, 0), (0, 1), (1, 0), (1, 1)]}[entries]
    rows, cols = np.array(listed).T
    A = material.tangent(point, listed)
    reference, geometric, (D, g) = _outer_product_tangent(material, point, rows, cols)
    tau = np.abs(point.tau_p).max(axis=1)
    size = (np.abs(point.Finv).max(axis=(1, 2)) ** 2
            * np.maximum(np.abs(D).max(axis=(1, 2)),
                         np.maximum(np.abs(g).max(axis=(1, 2)), tau)))
    error = np.abs(A - reference).max(axis=(1, 2))
    assert np.all(error <= C * EPS * size)
    # a misplaced geometric term would show: it is far above the bound
    assert np.all(np.abs(geometric).max(axis=(1, 2))[plastic] > 1e6 * C * EPS * size[plastic])
    if entries == "3d":  # the full (n, 3, 3, 3, 3) form is the same array
        full = material.tangent(point)
        assert np.array_equal(full.reshape(len(F), 9, 9), A)
