"""Consistency of the closed-form elasticity solutions."""

import numpy as np
import pytest

from skfem_rkpm.verification import exact

# cantilever of the usual meshfree benchmark
L, D, P = 48.0, 12.0, 1000.0
E, NU = 3.0e7, 0.3
# plate with a hole
A, T, E_PLATE = 1.0, 10.0, 1.0e3


def elasticity_matrix(E, nu, plane):
    """Voigt matrix mapping (exx, eyy, gxy) to (sxx, syy, sxy)."""
    if plane == "stress":
        return E / (1 - nu**2) * np.array(
            [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]]
        )
    return E / ((1 + nu) * (1 - 2 * nu)) * np.array(
        [[1 - nu, nu, 0], [nu, 1 - nu, 0], [0, 0, (1 - 2 * nu) / 2]]
    )


def gradient(f, x, step):
    """Central differences: ``g[i, j] = d f_i / d x_j``, shape (n, 2, ...)."""
    columns = []
    for j in range(2):
        dx = np.zeros_like(x)
        dx[j] = step
        columns.append((f(x + dx) - f(x - dx)) / (2 * step))
    return np.stack(columns, axis=1)


def strain_stress(u, x, step, E, nu, plane):
    """Stress C : sym(grad u) computed by finite differences."""
    g = gradient(u, x, step)
    strain = np.stack((g[0, 0], g[1, 1], g[0, 1] + g[1, 0]))
    return np.einsum("ij,j...->i...", elasticity_matrix(E, nu, plane), strain)


def divergence(s, x, step):
    """Divergence of a Voigt stress field by finite differences."""
    g = gradient(s, x, step)
    return np.stack((g[0, 0] + g[2, 1], g[2, 0] + g[1, 1]))


def beam_points(n=200, seed=1):
    rng = np.random.default_rng(seed)
    return np.stack((rng.uniform(0, L, n), rng.uniform(-D / 2, D / 2, n)))


def plate_points(n=200, seed=2):
    rng = np.random.default_rng(seed)
    r = rng.uniform(1.1 * A, 6 * A, n)
    theta = rng.uniform(0, 2 * np.pi, n)
    return np.stack((r * np.cos(theta), r * np.sin(theta)))


def gauss_line(a, b, n=8):
    """Gauss-Legendre points and weights on [a, b]."""
    s, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * s + 0.5 * (a + b), 0.5 * (b - a) * w


# ---------------------------------------------------------------------------
# cantilever
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_timoshenko_stress_is_elastic_stress_of_displacement(plane):
    x = beam_points()
    fd = strain_stress(
        lambda y: exact.timoshenko_displacement(y, L, D, P, E, NU, plane),
        x, 1e-3, E, NU, plane,
    )
    s = exact.timoshenko_stress(x, L, D, P)
    scale = np.abs(s).max()
    np.testing.assert_allclose(fd, s, rtol=0, atol=1e-6 * scale)


def test_timoshenko_stress_is_in_equilibrium():
    x = beam_points()
    div = divergence(lambda y: exact.timoshenko_stress(y, L, D, P), x, 1e-3)
    scale = np.abs(exact.timoshenko_stress(x, L, D, P)).max() / D
    assert np.abs(div).max() < 1e-6 * scale


def test_timoshenko_boundary_tractions():
    y, w = gauss_line(-D / 2, D / 2)
    ones = np.ones_like(y)
    free = exact.timoshenko_stress(np.stack((L * ones, y)), L, D, P)
    clamp = exact.timoshenko_stress(np.stack((0 * ones, y)), L, D, P)
    # load at x = L (normal +x): zero axial force, zero moment, shear P
    assert np.isclose(w @ free[0], 0, atol=1e-9 * P)
    assert np.isclose(w @ (y * free[0]), 0, atol=1e-9 * P * D)
    assert np.isclose(w @ free[2], P, rtol=1e-12)
    # reaction at the clamp x = 0 (normal -x): shear -P and moment P L
    assert np.isclose(w @ -clamp[2], -P, rtol=1e-12)
    assert np.isclose(w @ (y * clamp[0]), -P * L, rtol=1e-12)
    # traction-free edges y = +-D/2 (normal +-y): sxy = syy = 0
    xs = np.linspace(0, L, 7)
    for edge in (-D / 2, D / 2):
        s = exact.timoshenko_stress(np.stack((xs, edge + 0 * xs)), L, D, P)
        np.testing.assert_allclose(s[1:], 0, atol=1e-9 * P / D)


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_timoshenko_clamp_and_tip_deflection(plane):
    u = exact.timoshenko_displacement(
        np.array([[0, 0, 0, L], [0, -D / 2, D / 2, 0]]), L, D, P, E, NU, plane
    )
    np.testing.assert_allclose(u[:, 0], 0, atol=1e-15)
    np.testing.assert_allclose(u[0, 1:3], 0, atol=1e-15)
    Ee, nue = (E, NU) if plane == "stress" else (E / (1 - NU**2), NU / (1 - NU))
    inertia = D**3 / 12
    bending = P * L**3 / (3 * Ee * inertia)
    shear = (4 + 5 * nue) * P * D**2 * L / (24 * Ee * inertia)
    assert u[1, 3] > 0
    assert np.isclose(u[1, 3], bending + shear, rtol=1e-12)


