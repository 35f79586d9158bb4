"""Rigid tools in 3D scenes: a platen compressing one eighth of a block
through the command line against the exact homogeneous J2 solution (RKPM
and FEM Hex1), the same platen as a triangulated surface read from a file,
and the errors of tool sections that do not fit the model."""

import csv

import meshio
import numpy as np
import pytest

from skfem_rkpm.mechanics.surface_contact import SurfaceContact
from skfem_rkpm.mechanics.surfaces import Cylinder, Plane, Sphere, Torus
from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.scene import SceneError, material_from, parse_scene
from skfem_rkpm.verification.exact import uniaxial_compression

BLOCK = """
[model]
type = "3d"
method = "rkpm"

[geometry]
kind = "box"
lx = 10.0
ly = 10.0
lz = 10.0
divisions = [3, 3, 3]

[discretization]
quadrature = 2

[material]
E = 210e3
nu = 0.3
hardening = "swift"
K = 530.0
eps0 = 0.005
n = 0.26

[boundary.xmin]
symmetry = true
method = "weak"

[boundary.ymin]
symmetry = true
method = "weak"

[boundary.zmin]
symmetry = true
method = "weak"

[steps]
count = 3
tolerance = 1e-12
"""

PLATEN = """
[tools.platen]
kind = "platen"
point = [0.0, 0.0, 10.0]
normal = [0.0, 0.0, -1.0]
motion = [0.0, 0.0, -3.0]
slaves = ["zmax"]
collocation = "quadrature"
"""


