"""Background meshes: geometry, orientation and named boundaries."""

import gmsh
import numpy as np
import pytest
import skfem

from skfem_rkpm import meshes

SIDES = ("left", "right", "bottom", "top")


def cell_areas(mesh):
    """Signed cell areas (shoelace formula)."""
    x, y = mesh.p[0, mesh.t], mesh.p[1, mesh.t]
    return 0.5 * np.sum(x * np.roll(y, -1, 0) - np.roll(x, -1, 0) * y, axis=0)


def min_jacobian(mesh):
    """Smallest Jacobian determinant of the cell maps at quadrature points."""
    element = skfem.ElementTriP1() if mesh.t.shape[0] == 3 else skfem.ElementQuad1()
    basis = skfem.Basis(mesh, element, intorder=3)
    return basis.mapping.detDF(basis.X).min()


def facet_midpoints(mesh, facets):
    return mesh.p[:, mesh.facets[:, facets]].mean(axis=1)


def facet_lengths(mesh, facets):
    ends = mesh.p[:, mesh.facets[:, facets]]
    return np.linalg.norm(ends[:, 0] - ends[:, 1], axis=0)


def boundary_facets_where(mesh, test):
    """Boundary facets whose two vertices both satisfy ``test``."""
    facets = mesh.boundary_facets()
    ends = mesh.facets[:, facets]
    keep = test(mesh.p[:, ends[0]]) & test(mesh.p[:, ends[1]])
    return np.sort(facets[keep])


def assert_box_sides(mesh, x0, x1, y0, y1):
    """The four named sides hold exactly the boundary facets on them."""
    tol = 1e-10 * max(x1 - x0, y1 - y0)
    lines = {
        "left": lambda p: np.abs(p[0] - x0) < tol,
        "right": lambda p: np.abs(p[0] - x1) < tol,
        "bottom": lambda p: np.abs(p[1] - y0) < tol,
        "top": lambda p: np.abs(p[1] - y1) < tol,
    }
    for name, on_line in lines.items():
        expected = boundary_facets_where(mesh, on_line)
        assert len(expected) > 0
        np.testing.assert_array_equal(np.sort(mesh.boundaries[name]), expected)
    named = np.concatenate([mesh.boundaries[name] for name in SIDES])
    np.testing.assert_array_equal(np.sort(named), np.sort(mesh.boundary_facets()))
    assert np.isclose(facet_lengths(mesh, mesh.boundaries["left"]).sum(), y1 - y0)
    assert np.isclose(facet_lengths(mesh, mesh.boundaries["bottom"]).sum(), x1 - x0)


# ---------------------------------------------------------------------------
# structured meshes
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["quad", "tri"])
@pytest.mark.parametrize("perturb", [0.0, 0.2])
def test_rectangle(kind, perturb):
    mesh = meshes.rectangle(
        3.0, 2.0, 6, 5, kind=kind, origin=(1.0, -1.0), perturb=perturb
    )
    assert isinstance(mesh, skfem.MeshQuad1 if kind == "quad" else skfem.MeshTri1)
    assert mesh.nelements == (30 if kind == "quad" else 60)
    assert mesh.nvertices == 7 * 6
    assert np.isclose(cell_areas(mesh).sum(), 6.0, rtol=1e-12)
    assert cell_areas(mesh).min() > 0 and min_jacobian(mesh) > 0
    np.testing.assert_allclose(mesh.p.min(axis=1), [1.0, -1.0], atol=1e-14)
    np.testing.assert_allclose(mesh.p.max(axis=1), [4.0, 1.0], atol=1e-14)
    assert_box_sides(mesh, 1.0, 4.0, -1.0, 1.0)
    assert len(mesh.boundaries["left"]) == 5 and len(mesh.boundaries["top"]) == 6


