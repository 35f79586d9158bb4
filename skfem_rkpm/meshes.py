"""Background meshes with named boundaries.

The meshes returned here are ordinary scikit-fem meshes
(:class:`skfem.MeshTri1` or :class:`skfem.MeshQuad1`).  Their vertices serve
as the particles of the reproducing kernel approximation and their cells as
integration cells.  Every mesh carries named boundaries in
``mesh.boundaries`` (a dict of facet index arrays), so that boundary
conditions can be written as ``mesh.boundaries["left"]``.

Cells are always oriented counter-clockwise, i.e. the Jacobian of the
reference-to-physical map is positive everywhere.

Unstructured meshes are generated with the official gmsh Python API.  When
gmsh is not yet initialized, the functions here initialize it and finalize it
before returning; when it is, they work in a new model which is removed
afterwards, and the gmsh options they change are restored.
"""

import threading
from contextlib import contextmanager
from pathlib import Path

import gmsh
import numpy as np
import skfem

from .geo_check import check_geo

__all__ = [
    "rectangle",
    "graded_rectangle",
    "piecewise_rectangle",
    "gmsh_rectangle",
    "gmsh_plate_with_hole",
    "from_gmsh",
    "load",
    "local_spacing",
]

_KINDS = {"tri": skfem.MeshTri1, "quad": skfem.MeshQuad1}

# gmsh element type numbers of first-order cells and lines
_GMSH_TRI, _GMSH_QUAD, _GMSH_LINE = 2, 3, 1


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _check_kind(kind):
    if kind not in _KINDS:
        raise ValueError(f"kind must be 'tri' or 'quad', got {kind!r}")


def _number(value, name):
    """``value`` as a finite float; a ValueError naming ``name`` otherwise."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = None
    if x is None or isinstance(value, (bool, np.bool_)) or not np.isfinite(x):
        raise ValueError(f"{name} must be a finite number, not {value!r}")
    return x


def _positive(value, name):
    x = _number(value, name)
    if not x > 0:
        raise ValueError(f"{name} must be positive, not {value!r}")
    return x


def _cells(value, name):
    """A number of cells: an integer >= 1."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) \
            or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, not {value!r}")
    return int(value)


def _box(lx, ly, nx, ny):
    """Validated side lengths and cell counts of a rectangle."""
    return (_positive(lx, "lx"), _positive(ly, "ly"), _cells(nx, "nx"), _cells(ny, "ny"))


def _signed_areas(p, t):
    """Signed areas of triangles or (shoelace) quadrilaterals."""
    x, y = p[0, t], p[1, t]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=0) - np.roll(x, -1, axis=0) * y, axis=0)


def _orient_ccw(p, t):
    """Return a copy of ``t`` with every cell ordered counter-clockwise."""
    t = np.array(t, dtype=np.int64)
    flip = _signed_areas(p, t) < 0.0
    # reversing the order of the vertices after the first one flips the
    # orientation of a triangle (swap 1, 2) or a quadrilateral (swap 1, 3)
    t[1:, flip] = t[:0:-1, flip]
    return t


def _make_mesh(p, t, kind):
    """Build an oriented scikit-fem mesh of the given kind.

    Both arrays are handed over C-contiguous: scikit-fem would otherwise
    copy them and print "Transforming over 1000 vertices to C_CONTIGUOUS."
    (gmsh's coordinates arrive transposed).
    """
    p = np.ascontiguousarray(p, dtype=np.float64)
    t = np.ascontiguousarray(_orient_ccw(p, t))
    if kind == "tri":
        # keep the counter-clockwise vertex order instead of sorting it
        return skfem.MeshTri1(p, t, sort_t=False)
    return skfem.MeshQuad1(p, t)


def _with_box_sides(mesh, x0, x1, y0, y1):
    """Name the boundary facets on the four sides of a box."""
    tol = 1e-10 * max(x1 - x0, y1 - y0)
    return mesh.with_boundaries(
        {
            "left": lambda x: np.abs(x[0] - x0) < tol,
            "right": lambda x: np.abs(x[0] - x1) < tol,
            "bottom": lambda x: np.abs(x[1] - y0) < tol,
            "top": lambda x: np.abs(x[1] - y1) < tol,
        }
    )


def _tensor_mesh(x, y, kind):
    """Oriented tensor-product mesh on the sorted coordinates ``x``, ``y``."""
    _check_kind(kind)
    base = _KINDS[kind].init_tensor(x, y)
    return _make_mesh(base.p, base.t, kind)


