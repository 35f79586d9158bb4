"""Scene files: a forming simulation described in TOML, mapped one-to-one
onto the library's Python objects.

A scene has the sections ``model``, ``geometry``, ``discretization``,
``material``, ``tools``, ``boundary``, ``steps`` and ``output``, and the
optional ``dynamics`` and ``initial`` (:mod:`~skfem_rkpm.runs.scene_dynamics`;
see ``docs/scenes.md``, generated from :data:`SCHEMA`).  :func:`load_scene`
reads and validates a file; every error names the offending key and its
line in the file.  :func:`build` turns a validated scene into the mesh,
basis, problem, conditions and tools that :func:`skfem_rkpm.runs.runner.run`
drives, exactly as a script would.
"""

import math
import re
import tomllib
from pathlib import Path

import numpy as np

from ..solvers.backend import BACKENDS
from ..solvers.reuse import REUSE_ENTRIES, REUSE_LIMIT, REUSE_MODES
from .scene_dynamics import DENSITY, OPTIONAL_SECTIONS, check_dynamics
from .scene_geometry import check_components, check_geometry, mesh_from, model_dimension
from .scene_tools import TOOL_SCHEMA, check_tool
from .scene_values import (COMPONENTS, HISTORY, Key, SceneError, _angle_span, _annulus_radii,
                           _cell_counts, _flow_curve, _fraction, _grading, _history,
                           _increasing_pair, _named_points, _non_negative, _pair,
                           _poisson, _positive, _quadrature, _segments,
                           _triple, _vector_history)

__all__ = ["SceneError", "SCHEMA", "load_scene", "parse_scene", "apply_setting",
           "setting_origins",
           "schema_markdown", "prescribed_components", "mesh_from"]


#: α of the modified SCNI stabilization when a scene does not give one
DEFAULT_STABILIZATION = 1e-3


