"""3D scenes: the built-in block (``block_3d``, one eighth of a cube between
frictionless platens) run through the command line against the exact
homogeneous J2 solution for RKPM and FEM (Hex1, Tet1, F-bar); a gmsh volume
scene; dead loads in 3D; the output files; and the errors of scenes whose
geometry, model and vectors do not fit."""

import csv

import h5py
import meshio
import numpy as np
import pytest
import skfem

from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.runner import run
from skfem_rkpm.runs.scene import (SceneError, builtin_scenes, load_scene, material_from,
                                   parse_scene)
from skfem_rkpm.verification.exact import uniaxial_compression

from test_meshes_3d import TET_GEO

# 3 x 3 x 3 cells: 64 particles, 8 of them inside, so that supports cut by
# the boundary and whole ones both take part; a Newton tolerance far below
# the tolerances asserted (its residual is what is left of the error)
COARSE = ["geometry.divisions=[3, 3, 3]", "steps.count=5", "steps.tolerance=1e-12"]
TETS = ['geometry.cells="tet"', 'discretization.element="tet1"']


def run_block(tmp_path, method, settings):
    """Run ``block_3d`` through the command line; its history rows and scene."""
    out = tmp_path / method
    options = [x for s in settings for x in ("--set", s)]
    assert main(["run", "block_3d", "--out", str(out), "--quiet", "--method", method,
                 *options]) == 0
    with open(out / "history.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    return out, rows, load_scene(builtin_scenes()["block_3d"], settings)


def exact_block(scene, t):
    """The exact state of the block at load factor ``t`` and the force on
    its top face (nominal stress times the reference area)."""
    g, material = scene["geometry"], material_from(scene["material"])
    reduction = -scene["boundary.zmax"]["displacement"]["z"] * t / g["lz"]
    state = uniaxial_compression(reduction, material.E, material.nu, material.hardening)
    return state, reduction, state.nominal * g["lx"] * g["ly"]


@pytest.mark.parametrize("method, cells", [("rkpm", "hex"), ("fem", "hex"),
                                           ("rkpm", "tet"), ("fem", "tet")])
def test_block_follows_the_exact_uniaxial_solution(tmp_path, method, cells):
    """Every step's force on the top face (and the reaction of the bottom
    symmetry plane) is the exact nominal stress times the area, and the final
    displacement is the homogeneous u = ((λ - 1) X, (λ - 1) Y, -δ Z).

    Both discretizations hold a homogeneous deformation exactly (RK: linear
    completeness with VCI gradients and weak conditions; Hex1, Tet1: linear
    fields; F-bar averages a constant J), so what is left is the Newton
    residual and round-off: measured at most 7e-13 relative (forces) and
    1.1e-12 (displacements) with the Newton tolerance 1e-12 (with 1e-10 the
    force of the first plastic step is off by 1.3e-9); the exact curve is
    solved to 1e-15 (brentq).  Asserted: 1e-10.
    """
    out, rows, scene = run_block(tmp_path, method, COARSE + (TETS if cells == "tet" else []))
    assert len(rows) == 5
    for row in rows:
        state, _, force = exact_block(scene, float(row["t"]))
        assert float(row["reaction zmax[2]"]) == pytest.approx(force, rel=1e-10)
        assert float(row["reaction zmin[2]"]) == pytest.approx(-force, rel=1e-10)
        # the corner of the eighth: the lateral stretch in x and y
        assert float(row["corner x"]) == pytest.approx(10.0 * state.lateral_stretch,
                                                       rel=1e-10)
    state, reduction, _ = exact_block(scene, 1.0)
    assert reduction == 0.5 and state.alpha > 0.6  # far into the plastic range
    with h5py.File(out / "fields" / "mesh.h5", "r") as f:
        X = f["points"][:]
    with h5py.File(out / "fields" / "step-000005.h5", "r") as f:
        u, alpha = f["displacement"][:], f["plastic_strain"][:]
        stress = f["stress"][:].reshape(-1, 3, 3)
    stretch = np.array([state.lateral_stretch, state.lateral_stretch, 1.0 - reduction])
    np.testing.assert_allclose(u, X * (stretch - 1.0), rtol=0, atol=1e-10 * np.abs(u).max())
    np.testing.assert_allclose(alpha, state.alpha, rtol=1e-10)
    np.testing.assert_allclose(stress[:, 2, 2], state.cauchy, rtol=1e-10)
    np.testing.assert_allclose(stress[:, 0, 0], 0.0, atol=1e-10 * abs(state.cauchy))
    for name in ("deformed.png", "section.png", "forces.png", "fields.xdmf"):
        assert (out / name).exists(), name


def test_fields_open_as_valid_hexahedra(tmp_path):
    """``fields.xdmf`` read back by meshio (VTK vertex order) gives
    untwisted hexahedra of the box's volume: every cell's Jacobian is the
    same constant (a wrongly ordered cell has a varying or zero one)."""
    out, _, _ = run_block(tmp_path, "fem", ["geometry.divisions=[2, 3, 2]", "steps.count=1",
                                            "output.figures=false"])
    with meshio.xdmf.TimeSeriesReader(str(out / "fields.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        _, point_data, cell_data = reader.read_data(0)
    assert [c.type for c in cells] == ["hexahedron"] and len(cells[0].data) == 12
    assert point_data["displacement"].shape == (36, 3)
    assert cell_data["plastic_strain"][0].shape == (12,)
    mesh = skfem.io.meshio.from_meshio(meshio.Mesh(points, cells))
    basis = skfem.Basis(mesh, skfem.ElementHex1())
    J = basis.mapping.detDF(basis.X)
    np.testing.assert_allclose(J, J.flat[0], rtol=1e-12)
    assert basis.dx.sum() == pytest.approx(1000.0, rel=1e-12)


GMSH_SCENE = """
[model]
type = "3d"

[geometry]
kind = "gmsh"
file = "block.geo"

[discretization]
quadrature = 2
element = "tet1"

[material]
E = 200e3
nu = 0.3
yield = 300.0
hardening = "linear"
H = 1000.0

[boundary.xmin]
fix = ["x"]
method = "weak"

[boundary.ymin]
fix = ["y"]
method = "weak"

[boundary.zmin]
fix = ["z"]
method = "weak"

[boundary.zmax]
displacement = {z = -0.6}
method = "weak"

[steps]
count = 2
tolerance = 1e-12
"""

NAMED_GEO = TET_GEO.replace('Physical Surface("zmax") = {6};', """Physical Surface("ymin") = {3};
Physical Surface("zmin") = {5};
Physical Surface("zmax") = {6};""") + "MeshSize{PointsOf{Volume{1};}} = 0.8;\n"  # 100 particles


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_gmsh_volume_scene_compresses_homogeneously(tmp_path, method):
    """The block 1 x 2 x 3 of a ``.geo`` file, unstructured tetrahedra,
    compressed by 20 %: the same exact force as the structured box (the
    reasons and tolerance of :func:`test_block_follows_the_exact_uniaxial_solution`;
    measured 5e-13)."""
    (tmp_path / "block.geo").write_text(NAMED_GEO)
    scene = parse_scene(GMSH_SCENE, "block.toml", base=tmp_path)
    sim = build(scene, method)
    assert isinstance(sim.mesh, skfem.MeshTet1)
    result = run(sim, progress=False)
    assert result.completed, result.message
    material = material_from(scene["material"])
    for record in result.history:
        state = uniaxial_compression(0.2 * record.t, material.E, material.nu,
                                     material.hardening)
        assert record.reactions["zmax[2]"] == pytest.approx(state.nominal * 2.0, rel=1e-10)


@pytest.mark.parametrize("load", ["pressure = 100.0", "traction = [0.0, 0.0, -100.0]",
                                  "traction = {z = [[0.0, 0.0], [0.5, -100.0], [1.0, -100.0]]}"])
@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_dead_loads_on_a_face_are_carried_by_the_opposite_face(load, method):
    """A pressure or traction of 100 on the top face zmax (1 x 2) of an elastic
    block: the bottom's reaction is the applied 200 in every step (the
    equilibrium of the assembled forces, to the Newton tolerance 1e-12;
    measured 2e-12)."""
    text = (GMSH_SCENE.replace('kind = "gmsh"\nfile = "block.geo"',
                               'kind = "box"\nlx = 1.0\nly = 2.0\nlz = 1.0\n'
                               'divisions = [2, 2, 2]')
            .replace('element = "tet1"', 'element = "hex1"')
            .replace("displacement = {z = -0.6}", load)
            .replace('yield = 300.0\nhardening = "linear"\nH = 1000.0\n', ""))
    sim = build(parse_scene(text, "block.toml"), method)
    result = run(sim, progress=False)
    assert result.completed, result.message
    full = 1.0 if "[[" not in load else 2.0  # the table is at full load from t = 1/2
    for record in result.history:
        applied = 200.0 * min(1.0, full * record.t)
        assert record.reactions["zmin[2]"] == pytest.approx(applied, rel=1e-10)


# -- errors ------------------------------------------------------------------------

BOX = """
[model]
type = "3d"

[geometry]
kind = "box"
lx = 1.0
ly = 1.0
lz = 1.0
divisions = [2, 2, 2]

[material]
E = 200e3
nu = 0.3

[boundary.zmin]
fix = ["z"]
"""

RECTANGLE = """
[model]
type = "plane_strain"

[geometry]
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [2, 2]

[material]
E = 200e3
nu = 0.3

[boundary.bottom]
fix = ["y"]
"""


def error_of(text):
    with pytest.raises(SceneError) as info:
        parse_scene(text, "block.toml")
    return str(info.value)


@pytest.mark.parametrize("text, edit, expected", [
    (RECTANGLE, ('type = "plane_strain"', 'type = "3d"'),
     'block.toml, line 3: model.type: "3d" needs a 3D geometry (geometry.kind = "box", '
     'or a gmsh file with volumes), but geometry.kind = "rectangle" is a 2D section; use '
     'type = "plane_strain" or "axisymmetric", or a 3D geometry'),
    (BOX, ('type = "3d"', 'type = "axisymmetric"'),
     'block.toml, line 3: model.type: "axisymmetric" is a 2D model, but geometry.kind = '
     '"box" is a 3D body; use type = "3d"'),
    (BOX, ('type = "3d"\n', ''),
     'block.toml: model.type: "plane_strain" is a 2D model, but geometry.kind = "box" is '
     'a 3D body; use type = "3d"'),
    (BOX, ("lx = 1.0", "lx = 0.0"), "block.toml, line 7: geometry.lx: must be positive "
                                    "(got 0.0)"),
    (BOX, ("lz = 1.0", "lz = -2.0"), "line 9: geometry.lz: must be positive (got -2.0)"),
    (BOX, ("ly = 1.0\n", ""), "block.toml, line 5: geometry: kind = \"box\" needs 'ly'"),
    (BOX, ("divisions = [2, 2, 2]", "divisions = [2, 2]"),
     "line 10: geometry.divisions: a box needs 3 values [nx, ny, nz]"),
    (BOX, ("divisions = [2, 2, 2]", 'divisions = [2, 2, 2]\ncells = "quad"'),
     "line 11: geometry.cells: a box has hex or tet cells, not 'quad'"),
    (RECTANGLE, ("divisions = [2, 2]", 'divisions = [2, 2]\ncells = "hex"'),
     "geometry.cells: a rectangle has quad or tri cells, not 'hex'"),
    (RECTANGLE, ('fix = ["y"]', 'fix = ["z"]'),
     "line 15: boundary.bottom.fix: component 'z' exists in 3D models only; a 2D model "
     "has x (r) and y (the axis of an axisymmetric model is y)"),
    (RECTANGLE, ('fix = ["y"]', 'displacement = [0.0, 1.0, 0.0]'),
     "boundary.bottom.displacement: needs 2 components [x, y] in a 2D model, not 3"),
    (BOX, ('fix = ["z"]', 'traction = [0.0, 1.0]'),
     "line 17: boundary.zmin.traction: needs 3 components [x, y, z] in a 3D model, not 2"),
    (BOX, ('fix = ["z"]', 'fix = ["z"]\ndisplacement = {z = 1.0}'),
     "boundary.zmin.displacement: component z is also in fix"),
    (BOX, ('fix = ["z"]', 'pressure = 1.0\nfollower = true'),
     "boundary.zmin.follower: a follower pressure is implemented for 2D models only"),
    (BOX, ("nu = 0.3", 'nu = 0.3\n[output]\npoints = {a = [0.0, 1.0]}'),
     "output.points: point 'a' needs 3 coordinates [X, Y, Z] in a 3D model, not 2"),
])
def test_scene_errors_of_dimensions(text, edit, expected):
    assert edit[0] in text
    assert expected in error_of(text.replace(*edit))


def gmsh_scene(tmp_path, geo, model="3d", boundary="zmax"):
    (tmp_path / "part.geo").write_text(geo)
    text = (f'[model]\ntype = "{model}"\n[geometry]\nkind = "gmsh"\nfile = "part.geo"\n'
            f'[material]\nE = 1.0\nnu = 0.3\n[boundary.{boundary}]\nfix = ["x"]\n')
    return parse_scene(text, "part.toml", base=tmp_path)


def test_gmsh_volume_without_named_surfaces_names_what_to_add(tmp_path):
    geo = 'SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1};\nMesh.MeshSizeMax = 1;\n'
    with pytest.raises(SceneError) as info:
        build(gmsh_scene(tmp_path, geo))
    assert str(info.value) == (
        "[boundary.zmax]: the mesh has no boundary 'zmax'; the file part.geo defines no "
        "named boundaries: give its boundary surfaces names with Physical "
        "Surface(\"name\") = {...};")


def test_gmsh_mesh_of_the_wrong_dimension_is_refused(tmp_path):
    with pytest.raises(SceneError, match=r'model.type: "plane_strain" is a 2D model, but '
                                         r"the mesh of geometry.file 'part.geo' "
                                         r'\(MeshTet1\) is a 3D body; use type = "3d"'):
        build(gmsh_scene(tmp_path, NAMED_GEO, model="plane_strain", boundary="bottom"))
    square = ("Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0};\n"
              "Point(4) = {0, 1, 0}; Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4};\n"
              "Line(4) = {4, 1}; Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};\n"
              'Physical Curve("bottom") = {1};\n')
    with pytest.raises(SceneError, match=r"model.type: \"3d\" needs a 3D geometry .*, but "
                                         r"the mesh of geometry.file 'part.geo' "
                                         r"\(MeshTri1\) is a 2D section"):
        build(gmsh_scene(tmp_path, square, boundary="bottom"))


@pytest.mark.parametrize("setting, message", [
    ('discretization.element="quad1"',
     "discretization.element: 'quad1' does not fit the MeshHex1 cells; use hex1 or hex2"),
    ('discretization.quadrature=10',
     "discretization.quadrature: scikit-fem has no Gauss rule of degree 10 for the "
     "MeshTet1 cells"),
])
def test_build_errors_of_3d_cells(setting, message):
    from skfem_rkpm.runs.scene import apply_setting

    text = apply_setting(BOX, setting)
    if "quadrature" in setting:
        text = apply_setting(text, 'geometry.cells="tet"')
    with pytest.raises(SceneError, match=message):
        build(parse_scene(text, "block.toml"), "fem")


@pytest.mark.parametrize("kind", ["hex", "tet"])
def test_corner_jacobians_in_3d(kind):
    """A homogeneous F gives det F at every corner of every cell; the corner
    (1, 1, 1) of a unit cube moved to (0.2, 0.2, 0.2), behind the plane of
    its three neighbours, folds the cell there (det F = -1.4: the edges
    0.8 (1, 1, 1) - e_k) and nowhere else (its neighbours: 0.2, the others 1)."""
    from skfem_rkpm.meshes import box
    from skfem_rkpm.runs.io import corner_jacobians

    mesh = box(1.0, 2.0, 1.0, 2, 2, 1, kind=kind)
    A = np.array([[0.1, 0.2, 0.0], [0.0, -0.1, 0.3], [0.05, 0.0, 0.2]])
    J = corner_jacobians(mesh, (A @ mesh.p).T)
    np.testing.assert_allclose(J, np.linalg.det(np.eye(3) + A), rtol=1e-12)
    if kind == "tet":
        return
    cube = box(1.0, 1.0, 1.0, 1, 1, 1)
    corner = np.flatnonzero(np.all(cube.p == 1.0, axis=0))[0]
    u = np.zeros((8, 3))
    u[corner] = -0.8
    J = corner_jacobians(cube, u)[0]
    local = list(cube.t[:, 0]).index(corner)
    assert J[local] == pytest.approx(-1.4)
    np.testing.assert_allclose(sorted(np.delete(J, local)), [0.2] * 3 + [1.0] * 4)


@pytest.mark.parametrize("ny, layer_y", [(2, 1.0), (3, 2.0 / 3.0), (4, 1.0)])
def test_section_takes_the_layer_nearest_the_middle(ny, layer_y):
    from skfem_rkpm.meshes import box
    from skfem_rkpm.runs.plot3d import section_layer

    mesh = box(1.0, 2.0, 1.0, 2, ny, 2)
    vertices, Y = section_layer(mesh)
    assert Y == pytest.approx(layer_y)
    np.testing.assert_allclose(mesh.p[1, vertices], layer_y)
    assert len(vertices) == 3 * 3


# -- symmetry planes at any angle ---------------------------------------------------

SECTOR = """
[geometry]
kind = "annulus"
radii = [1.0, 2.0]
angles = [{start}, {end}]
divisions = [4, 6]

[material]
E = 200e3
nu = 0.3

[boundary.inner]
pressure = 20.0

[boundary.start]
{start_condition}
method = "{how}"

[boundary.end]
{end_condition}
method = "{how}"

[steps]
count = 1
tolerance = 1e-10
"""


@pytest.mark.parametrize("method, how", [("fem", "nodal"), ("fem", "weak"), ("rkpm", "weak")])
def test_symmetry_planes_at_an_angle_turn_the_solution(method, how):
    """A quarter ring under internal pressure with ``fix`` on its straight
    edges (on the axes), and the same quarter turned by 20° with
    ``symmetry = true`` there (normals not on the axes): the turned
    solution, to the Newton tolerance (1e-10; measured 4e-12 of the largest
    displacement; the turned mesh is the quarter's turned to 4e-16)."""
    quarter = build(parse_scene(SECTOR.format(start=0.0, end=90.0, how=how,
                                              start_condition='fix = ["y"]',
                                              end_condition='fix = ["x"]')), method)
    turned = build(parse_scene(SECTOR.format(start=20.0, end=110.0, how=how,
                                             start_condition="symmetry = true",
                                             end_condition="symmetry = true")), method)
    a = np.radians(20.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    np.testing.assert_allclose(turned.mesh.p, R @ quarter.mesh.p, atol=1e-14)
    reference = run(quarter, progress=False)
    assert reference.completed, reference.message
    u0 = quarter.basis.probes(quarter.mesh.p) @ reference.d
    result = run(turned, progress=False)
    assert result.completed, result.message
    u1 = turned.basis.probes(turned.mesh.p) @ result.d
    u0, u1 = u0.reshape(2, -1), u1.reshape(2, -1)
    np.testing.assert_allclose(u1, R @ u0, rtol=0, atol=1e-10 * np.abs(u0).max())
    # the reaction of a skew condition is named by its direction
    normal = np.array([np.sin(a), -np.cos(a)]) * -1  # largest component positive
    assert f"start[n={normal[0]:.4g} {normal[1]:.4g}]" in result.history[-1].reactions


ROTATED_CUBE = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Rotate {{0, 0, 1}, {0, 0, 0}, Pi / 6} { Volume{1}; }
Rotate {{1, 0, 0}, {0, 0, 0}, Pi / 9} { Volume{1}; }
// the faces of the box before the rotations: x = 0, y = 0, z = 0, z = 1
Physical Surface("a") = {1};
Physical Surface("b") = {3};
Physical Surface("c") = {5};
Physical Surface("top") = {6};
MeshSize{PointsOf{Volume{1};}} = 0.5;
"""

ROTATED_SCENE = """
[model]
type = "3d"

[geometry]
kind = "gmsh"
file = "cube.geo"

[discretization]
quadrature = 2
element = "tet1"

[material]
E = 200e3
nu = 0.3

[boundary.a]
symmetry = true
method = "{how}"

[boundary.b]
symmetry = true
method = "{how}"

[boundary.c]
symmetry = true
method = "{how}"

[boundary.top]
pressure = 2000.0

[steps]
count = 1
tolerance = 1e-12
"""


@pytest.mark.parametrize("method, how", [("fem", "nodal"), ("fem", "weak"), ("rkpm", "weak")])
def test_turned_cube_on_three_symmetry_planes_stretches_uniaxially(tmp_path, method, how):
    """A unit cube turned about z and x, unstructured tetrahedra, on
    symmetry planes (three skew faces) with a dead pressure p on the fourth:
    the homogeneous uniaxial state of the Hencky material, nominal stress
    E ln λ / λ = -p along the turned axis n (λ = 0.98997...), lateral
    stretch λ^(-ν) across it; the reaction of the opposite face along its
    normal is p (the resultant of a skew condition's multipliers along its
    direction).  Exact up to the Newton tolerance 1e-12: measured 2.6e-13 of
    the largest displacement and 2.5e-13 in the reaction."""
    from scipy.optimize import brentq

    (tmp_path / "cube.geo").write_text(ROTATED_CUBE)
    sim = build(parse_scene(ROTATED_SCENE.format(how=how), "cube.toml", base=tmp_path),
                method)
    result = run(sim, progress=False)
    assert result.completed, result.message
    E, nu, p = 200e3, 0.3, 2000.0
    stretch = brentq(lambda s: E * np.log(s) / s + p, 0.5, 1.0, xtol=1e-15)
    za, xa = np.radians(30.0), np.radians(20.0)
    Rz = np.array([[np.cos(za), -np.sin(za), 0], [np.sin(za), np.cos(za), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(xa), -np.sin(xa)], [0, np.sin(xa), np.cos(xa)]])
    R = Rx @ Rz  # the turned axes are the columns
    F = R @ np.diag([stretch ** -nu, stretch ** -nu, stretch]) @ R.T
    X = sim.mesh.p
    u = (sim.basis.probes(X) @ result.d).reshape(3, -1)
    np.testing.assert_allclose(u, (F - np.eye(3)) @ X, rtol=0, atol=1e-10 * np.abs(u).max())
    (name,) = [k for k in result.history[-1].reactions if k.startswith("c[")]
    assert name == "c[n=0 -0.342 0.9397]"  # R_x(20°) e_z
    assert abs(result.history[-1].reactions[name]) == pytest.approx(p, rel=1e-10)


def test_symmetry_on_a_curved_boundary_is_refused():
    text = SECTOR.format(start=0.0, end=90.0, how="nodal", start_condition='fix = ["y"]',
                         end_condition='fix = ["x"]').replace("pressure = 20.0",
                                                              "symmetry = true")
    with pytest.raises(SceneError, match=r"\[boundary.inner\] symmetry: boundary 'inner' is "
                                         r"not straight: its vertices lie up to 0.\d+ off the "
                                         r"best line .*; a symmetry plane must be flat"):
        build(parse_scene(text), "fem")


def test_symmetry_on_coordinate_planes_is_fix():
    """``symmetry = true`` on the box's faces is ``fix`` of the normal
    component: the same reactions, named by the component."""
    settings = COARSE + ["steps.count=2", "output.figures=false"]
    scene = load_scene(builtin_scenes()["block_3d"], settings)
    mirrored = load_scene(builtin_scenes()["block_3d"], settings + [
        f"boundary.{face}.{key}" for face in ("xmin", "ymin", "zmin")
        for key in ("fix=[]", "symmetry=true")])
    a = run(build(scene, "fem"), progress=False)
    b = run(build(mirrored, "fem"), progress=False)
    for ra, rb in zip(a.history, b.history):
        assert set(ra.reactions) == set(rb.reactions)
        for key in ra.reactions:
            assert rb.reactions[key] == pytest.approx(ra.reactions[key], rel=1e-12, abs=1e-6)