# ---------------------------------------------------------------------------
# structured meshes
# ---------------------------------------------------------------------------


def rectangle(lx, ly, nx, ny, kind="quad", origin=(0.0, 0.0), perturb=0.0, seed=0):
    """Structured mesh of a rectangle.

    Parameters
    ----------
    lx, ly : float
        Side lengths of the rectangle.
    nx, ny : int
        Number of cell columns and rows.
    kind : {"quad", "tri"}
        ``"quad"`` gives ``nx * ny`` quadrilaterals, ``"tri"`` splits each of
        them into two triangles.
    origin : tuple of float
        Lower-left corner of the rectangle.
    perturb : float
        Maximum random displacement of the vertices, as a fraction of the
        grid spacing in each direction (``lx / nx`` in x, ``ly / ny`` in y).
        Interior vertices move in both directions, vertices on a side only
        along that side, corners do not move.  Values below 0.25 (quads) or
        1/6 (triangles) always give valid cells.
    seed : int
        Seed of the random perturbation.

    Returns
    -------
    skfem.MeshQuad1 or skfem.MeshTri1
        Mesh with boundaries ``"left"``, ``"right"``, ``"bottom"``, ``"top"``.

    Raises
    ------
    ValueError
        If the arguments are invalid or the perturbation inverts a cell.
    """
    lx, ly, nx, ny = _box(lx, ly, nx, ny)
    if not _number(perturb, "perturb") >= 0:
        raise ValueError(f"perturb must be non-negative, got {perturb}")
    if np.shape(origin) != (2,):
        raise ValueError(f"origin must be two numbers (x, y), not {origin!r}")
    x0, y0 = _number(origin[0], "origin x"), _number(origin[1], "origin y")
    x = x0 + np.linspace(0.0, lx, nx + 1)
    y = y0 + np.linspace(0.0, ly, ny + 1)
    mesh = _tensor_mesh(x, y, kind)

    if perturb > 0:
        p = mesh.p.copy()
        rng = np.random.default_rng(seed)
        shift = rng.uniform(-perturb, perturb, size=p.shape)
        shift *= np.array([[lx / nx], [ly / ny]])
        tol = 1e-12 * max(lx, ly)
        on_x_side = (np.abs(p[0] - x0) < tol) | (np.abs(p[0] - x[-1]) < tol)
        on_y_side = (np.abs(p[1] - y0) < tol) | (np.abs(p[1] - y[-1]) < tol)
        shift[0, on_x_side] = 0.0
        shift[1, on_y_side] = 0.0
        p += shift
        if np.any(_signed_areas(p, mesh.t) <= 0.0):
            raise ValueError(
                f"perturb={perturb} inverts cells; use a smaller value"
            )
        mesh = _make_mesh(p, mesh.t, kind)

    return _with_box_sides(mesh, x0, x[-1], y0, y[-1])


def _geometric_nodes(length, n, ratio):
    """``n + 1`` nodes on ``[0, length]`` with sizes growing by ``ratio``."""
    if n == 1 or ratio == 1.0:
        return np.linspace(0.0, length, n + 1)
    q = ratio ** (1.0 / (n - 1))
    sizes = q ** np.arange(n)
    return length * np.concatenate(([0.0], np.cumsum(sizes))) / sizes.sum()


def graded_rectangle(lx, ly, nx, ny, ratio, kind="quad"):
    """Tensor-product mesh of ``[0, lx] x [0, ly]`` with geometric grading.

    The cell sizes grow by a constant factor from the origin outwards, so
    that in each direction the largest cell is ``ratio`` times the smallest
    one.  The smallest cells are at the origin corner.

    Parameters
    ----------
    lx, ly : float
        Side lengths of the rectangle.
    nx, ny : int
        Number of cell columns and rows (at least 2 unless ``ratio == 1``).
    ratio : float
        Ratio of the largest to the smallest cell size, ``>= 1``.
    kind : {"quad", "tri"}
        Cell type, as in :func:`rectangle`.

    Returns
    -------
    skfem.MeshQuad1 or skfem.MeshTri1
        Mesh with boundaries ``"left"``, ``"right"``, ``"bottom"``, ``"top"``.
    """
    lx, ly, nx, ny = _box(lx, ly, nx, ny)
    if not _number(ratio, "ratio") >= 1.0:
        raise ValueError(f"ratio must be >= 1, got {ratio}")
    if ratio != 1.0 and min(nx, ny) < 2:
        raise ValueError("grading needs at least 2 cells in each direction")
    return piecewise_rectangle(_geometric_nodes(lx, nx, ratio),
                               _geometric_nodes(ly, ny, ratio), kind)