SCHEMA = {
    "model": {
        "type": Key("str", "plane_strain", choices=("plane_strain", "axisymmetric", "3d"),
                    doc="kinematic model; axisymmetric: x is the radius, forces for the full "
                        "ring; 3d: a box or a gmsh volume mesh"),
        "method": Key("str", "rkpm", choices=("rkpm", "fem"), doc="discretization method"),
        "title": Key("str", "", doc="a name for reports"),
        "length_unit": Key("str", "mm", doc="unit of lengths, for the axes of figures and "
                                            "reports (the numbers are not converted)"),
        "force_unit": Key("str", "N", doc="unit of forces, for figures and reports"),
    },
    "geometry": {
        "kind": Key("str", "rectangle", choices=("rectangle", "annulus", "box", "ring_sector",
                                                 "quarter_cylinder", "gmsh"),
                    doc="rectangle section with divisions, ring or ring sector (annulus), "
                        "3D box, quarter cylinder, or a gmsh .geo/.msh file (2D or 3D)"),
        "x": Key("list[float]", check=_increasing_pair, doc="rectangle: [xmin, xmax]"),
        "y": Key("list[float]", check=_increasing_pair, doc="rectangle: [ymin, ymax]"),
        "divisions": Key("list[int]", check=_cell_counts,
                         doc="rectangle: cells [nx, ny]; particles are the (nx+1)(ny+1) "
                             "vertices; annulus: cells [across the wall, around]; box: "
                             "cells [nx, ny, nz]; ring_sector: [across, around, height]; "
                             "quarter_cylinder: [core, core to mantle, along z]"),
        "cells": Key("str", choices=("quad", "tri", "hex", "tet"),
                     doc="cell type; rectangle, annulus: quad (default) or tri; box: hex "
                         "(default) or tet"),
        "grading": Key("list[float]", check=_grading,
                       doc="rectangle: largest/smallest cell ratio [in x, in y] (1 = uniform); "
                           "annulus: [across the wall (smallest at the inner radius), 1]"),
        "radii": Key("list[float]", check=_annulus_radii,
                     doc="annulus, ring_sector: [inner, outer] radius; boundaries inner, "
                         "outer"),
        "angles": Key("list[float]", [0.0, 360.0], check=_angle_span,
                      doc="annulus: [start, end] in degrees from the x axis; a sector "
                          "(span < 360) also has the straight boundaries start and end; "
                          "ring_sector (3D, hexahedra): [0, angle], boundaries start (y = 0), "
                          "end, bottom (z = 0) and top (z = lz)"),
        "center": Key("list[float]", [0.0, 0.0], check=_pair, doc="annulus: center"),
        "radius": Key("float", check=_positive,
                      doc="quarter_cylinder (3D, hexahedra): radius of x, y >= 0, r <= radius, "
                          "0 <= z <= lz; boundaries xmin (x = 0), ymin (y = 0), outer, "
                          "bottom (z = 0), top (z = lz)"),
        "lx": Key("float", check=_positive, doc="box: edge length along x"),
        "ly": Key("float", check=_positive, doc="box: edge length along y"),
        "lz": Key("float", check=_positive, doc="box: edge length along z; ring_sector, "
                                                "quarter_cylinder: height"),
        "origin": Key("list[float]", [0.0, 0.0, 0.0], check=_triple,
                      doc="box: the corner with the smallest coordinates [x, y, z]; "
                          "boundaries xmin, xmax, ymin, ymax, zmin, zmax"),
        "file": Key("str", doc="gmsh: path of a .msh or .geo file (relative to the scene file) "
                               "with named physical boundaries: Physical Curve (2D) or "
                               "Physical Surface (3D; a .geo with volumes is meshed in 3D)"),
        "x_segments": Key("any", check=_segments,
                          doc="rectangle: piecewise uniform cells in x, [[x_end, cells], ...] "
                              "from x[0] to x[1] (replaces divisions[0] and grading)"),
        "y_segments": Key("any", check=_segments,
                          doc="rectangle: piecewise uniform cells in y, as x_segments"),
    },
    "discretization": {
        "support": Key("float", check=_positive,
                       doc="rkpm: support radius a of every particle (length unit); "
                           "overrides dilation"),
        "dilation": Key("float", 2.0, check=_positive,
                        doc="rkpm: normalized support c, a_I = c h_I"),
        "order": Key("int", 1, choices=(0, 1, 2), doc="rkpm: basis order"),
        "kernel": Key("str", "cubic", choices=("cubic", "quartic"), doc="rkpm: window"),
        "support_shape": Key("str", "radial", choices=("radial", "box"), doc="rkpm: support"),
        "integration": Key("str", "vci", choices=("vci", "vci_symmetric", "gauss", "scni", "dni"),
                           doc="rkpm: integration; scni/dni: one point per particle "
                               "(mesh vertices; see docs/nodal_integration.md)"),
        "interpolating": Key("bool", False,
                             doc="rkpm: interpolating RK functions, Ψ_I(X_J) = δ_IJ: the "
                                 "coefficients are nodal values (see docs/rk_basis.md)"),
        "smoothing": Key("str", "median_dual", choices=("median_dual", "voronoi"),
                         doc="rkpm, scni/dni: the smoothing cells, the median dual cells "
                             "of the mesh or the Voronoi cells of the particles clipped to "
                             "it (2D)"),
        "stabilization": Key("float", check=_non_negative,
                             doc="rkpm, scni: α of the modified SCNI stabilization "
                                 f"(default {DEFAULT_STABILIZATION}; 0: plain SCNI)"),
        "stabilization_moduli": Key("str", None, choices=("elastic", "shear", "tangent"),
                                    doc="rkpm, scni: moduli of the stabilization energy "
                                        "(default elastic; shear: the deviatoric part only; "
                                        "tangent: the material tangent at the particles, "
                                        "see docs/nodal_integration.md)"),
        "rereference": Key("float", check=_fraction,
                           doc="rkpm: rebuild the RK functions on the current "
                               "configuration when det F since the last reference, or a "
                               "cell's Jacobian ratio at a Gauss point, falls below this value, and "
                               "after a failed step (0 < value < 1; default: never; see "
                               "docs/large_deformation.md)"),
        "rereference_supports": Key("str", None, choices=("keep", "spacing"),
                                    doc="rkpm, rereference: the support radii at a "
                                        "rebuild: kept (default), or scaled with the "
                                        "current particle spacing"),
        "rereference_transfer": Key("str", None, choices=("local", "basis", "points"),
                                    doc="rkpm, rereference: how the material state "
                                        "reaches the new points: an L² fit with local "
                                        "supports (default), one with the basis's "
                                        "supports, or copied Gauss point by Gauss point "
                                        "(the same cells moved)"),
        "quadrature": Key("int", 4, check=_quadrature,
                          doc="degree of the Gauss rule per cell (7: 4x4 points on quads)"),
        "element": Key("str", None,
                       choices=("quad1", "quad2", "tri1", "tri2", "hex1", "hex2", "tet1",
                                "tet2"),
                       doc="fem: element (default: the linear one of the cells); it must "
                           "fit the cells (hex1, hex2 on hexahedra, tet1, tet2 on "
                           "tetrahedra)"),
        "locking": Key("str", "auto", choices=("none", "fbar", "auto"),
                       doc="volumetric locking control; auto: F-bar for RKPM and linear "
                           "FEM elements, none for quadratic elements and for 2D RKPM when "
                           "a tool slides with friction (measured: docs/plasticity.md, "
                           "docs/forming_3d.md); "
                           "ignored with nodal integration"),
    },
    "material": {
        "E": Key("float", required=True, check=_positive, doc="Young's modulus"),
        "nu": Key("float", required=True, check=_poisson, doc="Poisson's ratio"),
        "yield": Key("float", check=_positive, doc="initial yield stress; omit for elastic"),
        "hardening": Key("str", "perfect",
                         choices=("perfect", "linear", "swift", "voce", "table"),
                         doc="perfect, linear (yield + H ε̄ᵖ), swift (K (eps0 + ε̄ᵖ)^n), "
                             "voce (yield + Q (1 - exp(-b ε̄ᵖ)) + H ε̄ᵖ) or table "
                             "(piecewise-linear curve)"),
        "H": Key("float", 0.0, check=_non_negative,
                 doc="linear: hardening modulus; voce: optional linear term"),
        "K": Key("float", check=_positive, doc="swift: strength coefficient"),
        "eps0": Key("float", 1e-4, check=_positive, doc="swift: prestrain"),
        "n": Key("float", check=_positive, doc="swift: exponent"),
        "Q": Key("float", check=_non_negative, doc="voce: saturation stress increase"),
        "b": Key("float", check=_non_negative, doc="voce: saturation rate"),
        "curve": Key("any", check=_flow_curve,
                     doc="table: [[ε̄ᵖ, σ], ...] true stress against true plastic strain, "
                         "from ε̄ᵖ = 0 (the initial yield stress), increasing strains, "
                         "non-decreasing stresses; linear between the points"),
        "extrapolation": Key("str", "linear", choices=("linear", "constant"),
                             doc="table: beyond the last point, continue the last "
                                 "segment's slope or keep the last stress"),
        "density": DENSITY,
    },
    "tools.*": TOOL_SCHEMA,
    "boundary.*": {
        "fix": Key("list[str]", doc='components held at 0 on this boundary, e.g. ["y"] for '
                                    'a symmetry plane y = const (3D: ["z"] for z = const), '
                                    '["x", "y"] to clamp'),
        "symmetry": Key("bool", False,
                        doc="a symmetry plane: zero displacement normal to this boundary, "
                            "which must be flat (straight in 2D), at any angle"),
        "method": Key("str", "nodal", choices=("nodal", "weak"),
                      doc="prescribe nodal values (transformation method) or weakly"),
        "pressure": Key("any", check=_history,
                        doc="normal pressure, positive inward, on the reference boundary "
                            "(dead load; see follower): " + HISTORY),
        "follower": Key("bool", False,
                        doc="the pressure acts on the current boundary (its normal and "
                            "length follow the deformation) instead of the reference one"),
        "traction": Key("any", check=_vector_history,
                        doc="traction vector per unit reference length (axisymmetric: area "
                            "of the full ring; 3D: area), a dead load: [x, y] (3D: [x, y, z]) "
                            "reached linearly in t, or {x = ..., y = ...}, each " + HISTORY),
        "displacement": Key("any", check=_vector_history,
                            doc="prescribed displacement of the boundary's points: [x, y] "
                                "(3D: [x, y, z]) reached linearly in t, or only some "
                                "components, "
                                "{y = ...}, each " + HISTORY + "; enforced as fix "
                                "(method)"),
    },
    "steps": {
        "count": Key("int", 20, check=_positive, doc="load steps"),
        "tolerance": Key("float", 1e-6, check=_positive, doc="relative residual tolerance"),
        "max_iterations": Key("int", 20, check=_positive, doc="Newton iterations per step"),
        "max_cutbacks": Key("int", 8, check=_non_negative, doc="step halvings allowed"),
        "solver": Key("str", "auto",
                      choices=("auto", *BACKENDS),
                      doc="linear solver of the Newton iterations (skfem_rkpm.solvers.linear)"),
        "reuse_factorization": Key("str", "auto", choices=REUSE_MODES,
                                   doc="keep the last factorization and solve the next "
                                       "tangents by GMRES preconditioned by it, factoring "
                                       "again when GMRES stalls (skfem_rkpm.solvers.reuse); "
                                       f"auto: from {REUSE_LIMIT} unknowns or "
                                       f"{REUSE_ENTRIES:,} matrix entries on"),
    },
    **OPTIONAL_SECTIONS,
    "output": {
        "fields": Key("bool", True, doc="write fields.xdmf (+ .h5) for ParaView"),
        "every": Key("int", 1, check=_positive, doc="write fields every n-th step"),
        "figures": Key("bool", True, doc="write PNG figures"),
        "points": Key("any", {}, check=_named_points,
                      doc="material points to follow, {name = [X, Y]} (3D: [X, Y, Z]); "
                          "their current positions go into history.csv"),
    },
}

