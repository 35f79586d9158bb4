"""Bad input never ends in a bare traceback (docs/stability.md, "Bad input").

Scene files made by mutating the built-in ring scene (keys dropped, unknown
keys, values of every type, NaN, inf, zero, negative and huge numbers,
garbage text) are either refused with a :class:`SceneError` that names the
section, or accepted and then built, where the only errors allowed are the
project's own (a ``SceneError`` or a ``SingularMomentError``).  The public
constructors get the same treatment: each either works or raises a
``ValueError`` whose message names the argument.  Then the explicit cases:
corrupt ``.msh`` files, meshes without named boundaries, duplicate particles
from a ``.geo`` file, and a tool that never reaches the part.

Hypothesis runs derandomized (the same examples on every run) with small
example counts, so that the file takes about 20 s.
"""

import copy
import json
import math
import tomllib
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.tools import Arc, Platen, Polyline
from skfem_rkpm.mechanics.materials import J2Material, linear, perfect, swift
from skfem_rkpm.meshes import gmsh_rectangle, graded_rectangle, load, rectangle
from skfem_rkpm.runs.runner import build, run
from skfem_rkpm.runs.scene import SCHEMA, SceneError, builtin_scenes, load_scene, parse_scene
from skfem_rkpm.approximation.shape import SingularMomentError, rk_shape_functions

FUZZ = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])

RING = builtin_scenes()["ring"].read_text()
BASE = tomllib.loads(RING)


# ---------------------------------------------------------------------------
# TOML text of a scene dict
# ---------------------------------------------------------------------------


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml_text(data):
    lines = []

    def table(prefix, content):
        plain = {k: v for k, v in content.items() if not isinstance(v, dict)}
        tables = {k: v for k, v in content.items() if isinstance(v, dict)}
        if prefix and (plain or not tables):
            lines.append(f"[{prefix}]")
        for k, v in plain.items():
            lines.append(f"{json.dumps(k)} = {toml_value(v)}")
        for k, v in tables.items():
            table(f"{prefix}.{json.dumps(k)}" if prefix else json.dumps(k), v)

    table("", data)
    return "\n".join(lines) + "\n"


def test_toml_writer_round_trips_the_ring_scene():
    assert tomllib.loads(toml_text(BASE)) == BASE


# ---------------------------------------------------------------------------
# scene mutations
# ---------------------------------------------------------------------------

IMPOSSIBLE = [0.0, -1.0, 1e308, -1e308, 5e-324, math.nan, math.inf, -math.inf, 0, -1,
              2**62, -(2**63)]
WORDS = ["stick", "platen", "arc", "polyline", "gmsh", "rectangle", "x", "y", "top",
         "hole", "quad", "tri", "fem", "3d", "swift", "linear", "box", "gauss", "fbar",
         "weak", "quadrature", ""]
scalars = st.one_of(
    st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=6),
    st.sampled_from(WORDS),
    st.floats(),
    st.sampled_from(IMPOSSIBLE),
    st.integers(min_value=-2**63, max_value=2**63 - 1),
    st.booleans(),
)
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4),
    st.dictionaries(st.sampled_from(["a", "b", "kind", "x"]), inner, max_size=3)),
    max_leaves=8)


def _key_paths():
    """Every key of the ring scene and of the schema, as (section..., key)."""
    paths = []
    for name, section in BASE.items():
        if name in ("tools", "boundary"):
            for entry, content in section.items():
                keys = set(content) | set(SCHEMA[f"{name}.*"])
                paths += [(name, entry, key) for key in sorted(keys)]
        else:
            paths += [(name, key) for key in sorted(set(section) | set(SCHEMA[name]))]
    return paths


PATHS = _key_paths()
SECTIONS = [(name,) for name in BASE] + [("tools", "platen"), ("boundary", "bottom"),
                                         ("tools",), ("solver",)]


def _parent(data, path):
    for p in path[:-1]:
        if not isinstance(data.get(p), dict):
            return None
        data = data[p]
    return data