def piecewise_rectangle(x, y, kind="quad"):
    """Tensor-product mesh on given vertex coordinates, e.g. piecewise
    uniform divisions that are denser where the deformation concentrates.

    Parameters
    ----------
    x, y : array_like
        Strictly increasing vertex coordinates in each direction.
    kind : {"quad", "tri"}
        Cell type, as in :func:`rectangle`.

    Returns
    -------
    skfem.MeshQuad1 or skfem.MeshTri1
        Mesh with boundaries ``"left"``, ``"right"``, ``"bottom"``, ``"top"``.
    """
    coords = []
    for name, c in (("x", x), ("y", y)):
        try:
            c = np.asarray(c, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} coordinates must be numbers, not {c!r}") from None
        if c.ndim != 1 or len(c) < 2 or not np.all(np.diff(c) > 0):
            raise ValueError(f"{name} coordinates must be at least two strictly "
                             "increasing values")
        if not np.all(np.isfinite(c)):
            raise ValueError(f"{name} coordinates must be finite, not {c.tolist()}")
        coords.append(c)
    x, y = coords
    return _with_box_sides(_tensor_mesh(x, y, kind), x[0], x[-1], y[0], y[-1])


# ---------------------------------------------------------------------------
# gmsh
# ---------------------------------------------------------------------------


# gmsh options changed by this module; restored when gmsh was already running
_OPTIONS = (
    "General.Terminal",
    "Mesh.Algorithm",
    "Mesh.RecombineAll",
    "Mesh.RecombinationAlgorithm",
    "Mesh.MeshSizeExtendFromBoundary",
    "Mesh.MeshSizeFromPoints",
    "Mesh.MeshSizeFromCurvature",
)


@contextmanager
def _gmsh_model(name):
    """Work in a fresh gmsh model, initializing gmsh if needed.

    If gmsh is already initialized, the current model and the options in
    ``_OPTIONS`` are restored on exit; otherwise gmsh is finalized.
    """
    started = not gmsh.isInitialized()
    if started:
        kwargs = {"readConfigFiles": False}
        if threading.current_thread() is not threading.main_thread():
            # the default installs a SIGINT handler, only possible in the
            # main thread
            kwargs["interruptible"] = False
        gmsh.initialize(**kwargs)
    else:
        previous_model = gmsh.model.getCurrent()
        previous_options = {key: gmsh.option.getNumber(key) for key in _OPTIONS}
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(name)
        yield
    finally:
        if started:
            gmsh.finalize()
        else:
            gmsh.model.setCurrent(name)
            gmsh.model.remove()
            gmsh.model.setCurrent(previous_model)
            for key, value in previous_options.items():
                gmsh.option.setNumber(key, value)


def _format(value):
    return f"{float(value):.17g}"


def _set_size_field(expression):
    """Use the gmsh formula ``expression`` of x, y as the only size source."""
    field = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(field, "F", expression)
    gmsh.model.mesh.field.setAsBackgroundMesh(field)
    for option in (
        "Mesh.MeshSizeExtendFromBoundary",
        "Mesh.MeshSizeFromPoints",
        "Mesh.MeshSizeFromCurvature",
    ):
        gmsh.option.setNumber(option, 0)


def _generate(kind):
    """Mesh the current 2D model with triangles or quadrilaterals only."""
    _check_kind(kind)
    if kind == "quad":
        gmsh.option.setNumber("Mesh.Algorithm", 8)  # frontal-Delaunay for quads
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 3)  # blossom full-quad
    else:
        gmsh.option.setNumber("Mesh.Algorithm", 6)  # frontal-Delaunay
        gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.model.mesh.generate(2)
    types = set(gmsh.model.mesh.getElements(2)[0])
    expected = {_GMSH_QUAD if kind == "quad" else _GMSH_TRI}
    if types != expected:
        raise RuntimeError(
            f"gmsh produced cell types {sorted(types)}, expected only {kind} cells"
        )


def _add_physical(dim, tags, name):
    tag = gmsh.model.addPhysicalGroup(dim, list(tags))
    gmsh.model.setPhysicalName(dim, tag, name)


