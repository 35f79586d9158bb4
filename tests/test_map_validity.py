"""``det F`` of the deformation map sampled in every cell: against maps whose
``det F`` and folds are known in closed form (RK functions of order 2
reproduce the quadratic displacements exactly, Eq. 2.27-2.33), and against
the corner Jacobians of Q1 elements (an independent computation)."""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.map_validity import MapSampler, map_validity, reference_samples
from skfem_rkpm.meshes import box, rectangle
from skfem_rkpm.runs.io import corner_jacobians


def coefficients(basis, u):
    """Coefficients that reproduce the polynomial field ``u(X)`` (dim, n):
    its values at the particles (RK functions of that order reproduce it)."""
    return np.asarray(u(basis.nodes)).T.ravel()


@pytest.mark.parametrize("kind, per_axis, count", [("quad", 5, 25), ("tri", 5, 15),
                                                    ("hex", 4, 64), ("tet", 4, 20)])
def test_the_samples_fill_the_reference_cell_corners_included(kind, per_axis, count):
    mesh = (rectangle(1.0, 1.0, 1, 1, kind=kind) if kind in ("quad", "tri")
            else box(1.0, 1.0, 1.0, 1, 1, 1, kind=kind))
    ref = reference_samples(mesh, per_axis)
    assert ref.shape == (mesh.dim(), count)  # p^d, or the simplex numbers C(p+d-1, d)
    corners = np.asarray(type(mesh).elem().doflocs)[:mesh.refdom.nnodes]
    for c in corners:
        assert np.any(np.all(np.isclose(ref.T, c), axis=1))
    with pytest.raises(ValueError, match="at least 2 sample points"):
        reference_samples(mesh, 1)