REQUIRED_SECTIONS = ("material",)


# -- reading ---------------------------------------------------------------------


def _key_lines(text):
    """Line of every ``key`` as a dotted path, from the TOML source text."""
    lines, table = {}, ""
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        header = re.match(r"^\[\s*([^\]]+?)\s*\]$", line)
        if header:
            table = header.group(1).replace('"', "").replace(" ", "")
            lines.setdefault(table, number)
            continue
        assign = re.match(r"^([A-Za-z0-9_.\-\"]+)\s*=", line)
        if assign:
            key = assign.group(1).replace('"', "")
            lines.setdefault(f"{table}.{key}" if table else key, number)
    return lines


def _schema_for(section):
    if section in SCHEMA:
        return SCHEMA[section]
    head = section.split(".")[0]
    if f"{head}.*" in SCHEMA and section.count(".") == 1:
        return SCHEMA[f"{head}.*"]
    return None


def _check_type(kind, value):
    number = (int, float)
    if kind == "any":
        return True
    if kind == "str":
        return isinstance(value, str)
    if kind == "float":
        return isinstance(value, number) and not isinstance(value, bool)
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "bool":
        return isinstance(value, bool)
    if kind.startswith("list["):
        item = kind[5:-1]
        return isinstance(value, list) and all(_check_type(item, v) for v in value)
    raise AssertionError(kind)


