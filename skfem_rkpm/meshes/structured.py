"""Structured meshes with named boundaries: rectangles (uniform, perturbed,
graded or with piecewise divisions) and boxes (hexahedra or tetrahedra).

2D cells are always oriented counter-clockwise, i.e. the Jacobian of the
reference-to-physical map is positive everywhere.
"""

import numpy as np
import skfem

from ._cells import (_box, _cells, _make_mesh, _number, _positive, _signed_areas,
                     _tensor_mesh, _with_box_sides)

__all__ = ["rectangle", "graded_rectangle", "piecewise_rectangle", "box"]


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


#: the faces of a box: (name, axis, at the largest coordinate)
BOX_FACES = (("xmin", 0, False), ("xmax", 0, True), ("ymin", 1, False),
             ("ymax", 1, True), ("zmin", 2, False), ("zmax", 2, True))


def box(lx, ly, lz, nx, ny, nz, kind="hex", origin=(0.0, 0.0, 0.0)):
    """Structured mesh of a rectangular box (a cuboid).

    Parameters
    ----------
    lx, ly, lz : float
        Edge lengths along x, y and z.
    nx, ny, nz : int
        Number of cells along x, y and z.
    kind : {"hex", "tet"}
        ``"hex"`` gives ``nx * ny * nz`` trilinear hexahedra, ``"tet"``
        splits each of them into tetrahedra (scikit-fem's
        :meth:`skfem.MeshTet1.init_tensor`).
    origin : sequence of float
        The corner with the smallest coordinates.

    Returns
    -------
    skfem.MeshHex1 or skfem.MeshTet1
        Mesh with the boundaries ``"xmin"``, ``"xmax"``, ``"ymin"``,
        ``"ymax"``, ``"zmin"``, ``"zmax"`` (the facets on each face).

    Raises
    ------
    ValueError
        If a length is not positive, a cell count not an integer >= 1, the
        kind unknown or the origin not three finite numbers.
    """
    lengths = [_positive(v, name) for v, name in zip((lx, ly, lz), ("lx", "ly", "lz"))]
    counts = [_cells(v, name) for v, name in zip((nx, ny, nz), ("nx", "ny", "nz"))]
    mesh_type = {"hex": skfem.MeshHex1, "tet": skfem.MeshTet1}.get(kind)
    if mesh_type is None:
        raise ValueError(f"kind must be 'hex' or 'tet', got {kind!r}")
    if np.shape(origin) != (3,):
        raise ValueError(f"origin must be three numbers (x, y, z), not {origin!r}")
    start = [_number(v, f"origin {a}") for v, a in zip(origin, "xyz")]
    axes = [a + np.linspace(0.0, length, n + 1)
            for a, length, n in zip(start, lengths, counts)]
    mesh = mesh_type.init_tensor(*axes)
    tol = 1e-10 * max(lengths)
    return mesh.with_boundaries({
        name: (lambda x, axis=axis, at=axes[axis][-1 if last else 0]:
               np.abs(x[axis] - at) < tol)
        for name, axis, last in BOX_FACES})