def gmsh_rectangle(lx, ly, h, kind="tri", h_corner=None):
    """Unstructured mesh of ``[0, lx] x [0, ly]`` generated by gmsh.

    Parameters
    ----------
    lx, ly : float
        Side lengths of the rectangle.
    h : float
        Target cell size.
    kind : {"tri", "quad"}
        Triangles, or quadrilaterals obtained by recombination (only
        quadrilaterals are returned).
    h_corner : float, optional
        Target cell size at the origin corner.  The size then grows linearly
        with the distance ``d`` to the origin, reaching ``h`` at
        ``d = min(lx, ly) / 2``.

    Returns
    -------
    skfem.MeshTri1 or skfem.MeshQuad1
        Mesh with boundaries ``"left"``, ``"right"``, ``"bottom"``, ``"top"``
        and subdomain ``"domain"``.
    """
    _check_kind(kind)
    lx, ly, h = _positive(lx, "lx"), _positive(ly, "ly"), _positive(h, "h")
    if h_corner is not None:
        h_corner = _positive(h_corner, "h_corner")
    with _gmsh_model("rectangle"):
        geo = gmsh.model.geo
        corners = [(0.0, 0.0), (lx, 0.0), (lx, ly), (0.0, ly)]
        points = [geo.addPoint(x, y, 0.0) for x, y in corners]
        lines = [geo.addLine(points[i], points[(i + 1) % 4]) for i in range(4)]
        surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
        geo.synchronize()
        for line, name in zip(lines, ("bottom", "right", "top", "left")):
            _add_physical(1, [line], name)
        _add_physical(2, [surface], "domain")

        if h_corner is None:
            _set_size_field(_format(h))
        else:
            hc, reach = _format(h_corner), _format(0.5 * min(lx, ly))
            _set_size_field(
                f"Min({_format(h)}, {hc} + ({_format(h)} - {hc}) * "
                f"Sqrt(x * x + y * y) / {reach})"
            )
        _generate(kind)
        return from_gmsh()


def gmsh_plate_with_hole(radius, length, h, kind="tri", h_hole=None):
    """Quarter of a square plate with a central circular hole.

    The domain is ``[0, length]^2`` minus the disc of the given radius
    centred at the origin, i.e. the quarter of a plate with a hole modelled
    with two symmetry planes.

    Parameters
    ----------
    radius : float
        Radius of the hole, ``0 < radius < length``.
    length : float
        Side length of the quarter plate.
    h : float
        Target cell size at the far edges ``x = length`` and ``y = length``.
    kind : {"tri", "quad"}
        Cell type, as in :func:`gmsh_rectangle`.
    h_hole : float, optional
        Target cell size on the hole (default ``h``).  The size grows
        linearly with the distance ``r - radius`` to the hole and reaches
        ``h`` at ``r = length``.

    Returns
    -------
    skfem.MeshTri1 or skfem.MeshQuad1
        Mesh with boundaries ``"hole"``, ``"left"`` (``x = 0``),
        ``"bottom"`` (``y = 0``), ``"right"`` (``x = length``), ``"top"``
        (``y = length``) and subdomain ``"domain"``.
    """
    _check_kind(kind)
    radius, length = _positive(radius, "radius"), _positive(length, "length")
    if not radius < length:
        raise ValueError(f"radius must satisfy 0 < radius < length, not {radius} >= {length}")
    h = _positive(h, "h")
    if h_hole is not None:
        h_hole = _positive(h_hole, "h_hole")
    h_hole = h if h_hole is None else h_hole
    with _gmsh_model("plate_with_hole"):
        geo = gmsh.model.geo
        centre = geo.addPoint(0.0, 0.0, 0.0)
        a = geo.addPoint(radius, 0.0, 0.0)
        b = geo.addPoint(length, 0.0, 0.0)
        c = geo.addPoint(length, length, 0.0)
        d = geo.addPoint(0.0, length, 0.0)
        e = geo.addPoint(0.0, radius, 0.0)
        lines = {
            "bottom": geo.addLine(a, b),
            "right": geo.addLine(b, c),
            "top": geo.addLine(c, d),
            "left": geo.addLine(d, e),
            "hole": geo.addCircleArc(e, centre, a),
        }
        surface = geo.addPlaneSurface([geo.addCurveLoop(list(lines.values()))])
        geo.synchronize()
        for name, line in lines.items():
            _add_physical(1, [line], name)
        _add_physical(2, [surface], "domain")

        hh, hf = _format(h_hole), _format(h)
        r0, span = _format(radius), _format(length - radius)
        _set_size_field(
            f"Min({hf}, {hh} + ({hf} - {hh}) * (Sqrt(x * x + y * y) - {r0}) / {span})"
        )
        _generate(kind)
        return from_gmsh()


