"""3D background meshes: the structured box and gmsh volume meshes with
named surfaces (``.geo`` and ``.msh``)."""

import gmsh
import numpy as np
import pytest
import skfem

from skfem_rkpm.meshes import box, load

FACES = {"xmin": (0, 0), "xmax": (0, 1), "ymin": (1, 0), "ymax": (1, 1), "zmin": (2, 0),
         "zmax": (2, 1)}


def facet_areas(mesh, facets):
    """Areas of triangular or quadrilateral (planar) facets."""
    corners = mesh.p[:, mesh.facets[:, facets]]  # (3, corners, facets)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0], axis=0), axis=0)
    if corners.shape[1] == 4:  # a planar quad in cyclic order: two triangles
        area += 0.5 * np.linalg.norm(np.cross(corners[:, 2] - corners[:, 0],
                                              corners[:, 3] - corners[:, 0], axis=0), axis=0)
    return area


def cell_volume(mesh):
    element = skfem.ElementHex1() if isinstance(mesh, skfem.MeshHex1) else skfem.ElementTetP1()
    return skfem.Basis(mesh, element).dx.sum()


def assert_faces(mesh, low, high):
    """Each named face holds exactly the boundary facets on that face, and
    their areas add up to the face's."""
    lengths = np.subtract(high, low)
    boundary = mesh.boundary_facets()
    middle = mesh.p[:, mesh.facets[:, boundary]].mean(axis=1)
    for name, (axis, side) in FACES.items():
        at = (low, high)[side][axis]
        expected = np.sort(boundary[np.abs(middle[axis] - at) < 1e-9])
        np.testing.assert_array_equal(np.sort(mesh.boundaries[name]), expected)
        others = [lengths[k] for k in range(3) if k != axis]
        assert facet_areas(mesh, mesh.boundaries[name]).sum() == pytest.approx(
            others[0] * others[1], rel=1e-12)


@pytest.mark.parametrize("kind, mesh_type, per_cell", [("hex", skfem.MeshHex1, 1),
                                                        ("tet", skfem.MeshTet1, None)])
def test_box_has_its_six_named_faces(kind, mesh_type, per_cell):
    mesh = box(2.0, 1.0, 3.0, 4, 2, 3, kind=kind, origin=(1.0, -1.0, 0.5))
    assert isinstance(mesh, mesh_type)
    assert mesh.nvertices == 5 * 3 * 4
    if per_cell:
        assert mesh.nelements == 4 * 2 * 3
    assert cell_volume(mesh) == pytest.approx(6.0, rel=1e-12)
    assert_faces(mesh, (1.0, -1.0, 0.5), (3.0, 0.0, 3.5))


@pytest.mark.parametrize("args, message", [
    ((0.0, 1.0, 1.0, 2, 2, 2), "lx must be positive"),
    ((1.0, 1.0, -2.0, 2, 2, 2), "lz must be positive"),
    ((1.0, 1.0, 1.0, 2, 0, 2), "ny must be an integer >= 1"),
    ((1.0, 1.0, 1.0, 2, 2, 2.5), "nz must be an integer >= 1"),
])
def test_box_refuses_bad_sizes(args, message):
    with pytest.raises(ValueError, match=message):
        box(*args)


def test_box_refuses_bad_kind_and_origin():
    with pytest.raises(ValueError, match="kind must be 'hex' or 'tet'"):
        box(1, 1, 1, 1, 1, 1, kind="quad")
    with pytest.raises(ValueError, match="origin must be three numbers"):
        box(1, 1, 1, 1, 1, 1, origin=(0.0, 0.0))