@st.composite
def wild_scenes(draw):
    """1-3 mutations of any kind: drop, unknown key, any value, bad section."""
    data, touched = copy.deepcopy(BASE), []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["drop", "unknown", "value", "value", "section"]))
        path = draw(st.sampled_from(SECTIONS if kind == "section" else PATHS))
        parent = _parent(data, path)
        if parent is None:
            continue
        if kind == "drop":
            parent.pop(path[-1], None)
        elif kind == "unknown":
            path = path[:-1] + ("colour",)
            parent["colour"] = draw(values)
        elif kind == "section":
            if draw(st.booleans()):
                parent.pop(path[-1], None)
            else:
                parent[path[-1]] = draw(scalars)
        else:
            parent[path[-1]] = draw(values)
        touched.append(".".join(path))
    return toml_text(data), touched


FINITE = st.one_of(st.floats(allow_nan=False, allow_infinity=False),
                   st.sampled_from([0.0, -1.0, 1e-300, 1e300, 0.5, 1.0, 2.0, 20.0, 60.0]))


def typed(spec):
    """Values of the key's own type, so that most scenes pass the reader."""
    if spec.choices:
        return st.sampled_from(list(spec.choices))
    return {
        "float": FINITE,
        "int": st.one_of(st.integers(-3, 30), st.integers()),
        "str": st.sampled_from(["top", "bottom", "left", "x", "stick", ""]),
        "bool": st.booleans(),
        "list[float]": st.lists(FINITE, min_size=1, max_size=3),
        "list[int]": st.lists(st.integers(-2, 40), min_size=1, max_size=3),
        "list[str]": st.lists(st.sampled_from(["top", "bottom", "left", "right", "x", "y",
                                               "r", "z", "hole"]), max_size=3),
    }.get(spec.kind, st.one_of(
        FINITE, st.just("stick"),
        st.lists(st.lists(FINITE, min_size=2, max_size=2), max_size=4),
        st.dictionaries(st.sampled_from(["a", "b"]),
                        st.lists(FINITE, min_size=2, max_size=2), max_size=2)))


@st.composite
def plausible_scenes(draw):
    """1-3 keys dropped or set to a value of their own type."""
    data, touched = copy.deepcopy(BASE), []
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        spec = SCHEMA[f"{path[0]}.*" if len(path) == 3 else path[0]][path[-1]]
        parent = data
        for p in path[:-1]:
            parent = parent.setdefault(p, {})
        if draw(st.integers(0, 5)) == 0:
            parent.pop(path[-1], None)
        else:
            parent[path[-1]] = draw(typed(spec))
        touched.append(".".join(path))
    return toml_text(data), touched


def assert_names_a_touched_section(message, touched):
    assert any(t.split(".")[0] in message for t in touched), (message, touched)


def small(scene):
    """Scenes cheap enough to build in a test (about 0.1 s)."""
    g, d = scene["geometry"], scene["discretization"]
    cells = g["divisions"][0] * g["divisions"][1]
    for key in ("x_segments", "y_segments"):
        if g[key]:
            cells *= sum(n for _, n in g[key])
    return cells <= 600 and d["quadrature"] <= 9


def check_scene(text, touched, build_it):
    try:
        scene = parse_scene(text, "ring.toml")
    except SceneError as err:
        message = str(err)
        assert message.startswith("ring.toml")
        assert_names_a_touched_section(message, touched)
        return
    if not build_it or not small(scene):
        return
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            build(scene)
    except SingularMomentError as err:
        # the way out: a normalized support (dilation), the growth factor of
        # explicit radii (discretization.support), or the particle positions
        assert any(way in str(err) for way in ("smallest normalized support",
                                               "Supports must grow by a factor",
                                               "do not help"))
    except SceneError as err:
        assert_names_a_touched_section(str(err), touched)
    except ValueError as err:
        # slaves are checked against the mesh's boundaries when it exists
        assert "the mesh has no boundary named" in str(err), err


@FUZZ
@given(wild_scenes())
def test_mutated_scenes_are_accepted_or_refused_naming_the_section(case):
    check_scene(*case, build_it=False)


@settings(FUZZ, max_examples=40)
@given(plausible_scenes())
def test_plausible_scenes_build_or_fail_with_a_project_error(case):
    check_scene(*case, build_it=True)


