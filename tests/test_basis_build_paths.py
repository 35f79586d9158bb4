"""The fast paths of the basis build give the tables of the general ones.

- The pair search by groups of points (the quadrature points of a cell,
  :mod:`skfem_rkpm.approximation.neighbours`) finds exactly the pairs of the
  KD-tree search point by point, in the same order: the same decisions,
  since it computes each distance as the KD-tree does.
- The symmetric VCI correction formed cell by cell
  (:mod:`skfem_rkpm.approximation.symmetric_cells`) equals the one of the
  sparse products over all pairs to round-off: only the order of the sums of
  ``Bᵀ W B`` differs, and the solve with that matrix spreads a relative
  difference of ~1e-16 by its condition number (measured 3e-15 to 9e-15 on
  these meshes; asserted 1e-12).
- A whole basis, built with both, equals the one built from the general
  paths: values exactly, corrected gradients to the same round-off.
"""

import numpy as np
import pytest
from skfem import ElementTetP1, MeshTet, MeshTri

from skfem_rkpm import RKBasis
from skfem_rkpm.approximation import cell_layout, integration
from skfem_rkpm.approximation.integration import cell_geometry, facet_geometry, vci_gradients
from skfem_rkpm.approximation.neighbours import group_pointers, grouped_pairs
from skfem_rkpm.approximation.shape import find_pairs, rk_shape_functions
from skfem_rkpm.meshes import local_spacing, rectangle


def tet_cube(n):
    p = np.linspace(0, 1, n + 1)
    return MeshTet.init_tensor(p, p, p)


def graded_triangles():
    """Triangles refined towards a corner: radii of several size classes."""
    m = MeshTri().refined(3)
    return MeshTri(m.p ** 2, m.t)


MESHES = {"quads": lambda: rectangle(0.6, 0.4, 15, 10),
          "graded triangles": graded_triangles,
          "tetrahedra": lambda: tet_cube(4)}


def quadrature_points(mesh, intorder):
    """Cell and boundary quadrature points and the particles, with their
    groups, as the basis searches them."""
    cells, facets = cell_geometry(mesh, intorder), facet_geometry(mesh, intorder)
    x = np.hstack([cells.global_coordinates().reshape(mesh.dim(), -1),
                   facets.global_coordinates().reshape(mesh.dim(), -1), mesh.p])
    groups = group_pointers((cells.nelems, cells.X.shape[-1]),
                            (facets.nelems, facets.X.shape[-1]), (mesh.nvertices, 1))
    return x, groups


@pytest.mark.parametrize("support", ["radial", "box"])
@pytest.mark.parametrize("name", sorted(MESHES))
def test_grouped_search_finds_the_kd_tree_pairs(name, support):
    mesh = MESHES[name]()
    x, groups = quadrature_points(mesh, 4)
    radius = 2.0 * local_spacing(mesh)
    points, nodes = x.T.copy(), mesh.p.T.copy()
    expected = find_pairs(points, nodes, radius, support)
    found = find_pairs(points, nodes, radius, support, groups)
    assert len(expected[0]) > 10 * x.shape[1]  # many pairs per point
    if name == "graded triangles":  # radii in several classes of the search
        assert np.unique(np.floor(np.log(radius / radius.min()) / np.log(1.5))).size > 2
    for a, b in zip(expected, found):
        np.testing.assert_array_equal(a, b)


def test_grouped_search_on_points_on_support_boundaries():
    """Particles on a grid of spacing h with radius exactly 2h: other
    particles sit on the support boundaries, where the strict test decides;
    groups of scattered points (far apart) are still searched right."""
    g = np.arange(6) * 0.1
    nodes = np.array(np.meshgrid(g, g)).reshape(2, -1).T.copy()
    radius = np.full(len(nodes), 0.2)
    rng = np.random.default_rng(3)
    points = np.vstack([nodes, rng.uniform(0, 0.5, (40, 2))])
    groups = np.array([0, 1, 7, 36, 50, len(points)])  # odd sizes, far-apart members
    expected = find_pairs(points, nodes, radius)
    for a, b in zip(expected, grouped_pairs(points, nodes, radius, 2.0, groups)):
        np.testing.assert_array_equal(a, b)


def test_groups_must_cover_the_points():
    points = np.zeros((5, 2))
    with pytest.raises(ValueError, match="cover the 5 points"):
        grouped_pairs(points, points, np.ones(5), 2.0, np.array([0, 2, 4]))
    with pytest.raises(ValueError, match="at least one point"):
        group_pointers((3, 0))


