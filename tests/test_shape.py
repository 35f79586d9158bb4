"""RK shape functions: consistency (Eq. 2.36, 3.19), derivative consistency
(Eq. 2.38), kernels, supports and the error for singular moment matrices."""

import numpy as np
import pytest

from skfem_rkpm import SingularMomentError, rk_shape_functions
from skfem_rkpm.approximation.kernels import cubic_spline, get_kernel, quartic_spline
from skfem_rkpm.approximation.shape import monomial_exponents


def grid(dim, n, perturb=0.0, graded=False, seed=0):
    """Particles on [0, 1]^dim: uniform, graded (cubic map) or perturbed."""
    t = np.linspace(0.0, 1.0, n)
    if graded:
        t = t**2.0
    nodes = np.array([a.ravel() for a in np.meshgrid(*[t] * dim, indexing="ij")])
    rng = np.random.default_rng(seed)
    spacing = np.diff(t).max()
    nodes += perturb * spacing * rng.uniform(-1, 1, nodes.shape)
    return nodes


def monomial(x, e):
    return np.prod(x ** e[:, None], axis=0)


def dmonomial(x, e, k):
    if e[k] == 0:
        return np.zeros(x.shape[1])
    lowered = e.copy()
    lowered[k] -= 1
    return e[k] * monomial(x, lowered)


CASES = [
    # dim, order, support shape, normalized support
    (1, 0, "radial", 1.5), (1, 1, "radial", 2.0), (1, 2, "radial", 3.0),
    (2, 0, "radial", 1.5), (2, 1, "radial", 2.0), (2, 2, "radial", 3.0),
    (2, 1, "box", 1.5), (2, 2, "box", 2.5),
    (3, 1, "radial", 2.0), (3, 2, "box", 2.5),
]


@pytest.mark.parametrize("dim, order, support, c", CASES)
@pytest.mark.parametrize("layout", ["uniform", "graded", "perturbed"])
@pytest.mark.parametrize("kernel", ["cubic", "quartic"])
def test_reproduces_monomials_and_their_derivatives(dim, order, support, c,
                                                    layout, kernel):
    n = {1: 21, 2: 11, 3: 6}[dim]
    nodes = grid(dim, n, perturb=0.3 if layout == "perturbed" else 0.0,
                 graded=layout == "graded")
    # support radius from the largest spacing so graded grids stay covered
    h = 1.0 / (n - 1) * (2.0 if layout == "graded" else 1.0)
    rng = np.random.default_rng(1)
    x = rng.uniform(0.0, 1.0, (dim, 300))
    table = rk_shape_functions(x, nodes, c * h, order=order, kernel=kernel,
                               support=support)
    A = table.matrix()
    for e in monomial_exponents(dim, order):
        p = monomial(nodes, e)
        # Eq. (2.36): Σ Ψ_I(x) x_I^α = x^α, to round-off
        np.testing.assert_allclose(A @ p, monomial(x, e), rtol=0, atol=1e-12)
        for k in range(dim):
            # Eq. (2.38): Σ Ψ_I,k(x) x_I^α = ∂_k x^α; gradients scale as 1/h
            np.testing.assert_allclose(table.gradient_matrix(k) @ p,
                                       dmonomial(x, e, k), rtol=0,
                                       atol=1e-12 / h)


def test_gradients_match_finite_differences():
    nodes = grid(2, 9, perturb=0.25)
    x = np.random.default_rng(3).uniform(0.1, 0.9, (2, 50))
    t = rk_shape_functions(x, nodes, 2.3 / 8, order=2)
    eps = 1e-6
    for k in range(2):
        dx = np.zeros((2, 1))
        dx[k] = eps
        plus = rk_shape_functions(x + dx, nodes, 2.3 / 8, order=2,
                                  gradients=False).matrix()
        minus = rk_shape_functions(x - dx, nodes, 2.3 / 8, order=2,
                                   gradients=False).matrix()
        fd = ((plus - minus) / (2 * eps)).toarray()
        np.testing.assert_allclose(t.gradient_matrix(k).toarray(), fd, atol=1e-6)


def test_shepard_functions_are_normalized_kernels():
    """Order 0 gives Eq. (2.32): Ψ_I = φ_I / Σ_J φ_J."""
    nodes = grid(1, 11)
    x = np.array([[0.33, 0.71]])
    t = rk_shape_functions(x, nodes, 0.25, order=0)
    phi, _ = cubic_spline(np.abs(x.T - nodes) / 0.25)
    np.testing.assert_allclose(t.matrix().toarray(), phi / phi.sum(1, keepdims=True),
                               atol=1e-15)