def parse_scene(text, source="<scene>", base=None, origins=None):
    """Validate the TOML ``text`` of a scene; return the filled-in dict.

    ``origins``: the keys whose values came from elsewhere than ``source``
    (:func:`setting_origins`: ``{"material.E": "--set material.E=nan"}``);
    a bad value of one of them is reported by its origin, not by a line of
    ``source``.

    Raises
    ------
    SceneError
        Naming the key, the problem and the line of ``source`` (or the
        ``--set`` that gave the value).
    """
    lines = _key_lines(text)
    origins = origins or {}

    def fail(path, message):
        if path in origins:
            raise SceneError(f"{origins[path]}: {message}")
        where = f"{source}, line {lines[path]}" if path in lines else source
        raise SceneError(f"{where}: {path}: {message}")

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"{source}: not valid TOML: {err}") from None
    scene = {}
    for name, content in data.items():
        if name in ("tools", "boundary"):
            if not isinstance(content, dict):
                fail(name, "must be a table of named entries")
            for entry, values in content.items():
                scene[f"{name}.{entry}"] = _section(f"{name}.{entry}", values, fail)
        elif name in SCHEMA:
            scene[name] = _section(name, content, fail)
        else:
            known = sorted(s.replace(".*", "") for s in SCHEMA)
            fail(name, f"unknown section; known sections: {', '.join(known)}")
    for name in SCHEMA:
        if "*" not in name and name not in scene and name not in OPTIONAL_SECTIONS:
            if name in REQUIRED_SECTIONS:
                raise SceneError(f"{source}: missing required section [{name}]")
            scene[name] = _section(name, {}, fail)
    if scene["material"]["density"] is None:  # a static scene's keys as before it
        del scene["material"]["density"]
    for name in [n for n in scene if n.startswith("tools.") and scene[n]["ramp"] is None]:
        del scene[name]["ramp"]
    scene["_base"] = str(base) if base is not None else None
    _check_combinations(scene, fail)
    scene["_source"] = source
    scene["_text"] = text
    return scene