def test_a_large_mesh_is_sampled_more_sparsely_down_to_its_corners():
    """By default at most MAX_SAMPLES = 1e5 samples: 5 x 5 on 16 x 8 cells,
    4 x 4 on 100 x 50 (20 per cell would fit), the 4 corners on 150 x 75
    (8.9 per cell would fit, fewer than 3 x 3)."""
    from skfem_rkpm.mechanics import map_validity as mv

    assert mv.MAX_SAMPLES == 100_000
    for n, per_cell in ((16, 25), (100, 16), (150, 4)):
        mesh = rectangle(2.0, 1.0, n, n // 2)
        sampler = MapSampler(Basis(mesh, ElementVector(ElementQuad1())))
        assert sampler.per_cell == per_cell


def test_a_homogeneous_map_has_its_determinant_everywhere():
    """u = A X: det F = det(I + A) at every sample (plane strain), and the
    hoop stretch 1 + a of u_r = a R multiplies it (axisymmetric)."""
    mesh = rectangle(2.0, 1.0, 8, 4, origin=(1.0, 0.0))
    basis = RKBasis(mesh, vector=True, support=2.0, order=1)
    A = np.array([[-0.3, 0.0], [0.1, 0.4]])  # u_r / R = -0.3 everywhere
    d = coefficients(basis, lambda X: A @ X)
    J, _ = MapSampler(basis).jacobians(d)
    np.testing.assert_allclose(J, np.linalg.det(np.eye(2) + A), rtol=1e-10)
    J, _ = MapSampler(basis, "axisymmetric").jacobians(d)
    np.testing.assert_allclose(J, np.linalg.det(np.eye(2) + A) * (1 - 0.3), rtol=1e-10)
    # a reflection: every sample and every cell folded, det F = -1
    check = map_validity(basis, coefficients(basis, lambda X: np.array([-2 * X[0], 0 * X[1]])))
    assert check.folded_points == check.npoints == 32 * 25 and check.folded_cells.size == 32
    assert check.min_det == pytest.approx(-1.0, rel=1e-10)
    # u = -2 X (x = -X, a rotation by π in the plane) has det F = +1 in plane
    # strain, but the hoop stretch 1 + u_r/R = -1 folds it
    d = coefficients(basis, lambda X: -2.0 * X)
    assert map_validity(basis, d).valid
    check = map_validity(basis, d, "axisymmetric")
    assert check.folded_points == check.npoints
    assert check.min_det == pytest.approx(-1.0, rel=1e-10)


def test_a_known_fold_in_plane_strain_is_found_in_its_cells():
    """u_x = -κ X², reproduced by order-2 RK functions: det F = 1 - 2κX,
    folded for X > 1/(2κ) = 1.11 (the cells reaching past that line, which
    lies on no sample) and smallest, 1 - 4κ = -0.8, on the right side X = 2."""
    kappa = 0.45
    mesh = rectangle(2.0, 1.0, 8, 4)
    basis = RKBasis(mesh, vector=True, support=2.5, order=2)
    d = coefficients(basis, lambda X: np.array([-kappa * X[0] ** 2, 0 * X[1]]))
    sampler = MapSampler(basis, per_axis=5)
    J, u = sampler.jacobians(d)
    X = sampler.X[0]
    np.testing.assert_allclose(J, 1 - 2 * kappa * X, atol=1e-9)
    check = sampler.check(d)
    assert check.min_det == pytest.approx(1 - 4 * kappa, abs=1e-9)
    assert check.X[0] == pytest.approx(2.0)
    assert check.x[0] == pytest.approx(2.0 - kappa * 4.0, abs=1e-9)
    line = 1 / (2 * kappa)
    assert check.folded_points == int((X > line).sum()) > 0
    right = mesh.p[0, mesh.t].max(axis=0)  # the right side of each cell
    np.testing.assert_array_equal(check.folded_cells, np.flatnonzero(right > line))
    assert "the RK map itself folds: det F <= 0 at" in check.describe()
    assert f"in {check.folded_cells.size} of 32 cells" in check.describe()


def test_the_hoop_stretch_folds_and_unfolds_the_axisymmetric_map():
    """u_r = -κ R²: det F = (1 - 2κR)(1 - κR), folded for 1.11 < R < 2.22
    (κ = 0.45; on no sample) and positive again beyond, where both factors
    are negative; without the hoop stretch every sample beyond R = 1.11
    would be folded."""
    kappa = 0.45
    mesh = rectangle(2.0, 1.0, 8, 4, origin=(1.0, 0.0))
    basis = RKBasis(mesh, vector=True, support=2.5, order=2, axisymmetric=True)
    d = coefficients(basis, lambda X: np.array([-kappa * X[0] ** 2, 0 * X[1]]))
    sampler = MapSampler(basis, "axisymmetric")
    J, _ = sampler.jacobians(d)
    R = sampler.X[0]
    exact = (1 - 2 * kappa * R) * (1 - kappa * R)
    np.testing.assert_allclose(J, exact, atol=1e-9)
    check = sampler.check(d)
    inside = (R > 1 / (2 * kappa)) & (R < 1 / kappa)
    assert check.folded_points == int(inside.sum()) > 0
    # smallest at the sample nearest the parabola's vertex R = 3/(4κ) = 1.67
    assert check.min_det == pytest.approx(exact.min(), abs=1e-9)
    assert exact.min() < -0.1
    assert check.X[0] == pytest.approx(R.flat[np.argmin(exact)])
    beyond = R > 1 / kappa
    assert (J[beyond] > 0).sum() == beyond.sum() > 0
    # on the axis the hoop stretch is the limit of u_r / R: ∂u_r/∂R
    axis = rectangle(1.0, 1.0, 4, 4)
    basis = RKBasis(axis, vector=True, support=2.5, order=2, axisymmetric=True)
    a = 0.2
    d = coefficients(basis, lambda X: np.array([a * X[0], 0 * X[1]]))
    J, _ = MapSampler(basis, "axisymmetric").jacobians(d)
    np.testing.assert_allclose(J, (1 + a) ** 2, rtol=1e-10)


def test_a_known_fold_in_3d():
    """u_x = -κ X² in a box: det F = 1 - 2κX, folded for X > 1.11."""
    kappa = 0.45
    mesh = box(2.0, 1.0, 1.0, 4, 2, 2)
    basis = RKBasis(mesh, vector=True, support=2.5, order=2)
    d = coefficients(basis, lambda X: np.array([-kappa * X[0] ** 2, 0 * X[1], 0 * X[2]]))
    sampler = MapSampler(basis, "3d")
    J, _ = sampler.jacobians(d)
    np.testing.assert_allclose(J, 1 - 2 * kappa * sampler.X[0], atol=1e-9)
    check = sampler.check(d)
    right = mesh.p[0, mesh.t].max(axis=0)
    np.testing.assert_array_equal(check.folded_cells, np.flatnonzero(right > 1 / (2 * kappa)))
    assert check.min_det == pytest.approx(1 - 4 * kappa, abs=1e-9)
    with pytest.raises(ValueError, match="model 'plane_strain' on a 3D mesh"):
        MapSampler(basis, "plane_strain")


def test_q1_elements_at_their_corners_are_the_corner_jacobians():
    """For Q1 the map is the bilinear interpolation: sampled at the corners
    (per_axis = 2) its det F is the corner Jacobian of the moved cell."""
    mesh = rectangle(2.0, 1.0, 4, 2)
    basis = Basis(mesh, ElementVector(ElementQuad1()))
    rng = np.random.default_rng(3)
    u = 0.2 * rng.standard_normal((mesh.nvertices, 2))  # folds some cells
    sampler = MapSampler(basis, per_axis=2)
    J, _ = sampler.jacobians(u.ravel())
    corners = corner_jacobians(mesh, u)
    assert (corners < 0).any()
    # the same numbers, the corners in another order
    np.testing.assert_allclose(np.sort(J, axis=1), np.sort(corners, axis=1), atol=1e-12)
    check = sampler.check(u.ravel())
    assert check.kind == "FEM" and check.min_det == pytest.approx(corners.min(), abs=1e-12)
    np.testing.assert_array_equal(check.folded_cells, np.flatnonzero((corners <= 0).any(1)))


@pytest.mark.parametrize("kind, element", [("quad", "ElementQuad2"), ("hex", "ElementHex1"),
                                           ("tet", "ElementTetP2")])
def test_vector_elements_are_sampled_as_scikit_fem_interpolates(kind, element):
    """The vector-element path (scalar shape functions combined per
    component) against scikit-fem's own ``interpolate`` at the samples and
    ``det`` by LAPACK, on a random displacement: the same sums in the same
    order, so equal to round-off (asserted 1e-12 of values of order 1)."""
    import skfem

    from skfem_rkpm.mechanics.map_validity import reference_samples as samples

    mesh = (rectangle(2.0, 1.0, 4, 3, kind=kind) if kind == "quad"
            else box(1.0, 1.0, 1.0, 2, 2, 2, kind=kind))
    basis = Basis(mesh, ElementVector(getattr(skfem, element)()))
    d = 0.05 * np.random.default_rng(3).standard_normal(basis.N)
    sampler = MapSampler(basis, "3d" if mesh.dim() == 3 else "plane_strain", per_axis=3)
    assert sampler._scalar is not None
    J, u = sampler.jacobians(d)
    ref = samples(mesh, 3)
    weights = np.full(ref.shape[1], 1.0 / ref.shape[1])
    field = Basis(mesh, basis.elem, quadrature=(ref, weights)).interpolate(d)
    F = np.eye(mesh.dim())[:, :, None, None] + np.asarray(field.grad)
    np.testing.assert_allclose(u, np.asarray(field), rtol=0, atol=1e-12)
    np.testing.assert_allclose(J, np.linalg.det(np.moveaxis(F, (0, 1), (-2, -1))),
                               rtol=0, atol=1e-12)