@pytest.mark.parametrize("kind", ["quad", "tri"])
def test_rectangle_perturbation(kind):
    lx, ly, nx, ny, perturb = 2.0, 1.0, 8, 4, 0.15
    regular = meshes.rectangle(lx, ly, nx, ny, kind=kind)
    moved = meshes.rectangle(lx, ly, nx, ny, kind=kind, perturb=perturb, seed=3)
    shift = moved.p - regular.p
    h = np.array([[lx / nx], [ly / ny]])
    assert np.all(np.abs(shift) <= perturb * h + 1e-14)
    on_x_side = np.isclose(regular.p[0], 0) | np.isclose(regular.p[0], lx)
    on_y_side = np.isclose(regular.p[1], 0) | np.isclose(regular.p[1], ly)
    # vertices on a side only slide along it, corners stay put
    assert np.all(shift[0, on_x_side] == 0) and np.all(shift[1, on_y_side] == 0)
    interior = ~on_x_side & ~on_y_side
    assert np.all(np.abs(shift[:, interior]).max(axis=1) > 0.5 * perturb * h[:, 0])
    assert np.all(np.abs(shift[0, on_y_side & ~on_x_side]) > 0)
    # reproducible with the seed
    again = meshes.rectangle(lx, ly, nx, ny, kind=kind, perturb=perturb, seed=3)
    other = meshes.rectangle(lx, ly, nx, ny, kind=kind, perturb=perturb, seed=4)
    np.testing.assert_array_equal(again.p, moved.p)
    assert not np.allclose(other.p, moved.p)


def test_rectangle_rejects_bad_input():
    with pytest.raises(ValueError, match="kind"):
        meshes.rectangle(1, 1, 2, 2, kind="hex")
    with pytest.raises(ValueError, match="perturb"):
        meshes.rectangle(1, 1, 2, 2, perturb=-0.1)
    with pytest.raises(ValueError, match="inverts"):
        meshes.rectangle(1, 1, 20, 20, kind="tri", perturb=0.49)


@pytest.mark.parametrize("kind", ["quad", "tri"])
@pytest.mark.parametrize("ratio", [1.0, 8.0])
def test_graded_rectangle(kind, ratio):
    mesh = meshes.graded_rectangle(3.0, 2.0, 7, 5, ratio, kind=kind)
    for axis, length, n in ((0, 3.0, 7), (1, 2.0, 5)):
        nodes = np.unique(mesh.p[axis])
        sizes = np.diff(nodes)
        assert len(sizes) == n
        assert np.isclose(nodes[0], 0) and np.isclose(nodes[-1], length)
        assert np.isclose(sizes.max() / sizes.min(), ratio, rtol=1e-12)
        assert np.all(np.diff(sizes) >= -1e-15)  # smallest cells at the origin
        # geometric: constant growth factor
        np.testing.assert_allclose(sizes[1:] / sizes[:-1], ratio ** (1 / (n - 1)))
    assert np.isclose(cell_areas(mesh).sum(), 6.0, rtol=1e-12)
    assert min_jacobian(mesh) > 0
    assert_box_sides(mesh, 0.0, 3.0, 0.0, 2.0)


def test_graded_rectangle_rejects_bad_ratio():
    with pytest.raises(ValueError, match="ratio"):
        meshes.graded_rectangle(1, 1, 4, 4, 0.5)


# ---------------------------------------------------------------------------
# gmsh meshes
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["tri", "quad"])
@pytest.mark.parametrize("h_corner", [None, 0.01])
def test_gmsh_rectangle(kind, h_corner):
    lx, ly, h = 2.0, 1.0, 0.1
    mesh = meshes.gmsh_rectangle(lx, ly, h, kind=kind, h_corner=h_corner)
    assert mesh.t.shape[0] == (3 if kind == "tri" else 4)
    assert np.isclose(cell_areas(mesh).sum(), lx * ly, rtol=1e-12)
    assert cell_areas(mesh).min() > 0 and min_jacobian(mesh) > 0
    assert_box_sides(mesh, 0.0, lx, 0.0, ly)
    np.testing.assert_array_equal(mesh.subdomains["domain"], np.arange(mesh.nelements))
    assert mesh.nvertices == len(np.unique(mesh.t))
    spacing = meshes.local_spacing(mesh)
    far = np.hypot(*mesh.p) > 0.5 * ly
    assert 0.7 * h < np.median(spacing[far]) < 1.3 * h
    if h_corner is not None:
        origin = np.argmin(np.hypot(*mesh.p))
        assert np.allclose(mesh.p[:, origin], 0)
        assert 0.5 * h_corner < spacing[origin] < 2 * h_corner