@FUZZ
@given(st.text(max_size=200))
def test_garbage_text_is_refused_as_a_scene_error(text):
    try:
        parse_scene(text, "junk.toml")
    except SceneError as err:
        assert str(err).startswith("junk.toml")


@settings(FUZZ, max_examples=25)
@given(st.binary(min_size=1, max_size=200))
def test_random_bytes_scene_file(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("scene") / "junk.toml"
    path.write_bytes(data)
    try:
        load_scene(path)
    except SceneError as err:
        assert str(err).startswith(str(path))


@pytest.mark.parametrize("setting, message", [
    ("material.E=nan", "line 24: material.E: must be finite, not nan"),
    ("material.E=inf", "line 24: material.E: must be finite, not inf"),
    ("geometry.divisions=[0, 10]", "geometry.divisions: needs at least one cell"),
    ("geometry.grading=[0.5, 0.5]", "geometry.grading: ratios must be >= 1"),
    ("discretization.quadrature=20", "discretization.quadrature: must be at most 19"),
    ("tools.platen.friction=[1]", 'tools.platen.friction: must be a number >= 0 or "stick"'),
    ("tools.platen.friction=inf", 'tools.platen.friction: must be finite; use "stick"'),
    ("tools.platen.normal=[0.0, 0.0]",
     "tools.platen: platen normal must be a finite non-zero 2D vector"),
    ("tools.platen.slaves=[]", "tools.platen.slaves: must name at least one boundary"),
    ('tools.platen.kind="polyline"', "tools.platen: a polyline needs 'points'"),
    ("output.points=3", "output.points: must be a table of points"),
    ('output.points={a = "x"}', "output.points: must be a table of points"),
    ('model.type="3d"', 'model.type: "3d" needs a 3D geometry'),
    ("material.H=1e309", "material.H: must be finite"),
])
def test_bugs_found_by_fuzzing_are_scene_errors(setting, message):
    """Each of these once passed the reader (and then crashed or built a
    NaN model) or raised a TypeError."""
    from skfem_rkpm.runs.scene import apply_setting

    with pytest.raises(SceneError) as info:
        parse_scene(apply_setting(RING, setting), "ring.toml")
    assert message in str(info.value)


def test_polyline_points_of_the_wrong_shape():
    text = RING.replace('kind = "platen"', 'kind = "polyline"\npoints = [[0, 20], [60]]')
    with pytest.raises(SceneError, match=r"tools.platen.points: must be a list of at "
                                         r"least two \[x, y\] points"):
        parse_scene(text, "ring.toml")


# ---------------------------------------------------------------------------
# public constructors
# ---------------------------------------------------------------------------

BAD_NUMBERS = [math.nan, math.inf, -math.inf, 0.0, -1.0, 1e308, 5e-324, "a", None, True,
               [1.0, 2.0]]
numbers = st.one_of(st.sampled_from(BAD_NUMBERS), st.floats(), st.integers(-5, 5))


def works_or_names(call, *names):
    """``call()`` works or raises a ValueError naming one of ``names``."""
    try:
        return call()
    except ValueError as err:
        assert any(n in str(err) for n in names), err
    return None


MESH = rectangle(1.0, 1.0, 3, 3)


@FUZZ
@given(support=numbers, order=st.sampled_from([0, 1, 2, 3, -1, 1.0, True, "1", None]),
       kernel=st.sampled_from(["cubic", "quartic", "gaussian", None]),
       intorder=st.sampled_from([1, 2, 4, 0, -1, 1.5, 19, 20, "4", None]))
def test_rk_basis_arguments(support, order, kernel, intorder):
    mesh = MESH if intorder != 20 else rectangle(1.0, 1.0, 3, 3, kind="tri")
    works_or_names(lambda: RKBasis(mesh, support=support, order=order, kernel=kernel,
                                   intorder=intorder),
                   "support", "order", "kernel", "intorder", "Gauss rule",
                   "moment matrix")


@FUZZ
@given(value=st.sampled_from([math.nan, math.inf, -math.inf]),
       where=st.sampled_from(["x", "nodes"]), index=st.integers(0, 15), axis=st.integers(0, 1))
def test_shape_functions_name_the_non_finite_point(value, where, index, axis):
    x = np.array([[0.4, 0.5], [0.5, 0.6]])
    nodes = MESH.p.copy()
    target = x if where == "x" else nodes
    target[axis, index % target.shape[1]] = value
    with pytest.raises(ValueError, match=r"(evaluation point|particle) \d+ has non-finite "
                                         r"coordinates"):
        rk_shape_functions(x, nodes, 0.7)


@FUZZ
@given(E=numbers, nu=numbers, sigma=numbers, H=numbers, K=numbers, eps0=numbers, n=numbers,
       law=st.sampled_from(["perfect", "linear", "swift", None]))
def test_material_constants(E, nu, sigma, H, K, eps0, n, law):
    def make():
        hardening = {"perfect": lambda: perfect(sigma), "linear": lambda: linear(sigma, H),
                     "swift": lambda: swift(K, eps0, n), None: lambda: None}[law]()
        return J2Material(E, nu, hardening)

    material = works_or_names(make, "Young's modulus", "Poisson's ratio", "yield stress",
                              "hardening modulus", "Swift law")
    if material is not None:
        assert np.isfinite(material.G) and np.isfinite(material.K)


points2 = st.one_of(st.lists(numbers, min_size=0, max_size=3), numbers)


@FUZZ
@given(kind=st.sampled_from(["platen", "polyline", "arc"]), a=points2, b=points2,
       radius=numbers, motion=st.one_of(points2, st.just((0.0, -1.0))),
       polyline=st.lists(st.lists(st.one_of(st.floats(), st.sampled_from([0.0, 1.0])),
                                  min_size=1, max_size=3), max_size=4),
       fillet=numbers)
def test_tool_geometry(kind, a, b, radius, motion, polyline, fillet):
    make = {"platen": lambda: Platen(a, b, motion),
            "polyline": lambda: Polyline(polyline, fillet, motion=motion),
            "arc": lambda: Arc(a, radius, b, motion)}[kind]
    tool = works_or_names(make, "platen", "polyline", "fillet", "arc", "motion")
    if tool is not None:  # a usable tool: finite projections of a point
        proj = tool.project(np.array([[0.3], [0.2]]), 0.5)
        assert np.all(np.isfinite(proj.gap))


@FUZZ
@given(lx=numbers, ly=numbers, nx=st.sampled_from([1, 3, 0, -2, 2.5, "3", None, True]),
       ratio=numbers, kind=st.sampled_from(["quad", "tri", "hex"]),
       builder=st.sampled_from(["rectangle", "graded", "gmsh"]))
def test_mesh_builders(lx, ly, nx, ratio, kind, builder):
    if builder == "gmsh":  # keep gmsh's cell count small: h = lx / 4
        def make():
            return gmsh_rectangle(1.0, 1.0, lx, kind=kind) if not (
                isinstance(lx, float) and 0 < lx < 0.2) else None
    else:
        def make():
            if builder == "rectangle":
                return rectangle(lx, ly, nx, 2, kind=kind)
            return graded_rectangle(lx, ly, nx, 3, ratio, kind=kind)
    mesh = works_or_names(make, "lx", "ly", "nx", "ratio", "kind", "grading", "h must")
    if mesh is not None:
        assert np.all(np.isfinite(mesh.p))


# ---------------------------------------------------------------------------
# explicit cases
# ---------------------------------------------------------------------------


def test_random_bytes_mesh_files_name_the_file(tmp_path):
    """Random bytes as .msh or .geo are refused before gmsh parses them:
    gmsh's .geo parser, which reads anything that is not a .msh file, stays
    broken after NUL or non-UTF-8 bytes, so every later .geo file in the
    process failed with "syntax error"."""
    noise = np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    (tmp_path / "noise.msh").write_bytes(noise)
    with pytest.raises(ValueError, match=r"mesh file '.*noise.msh' is not a gmsh .msh "
                                         r"file: it does not start with \$MeshFormat"):
        load(tmp_path / "noise.msh")
    (tmp_path / "noise.geo").write_bytes(b"Point(1) = {0, 0, 0};\n\xfe\x00" + noise)
    with pytest.raises(ValueError, match=r"mesh file '.*noise.geo' is neither a .msh file "
                                         r"nor .geo text: byte 2[23] \(line 2\)"):
        load(tmp_path / "noise.geo")
    (tmp_path / "plain.geo").write_text(SQUARE)
    assert load(tmp_path / "plain.geo").nvertices > 10  # gmsh still parses .geo files
    with pytest.raises(ValueError, match="mesh file '.*' is not a file"):
        load(tmp_path)
    scene = parse_scene(RING.replace('kind = "rectangle"', 'kind = "gmsh"\nfile = '
                                     '"noise.msh"'), "ring.toml", base=tmp_path)
    with pytest.raises(SceneError, match="geometry.file: mesh file '.*noise.msh' is not"):
        build(scene)


SQUARE = """
Point(1) = {0, 0, 0, 0.25}; Point(2) = {1, 0, 0, 0.25};
Point(3) = {1, 1, 0, 0.25}; Point(4) = {0, 1, 0, 0.25};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
"""


def test_geo_without_physical_groups(tmp_path):
    """A plain mesh loads (no named boundaries); a scene that names one is
    told that the file defines none and how to name them."""
    geo = tmp_path / "plain.geo"
    geo.write_text(SQUARE)
    mesh = load(geo)
    assert mesh.nvertices > 10 and not mesh.boundaries
    text = RING.replace('kind = "rectangle"', 'kind = "gmsh"\nfile = "plain.geo"')
    text = text.replace("[tools.platen]", "[tools.platen]\n").split("[tools.platen]")[0] \
        + "[boundary.bottom]\nfix = [\"y\"]\n"
    scene = parse_scene(text, str(tmp_path / "part.toml"), base=tmp_path)
    with pytest.raises(SceneError, match=r"\[boundary.bottom\]: the mesh has no boundary "
                                         r"'bottom'; the file plain.geo defines no named "
                                         r"boundaries: give its boundary curves names "
                                         r"with Physical Curve"):
        build(scene)


def test_duplicate_nodes_of_a_geo_file_are_named(tmp_path):
    """Two squares side by side with their own points on the common side
    (no Coherence): the nodes there are doubled, so the basis refuses."""
    second = """
Point(11) = {1, 0, 0, 0.25}; Point(12) = {2, 0, 0, 0.25};
Point(13) = {2, 1, 0, 0.25}; Point(14) = {1, 1, 0, 0.25};
Line(11) = {11, 12}; Line(12) = {12, 13}; Line(13) = {13, 14}; Line(14) = {14, 11};
Curve Loop(2) = {11, 12, 13, 14}; Plane Surface(2) = {2};
"""
    geo = tmp_path / "two.geo"
    geo.write_text(SQUARE + second)
    mesh = load(geo)
    assert mesh.p[0].max() == pytest.approx(2.0)
    with pytest.raises(ValueError, match=r"particles \d+ and \d+ coincide at \(1, .*such "
                                         r"pairs\).*remove the duplicate vertices"):
        RKBasis(mesh, vector=True)


def test_tool_that_never_reaches_the_part_warns_and_carries_no_force():
    """Platen 10 mm above the ring moving down 5 mm: a warning when the
    contact is built, then the run completes with zero platen force."""
    settings_ = ["tools.platen.point=[0.0, 30.0]", "tools.platen.motion=[0.0, -5.0]",
                 "steps.count=2", "geometry.divisions=[6, 4]", "discretization.support=12.0",
                 "output.fields=false", "output.figures=false"]
    scene = load_scene(builtin_scenes()["ring"], settings_)
    with pytest.warns(UserWarning, match=r"tool 'platen' does not reach the part during "
                                         r"its motion: the smallest gap to the undeformed "
                                         r"slave boundary is 5 \(at t = 1\)"):
        sim = build(scene)
    result = run(sim, progress=False)
    assert result.completed
    for record in result.history:
        np.testing.assert_array_equal(record.reactions["platen"], [0.0, 0.0])


def test_builtin_scenes_do_not_warn_about_their_tools():
    for path in builtin_scenes().values():
        with warnings.catch_warnings():
            warnings.simplefilter("error", UserWarning)
            build(load_scene(path))
