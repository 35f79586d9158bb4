"""The ``[tools.NAME]`` sections of a scene: their keys, their checks
against the model's dimension, and the rigid tool each describes.

2D models (plane strain, axisymmetric) take the tools of
:mod:`skfem_rkpm.mechanics.tools` (``platen``, ``polyline``, ``arc``);
3D models those of :mod:`skfem_rkpm.mechanics.surfaces` (``platen`` or
``plane``, ``cylinder``, ``sphere``, ``torus``, and ``surface``: a
triangulated surface read from a file).  Vectors have as many components
as the model has dimensions.
"""

from pathlib import Path

from ..mechanics.ramp import SmoothStart, ramped
from .scene_values import (HISTORY, Key, SceneError, _friction, _history, _non_negative,
                           _not_empty, _polyline_points, _positive)

__all__ = ["TOOL_SCHEMA", "TOOL_KINDS", "check_tool", "tool_from"]


def _vector(v):
    return None if len(v) in (2, 3) else "needs two values (2D) or three (3D)"


def _fraction(v):
    return None if 0.0 <= v <= 1.0 else "must be a fraction of the run in [0, 1]"


def _side(v):
    return None if v in ("outside", "inside") else 'must be "outside" or "inside"'


#: the kinds of tool of each dimension and the keys each needs
TOOL_KINDS = {
    2: {"platen": ("point", "normal"), "polyline": ("points",),
        "arc": ("center", "radius", "angles")},
    3: {"platen": ("point", "normal"), "plane": ("point", "normal"),
        "cylinder": ("point", "axis", "radius"), "sphere": ("center", "radius"),
        "torus": ("center", "axis", "radius", "minor_radius"), "surface": ("file",)},
}

TOOL_SCHEMA = {
    "kind": Key("str", "platen", choices=tuple(dict.fromkeys([*TOOL_KINDS[2],
                                                               *TOOL_KINDS[3]])),
                doc="2D: flat platen (infinite line), polyline of segments, circular arc; "
                    "3D: platen or plane, cylinder, sphere, torus, or a triangulated "
                    "surface from a file"),
    "point": Key("list[float]", check=_vector,
                 doc="platen/plane: a point of the surface; cylinder: a point of its axis"),
    "normal": Key("list[float]", check=_vector, doc="platen/plane: normal pointing to the body"),
    "points": Key("any", check=_polyline_points,
                  doc="polyline: [[x, y], ...], body on the left"),
    "fillet": Key("float", 0.0, check=_non_negative, doc="polyline: corner radius"),
    "center": Key("list[float]", check=_vector, doc="arc, sphere, torus: center"),
    "radius": Key("float", check=_positive,
                  doc="arc, cylinder, sphere: radius; torus: radius of its center circle"),
    "angles": Key("list[float]", check=lambda v: None if len(v) == 2 else "needs two values",
                  doc="arc: [start, end] in degrees"),
    "axis": Key("list[float]", check=_vector, doc="cylinder, torus (3D): axis direction"),
    "minor_radius": Key("float", check=_positive, doc="torus: radius of its tube"),
    "side": Key("str", "outside", check=_side,
                doc='cylinder, sphere, torus: the body "outside" (a punch, a roll) or '
                    '"inside" (a bore, a cavity)'),
    "file": Key("str", doc="surface: a triangulated surface (STL, OBJ, gmsh .msh, ... read "
                           "with meshio), relative to the scene file; the body on the side "
                           "its counter-clockwise triangles face"),
    "motion": Key("list[float]", check=_vector,
                  doc="displacement of the tool at the end of the run (default none)"),
    "rotation": Key("list[float]", check=lambda v: None if len(v) == 7 else
                    "needs 7 values: axis (3), a point of it (3), angle in degrees",
                    doc="3D: rotation about a fixed axis reached at the end of the run, "
                        "[ax, ay, az, px, py, pz, degrees] (a roll)"),
    "ramp": Key("float", check=_fraction,
                doc="dynamics: fraction of the duration over which the tool's speed rises "
                    "smoothly from zero (3τ² − 2τ³) to a constant speed, instead of "
                    "starting at full speed; the tool still reaches its motion (and "
                    "rotation) at the end (default 0; docs/dynamics.md)"),
    "force": Key("any", check=_history,
                 doc="force-driven tool: its push on the body along direction "
                     "follows this force history (" + HISTORY + "); the tool travels "
                     "as needed, on top of motion"),
    "direction": Key("list[float]", check=_vector,
                     doc="force-driven tool: direction of travel and push (default: "
                         "a platen's normal)"),
    "friction": Key("any", 0.0, check=_friction, doc='Coulomb μ, or "stick"'),
    "slaves": Key("list[str]", check=_not_empty,
                  doc="boundaries whose particles may touch the tool "
                      "(default: the whole boundary)"),
    "penalty": Key("float", check=_positive,
                   doc="normal penalty per unit area (default from E and the spacing)"),
    "collocation": Key("str", "nodal", choices=("nodal", "quadrature"),
                       doc="contact at the boundary particles (paper) or at boundary "
                           "quadrature points"),
    "enforcement": Key("str", "penalty", choices=("penalty", "augmented"),
                       doc="the paper's penalty law, or the augmented Lagrangian "
                           "(penetration and stick slip to `tolerance`; stick = μ ∞)"),
    "penalty_factor": Key("float", check=_positive,
                          doc="normal penalty as factor · E / spacing (default 1000); "
                              "ignored when `penalty` is given"),
    "tolerance": Key("float", 1e-6, check=_positive,
                     doc="augmented: penetration and stick slip allowed, as a fraction "
                         "of the particle spacing"),
}

