"""A structured hexahedral mesh of a quarter cylinder (a mapped quarter
disk, extruded).

The quarter disk ``x, y >= 0, x² + y² <= R²`` is cut into three mapped
blocks, so that no cell degenerates at the axis (a polar mesh would put
wedges there):

* the *core*, a quadrilateral with corners ``(0, 0)``, ``(a, 0)``,
  ``(b, b)`` and ``(0, a)``, in ``n_core x n_core`` bilinear cells;
* two *outer* blocks between the core and the arc, one on each side of the
  diagonal, in ``n_core`` cells along the arc (each spans 45 degrees) and
  ``n_outer`` cells across: the transfinite map between the straight core
  edge and the arc, linear across.

``a = R n_core / (n_core + n_outer)`` makes the radial cells along the
symmetry planes equal; ``b = a (1 + 1/√2) / 2`` puts the core's corner
halfway between the square and the circle through ``(a, 0)``.  The vertices
of the mantle lie on the circle ``r = R`` (its facets are flat
quadrilaterals through four of them).  The disk is extruded in ``nz``
uniform layers over ``0 <= z <= height``.

Named boundaries: ``xmin`` (the plane x = 0), ``ymin`` (y = 0), ``outer``
(the mantle r = R), ``bottom`` (z = 0) and ``top`` (z = height).
"""

import numpy as np

from ._cells import _cells, _make_mesh, _positive

__all__ = ["quarter_disk", "quarter_cylinder"]


def _block(corner_map, nu, nv):
    """Vertices ``(2, (nu+1)(nv+1))`` of ``corner_map(u, v)`` on the uniform
    grid of the unit square and its quadrilaterals (counter-clockwise in
    ``(u, v)``), numbered ``i * (nv + 1) + j``."""
    u, v = np.meshgrid(np.linspace(0.0, 1.0, nu + 1), np.linspace(0.0, 1.0, nv + 1),
                       indexing="ij")
    p = corner_map(u.ravel(), v.ravel())
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    i, j = i.ravel(), j.ravel()

    def node(a, b):
        return a * (nv + 1) + b

    return p, np.array([node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)])


def _quarter_disk_arrays(radius, n_core, n_outer):
    """Vertices and quadrilaterals of the three blocks, shared vertices merged."""
    a = radius * n_core / (n_core + n_outer)
    b = a * (1.0 + np.sqrt(0.5)) / 2.0

    def core(u, v):  # bilinear on (0, 0), (a, 0), (b, b), (0, a)
        return np.array([a * u * (1 - v) + b * u * v, b * u * v + a * (1 - u) * v])

    def outer(s, t):  # from the core edge (a, 0)-(b, b) to the arc, 0..45 degrees
        inner = np.array([a + (b - a) * s, b * s])
        arc = radius * np.array([np.cos(0.25 * np.pi * s), np.sin(0.25 * np.pi * s)])
        return (1 - t) * inner + t * arc

    parts = [_block(core, n_core, n_core), _block(lambda t, s: outer(s, t), n_outer, n_core)]
    p_side, t_side = parts[1]
    parts.append((p_side[::-1], t_side))  # the mirror image across the diagonal
    points, cells, offset = [], [], 0
    for p, t in parts:
        points.append(p)
        cells.append(t + offset)
        offset += p.shape[1]
    p, t = np.hstack(points), np.hstack(cells)
    # merge the vertices the blocks share (computed by the same formulas up
    # to round-off): snap to a grid far finer than the smallest cell
    key = np.round(p / (1e-9 * radius)).astype(np.int64)
    _, first, index = np.unique(key.T, axis=0, return_index=True, return_inverse=True)
    return p[:, first], index.ravel()[t]


def quarter_disk(radius, n_core, n_outer):
    """Quadrilateral mesh of the quarter disk ``x, y >= 0, r <= radius``
    (the three mapped blocks of the module's description).

    Named boundaries: ``xmin`` (x = 0), ``ymin`` (y = 0) and ``outer`` (the
    arc, chords through vertices on the circle).

    Returns
    -------
    skfem.MeshQuad1
    """
    radius = _positive(radius, "radius")
    n_core, n_outer = _cells(n_core, "n_core"), _cells(n_outer, "n_outer")
    p, t = _quarter_disk_arrays(radius, n_core, n_outer)
    mesh = _make_mesh(p, t, "quad")
    return mesh.with_boundaries(_named(mesh, radius, mesh.p))


def _named(mesh, radius, p, height=None):
    """Boundary facets of ``mesh`` whose vertices all lie on x = 0, y = 0,
    r = radius (and z = 0, z = height)."""
    tol = 1e-9 * radius
    on = {"xmin": np.abs(p[0]) < tol, "ymin": np.abs(p[1]) < tol,
          "outer": np.abs(np.hypot(p[0], p[1]) - radius) < tol}
    if height is not None:
        on.update(bottom=np.abs(p[2]) < tol, top=np.abs(p[2] - height) < tol)
    facets = mesh.boundary_facets()
    vertices = mesh.facets[:, facets]
    return {name: facets[np.all(flag[vertices], axis=0)] for name, flag in on.items()}


def quarter_cylinder(radius, height, n_core, n_outer, nz):
    """Hexahedral mesh of the quarter cylinder ``x, y >= 0, r <= radius,
    0 <= z <= height``: the quarter disk of :func:`quarter_disk` extruded in
    ``nz`` uniform layers.

    Parameters
    ----------
    radius, height : float
    n_core : int
        Cells along each side of the core and along each half of the arc
        (the arc has ``2 n_core`` cells).
    n_outer : int
        Cells from the core to the mantle.
    nz : int
        Layers along z.

    Returns
    -------
    skfem.MeshHex1
        With boundaries ``xmin``, ``ymin``, ``outer``, ``bottom`` and ``top``.
    """
    from skfem import MeshHex

    height = _positive(height, "height")
    nz = _cells(nz, "nz")
    disk = quarter_disk(radius, n_core, n_outer)
    q, t2 = disk.p, disk.t  # counter-clockwise quadrilaterals
    nq = q.shape[1]
    z = np.linspace(0.0, height, nz + 1)
    p = np.vstack([np.tile(q, nz + 1), np.repeat(z, nq)])
    lo = (t2[:, None, :] + nq * np.arange(nz)[None, :, None]).reshape(4, -1)  # layer by layer
    hi = lo + nq
    # scikit-fem's vertex order of a hexahedron, (u, v, w) in
    # {000, 010, 100, 001, 110, 011, 101, 111}, with the quadrilateral's
    # corners q0..q3 at (u, v) = (0, 0), (1, 0), (1, 1), (0, 1)
    t = np.array([lo[0], lo[3], lo[1], hi[0], lo[2], hi[3], hi[1], hi[2]])
    mesh = MeshHex(np.ascontiguousarray(p), np.ascontiguousarray(t))
    return MeshHex(mesh.p, mesh.t, _boundaries=_named(mesh, radius, mesh.p, height))