def _lookup(keys, table):
    """Positions of ``keys`` in the 1D integer array ``table`` (-1 if absent)."""
    order = np.argsort(table)
    pos = np.searchsorted(table, keys, sorter=order)
    pos = np.minimum(pos, len(table) - 1)
    found = table[order[pos]] == keys
    return np.where(found, order[pos], -1)


def from_gmsh():
    """Convert the current gmsh model to a scikit-fem mesh.

    The model must have been meshed in 2D (``gmsh.model.mesh.generate(2)``
    or ``gmsh.open``) with first-order triangles or quadrilaterals, not both.
    Nodes are renumbered from 0 and nodes not used by a 2D cell are dropped.

    Returns
    -------
    skfem.MeshTri1 or skfem.MeshQuad1
        Mesh with one named boundary per 1D physical group (its line
        elements matched to mesh facets) and one named subdomain per 2D
        physical group.  Groups without a name are named by their tag.

    Raises
    ------
    ValueError
        If the model has no 2D cells, mixed or higher-order cells, 3D cells,
        is not planar, or a 1D physical group has a line that is not a mesh
        facet.
    """
    mesh_api = gmsh.model.mesh
    if len(mesh_api.getElements(3)[0]) > 0:
        raise ValueError("the model has 3D cells; only 2D meshes are supported")
    types, cell_tags, cell_nodes = mesh_api.getElements(2)
    if len(types) == 0:
        raise ValueError("the model has no 2D cells (triangles or quadrilaterals)")
    if len(types) > 1:
        raise ValueError("mixed cell types are not supported; mesh with one kind")
    if types[0] not in (_GMSH_TRI, _GMSH_QUAD):
        name = mesh_api.getElementProperties(types[0])[0]
        raise ValueError(f"unsupported cell type {name!r}; use first-order cells")
    kind = "tri" if types[0] == _GMSH_TRI else "quad"
    nverts = 3 if kind == "tri" else 4
    cell_tags = np.asarray(cell_tags[0], dtype=np.int64)
    cell_nodes = np.asarray(cell_nodes[0], dtype=np.int64).reshape(-1, nverts).T

    # renumber the nodes used by the cells as 0..n-1
    node_tags, coords, _ = mesh_api.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords).reshape(-1, 3).T
    used, t = np.unique(cell_nodes, return_inverse=True)
    t = t.reshape(cell_nodes.shape)
    where = _lookup(used, node_tags)
    if np.any(where < 0):
        raise ValueError("cells refer to nodes that the model does not define")
    xyz = coords[:, where]
    scale = np.ptp(xyz[:2], axis=1).max()
    if np.ptp(xyz[2]) > 1e-10 * scale:
        raise ValueError("the mesh does not lie in a plane z = constant")
    mesh = _make_mesh(xyz[:2], t, kind)

    # named boundaries: line elements of the 1D physical groups -> facets
    facets = mesh.facets.astype(np.int64)
    n = mesh.p.shape[1]
    facet_keys = facets[0] * n + facets[1]
    boundaries = {}
    for dim, tag in gmsh.model.getPhysicalGroups(1):
        name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
        pairs = [np.empty((0, 2), dtype=np.int64)]
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            line_types, _, line_nodes = mesh_api.getElements(1, entity)
            for line_type, nodes in zip(line_types, line_nodes):
                if line_type != _GMSH_LINE:
                    raise ValueError(f"boundary {name!r} has non-linear line elements")
                pairs.append(np.asarray(nodes, dtype=np.int64).reshape(-1, 2))
        pairs = np.concatenate(pairs).T
        local = _lookup(pairs.ravel(), used).reshape(pairs.shape)
        local = np.sort(local, axis=0)
        index = _lookup(local[0] * n + local[1], facet_keys)
        if np.any(local[0] < 0) or np.any(index < 0):
            raise ValueError(f"boundary {name!r} has lines that are not mesh facets")
        boundaries[name] = np.unique(index)

    subdomains = {}
    for dim, tag in gmsh.model.getPhysicalGroups(2):
        name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
        tags = [np.empty(0, dtype=np.int64)]
        for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            tags.extend(np.asarray(x, dtype=np.int64)
                        for x in mesh_api.getElements(2, entity)[1])
        subdomains[name] = np.unique(_lookup(np.concatenate(tags), cell_tags))

    if boundaries:
        mesh = mesh.with_boundaries(boundaries)
    if subdomains:
        mesh = mesh.with_subdomains(subdomains)
    return mesh