_VECTORS = ("point", "normal", "center", "axis", "motion", "direction")


def check_tool(name, section, dim, fail, base=None):
    """Check a ``[tools.NAME]`` section against a ``dim``-D model: its kind,
    the keys the kind needs, vector lengths; then build the tool once so
    that its own checks (a zero normal, a fillet that does not fit, an
    unreadable surface file) name the section."""
    kind = section["kind"]
    if kind not in TOOL_KINDS[dim]:
        fail(f"{name}.kind", f"a {dim}D model takes the tools "
                             f"{', '.join(TOOL_KINDS[dim])}, not {kind!r}")
    for key in TOOL_KINDS[dim][kind]:
        if section[key] is None:
            fail(name, f"a {kind} needs {key!r}")
    for key in _VECTORS:
        if section.get(key) is not None and len(section[key]) != dim:
            fail(f"{name}.{key}", f"needs {dim} components in a {dim}D model, not "
                                  f"{len(section[key])}")
    if section.get("rotation") is not None and dim != 3:
        fail(f"{name}.rotation", "rotating tools are 3D only")
    if section["force"] is not None and section["direction"] is None \
            and kind not in ("platen", "plane"):
        fail(f"{name}.force", f"a force-driven {kind} needs 'direction'")
    try:
        tool_from(name.split(".", 1)[1], section, dim, base)
    except (ValueError, OSError) as err:
        fail(name, str(err))


def _rotation(section):
    values = section.get("rotation")
    if values is None:
        return None
    angle = values[6]
    if section.get("ramp"):
        profile = SmoothStart(section["ramp"])
        angle = lambda t: float(profile(t)) * values[6]  # noqa: E731
    return {"axis": values[:3], "point": values[3:6], "angle": angle}


#: triangulated tools built lately, by file (path, modification time, size)
#: and motion: the scene check builds each tool, and the build that follows
#: reuses it instead of reading the file and building its search tree again
_SURFACES = {}
_SURFACES_KEPT = 4


def _surface_from_file(path, moving, surface_class):
    """``surface_class.from_file(path, **moving)``, reused while the file is unchanged."""
    if not path.is_file():
        return surface_class.from_file(path, **moving)  # names the missing file
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size, repr(moving))
    if key not in _SURFACES:
        while len(_SURFACES) >= _SURFACES_KEPT:
            _SURFACES.pop(next(iter(_SURFACES)))
        _SURFACES[key] = surface_class.from_file(path, **moving)
    return _SURFACES[key]


def tool_from(name, section, dim=2, base=None):
    """The rigid tool of a ``[tools.NAME]`` section: a 2D
    :class:`~skfem_rkpm.mechanics.tools.Tool` or a 3D
    :class:`~skfem_rkpm.mechanics.surfaces.Surface` (``base``: the
    folder that a surface's file is relative to)."""
    kind = section.get("kind", "platen")
    motion = section.get("motion") or (0.0,) * dim
    if section.get("ramp"):
        motion = ramped(motion, section["ramp"])
    if dim == 2:
        from ..mechanics.tools import Arc, Platen, Polyline

        if kind == "platen":
            return Platen(section["point"], section["normal"], motion, name)
        if kind == "polyline":
            return Polyline(section["points"], section.get("fillet") or 0.0,
                            motion=motion, name=name)
        if kind == "arc":
            return Arc(section["center"], section["radius"], section["angles"], motion,
                       name)
    else:
        from ..mechanics import surfaces
        from ..mechanics.triangulated import TriangulatedSurface

        moving = {"motion": motion, "rotation": _rotation(section), "name": name}
        side = section.get("side") or "outside"
        if kind in ("platen", "plane"):
            return surfaces.Plane(section["point"], section["normal"], **moving)
        if kind == "cylinder":
            return surfaces.Cylinder(section["point"], section["axis"], section["radius"],
                                     side, **moving)
        if kind == "sphere":
            return surfaces.Sphere(section["center"], section["radius"], side, **moving)
        if kind == "torus":
            return surfaces.Torus(section["center"], section["axis"], section["radius"],
                                  section["minor_radius"], side, **moving)
        if kind == "surface":
            path = Path(section["file"])
            if base is not None and not path.is_absolute():
                path = Path(base) / path
            return _surface_from_file(path, moving, TriangulatedSurface)
    raise SceneError(f"tools.{name}.kind: a {dim}D model takes the tools "
                     f"{', '.join(TOOL_KINDS[dim])}, not {kind!r}")
