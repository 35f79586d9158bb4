"""The geometry of a scene and what its dimension implies.

:func:`check_geometry` checks the ``[geometry]`` section (the keys each
kind needs, the cell types it has) and that it fits ``model.type``: a
rectangle or an annulus is a 2D section (plane strain, axisymmetric), a
box a 3D body; a gmsh file is either, which :func:`check_mesh` checks once
the file is read.  :func:`check_components` checks the vectors of the rest
of the scene against the model's dimension: displacement components, the
length of tractions and of followed points, and what exists in 2D only.
:func:`mesh_from` makes the background mesh.  Used by
:mod:`skfem_rkpm.runs.scene` (parsing) and :mod:`skfem_rkpm.runs.build`.
"""

from pathlib import Path

import numpy as np

from .scene_values import COMPONENTS, SceneError

__all__ = ["DIMENSIONS", "model_dimension", "check_geometry", "check_components",
           "check_mesh", "mesh_from"]

#: the dimension of each kind of geometry (a gmsh file: that of its cells)
DIMENSIONS = {"rectangle": 2, "annulus": 2, "box": 3, "ring_sector": 3, "quarter_cylinder": 3}

#: what the divisions of a kind count, where not cells along x, y (and z)
DIVISIONS = {"quarter_cylinder": "[core, core to mantle, along z]"}

#: the cell types of each dimension, the default first
CELLS = {2: ("quad", "tri"), 3: ("hex", "tet")}

#: what each kind of geometry needs
NEEDS = {"rectangle": ("x", "y", "divisions"), "annulus": ("radii", "divisions"),
         "box": ("lx", "ly", "lz", "divisions"), "ring_sector": ("radii", "lz", "divisions"),
         "quarter_cylinder": ("radius", "lz", "divisions"),
         "gmsh": ("file",)}


def model_dimension(model_type):
    """3 for the ``"3d"`` model, 2 for plane strain and axisymmetry."""
    return 3 if model_type == "3d" else 2


def _fits(model_type, dim, what):
    """What is wrong when ``what`` (of dimension ``dim``) meets ``model_type``."""
    if model_dimension(model_type) == dim:
        return None
    if dim == 3:
        return (f'"{model_type}" is a 2D model, but {what} is a 3D body; use '
                f'type = "3d"')
    return (f'"3d" needs a 3D geometry (geometry.kind = "box", or a gmsh file with '
            f'volumes), but {what} is a 2D section; use type = "plane_strain" or '
            f'"axisymmetric", or a 3D geometry')


def check_geometry(scene, fail):
    """Check the ``[geometry]`` section and that it fits ``model.type``;
    fill in the default cell type of the kind.  ``fail(key, message)``
    raises."""
    geometry = scene["geometry"]
    kind = geometry["kind"]
    for key in NEEDS[kind]:
        if geometry[key] is None:
            fail("geometry", f"kind = \"{kind}\" needs {key!r}")
    if kind == "gmsh":
        return
    dim = DIMENSIONS[kind]
    problem = _fits(scene["model"]["type"], dim, f'geometry.kind = "{kind}"')
    if problem:
        fail("model.type", problem)
    if geometry["cells"] is None:
        geometry["cells"] = CELLS[dim][0]
    elif geometry["cells"] not in CELLS[dim]:
        fail("geometry.cells", f"a {kind} has {' or '.join(CELLS[dim])} cells, "
                               f"not {geometry['cells']!r}")
    if len(geometry["divisions"]) != dim:
        fail("geometry.divisions", f"a {kind} needs {dim} values " + DIVISIONS.get(
            kind, "[nx, ny, nz]" if dim == 3 else "[nx, ny]"))
    if kind == "quarter_cylinder" and geometry["cells"] != "hex":
        fail("geometry.cells", "a quarter_cylinder has hex cells only")
    if kind == "ring_sector":
        if geometry["cells"] != "hex":
            fail("geometry.cells", "a ring_sector has hex cells only")
        if geometry["angles"][0] != 0.0 or geometry["angles"][1] >= 180.0:
            fail("geometry.angles", "a ring_sector spans [0, angle] with angle < 180 "
                                    f"degrees, not {geometry['angles']}")
    if kind == "annulus":
        if geometry["grading"] is not None and geometry["grading"][1] != 1.0:
            fail("geometry.grading", "an annulus is graded across the wall only; give "
                                     "[ratio, 1]")
    elif kind == "rectangle":
        for axis, key in enumerate(("x_segments", "y_segments")):
            span = geometry["xy"[axis]]
            if geometry[key] is not None:
                first, last = geometry[key][0][0], geometry[key][-1][0]
                if not (first > span[0] and abs(last - span[1]) <= 1e-9 * max(abs(span[1]), 1)):
                    fail(f"geometry.{key}", f"segment ends must lie in ({span[0]:g}, "
                                            f"{span[1]:g}] and the last must be {span[1]:g}")


