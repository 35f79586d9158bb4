"""The quarter-cylinder mesh (skfem_rkpm.meshes.cylinders): its volume
against the chord polygon of the arc, a conforming mesh (every boundary
facet named once), cells of one orientation, the radial spacing, the
named boundaries on their surfaces, bad sizes refused, and the scene kind
``quarter_cylinder``."""

import numpy as np
import pytest
from skfem import Basis, ElementHex1, ElementQuad1, MeshHex

from skfem_rkpm.meshes import quarter_cylinder, quarter_disk
from skfem_rkpm.runs.scene import (SceneError, builtin_scenes, load_scene, mesh_from,
                                   parse_scene)


def fan_area(radius, n_core):
    """Area of the quarter disk's polygon: the fan of ``2 n_core`` chords
    of the arc from the origin (the mantle's vertices lie on the circle)."""
    n = 2 * n_core
    return n * 0.5 * radius ** 2 * np.sin(0.5 * np.pi / n)


@pytest.mark.parametrize("n_core, n_outer", [(1, 1), (2, 1), (3, 3), (4, 2)])
def test_quarter_disk_covers_the_chord_polygon(n_core, n_outer):
    """The cells' areas add up to the fan of chords (to round-off), all
    counter-clockwise, the arc's vertices on r = R, and the radial cells
    along y = 0 equal (R / (n_core + n_outer))."""
    mesh = quarter_disk(3.2, n_core, n_outer)
    basis = Basis(mesh, ElementQuad1())
    assert basis.mapping.detDF(basis.quadrature[0]).min() > 0
    assert sum(basis.dx.ravel()) == pytest.approx(fan_area(3.2, n_core), rel=1e-13)
    assert mesh.p.shape[1] == (n_core + 1) ** 2 + 2 * n_outer * (n_core + 1) - n_outer
    x = np.sort(mesh.p[0, np.abs(mesh.p[1]) < 1e-12])
    np.testing.assert_allclose(np.diff(x), 3.2 / (n_core + n_outer), rtol=1e-12)
    arc = mesh.p[:, np.unique(mesh.facets[:, mesh.boundaries["outer"]])]
    np.testing.assert_allclose(np.hypot(*arc), 3.2, rtol=1e-14)
    assert len(mesh.boundaries["outer"]) == 2 * n_core


def test_quarter_cylinder_is_conforming_and_named():
    """Volume = fan area x height; every boundary facet is in exactly one
    named boundary (unmerged vertices between the blocks would leave
    interior facets on the boundary); all cells have the orientation of
    scikit-fem's own hexahedra (MeshHex.init_tensor); each name on its
    surface."""
    R, H, nc, no, nz = 3.2, 32.4, 3, 2, 7
    mesh = quarter_cylinder(R, H, nc, no, nz)
    assert isinstance(mesh, MeshHex)
    assert mesh.t.shape[1] == (nc * nc + 2 * nc * no) * nz
    basis = Basis(mesh, ElementHex1())
    assert sum(basis.dx.ravel()) == pytest.approx(fan_area(R, nc) * H, rel=1e-12)
    reference = Basis(MeshHex.init_tensor([0.0, 1.0], [0.0, 1.0], [0.0, 1.0]), ElementHex1())
    sign = np.sign(reference.mapping.detDF(reference.quadrature[0]).ravel()[0])
    assert (sign * basis.mapping.detDF(basis.quadrature[0])).min() > 0
    named = np.concatenate(list(mesh.boundaries.values()))
    assert np.array_equal(np.sort(named), np.sort(mesh.boundary_facets()))
    counts = {k: len(v) for k, v in mesh.boundaries.items()}
    assert counts == {"xmin": (nc + no) * nz, "ymin": (nc + no) * nz, "outer": 2 * nc * nz,
                      "bottom": nc * nc + 2 * nc * no, "top": nc * nc + 2 * nc * no}
    p = lambda name: mesh.p[:, np.unique(mesh.facets[:, mesh.boundaries[name]])]  # noqa: E731
    assert np.all(p("xmin")[0] == 0.0) and np.all(p("ymin")[1] == 0.0)
    assert np.all(p("bottom")[2] == 0.0) and np.allclose(p("top")[2], H, rtol=1e-15)
    np.testing.assert_allclose(np.hypot(*p("outer")[:2]), R, rtol=1e-14)


@pytest.mark.parametrize("args, message", [
    ((0.0, 1.0, 1, 1, 1), "radius must be positive"),
    ((1.0, -1.0, 1, 1, 1), "height must be positive"),
    ((1.0, 1.0, 0, 1, 1), "n_core must be an integer >= 1"),
    ((1.0, 1.0, 1, 1.5, 1), "n_outer must be an integer >= 1"),
    ((1.0, 1.0, 1, 1, 0), "nz must be an integer >= 1"),
])
def test_quarter_cylinder_refuses_bad_sizes(args, message):
    with pytest.raises(ValueError, match=message):
        quarter_cylinder(*args)


def test_scene_kind_quarter_cylinder():
    """The scene's geometry gives the mesh; tetrahedra, a missing radius and
    two divisions are refused with the key named."""
    path = builtin_scenes()["taylor_bar_3d"]
    scene = load_scene(path, ["geometry.divisions=[2,1,4]"])
    mesh = mesh_from(scene["geometry"])
    assert mesh.t.shape[1] == (4 + 4) * 4 and set(mesh.boundaries) == {
        "xmin", "ymin", "outer", "bottom", "top"}
    with pytest.raises(SceneError, match="a quarter_cylinder has hex cells only"):
        load_scene(path, ['geometry.cells="tet"'])
    with pytest.raises(SceneError, match=r"a quarter_cylinder needs 3 values \[core, core "
                                         r"to mantle, along z\]"):
        load_scene(path, ["geometry.divisions=[2,4]"])
    text = path.read_text().replace("radius = 3.2\n", "")
    with pytest.raises(SceneError, match="kind = \"quarter_cylinder\" needs 'radius'"):
        parse_scene(text)