def _section(path, values, fail):
    schema = _schema_for(path)
    if not isinstance(values, dict):
        fail(path, "must be a table")
    out = {}
    for key, value in values.items():
        if key not in schema:
            fail(f"{path}.{key}", f"unknown key; known keys: {', '.join(sorted(schema))}")
        spec = schema[key]
        if spec.kind == "float" and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if spec.kind == "list[float]" and isinstance(value, list):
            value = [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                     for v in value]
        if not _check_type(spec.kind, value):
            fail(f"{path}.{key}", f"must be of type {spec.kind}, not {value!r}")
        if spec.kind in ("float", "list[float]") and not all(
                math.isfinite(v) for v in (value if isinstance(value, list) else [value])):
            fail(f"{path}.{key}", f"must be finite, not {value!r}")
        if spec.choices and value not in spec.choices:
            fail(f"{path}.{key}", f"must be one of {list(spec.choices)}, not {value!r}")
        if spec.check is not None:
            problem = spec.check(value)
            if problem:
                fail(f"{path}.{key}", f"{problem} (got {value!r})")
        out[key] = value
    for key, spec in schema.items():
        if key not in out:
            if spec.required:
                fail(path, f"missing required key {key!r}")
            out[key] = spec.default
    return out


def _check_combinations(scene, fail):
    check_geometry(scene, fail)
    check_components(scene, fail)
    material = scene["material"]
    law = material["hardening"]
    needs = {"swift": ("K", "n"), "voce": ("yield", "Q", "b"), "table": ("curve",),
             "linear": ("yield",)}.get(law, ())
    missing = [key for key in needs if material[key] is None]
    if missing:
        fail("material.hardening", f"{law} needs {', '.join(map(repr, missing))}")
    if law == "table" and material["yield"] is not None:
        fail("material.yield", "a table's first stress is the initial yield stress; "
                               "omit 'yield'")
    for name, section in scene.items():
        if name.startswith("boundary.") and section["follower"] \
                and section["pressure"] is None:
            fail(f"{name}.follower", "applies to a pressure; give 'pressure'")
        if name.startswith("tools."):
            check_tool(name, section, model_dimension(scene["model"]["type"]), fail,
                       scene.get("_base"))
    check_dynamics(scene, fail)
    try:
        material_from(material)
    except ValueError as err:
        fail("material", str(err))


def load_scene(path, settings=()):
    """Read, override (``settings``: ``"key.path=value"`` strings) and validate."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: no such scene file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise SceneError(f"{path}: not a TOML scene file (not UTF-8 text: byte "
                         f"{err.start} is {err.object[err.start:err.start + 1]!r})") from None
    for setting in settings:
        text = apply_setting(text, setting)
    return parse_scene(text, str(path), base=path.parent,
                       origins=setting_origins(settings))


def setting_origins(settings, flag="--set"):
    """``{dotted key: "--set KEY=VALUE"}`` of ``"KEY=VALUE"`` settings, the
    user's own text (the last one of a key wins, as in :func:`load_scene`)."""
    origins = {}
    for setting in settings:
        key = setting.split("=", 1)[0].strip().replace('"', "").replace(" ", "")
        origins[key] = f"{flag} {setting.strip()}"
    return origins


def apply_setting(text, setting):
    """Override one value in a scene's TOML text: ``"tools.platen.friction=0.3"``.

    The value is read as TOML (numbers, booleans, arrays, quoted strings);
    anything else is taken as a string.  Missing tables and keys are added.
    The key must be one of :data:`SCHEMA` (``SECTION.KEY`` or
    ``tools.NAME.KEY``, ``boundary.NAME.KEY``) and the value one line:
    otherwise a :class:`SceneError` names the setting.
    """
    if "=" not in setting:
        raise SceneError(f"--set {setting!r}: expected key=value")
    if "\n" in setting or "\r" in setting:
        raise SceneError(f"--set {setting!r}: a value must be one line (it would add "
                         f"lines to the scene file); give each key its own --set")
    path, value = (s.strip() for s in setting.split("=", 1))
    _check_setting_key(path, setting)
    try:
        tomllib.loads(f"v = {value}")
    except tomllib.TOMLDecodeError:
        value = '"' + value.replace('"', '\\"') + '"'
    *tables, key = path.split(".")
    table = ".".join(tables)
    out, current, done = [], "", False
    for line in text.splitlines():
        header = re.match(r"^\s*\[\s*([^\]]+?)\s*\]\s*(#.*)?$", line)
        if header:
            current = header.group(1).replace(" ", "")
        elif current == table and re.match(rf"^\s*{re.escape(key)}\s*=", line):
            line, done = f"{key} = {value}", True
        out.append(line)
    if not done:
        # insert after the table header, or append a new table
        for i, line in enumerate(out):
            header = re.match(r"^\s*\[\s*([^\]]+?)\s*\]", line)
            if header and header.group(1).replace(" ", "") == table:
                out.insert(i + 1, f"{key} = {value}")
                done = True
                break
        if not done:
            out += ["", f"[{table}]", f"{key} = {value}"] if table else [f"{key} = {value}"]
    return "\n".join(out) + "\n"


