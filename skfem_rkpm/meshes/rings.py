"""Structured meshes of a ring or a ring sector (an annulus in polar cells).

Cells are bounded by circles ``r = r_i`` and rays ``θ = θ_j``; the
vertices lie on the circles, so a facet on the inner or outer boundary is
a chord.  The radial cell sizes may grow geometrically (``grading``: the
largest over the smallest cell, the smallest at the inner radius, where
the stresses of a thick cylinder vary fastest).

Named boundaries: ``inner`` and ``outer`` (the circles) and, for a sector,
``start`` and ``end`` (the straight edges at the first and the last angle).
:func:`ring_sector` extrudes a sector into hexahedra (a 3D ring between
``bottom`` and ``top``).
"""

import numpy as np

from ._cells import _cells, _make_mesh, _number, _positive
from .structured import _geometric_nodes

__all__ = ["annulus", "ring_sector"]


def annulus(r_inner, r_outer, nr, nt, angles=(0.0, 360.0), grading=1.0, kind="quad",
            center=(0.0, 0.0)):
    """Mesh of the ring ``r_inner ≤ r ≤ r_outer`` between two angles.

    Parameters
    ----------
    r_inner, r_outer : float
        Radii, ``0 < r_inner < r_outer``.
    nr, nt : int
        Cells across the wall and around (along the arc of the sector).
    angles : (float, float)
        First and last angle in degrees, counter-clockwise from the x axis;
        a span of 360 makes the full ring (no ``start``/``end`` edges).
    grading : float
        Largest over smallest radial cell (>= 1; the smallest at the inner
        radius).
    kind : {"quad", "tri"}
        Quadrilaterals, or each split into two triangles.
    center : (float, float)
        Center of the circles.

    Returns
    -------
    skfem.MeshQuad1 or skfem.MeshTri1
        With boundaries ``inner``, ``outer`` and, for a sector, ``start``
        and ``end``.
    """
    r_inner, r_outer = _positive(r_inner, "r_inner"), _positive(r_outer, "r_outer")
    if not r_outer > r_inner:
        raise ValueError(f"the outer radius ({r_outer:g}) must exceed the inner radius "
                         f"({r_inner:g})")
    nr, nt = _cells(nr, "nr"), _cells(nt, "nt")
    a0, a1 = (_number(a, "angle") for a in angles)
    span = a1 - a0
    if not 0 < span <= 360.0 + 1e-9:
        raise ValueError(f"angles must increase by at most 360 degrees, got [{a0:g}, {a1:g}]")
    full = span >= 360.0 - 1e-9
    if full and nt < 3:
        raise ValueError("a full ring needs at least 3 cells around")
    grading = _number(grading, "grading")
    if grading < 1.0:
        raise ValueError(f"grading must be >= 1 (largest / smallest cell), got {grading:g}")
    if grading != 1.0 and nr < 2:
        raise ValueError("radial grading needs at least 2 cells across the wall")
    if kind not in ("quad", "tri"):
        raise ValueError(f"kind must be 'quad' or 'tri', got {kind!r}")

    radii = r_inner + _geometric_nodes(r_outer - r_inner, nr, grading)
    ncols = nt if full else nt + 1  # vertices around
    theta = np.deg2rad(a0 + span * np.arange(ncols) / nt)
    R, T = np.meshgrid(radii, theta, indexing="ij")  # (nr + 1, ncols)
    p = np.array([center[0] + R.ravel() * np.cos(T.ravel()),
                  center[1] + R.ravel() * np.sin(T.ravel())])

    def node(i, j):
        return i * ncols + (j % ncols)

    i, j = np.meshgrid(np.arange(nr), np.arange(nt), indexing="ij")
    i, j = i.ravel(), j.ravel()
    quads = np.array([node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)])
    if kind == "quad":
        t = quads
    else:
        t = np.hstack([quads[[0, 1, 2]], quads[[0, 2, 3]]])
    mesh = _make_mesh(p, t, kind)

    ring = np.repeat(np.arange(nr + 1), ncols)
    ray = np.tile(np.arange(ncols), nr + 1)
    facets = mesh.facets
    on = {"inner": ring == 0, "outer": ring == nr}
    if not full:
        on.update(start=ray == 0, end=ray == nt)
    boundary = np.zeros(facets.shape[1], bool)
    boundary[mesh.boundary_facets()] = True
    named = {name: np.flatnonzero(flag[facets[0]] & flag[facets[1]] & boundary)
             for name, flag in on.items()}
    return mesh.with_boundaries(named)


def ring_sector(r_inner, r_outer, height, nr, nt, nz, angle=15.0):
    """Hexahedral mesh of the ring sector ``r_inner ≤ r ≤ r_outer``,
    ``0 ≤ θ ≤ angle`` (degrees from the x axis), ``0 ≤ z ≤ height``.

    Vertices lie on the circles (facets on ``inner``/``outer`` are flat
    quadrilaterals through four of them).  Named boundaries: ``inner``,
    ``outer``, ``start`` (θ = 0, the plane y = 0), ``end`` (θ = angle),
    ``bottom`` (z = 0) and ``top`` (z = height).

    Returns
    -------
    skfem.MeshHex1
    """
    from skfem import MeshHex

    r_inner, r_outer = _positive(r_inner, "r_inner"), _positive(r_outer, "r_outer")
    if not r_outer > r_inner:
        raise ValueError(f"the outer radius ({r_outer:g}) must exceed the inner radius "
                         f"({r_inner:g})")
    height, angle = _positive(height, "height"), _positive(angle, "angle")
    if angle >= 180.0:
        raise ValueError(f"a ring sector spans less than 180 degrees, not {angle:g}")
    nr, nt, nz = _cells(nr, "nr"), _cells(nt, "nt"), _cells(nz, "nz")
    r = np.linspace(r_inner, r_outer, nr + 1)
    theta = np.linspace(0.0, np.radians(angle), nt + 1)
    z = np.linspace(0.0, height, nz + 1)
    box = MeshHex.init_tensor(r, theta, z)  # cells of the (r, θ, z) box
    q = box.p
    tol = 1e-9 * np.array([r_outer, np.radians(angle), height])
    sides = {"inner": (0, r_inner), "outer": (0, r_outer), "start": (1, 0.0),
             "end": (1, theta[-1]), "bottom": (2, 0.0), "top": (2, height)}
    named = box.with_boundaries({name: (lambda x, k=k, v=v: np.abs(x[k] - v) < tol[k])
                                 for name, (k, v) in sides.items()}).boundaries
    p = np.array([q[0] * np.cos(q[1]), q[0] * np.sin(q[1]), q[2]])
    return MeshHex(p, box.t, _boundaries=named)
