"""Voronoi smoothing cells for SCNI: the cells tile the domain and are the
Voronoi cells, every piece closes, on a uniform grid they are the median
dual cells, and SCNI on them passes the patch tests, keeps the integration
constraint (tests/test_nodal_integration.py, with both kinds of cells) and
(stabilized) has no spurious zero-energy modes."""

import numpy as np
import pytest
from scipy.spatial import cKDTree
from skfem import MeshHex, MeshQuad, MeshTri

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.approximation.nodal_integration import smoothing_cells, stabilization_matrix
from skfem_rkpm.approximation.voronoi_cells import mesh_triangles
from skfem_rkpm.meshes import gmsh_rectangle
from test_nodal_integration import assert_cells_close, mesh_area, mesh_named
from test_patch import assert_round_off, field_gradient, linear_field, solve_patch

from _roundoff import field_bounds

C = isotropic_tangent(1.0, 1.0, 2)


def voronoi(mesh):
    return smoothing_cells(mesh, 2, "voronoi")


def patch_error(mesh, smoothing, **options):
    basis = RKBasis(mesh, vector=True, support=2.0, integration="scni", smoothing=smoothing,
                    **options)
    d, bound = solve_patch(basis, basis.boundary(), linear_field, bound=True)
    u = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    return ((np.abs(np.asarray(u) - linear_field(x)).max(),
             np.abs(u.grad - field_gradient(linear_field, x)).max()),
            field_bounds(basis, bound, d))


@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris", "graded_tris"])
def test_cells_are_the_voronoi_cells_and_tile_the_domain(mesh, request):
    m = mesh_named(mesh, request)
    cells = voronoi(m)
    assert cells.area.min() > 0
    np.testing.assert_allclose(cells.cell_area.sum(), mesh_area(m).sum(), rtol=1e-13)
    # every piece lies in its owner's Voronoi cell: its centroid (inside
    # the convex piece) is nearer to the owner than to any other particle
    centroid = cells.corners[:, :, :3].mean(axis=2)
    distance, _ = cKDTree(m.p.T).query(centroid.T)
    own = np.linalg.norm(centroid - m.p[:, cells.owner], axis=0)
    np.testing.assert_allclose(own, distance, rtol=1e-12, atol=1e-15)
    assert_cells_close(cells)


def test_on_a_uniform_grid_they_are_the_median_dual_cells():
    """Square cells: the Voronoi cell of a vertex is the square around it,
    the median dual cell; SCNI gives the same stiffness to round-off."""
    t = np.linspace(0.0, 1.0, 9)
    m = MeshQuad.init_tensor(t, t)
    np.testing.assert_allclose(voronoi(m).cell_area, smoothing_cells(m).cell_area,
                               rtol=1e-12)
    K = [Assembler(RKBasis(m, vector=True, integration="scni", smoothing=s)).bilinear(C)
         for s in ("median_dual", "voronoi")]
    assert abs(K[0] - K[1]).max() < 1e-12 * abs(K[0]).max()


def test_merged_cells_keep_only_the_cell_boundaries():
    """The sides inside a cell (fan diagonals, mesh edges) cancel exactly
    and are dropped; on the uniform grid the boundaries are those of the
    median dual cells (4 half sides per particle inside)."""
    t = np.linspace(0.0, 1.0, 9)
    m = MeshQuad.init_tensor(t, t)
    merged = voronoi(m).merged()
    assert merged.segment_points.shape[1] == smoothing_cells(m).merged().segment_points.shape[1]


# round-off bounds from the constrained system (test_patch.rk_error)
@pytest.mark.roundoff
@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
def test_linear_patch_round_off(mesh, request):
    assert_round_off(*patch_error(request.getfixturevalue(mesh), "voronoi"))


@pytest.mark.roundoff
@pytest.mark.parametrize("kind", ["tri", "quad"])
def test_linear_patch_on_graded_gmsh_meshes(kind):
    assert_round_off(*patch_error(gmsh_rectangle(1.0, 1.0, 0.1, kind=kind, h_corner=0.01),
                                  "voronoi"))


def test_stabilized_voronoi_scni_has_only_rigid_zero_modes(distorted_tris):
    """Free patch: plain SCNI and the stabilized version keep 3 zero
    eigenvalues (rigid motions) and no more; the stabilization vanishes on
    linear fields."""
    for alpha in (0.0, 1.0):
        basis = RKBasis(distorted_tris, vector=True, support=1.5, integration="scni",
                        smoothing="voronoi", stabilization=alpha)
        K = Assembler(basis).bilinear(C)
        if alpha:
            S = stabilization_matrix(basis.nodal_quadrature, C, 2)
            d = linear_field(distorted_tris.p).T.ravel()
            assert np.abs(S @ d).max() < 1e-9 * abs(S).max() * np.abs(d).max()
            K = K + alpha * S
        ev = np.linalg.eigvalsh(K.toarray())
        assert np.sum(ev < 1e-10 * ev.max()) == 3


def test_axisymmetric_smoothing_reproduces_linear_fields(distorted_quads):
    """In the measure R dA: the smoothed gradients of x are I, the mean
    values reproduce R at the cell centroids (Ψ̄ x = R̄)."""
    m = distorted_quads.translated((0.5, 0.0))
    basis = RKBasis(m, support=2.0, integration="scni", smoothing="voronoi",
                    axisymmetric=True)
    grads = np.stack([basis.table.gradient_matrix(k) @ m.p.T for k in range(2)], axis=1)
    np.testing.assert_allclose(grads, np.broadcast_to(np.eye(2), grads.shape), atol=1e-12)
    x = np.asarray(basis.global_coordinates()).reshape(2, -1)
    np.testing.assert_allclose(basis.table.matrix() @ m.p.T, x.T, atol=1e-12)


def test_quadrilaterals_split_into_positive_triangles():
    p = np.array([[0.0, 1.0, 0.3, 0.0], [0.0, 0.0, 0.3, 1.0]])  # reflex corner at 2
    m = MeshQuad(p, np.array([[0], [1], [2], [3]]))
    tri = mesh_triangles(m)
    a, b, c = (p[:, tri[j]] for j in range(3))
    area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
    assert np.all(area > 0) and area.sum() == pytest.approx(0.3)


def test_input_errors():
    with pytest.raises(ValueError, match="in 2D"):
        smoothing_cells(MeshHex(), 2, "voronoi")
    with pytest.raises(ValueError, match="needs integration='scni' or 'dni'"):
        RKBasis(MeshTri().refined(2), smoothing="voronoi")
    with pytest.raises(ValueError, match="smoothing must be one of"):
        RKBasis(MeshTri().refined(2), integration="scni", smoothing="delaunay")