@pytest.mark.parametrize("kind", ["tri", "quad"])
@pytest.mark.parametrize("h_hole", [None, 0.02])
def test_gmsh_plate_with_hole(kind, h_hole):
    radius, length, h = 0.5, 2.0, 0.2
    mesh = meshes.gmsh_plate_with_hole(radius, length, h, kind=kind, h_hole=h_hole)
    assert mesh.t.shape[0] == (3 if kind == "tri" else 4)
    exact_area = length**2 - np.pi * radius**2 / 4
    area = cell_areas(mesh).sum()
    # the polygonal hole is inscribed in the circle: the mesh is a bit larger
    assert exact_area < area < exact_area * (1 + 1e-2)
    assert cell_areas(mesh).min() > 0 and min_jacobian(mesh) > 0

    r = np.hypot(*mesh.p)
    tol = 1e-10
    lines = {
        "hole": lambda p: np.abs(np.hypot(*p) - radius) < tol,
        "left": lambda p: np.abs(p[0]) < tol,
        "bottom": lambda p: np.abs(p[1]) < tol,
        "right": lambda p: np.abs(p[0] - length) < tol,
        "top": lambda p: np.abs(p[1] - length) < tol,
    }
    for name, on_line in lines.items():
        expected = boundary_facets_where(mesh, on_line)
        np.testing.assert_array_equal(np.sort(mesh.boundaries[name]), expected)
    named = np.concatenate([mesh.boundaries[name] for name in lines])
    np.testing.assert_array_equal(np.sort(named), np.sort(mesh.boundary_facets()))
    lengths = {k: facet_lengths(mesh, v).sum() for k, v in mesh.boundaries.items()}
    assert np.isclose(lengths["left"], length - radius)
    assert np.isclose(lengths["bottom"], length - radius)
    assert np.isclose(lengths["right"], length) and np.isclose(lengths["top"], length)
    assert np.isclose(lengths["hole"], np.pi * radius / 2, rtol=1e-2)
    assert r.min() > radius - 1e-10

    spacing = meshes.local_spacing(mesh)
    on_hole = np.unique(mesh.facets[:, mesh.boundaries["hole"]])
    h_expected = h if h_hole is None else h_hole
    assert 0.5 * h_expected < np.median(spacing[on_hole]) < 1.5 * h_expected


def test_gmsh_meshes_reject_bad_input():
    with pytest.raises(ValueError, match="radius"):
        meshes.gmsh_plate_with_hole(2.0, 1.0, 0.1)
    with pytest.raises(ValueError, match="kind"):
        meshes.gmsh_rectangle(1.0, 1.0, 0.1, kind="hex")
    assert not gmsh.isInitialized()


def test_gmsh_state_of_the_caller_is_kept():
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("mine")
        gmsh.option.setNumber("Mesh.Algorithm", 5)
        mesh = meshes.gmsh_rectangle(1.0, 1.0, 0.25, kind="quad")
        assert mesh.t.shape[0] == 4
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() == "mine"
        assert "rectangle" not in gmsh.model.list()
        assert gmsh.option.getNumber("Mesh.Algorithm") == 5
    finally:
        gmsh.finalize()


# ---------------------------------------------------------------------------
# conversion and files
# ---------------------------------------------------------------------------


