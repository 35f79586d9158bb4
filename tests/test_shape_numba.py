"""The compiled shape-function kernel (numba) against the numpy path: the
same pairs in the same order, values and gradients equal to round-off, the
same errors; and a clear error when numba is requested but missing."""

import sys

import numpy as np
import pytest

from skfem_rkpm import SingularMomentError, rk_shape_functions
from skfem_rkpm.approximation import shape, shape_backend
from skfem_rkpm.approximation.kernels import cubic_spline


@pytest.fixture
def numba():
    return pytest.importorskip("numba")


def grid(dim, n, perturb=0.0, seed=0):
    t = np.linspace(0.0, 1.0, n)
    nodes = np.array([a.ravel() for a in np.meshgrid(*[t] * dim, indexing="ij")])
    h = t[1] - t[0]
    nodes += perturb * h * np.random.default_rng(seed).uniform(-1, 1, nodes.shape)
    return nodes, h


def assert_same_table(a, b):
    np.testing.assert_array_equal(a.indptr, b.indptr)
    np.testing.assert_array_equal(a.indices, b.indices)
    assert a.indptr.dtype == b.indptr.dtype and a.indices.dtype == b.indices.dtype
    assert a.nnodes == b.nnodes
    scale = np.abs(a.values).max()
    np.testing.assert_allclose(b.values, a.values, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(b.kernel, a.kernel, rtol=0, atol=1e-14)  # φ <= 1
    if a.grads is None:
        assert b.grads is None
    else:
        assert b.grads.shape == a.grads.shape
        np.testing.assert_allclose(b.grads, a.grads, rtol=0,
                                   atol=1e-12 * np.abs(a.grads).max())


def both(x, nodes, radius, **kwargs):
    a = rk_shape_functions(x, nodes, radius, backend="numpy", **kwargs)
    b = rk_shape_functions(x, nodes, radius, backend="numba", **kwargs)
    assert_same_table(a, b)
    return a


CASES = [
    # dim, order, support shape, normalized support
    (1, 0, "radial", 1.5), (1, 1, "radial", 2.0), (1, 2, "box", 3.0),
    (2, 0, "radial", 1.5), (2, 1, "radial", 2.0), (2, 2, "radial", 3.0),
    (2, 1, "box", 1.5), (2, 2, "box", 2.5),
    (3, 1, "radial", 2.0), (3, 1, "box", 1.5), (3, 2, "radial", 3.0),
    (3, 2, "box", 2.5),
]


@pytest.mark.parametrize("dim, order, support, c", CASES)
@pytest.mark.parametrize("kernel", ["cubic", "quartic"])
@pytest.mark.parametrize("layout", ["random", "grid"])
def test_same_table_as_numpy(numba, dim, order, support, c, kernel, layout):
    n = {1: 21, 2: 11, 3: 6}[dim]
    nodes, h = grid(dim, n, perturb=0.3, seed=dim + order)
    rng = np.random.default_rng(7)
    radius = c * h * rng.uniform(1.0, 1.4, nodes.shape[1])  # each its own
    if layout == "random":
        x = rng.uniform(0.0, 1.0, (dim, 400))
    else:  # points on a grid: many exactly on particle rows
        x, _ = grid(dim, 2 * n - 1)
    for gradients in (True, False):
        both(x, nodes, radius, order=order, kernel=kernel, support=support,
             gradients=gradients)


def test_particles_on_points_and_graded_radii(numba):
    """Points on the particles (r = 0 in the kernel gradient), radii from h
    to 4h, a callable kernel given as the function itself."""
    nodes, h = grid(2, 15, perturb=0.2)
    radius = h * np.linspace(2.0, 5.0, nodes.shape[1])
    both(nodes, nodes, radius, order=1)
    both(nodes, nodes, radius, order=2, kernel=cubic_spline, support="box")


def test_shifted_scaled_coordinates(numba):
    nodes, h = grid(2, 9, perturb=0.25)
    x = np.random.default_rng(1).uniform(0, 1, (2, 200))
    both(1e4 + 1e-3 * x, 1e4 + 1e-3 * nodes, 2.2e-3 * h, order=2)


def test_points_outside_and_far_away(numba):
    nodes, h = grid(2, 6)
    x = np.array([[0.5, -0.1, 1.05, 3.0, 1e6], [0.5, 0.5, 1.05, 3.0, -1e6]])
    for backend in ("numpy", "numba"):
        with pytest.raises(SingularMomentError, match="covered by 0 particles"):
            rk_shape_functions(x, nodes, 2 * h, order=1, backend=backend)
    both(x[:, :3], nodes, 2.5 * h, order=1)


@pytest.mark.parametrize("x, radius, order", [
    (np.array([[0.52], [0.55]]), 0.06, 1),       # too few particles
    (np.array([[0.5], [0.5]]), 0.101, 2),        # on a line: singular
])
def test_same_error_as_numpy(numba, x, radius, order):
    nodes, _ = grid(2, 11)
    messages = []
    for backend in ("numpy", "numba"):
        with pytest.raises(SingularMomentError) as info:
            rk_shape_functions(x, nodes, radius, order=order, dilation=0.6,
                               backend=backend)
        messages.append(str(info.value))
    assert messages[0] == messages[1]


def test_auto_and_environment_variable(numba, monkeypatch):
    nodes, h = grid(2, 11)
    x = np.random.default_rng(2).uniform(0, 1, (2, 50))
    reference = rk_shape_functions(x, nodes, 2 * h, backend="numpy")
    for value in ("auto", "numba", "numpy", ""):
        monkeypatch.setenv(shape_backend.BACKEND_VARIABLE, value)
        assert_same_table(reference, rk_shape_functions(x, nodes, 2 * h))
    monkeypatch.setenv(shape_backend.BACKEND_VARIABLE, "fortran")
    with pytest.raises(ValueError, match="'auto', 'numpy' or 'numba'"):
        rk_shape_functions(x, nodes, 2 * h)
    # a kernel the compiled path does not know: auto falls back, numba refuses
    def window(z):
        return cubic_spline(z)
    monkeypatch.delenv(shape_backend.BACKEND_VARIABLE)
    assert_same_table(reference, rk_shape_functions(x, nodes, 2 * h,
                                                    kernel=window))
    with pytest.raises(ValueError, match="covers the kernels"):
        rk_shape_functions(x, nodes, 2 * h, kernel=window, backend="numba")


def test_auto_loads_the_kernel_only_for_large_calls(monkeypatch):
    loads = []
    monkeypatch.delenv(shape_backend.BACKEND_VARIABLE, raising=False)
    monkeypatch.setattr(shape_backend, "_loaded", None)
    monkeypatch.setattr(shape_backend, "_load_compiled", lambda: loads.append(1) or False)
    nodes, h = grid(2, 6)
    x = np.random.default_rng(3).uniform(0, 1, (2, 30))
    rk_shape_functions(x, nodes, 2 * h)
    assert not loads
    monkeypatch.setattr(shape_backend, "AUTO_MIN_POINTS", 10)
    rk_shape_functions(x, nodes, 2 * h)
    assert loads


def test_numba_backend_without_numba_is_a_clear_error(monkeypatch):
    """Simulate an installation without numba."""
    monkeypatch.delenv(shape_backend.BACKEND_VARIABLE, raising=False)
    monkeypatch.setitem(sys.modules, "numba", None)
    monkeypatch.setitem(sys.modules, "skfem_rkpm.approximation._shape_numba", None)
    monkeypatch.setattr(shape_backend, "_loaded", None)
    nodes, h = grid(2, 6)
    x = np.random.default_rng(4).uniform(0, 1, (2, 30))
    with pytest.raises(ImportError, match=r"pip install skfem-rkpm\[fast\]") as info:
        rk_shape_functions(x, nodes, 2 * h, backend="numba")
    assert isinstance(info.value, shape.BackendUnavailableError)
    # auto silently uses numpy, also above the size limit
    monkeypatch.setattr(shape_backend, "AUTO_MIN_POINTS", 1)
    table = rk_shape_functions(x, nodes, 2 * h)
    assert_same_table(rk_shape_functions(x, nodes, 2 * h, backend="numpy"), table)