def check_components(scene, fail):
    """Check the vectors of boundaries and followed points, and the 2D-only
    options, against the dimension of ``model.type``."""
    dim = model_dimension(scene["model"]["type"])
    names = "xyz"[:dim]
    for name, section in scene.items():
        if not name.startswith("boundary."):
            continue
        for comp in section["fix"] or []:
            if comp not in COMPONENTS:
                fail(f"{name}.fix", f"unknown component {comp!r}; use x, y, z or r")
            _check_component(comp, dim, f"{name}.fix", fail)
        for key in ("displacement", "traction"):
            value = section[key]
            if isinstance(value, list) and len(value) != dim:
                fail(f"{name}.{key}", f"needs {dim} components [{', '.join(names)}] in a "
                                      f"{dim}D model, not {len(value)}")
            for comp in value if isinstance(value, dict) else ():
                _check_component(comp, dim, f"{name}.{key}", fail)
        moved = set(prescribed_indices(section["displacement"]))
        both = sorted({COMPONENTS[c] for c in section["fix"] or []} & moved)
        if both:
            fail(f"{name}.displacement", f"component {'xyz'[both[0]]} is also in fix; "
                                         "fix holds it at 0, give it once")
        if dim == 3 and section["follower"]:
            fail(f"{name}.follower", "a follower pressure is implemented for 2D models "
                                     "only; omit follower (a dead pressure) in 3D")
    for point, X in scene["output"]["points"].items():
        if len(X) != dim:
            fail("output.points", f"point {point!r} needs {dim} coordinates "
                                  f"[{', '.join(n.upper() for n in names)}] in a "
                                  f"{dim}D model, not {len(X)}")


def _check_component(name, dim, key, fail):
    """A component named in ``key`` must exist in a ``dim``-D model."""
    if COMPONENTS[name] >= dim:
        fail(key, f"component {name!r} exists in 3D models only; a 2D model has x (r) "
                  "and y (the axis of an axisymmetric model is y)")


def prescribed_indices(values):
    """The component indices of a ``displacement`` or ``traction`` value."""
    if values is None:
        return []
    if isinstance(values, list):
        return list(range(len(values)))
    return [COMPONENTS[name] for name in values]


def check_mesh(scene, mesh):
    """Check a read mesh against the scene: its dimension against
    ``model.type`` (a gmsh file may hold either) and the Gauss rule of
    ``discretization.quadrature`` on its cells.  Raises :class:`SceneError`."""
    from skfem.quadrature import get_quadrature

    geometry = scene["geometry"]
    what = (f"the mesh of geometry.file {geometry['file']!r} ({type(mesh).__name__})"
            if geometry["kind"] == "gmsh" else f'geometry.kind = "{geometry["kind"]}"')
    problem = _fits(scene["model"]["type"], mesh.dim(), what)
    if problem:
        raise SceneError(f"model.type: {problem}")
    degree = scene["discretization"]["quadrature"]
    try:
        get_quadrature(mesh.refdom, degree)
    except NotImplementedError:
        raise SceneError(f"discretization.quadrature: scikit-fem has no Gauss rule of "
                         f"degree {degree} for the {type(mesh).__name__} cells; use a "
                         f"lower degree (tetrahedra: at most 8)") from None


def mesh_from(section, base=None, trust_geo=False):
    """The background mesh of a scene's geometry section (``trust_geo``: let a
    ``.geo`` file run programs or read other files, see
    :func:`skfem_rkpm.meshes.geo_check.check_geo`)."""
    from ..meshes import box, graded_rectangle, load, rectangle

    if section["kind"] == "annulus":
        from ..meshes import annulus

        nr, nt = section["divisions"]
        grading = (section.get("grading") or [1.0, 1.0])[0]
        try:
            return annulus(*section["radii"], nr, nt, section.get("angles") or (0.0, 360.0),
                           grading, section.get("cells") or "quad",
                           section.get("center") or (0.0, 0.0))
        except ValueError as err:
            raise SceneError(f"geometry: {err}") from err
    if section["kind"] == "ring_sector":
        from ..meshes import ring_sector

        try:
            return ring_sector(*section["radii"], section["lz"], *section["divisions"],
                               angle=section["angles"][1])
        except ValueError as err:
            raise SceneError(f"geometry: {err}") from err
    if section["kind"] == "quarter_cylinder":
        from ..meshes import quarter_cylinder

        try:
            return quarter_cylinder(section["radius"], section["lz"], *section["divisions"])
        except ValueError as err:
            raise SceneError(f"geometry: {err}") from err
    if section["kind"] == "gmsh":
        path = Path(section["file"])
        if base is not None and not path.is_absolute():
            path = Path(base) / path
        try:
            return load(path, trust_geo=trust_geo)
        except ValueError as err:
            raise SceneError(f"geometry.file: {err}") from err
    if section["kind"] == "box":
        try:
            return box(section["lx"], section["ly"], section["lz"], *section["divisions"],
                       kind=section.get("cells") or "hex",
                       origin=section.get("origin") or (0.0, 0.0, 0.0))
        except ValueError as err:
            raise SceneError(f"geometry: {err}") from err
    (x0, x1), (y0, y1) = section["x"], section["y"]
    nx, ny = section["divisions"]
    cells = section.get("cells") or "quad"
    if section.get("x_segments") or section.get("y_segments"):
        from ..meshes import piecewise_rectangle

        return piecewise_rectangle(_breaks(x0, x1, nx, section.get("x_segments")),
                                   _breaks(y0, y1, ny, section.get("y_segments")),
                                   kind=cells)
    grading = section["grading"] or [1.0, 1.0]
    if grading != [1.0, 1.0]:
        if grading[0] != grading[1]:
            raise SceneError("geometry.grading: different ratios per direction are "
                             "not supported yet; give equal values")
        mesh = graded_rectangle(x1 - x0, y1 - y0, nx, ny, grading[0], kind=cells)
        return mesh.translated((x0, y0))
    return rectangle(x1 - x0, y1 - y0, nx, ny, kind=cells, origin=(x0, y0))


def _breaks(start, stop, cells, segments):
    """Vertex coordinates of piecewise uniform divisions (``[[end, cells], ...]``)."""
    if not segments:
        return np.linspace(start, stop, cells + 1)
    parts, a = [np.array([start])], start
    for end, n in segments:
        parts.append(np.linspace(a, end, n + 1)[1:])
        a = end
    return np.concatenate(parts)