def general_symmetric_gradients(basis, mesh):
    """The corrected gradients of ``basis`` (pairs of its table) from the
    general paths: the KD-tree search and the pair-wide symmetric VCI."""
    geometry, boundary = cell_geometry(mesh, basis.intorder), facet_geometry(mesh, basis.intorder)
    xq = geometry.global_coordinates().reshape(mesh.dim(), -1)
    xb = boundary.global_coordinates().reshape(mesh.dim(), -1)
    table = rk_shape_functions(xq, basis.nodes, basis.radius, backend="numpy")
    btable = rk_shape_functions(xb, basis.nodes, basis.radius, gradients=False,
                                backend="numpy")
    grads = vci_gradients(table, xq, geometry.dx.ravel(), btable, xb, boundary.dx.ravel(),
                          boundary.normals.reshape(mesh.dim(), -1), basis.nodes,
                          basis.radius, 1, symmetric=True)
    return table, grads


@pytest.mark.parametrize("name", ["quads", "tetrahedra"])
def test_symmetric_vci_by_cells_equals_the_pair_wide_correction(name):
    mesh = MESHES[name]()
    basis = RKBasis(mesh, integration="vci_symmetric")
    table, general = general_symmetric_gradients(basis, mesh)
    built = basis.table
    np.testing.assert_array_equal(built.indptr, table.indptr)
    np.testing.assert_array_equal(built.indices, table.indices)
    np.testing.assert_array_equal(built.values, table.values)  # values: no VCI
    fast = basis.test_grads
    assert np.abs(fast - general).max() <= 1e-12 * np.abs(general).max()
    # and the correction is not nothing: it moves the gradients by far more
    assert np.abs(general - table.grads).max() > 1e-6 * np.abs(general).max()


def test_symmetric_vci_by_cells_is_the_call_with_cells():
    """``vci_gradients(..., cells=...)`` on the same table against the call
    without: one table, so only the correction's path differs."""
    mesh = tet_cube(3)
    geometry, boundary = cell_geometry(mesh, 4), facet_geometry(mesh, 4)
    xq = geometry.global_coordinates().reshape(3, -1)
    xb = boundary.global_coordinates().reshape(3, -1)
    radius = 2.0 * local_spacing(mesh)
    table = rk_shape_functions(xq, mesh.p, radius, backend="numpy")
    btable = rk_shape_functions(xb, mesh.p, radius, gradients=False, backend="numpy")
    args = (table, xq, geometry.dx.ravel(), btable, xb, boundary.dx.ravel(),
            boundary.normals.reshape(3, -1), mesh.p, radius, 1)
    cells = (geometry.X.shape[-1], cell_layout.cell_particles(table, mesh.nelements,
                                                              geometry.X.shape[-1]))
    general = vci_gradients(*args, symmetric=True)
    fast = vci_gradients(*args, symmetric=True, cells=cells)
    assert np.abs(fast - general).max() <= 1e-12 * np.abs(general).max()
    # the order-1 (non-symmetric) correction has one path: cells change nothing
    np.testing.assert_array_equal(vci_gradients(*args), vci_gradients(*args, cells=cells))


def test_order_one_correction_blocks_equal_one_pass(monkeypatch):
    """The order-1 VCI correction formed block by block of points equals the
    same formula over all pairs at once, bit for bit (the same operations in
    the same order), also with blocks smaller than a point's pairs."""
    mesh = rectangle(0.6, 0.4, 12, 8)
    basis = RKBasis(mesh, support=2.0)
    table = basis.table
    rng = np.random.default_rng(0)
    xi = rng.standard_normal((basis.nnodes, 2))
    mean = rng.standard_normal((table.npoints, 2))
    phi = rng.uniform(0.1, 1.0, len(table.indices))
    whole = np.take(xi.T, table.indices, axis=1)
    for k in range(2):
        whole[k] -= np.repeat(mean[:, k], np.diff(table.indptr))
    whole *= phi
    whole += table.grads
    from skfem_rkpm.approximation import symmetric_cells

    for block in (2**17, 7):
        monkeypatch.setattr(symmetric_cells, "PAIRS_PER_BLOCK", block)
        np.testing.assert_array_equal(
            integration._constant_correction(table, xi, mean, phi), whole)