def test_shape_functions_do_not_depend_on_units():
    nodes = grid(2, 7, perturb=0.2)
    x = np.random.default_rng(0).uniform(0, 1, (2, 40))
    a = rk_shape_functions(x, nodes, 2.0 / 6, order=2)
    b = rk_shape_functions(1e3 * x, 1e3 * nodes, 2e3 / 6, order=2)
    np.testing.assert_allclose(a.values, b.values, atol=1e-13)
    np.testing.assert_allclose(a.grads, 1e3 * b.grads, atol=1e-10)


def test_kernels():
    z = np.linspace(0, 1.2, 121)
    for kernel in (cubic_spline, quartic_spline):
        phi, dphi = kernel(z)
        assert np.all(phi[z >= 1] == 0) and np.all(dphi[z >= 1] == 0)
        assert np.all(np.diff(phi[z <= 1]) < 0)  # decreasing
        # derivative is the derivative (central differences)
        h = 1e-7
        fd = (kernel(z[1:-1] + h)[0] - kernel(z[1:-1] - h)[0]) / (2 * h)
        np.testing.assert_allclose(dphi[1:-1], fd, atol=1e-6)
    assert cubic_spline(0.0)[0] == pytest.approx(2 / 3)  # Eq. (3.12) at z = 0
    assert cubic_spline(0.5)[0] == pytest.approx(1 / 6)
    with pytest.raises(ValueError, match="unknown kernel 'gauss'"):
        get_kernel("gauss")


def test_too_small_support_names_point_count_and_smallest_dilation():
    nodes = grid(2, 11)
    h = 0.1
    # two particles (x = 0.5) lie within 0.054 of the point, the next two at 0.094
    x = np.array([[0.52], [0.55]])
    with pytest.raises(SingularMomentError) as info:
        rk_shape_functions(x, nodes, 0.6 * h, order=1, dilation=0.6)
    err = info.value
    msg = str(err)
    assert "(0.52, 0.55)" in msg and "covered by 2 particles" in msg
    c_min = 0.6 * err.factor
    assert f"{c_min:.3g}" in msg
    # the suggestion is the first 2 % step past the third particle at 0.943 h
    assert 0.943 < c_min < 0.943 * 1.021
    rk_shape_functions(x, nodes, c_min * h, order=1)
    with pytest.raises(SingularMomentError):
        rk_shape_functions(x, nodes, c_min / 1.02 * h, order=1)


def test_collinear_particles_are_reported_singular():
    nodes = np.array([[0.0, 1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 0.0]])
    with pytest.raises(SingularMomentError, match="do not span the basis"):
        rk_shape_functions(np.array([[1.5], [0.0]]), nodes, 2.5, order=1)


def test_uncovered_point_is_an_error_not_nan():
    nodes = grid(2, 5)
    with pytest.raises(SingularMomentError, match="covered by 0 particles"):
        rk_shape_functions(np.array([[5.0], [5.0]]), nodes, 0.5, order=1)


def test_bad_radius_and_support_shape():
    nodes = grid(2, 5)
    with pytest.raises(ValueError, match="radius of particle 0"):
        rk_shape_functions(nodes, nodes, np.r_[0.0, np.ones(24)])
    with pytest.raises(ValueError, match="'radial' or 'box'"):
        rk_shape_functions(nodes, nodes, 0.5, support="disc")


@pytest.mark.parametrize("support", ["radial", "box"])
def test_table_keeps_the_kernel_of_every_pair(support):
    """``ShapeTable.kernel`` is the window φ(X - X_I; a_I) of Eq. (3.12) at
    each pair, evaluated here independently from the distances."""
    from skfem_rkpm.approximation.kernels import cubic_spline

    rng = np.random.default_rng(4)
    nodes = rng.uniform(0, 1, (2, 60))
    x = rng.uniform(0.2, 0.8, (2, 40))
    radius = rng.uniform(0.3, 0.4, 60)
    t = rk_shape_functions(x, nodes, radius, support=support, backend="numpy")
    d = np.abs(x[:, t.rows] - nodes[:, t.indices]) / radius[t.indices]
    if support == "radial":
        expected = cubic_spline(np.hypot(d[0], d[1]))[0]
    else:
        expected = cubic_spline(d[0])[0] * cubic_spline(d[1])[0]
    np.testing.assert_allclose(t.kernel, expected, rtol=1e-12, atol=1e-15)