TET_GEO = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 2, 3};
// OpenCASCADE numbers the faces of a box x = 0, x = 1, y = 0, y = 1, z = 0, z = 1
Physical Surface("xmin") = {1};
Physical Surface("zmax") = {6};
Physical Volume("part") = {1};
Mesh.MeshSizeMax = 0.6;
"""

HEX_GEO = """Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0}; Point(4) = {0, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Transfinite Curve{1, 2, 3, 4} = 3; Transfinite Surface{1}; Recombine Surface{1};
out[] = Extrude {0, 0, 2} { Surface{1}; Layers{4}; Recombine; };
Physical Surface("zmin") = {1};
Physical Surface("zmax") = {out[0]};
Physical Volume("part") = {out[1]};
"""


def test_geo_volume_with_named_surfaces_gives_tetrahedra(tmp_path):
    path = tmp_path / "block.geo"
    path.write_text(TET_GEO)
    mesh = load(path)
    assert isinstance(mesh, skfem.MeshTet1)
    assert cell_volume(mesh) == pytest.approx(6.0, rel=1e-12)
    assert sorted(mesh.boundaries) == ["xmin", "zmax"]
    assert set(mesh.subdomains) == {"part"}
    assert len(mesh.subdomains["part"]) == mesh.nelements
    for name, axis, at, area in (("xmin", 0, 0.0, 6.0), ("zmax", 2, 3.0, 2.0)):
        facets = mesh.boundaries[name]
        np.testing.assert_allclose(mesh.p[axis, mesh.facets[:, facets]], at, atol=1e-12)
        assert facet_areas(mesh, facets).sum() == pytest.approx(area, rel=1e-12)
        assert np.all(np.isin(facets, mesh.boundary_facets()))


def test_geo_extruded_with_layers_gives_hexahedra(tmp_path):
    path = tmp_path / "column.geo"
    path.write_text(HEX_GEO)
    mesh = load(path)
    assert isinstance(mesh, skfem.MeshHex1)
    assert mesh.nelements == 2 * 2 * 4 and mesh.nvertices == 3 * 3 * 5
    # gmsh's (VTK's) vertex order is mapped to scikit-fem's: every cell maps
    # onto the reference hexahedron with the same Jacobian (no twisted cells)
    basis = skfem.Basis(mesh, skfem.ElementHex1())
    J = basis.mapping.detDF(basis.X)
    np.testing.assert_allclose(J, J.flat[0], rtol=1e-9)  # gmsh rounds its points to ~1e-12
    assert basis.dx.sum() == pytest.approx(2.0, rel=1e-12)
    for name, z in (("zmin", 0.0), ("zmax", 2.0)):
        facets = mesh.boundaries[name]
        assert len(facets) == 4
        np.testing.assert_allclose(mesh.p[2, mesh.facets[:, facets]], z, atol=1e-12)


def test_msh_volume_file_is_read_with_its_named_surfaces(tmp_path):
    geo, msh = tmp_path / "block.geo", tmp_path / "block.msh"
    geo.write_text(TET_GEO)
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(geo))
        gmsh.model.mesh.generate(3)
        gmsh.write(str(msh))
    finally:
        gmsh.finalize()
    from_geo, from_msh = load(geo), load(msh)
    assert isinstance(from_msh, skfem.MeshTet1)
    assert from_msh.nelements == from_geo.nelements
    for name in ("xmin", "zmax"):
        assert facet_areas(from_msh, from_msh.boundaries[name]).sum() == pytest.approx(
            facet_areas(from_geo, from_geo.boundaries[name]).sum(), rel=1e-12)


def test_volume_geo_that_runs_programs_is_still_refused(tmp_path):
    path = tmp_path / "block.geo"
    path.write_text(TET_GEO + 'SystemCall "touch owned";\n')
    with pytest.raises(ValueError, match="line 8: SystemCall runs a program"):
        load(path)
    assert not (tmp_path / "owned").exists()


def test_prisms_are_refused(tmp_path):
    """Triangles extruded in recombined layers make prisms, which have no
    scikit-fem mesh."""
    path = tmp_path / "prisms.geo"
    path.write_text(HEX_GEO.replace("Recombine Surface{1};", ""))
    with pytest.raises(ValueError, match="prisms.geo': unsupported cell type 'Prism 6'; "
                                         "use first-order tetrahedra or hexahedra"):
        load(path)
