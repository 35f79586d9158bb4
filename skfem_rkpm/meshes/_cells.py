"""Cells of the generated meshes: argument checks, counter-clockwise
orientation and the scikit-fem mesh with its box sides, shared by
:mod:`.structured`, :mod:`.gmsh` and :mod:`.rings`."""

import numpy as np
import skfem

_KINDS = {"tri": skfem.MeshTri1, "quad": skfem.MeshQuad1}


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