def write_square(path, clockwise=False, stray_point=False, version=4.1):
    """Mesh the unit square with gmsh and write it to ``path``."""
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        geo = gmsh.model.geo
        pts = [geo.addPoint(x, y, 0, 0.25) for x, y in [(0, 0), (1, 0), (1, 1), (0, 1)]]
        lines = [geo.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
        loop = [-line for line in reversed(lines)] if clockwise else lines
        surface = geo.addPlaneSurface([geo.addCurveLoop(loop)])
        if stray_point:
            geo.addPoint(5, 5, 0, 0.25)
        geo.synchronize()
        gmsh.model.addPhysicalGroup(1, [lines[0], lines[1]], name="bottom_right")
        gmsh.model.addPhysicalGroup(1, [lines[3]])
        gmsh.model.addPhysicalGroup(2, [surface], name="square")
        # keep the stray node, which belongs to no physical group
        gmsh.option.setNumber("Mesh.SaveAll", int(stray_point))
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.model.mesh.generate(2)
        types, _, nodes = gmsh.model.mesh.getElements(2)
        xyz = gmsh.model.mesh.getNodes()[1].reshape(-1, 3)
        tags = gmsh.model.mesh.getNodes()[0]
        order = np.argsort(tags)
        t = np.searchsorted(tags[order], np.asarray(nodes[0]).reshape(-1, 3).T)
        gmsh_areas = cell_areas(skfem.MeshTri1(xyz[order, :2].T, t, sort_t=False))
        gmsh.write(str(path))
        return gmsh_areas
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("version", [4.1, 2.2])
def test_load_round_trip(tmp_path, version):
    path = tmp_path / "square.msh"
    write_square(path, version=version)
    mesh = meshes.load(path)
    assert isinstance(mesh, skfem.MeshTri1)
    assert np.isclose(cell_areas(mesh).sum(), 1.0)
    assert set(mesh.boundaries) == {"bottom_right", "2"}
    x = facet_midpoints(mesh, mesh.boundaries["bottom_right"])
    assert np.all(np.isclose(x[1], 0) | np.isclose(x[0], 1))
    assert np.isclose(facet_lengths(mesh, mesh.boundaries["bottom_right"]).sum(), 2)
    assert np.allclose(facet_midpoints(mesh, mesh.boundaries["2"])[0], 0)
    np.testing.assert_array_equal(mesh.subdomains["square"], np.arange(mesh.nelements))
    assert not gmsh.isInitialized()


def test_from_gmsh_orients_cells_and_drops_unused_nodes(tmp_path):
    path = tmp_path / "cw.msh"
    gmsh_areas = write_square(path, clockwise=True, stray_point=True)
    assert np.all(gmsh_areas < 0)  # gmsh gives clockwise cells here
    mesh = meshes.load(path)
    assert cell_areas(mesh).min() > 0 and min_jacobian(mesh) > 0
    assert mesh.nvertices == len(np.unique(mesh.t))
    assert mesh.p.max() <= 1.0


def test_load_errors_name_the_file(tmp_path):
    missing = tmp_path / "missing.msh"
    with pytest.raises(ValueError, match="missing.msh.*does not exist"):
        meshes.load(missing)

    garbage = tmp_path / "garbage.msh"
    garbage.write_text("not a mesh\n")
    with pytest.raises(ValueError, match="garbage.msh"):
        meshes.load(garbage)

    lines_only = tmp_path / "line.msh"
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        a = gmsh.model.geo.addPoint(0, 0, 0, 0.1)
        b = gmsh.model.geo.addPoint(1, 0, 0, 0.1)
        gmsh.model.geo.addLine(a, b)
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(1)
        gmsh.write(str(lines_only))
    finally:
        gmsh.finalize()
    with pytest.raises(ValueError, match="line.msh.*no 2D cells"):
        meshes.load(lines_only)
    assert not gmsh.isInitialized()


# ---------------------------------------------------------------------------
# local spacing
# ---------------------------------------------------------------------------


def interior(mesh):
    mask = np.ones(mesh.nvertices, dtype=bool)
    mask[mesh.boundary_nodes()] = False
    return mask


def test_local_spacing_of_uniform_grids():
    h = 0.25
    quad = meshes.rectangle(2.0, 1.0, 8, 4, kind="quad")
    spacing = meshes.local_spacing(quad)
    assert spacing.shape == (quad.nvertices,)
    np.testing.assert_allclose(spacing, h)

    # interior vertices of the triangle grid also see two diagonals
    tri = meshes.rectangle(2.0, 1.0, 8, 4, kind="tri")
    spacing = meshes.local_spacing(tri)[interior(tri)]
    np.testing.assert_allclose(spacing, (4 + 2 * np.sqrt(2)) * h / 6)

    # rectangular cells: mean of the two spacings
    stretched = meshes.rectangle(2.0, 1.0, 4, 10, kind="quad")
    spacing = meshes.local_spacing(stretched)[interior(stretched)]
    np.testing.assert_allclose(spacing, (0.5 + 0.1) / 2)


def test_local_spacing_in_1d_and_3d():
    x = np.array([0.0, 0.1, 0.3, 0.7, 1.5])
    line = skfem.MeshLine1(x[None, :], np.array([[0, 1, 2, 3], [1, 2, 3, 4]]))
    np.testing.assert_allclose(meshes.local_spacing(line), [0.1, 0.15, 0.3, 0.6, 0.8])

    g = np.linspace(0, 1, 5)
    hexes = skfem.MeshHex.init_tensor(g, g, g)
    np.testing.assert_allclose(meshes.local_spacing(hexes), 0.25)


def test_large_gmsh_mesh_is_handed_to_skfem_contiguous(caplog):
    """scikit-fem logs "Transforming over 1000 vertices to C_CONTIGUOUS."
    for arrays that are not; gmsh's transposed coordinates were."""
    import logging

    from skfem_rkpm.meshes import gmsh_rectangle

    with caplog.at_level(logging.WARNING):
        mesh = gmsh_rectangle(1.0, 1.0, 0.025)
    assert mesh.nvertices > 1000 and mesh.nelements > 1000
    assert "C_CONTIGUOUS" not in caplog.text
    assert mesh.p.flags["C_CONTIGUOUS"] and mesh.t.flags["C_CONTIGUOUS"]