def _check_gmsh_input(path):
    """Refuse files that are neither a ``.msh`` (which starts with
    ``$MeshFormat``) nor ``.geo`` text before gmsh sees them: gmsh reads
    anything else with its ``.geo`` parser, which NUL or non-UTF-8 bytes
    leave broken for the rest of the process (every later ``.geo`` file
    then fails with a syntax error).  Returns the text of a ``.geo`` file
    (None for a ``.msh`` file)."""
    with open(path, "rb") as handle:
        head = handle.read(64)
        if head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"$MeshFormat"):
            return None
        data = head + handle.read()
    if path.suffix.lower() == ".msh":
        raise ValueError(f"mesh file '{path}' is not a gmsh .msh file: it does not start "
                         "with $MeshFormat (truncated at the start, or another format?)")
    bad = data.find(b"\0")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as err:
        bad = err.start if bad < 0 else min(bad, err.start)
    if bad >= 0:
        line = data.count(b"\n", 0, bad) + 1
        raise ValueError(f"mesh file '{path}' is neither a .msh file nor .geo text: byte "
                         f"{bad} (line {line}) is {data[bad:bad + 1]!r}")
    return data.decode("utf-8")


def load(path, trust_geo=False):
    """Read a gmsh ``.msh`` file, or mesh a ``.geo`` file, into a scikit-fem mesh.

    A ``.geo`` file is meshed in 2D with the options it sets (for example
    ``Mesh.RecombineAll = 1;`` for quadrilaterals).  It is refused if it
    runs programs, reads other files or writes files
    (:func:`skfem_rkpm.geo_check.check_geo`), unless ``trust_geo``.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.
    trust_geo : bool
        Let gmsh run a ``.geo`` file whatever it does (only for files you
        trust).

    Returns
    -------
    skfem.MeshTri1 or skfem.MeshQuad1
        The mesh, as returned by :func:`from_gmsh`.

    Raises
    ------
    ValueError
        If the file does not exist, cannot be read by gmsh, does not
        hold a usable 2D mesh, or is a ``.geo`` script that reaches outside
        its geometry; the message names the file (and the line).
    """
    path = Path(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "does not exist"
        raise ValueError(f"mesh file '{path}' {what}")
    geo_text = _check_gmsh_input(path)
    if geo_text is not None:
        check_geo(f"mesh file '{path}'", geo_text, trust_geo)
    with _gmsh_model("load"):
        try:
            gmsh.merge(str(path))
            if path.suffix.lower() == ".geo":
                gmsh.model.mesh.generate(2)
        except Exception as error:
            raise ValueError(f"gmsh cannot read mesh file '{path}': {error}") from error
        try:
            return from_gmsh()
        except ValueError as error:
            raise ValueError(f"mesh file '{path}': {error}") from error


# ---------------------------------------------------------------------------
# spacing
# ---------------------------------------------------------------------------


def local_spacing(mesh):
    """Mean length of the mesh edges incident to each vertex.

    Parameters
    ----------
    mesh : skfem.Mesh
        Any scikit-fem mesh.  The edges are the cells in 1D, the facets in
        2D and the edges in 3D.

    Returns
    -------
    ndarray
        Spacing ``h_I`` of each vertex, shape ``(nvertices,)``; ``nan`` for
        vertices not used by any cell.
    """
    dim = mesh.p.shape[0]
    edges = {1: lambda: mesh.t, 2: lambda: mesh.facets, 3: lambda: mesh.edges}[dim]()
    edges = edges[:2]
    lengths = np.linalg.norm(mesh.p[:, edges[0]] - mesh.p[:, edges[1]], axis=0)
    nv = mesh.p.shape[1]
    total = np.bincount(edges.ravel(), weights=np.tile(lengths, 2), minlength=nv)
    count = np.bincount(edges.ravel(), minlength=nv)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / count