def _check_setting_key(path, setting):
    """SceneError unless ``path`` names a key of :data:`SCHEMA`."""
    *tables, key = path.split(".")
    table = ".".join(tables)
    sections = sorted(s.replace(".*", ".NAME") for s in SCHEMA)
    if not tables:
        raise SceneError(f"--set {setting!r}: unknown key {path!r}: give SECTION.KEY, e.g. "
                         f"tools.platen.friction; sections: {', '.join(sections)}")
    schema = _schema_for(table)
    if schema is None:
        if f"{table}.*" in SCHEMA:
            example = {"tools": "platen", "boundary": "bottom"}[table]
            raise SceneError(f"--set {setting!r}: {path!r} names no {table}: give "
                             f"{table}.NAME.KEY, e.g. {table}.{example}.{key}")
        raise SceneError(f"--set {setting!r}: unknown section {table!r} in {path!r}; "
                         f"sections: {', '.join(sections)}")
    if key not in schema:
        raise SceneError(f"--set {setting!r}: unknown key {path!r}; known keys of "
                         f"[{table}]: {', '.join(sorted(schema))}")


def schema_markdown():
    """The reference tables of ``docs/scenes.md``, generated from :data:`SCHEMA`."""
    parts = []
    for section, keys in SCHEMA.items():
        title = section.replace(".*", ".NAME")
        parts.append(f"### `[{title}]`\n")
        parts.append("| key | type | default | meaning |")
        parts.append("|---|---|---|---|")
        for key, spec in keys.items():
            default = "required" if spec.required else (
                "—" if spec.default is None else f"`{spec.default!r}`")
            doc = spec.doc + (f" ({', '.join(map(str, spec.choices))})" if spec.choices else "")
            parts.append(f"| `{key}` | {spec.kind} | {default} | {doc} |")
        parts.append("")
    return "\n".join(parts)


def builtin_scenes():
    """Names and paths of the scenes shipped with the library."""
    folder = Path(__file__).parent / "scenes"
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def components(names):
    """Component indices of names like ``["x", "y"]``."""
    return [COMPONENTS[n] for n in names]


def prescribed_components(values):
    """``{component index: number or table}`` of a ``displacement`` or
    ``traction`` value (a vector [x, y] or a table of named components)."""
    if values is None:
        return {}
    if isinstance(values, list):
        return dict(enumerate(values))
    return {COMPONENTS[name]: value for name, value in values.items()}


def material_from(section):
    """The :class:`~skfem_rkpm.mechanics.materials.J2Material` of a scene."""
    from ..mechanics.materials import J2Material, linear, perfect, swift, table, voce

    law = section["hardening"]
    if law == "swift":
        hardening = swift(section["K"], section["eps0"], section["n"])
    elif law == "table":
        strains, stresses = zip(*section["curve"])
        hardening = table(strains, stresses, section.get("extrapolation") or "linear")
    elif law == "voce":
        hardening = voce(section["yield"], section["Q"], section["b"], section["H"])
    elif section["yield"] is None:
        hardening = None
    elif law == "linear":
        hardening = linear(section["yield"], section["H"])
    else:
        hardening = perfect(section["yield"])
    return J2Material(section["E"], section["nu"], hardening)


def spacing_radius(mesh, section):
    """Support radii of a scene's particles, checked for every particle."""
    from ..meshes import local_spacing

    if section["support"] is not None:
        return np.full(mesh.nvertices, section["support"])
    return section["dilation"] * local_spacing(mesh)