def test_timoshenko_tip_deflection_of_the_standard_benchmark():
    # the value usually quoted for L=48, D=12, P=1000, E=3e7, nu=0.3
    tip = exact.timoshenko_displacement(np.array([[L], [0.0]]), L, D, P, E, NU)
    assert np.isclose(tip[1, 0], 0.0089, rtol=1e-12)


# ---------------------------------------------------------------------------
# plate with a hole
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_kirsch_stress_is_elastic_stress_of_displacement(plane):
    x = plate_points()
    fd = strain_stress(
        lambda y: exact.kirsch_displacement(y, A, T, E_PLATE, NU, plane),
        x, 1e-5, E_PLATE, NU, plane,
    )
    s = exact.kirsch_stress(x, A, T)
    np.testing.assert_allclose(fd, s, rtol=0, atol=1e-6 * 3 * T)


def test_kirsch_stress_is_in_equilibrium():
    x = plate_points()
    div = divergence(lambda y: exact.kirsch_stress(y, A, T), x, 1e-5)
    assert np.abs(div).max() < 1e-6 * 3 * T / A


def test_kirsch_hole_is_traction_free_and_concentrates_stress():
    theta = np.linspace(0, 2 * np.pi, 73)
    n = np.stack((np.cos(theta), np.sin(theta)))
    sxx, syy, sxy = exact.kirsch_stress(A * n, A, T)
    traction = np.stack((sxx * n[0] + sxy * n[1], sxy * n[0] + syy * n[1]))
    np.testing.assert_allclose(traction, 0, atol=1e-12 * T)
    top, side = exact.kirsch_stress(np.array([[0, A], [A, 0]]), A, T).T
    np.testing.assert_allclose(top, [3 * T, 0, 0], atol=1e-12 * T)
    np.testing.assert_allclose(side, [0, -T, 0], atol=1e-12 * T)


def test_kirsch_far_field_is_remote_tension():
    theta = np.linspace(0, 2 * np.pi, 13)
    far = 1e4 * A * np.stack((np.cos(theta), np.sin(theta)))
    s = exact.kirsch_stress(far, A, T)
    np.testing.assert_allclose(s, [[T], [0], [0]] * np.ones_like(theta), atol=1e-7 * T)


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_kirsch_displacement_symmetry(plane):
    r = np.linspace(A, 5 * A, 9)
    on_x = exact.kirsch_displacement(np.stack((r, 0 * r)), A, T, E_PLATE, NU, plane)
    on_y = exact.kirsch_displacement(np.stack((0 * r, r)), A, T, E_PLATE, NU, plane)
    np.testing.assert_allclose(on_x[1], 0, atol=1e-15)
    np.testing.assert_allclose(on_y[0], 0, atol=1e-15)
    assert np.all(on_x[0] > 0) and np.all(on_y[1] < 0)


# ---------------------------------------------------------------------------
# interface
# ---------------------------------------------------------------------------


def test_shapes_follow_the_coordinates():
    x = np.stack(np.meshgrid(np.linspace(1, 2, 3), np.linspace(1, 2, 4)))
    assert exact.timoshenko_displacement(x, L, D, P, E, NU).shape == (2, 4, 3)
    assert exact.timoshenko_stress(x, L, D, P).shape == (3, 4, 3)
    assert exact.kirsch_displacement(x, A, T, E, NU).shape == (2, 4, 3)
    assert exact.kirsch_stress(x, A, T).shape == (3, 4, 3)


def test_plane_strain_constants_and_bad_plane():
    assert exact.effective_constants(E, NU, "stress") == (E, NU)
    Ee, nue = exact.effective_constants(E, NU, "strain")
    assert np.isclose(Ee, E / (1 - NU**2)) and np.isclose(nue, NU / (1 - NU))
    with pytest.raises(ValueError, match="plane"):
        exact.kirsch_displacement(np.ones((2, 1)), A, T, E, NU, plane="3d")