def run_scene(tmp_path, text, method, name="scene"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    out = tmp_path / f"{name}-{method}"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--method", method]) == 0
    with open(out / "history.csv", newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_platen_compresses_the_block_on_the_exact_curve(tmp_path, method):
    """Every step's platen force is the exact nominal stress times the area
    (100 mm²) at the height change ``3 t - penetration``: a homogeneous
    state is exact for both bases (RK: quadrature collocation integrates the
    uniform traction like the VCI boundary terms, weak symmetry planes);
    measured 2e-12, asserted 1e-9 against a Newton tolerance of 1e-12."""
    rows = run_scene(tmp_path, BLOCK + PLATEN, method)
    material = material_from(parse_scene(BLOCK + PLATEN)["material"])
    assert len(rows) == 3
    for row in rows:
        change = 3.0 * float(row["t"]) - float(row["platen penetration"])
        state = uniaxial_compression(change / 10.0, material.E, material.nu,
                                     material.hardening)
        assert float(row["reaction platen z"]) == pytest.approx(100.0 * state.nominal,
                                                                rel=1e-9)
        assert abs(float(row["reaction platen x"])) < 1e-9 * abs(state.nominal)
        assert float(row["platen dz"]) == pytest.approx(-3.0 * float(row["t"]))
    assert 0 < float(rows[-1]["platen penetration"]) < 1e-4


def test_a_platen_read_from_a_surface_file_is_the_platen(tmp_path, monkeypatch):
    """The platen as two triangles in an STL file (path relative to the
    scene): the same closest points, normals and curvature (zero), so the
    same run up to the Newton tolerance (1e-12 on the residual; measured
    5e-11 between the forces, asserted 1e-9)."""
    square = np.array([[-1, -1, 10], [20, -1, 10], [20, 20, 10], [-1, 20, 10]], float)
    # counter-clockwise seen from below: the body lies under the tool
    meshio.write(tmp_path / "platen.stl", meshio.Mesh(square, [("triangle",
                 np.array([[0, 2, 1], [0, 3, 2]]))]))
    surface = PLATEN.replace('kind = "platen"', 'kind = "surface"\nfile = "platen.stl"')
    surface = surface.replace('point = [0.0, 0.0, 10.0]\nnormal = [0.0, 0.0, -1.0]\n', "")
    plane = run_scene(tmp_path, BLOCK + PLATEN, "fem", "plane")
    reads = []
    read = meshio.read
    monkeypatch.setattr(meshio, "read", lambda *a, **k: reads.append(a) or read(*a, **k))
    faceted = run_scene(tmp_path, BLOCK + surface, "fem", "faceted")
    assert len(reads) == 1  # checked and built from one reading of the file
    for a, b in zip(plane, faceted):
        assert float(b["reaction platen z"]) == pytest.approx(float(a["reaction platen z"]),
                                                              rel=1e-9)


@pytest.mark.parametrize("section, kind", [
    ('kind = "cylinder"\npoint = [0.0, 0.0, 15.0]\naxis = [1.0, 0.0, 0.0]\nradius = 5.0',
     Cylinder),
    ('kind = "sphere"\ncenter = [0.0, 0.0, 15.0]\nradius = 5.0', Sphere),
    ('kind = "torus"\ncenter = [0.0, 0.0, 13.0]\naxis = [0.0, 0.0, 1.0]\nradius = 4.0\n'
     'minor_radius = 3.0', Torus),
    ('kind = "plane"\npoint = [0.0, 0.0, 10.0]\nnormal = [0.0, 0.0, -1.0]\n'
     'rotation = [0.0, 1.0, 0.0, 0.0, 0.0, 10.0, 5.0]', Plane),
])
def test_every_3d_tool_kind_builds_its_surface_contact(section, kind):
    """Each kind maps to its surface with the keys given (the torus's
    ``radius`` is the radius of its center circle) and a SurfaceContact on
    the slave boundaries."""
    scene = parse_scene(BLOCK + f"\n[tools.punch]\n{section}\nmotion = [0.0, 0.0, -1.0]\n"
                                "slaves = [\"zmax\"]\n")
    sim = build(scene)
    (contact,) = sim.tools
    assert isinstance(contact, SurfaceContact) and isinstance(contact.tool, kind)
    assert contact.tool.name == "punch"
    np.testing.assert_allclose(contact.tool.translation(1.0)[2],
                               -1.0 if kind is not Plane else contact.tool.translation(1.0)[2])
    if kind is Torus:
        proj = contact.tool.project(np.array([[4.0], [0.0], [9.0]]))
        assert proj.gap[0] == pytest.approx(1.0)  # below the tube: 13 - 3 - 9


@pytest.mark.parametrize("tool, message", [
    ('kind = "arc"\ncenter = [0.0, 0.0, 5.0]\nradius = 1.0\nangles = [0.0, 90.0]',
     "a 3D model takes the tools platen, plane, cylinder, sphere, torus, surface"),
    ('kind = "platen"\npoint = [0.0, 10.0]\nnormal = [0.0, -1.0]',
     "tools.platen.point: needs 3 components in a 3D model, not 2"),
    ('kind = "sphere"\ncenter = [0.0, 0.0, 15.0]', "a sphere needs 'radius'"),
    ('kind = "sphere"\ncenter = [0.0, 0.0, 15.0]\nradius = 5.0\nforce = 100.0',
     "a force-driven sphere needs 'direction'"),
    ('kind = "surface"\nfile = "no-such-tool.stl"', "no-such-tool.stl"),
    ('kind = "platen"\npoint = [0.0, 0.0, 10.0]\nnormal = [0.0, 0.0, 0.0]', "normal"),
])
def test_tool_sections_that_do_not_fit_a_3d_model_are_refused(tmp_path, tool, message):
    path = tmp_path / "bad.toml"
    path.write_text(BLOCK + f"\n[tools.platen]\n{tool}\n")
    with pytest.raises(SceneError, match="tools.platen") as err:
        from skfem_rkpm.runs.scene import load_scene
        load_scene(path)
    assert message in str(err.value)


def test_3d_tool_kinds_are_refused_in_2d():
    text = """
[model]
type = "plane_strain"
[geometry]
kind = "rectangle"
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [2, 2]
[material]
E = 1000.0
nu = 0.3
[tools.ball]
kind = "sphere"
center = [0.5, 2.0]
radius = 1.0
"""
    with pytest.raises(SceneError, match="a 2D model takes the tools platen, polyline, arc, "
                                         "not 'sphere'"):
        parse_scene(text)
    with pytest.raises(SceneError, match="rotating tools are 3D only"):
        parse_scene(text.replace('kind = "sphere"\ncenter = [0.5, 2.0]\nradius = 1.0',
                                 'kind = "platen"\npoint = [0.0, 1.0]\nnormal = [0.0, -1.0]\n'
                                 'rotation = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 5.0]'))


def test_force_driven_platen_presses_the_block_with_its_force(tmp_path):
    """A platen driven by a force history (20 kN, reached linearly) instead
    of a motion: every step's platen reaction is the force (the travel is
    solved for it, to 1e-9), and the height change it reaches is the one
    at which the exact uniaxial J2 state carries that force (to 1e-6: the
    penetration p/ω is part of the travel)."""
    from scipy.optimize import brentq

    text = BLOCK + PLATEN.replace("motion = [0.0, 0.0, -3.0]", "force = 20000.0")
    rows = run_scene(tmp_path, text, "fem", "pressed")
    material = material_from(parse_scene(text)["material"])
    for row in rows:
        force = 20000.0 * float(row["t"])
        assert -float(row["reaction platen z"]) == pytest.approx(force, rel=1e-9)
        change = brentq(lambda c: -uniaxial_compression(c, material.E, material.nu,
                                                        material.hardening).nominal
                        * 100.0 - force, 0.0, 0.5, xtol=1e-14)
        travel = float(row["platen travel"]) - float(row["platen penetration"])
        assert travel / 10.0 == pytest.approx(change, rel=1e-6)
