"""Will the RK basis fit in memory?  An estimate before it is built.

Building an :class:`~skfem_rkpm.approximation.basis.RKBasis` stores, and
works on, every (evaluation point, particle) pair with the point inside the
particle's support.  The number of pairs is about the number of points
(cell and boundary quadrature points, particles) times the mean number of
supports covering a point, ``Σ_I |supp_I ∩ B| / |Ω|`` (``B`` the bounding
box of the mesh: supports at the boundary reach out of the body).  The
bytes per estimated pair are :data:`BYTES_PER_PAIR`, measured, plus a
quarter; ``20 + 60 m`` (``m`` monomials) where nothing was measured.
:func:`check_rk_memory` refuses, before anything is built, a basis
whose estimate exceeds the memory available (``MemAvailable`` of
``/proc/meminfo``, a cgroup limit, ``ulimit -v``), with the estimate and
what to change.
"""

import math
import resource
from math import comb
from pathlib import Path

import numpy as np

__all__ = ["ProblemTooLarge", "estimate_rk_bytes", "available_bytes", "check_rk_memory"]

GiB = 2.0 ** 30

#: peak resident memory of the build and ``basis.trial`` over the estimated
#: pairs, by (dimension, order), the larger of radial and box supports
#: (2026-12-02; 2D: rectangle of 17k particles, 16 Gauss points per cell,
#: radial 105 and box 94 at order 1, 425 and 382 at order 2, where the
#: factorization of the order-2 VCI system takes most of it; 3D: hexahedra,
#: 24³ and 20³ cells, 27 points per cell, radial 160 and box 105)
BYTES_PER_PAIR = {(2, 1): 105, (2, 2): 425, (3, 1): 160}
#: the margin on :data:`BYTES_PER_PAIR` for what the measurements did not see
MARGIN = 1.25


class ProblemTooLarge(ValueError):
    """The RK basis would not fit in the memory available."""


def _volume(mesh):
    """Measure of the mesh: cell areas in 2D (shoelace), cell volumes in 3D
    (the Jacobian of the cell maps on a degree-2 Gauss rule: exact for
    tetrahedra and parallelepipeds), the bounding box otherwise."""
    p = mesh.p
    if p.shape[0] == 2:
        x, y = p[0, mesh.t], p[1, mesh.t]  # (vertices per cell, cells), in order
        return float(np.sum(np.abs(np.sum(x * np.roll(y, -1, 0) - np.roll(x, -1, 0) * y,
                                          axis=0))) / 2)
    if p.shape[0] == 3:
        from skfem.quadrature import get_quadrature

        X, W = get_quadrature(mesh.refdom, 2)
        return float(np.sum(np.abs(mesh.mapping().detDF(X)) @ W))
    return float(np.prod(p.max(axis=1) - p.min(axis=1)))


def estimate_rk_bytes(mesh, radius, order, support_shape, intorder):
    """``(pairs, bytes, points)``: estimated point-particle pairs, peak bytes
    of the basis build (see the module notes) and evaluation points."""
    from skfem.quadrature import get_quadrature

    dim = mesh.p.shape[0]
    _, weights = get_quadrature(mesh.refdom, intorder)
    _, facet_weights = get_quadrature(mesh.brefdom, intorder) if dim > 1 else (None, [1])
    points = (mesh.nelements * len(weights) + len(mesh.boundary_facets()) *
              len(facet_weights) + mesh.nvertices)
    radius = np.broadcast_to(np.asarray(radius, float), (mesh.nvertices,))
    if support_shape == "box":
        measure = (2 * radius) ** dim
    else:
        measure = math.pi ** (dim / 2) / math.gamma(dim / 2 + 1) * radius ** dim
    # the part of each support inside the mesh's bounding box: supports of
    # particles near the boundary reach out of the body and cover fewer points
    lo, hi = mesh.p.min(axis=1, keepdims=True), mesh.p.max(axis=1, keepdims=True)
    inside = (np.minimum(mesh.p + radius, hi) - np.maximum(mesh.p - radius, lo)) / (2 * radius)
    measure = measure * np.prod(np.clip(inside, 0, 1), axis=0)
    covering = min(float(measure.sum()) / max(_volume(mesh), 1e-300), mesh.nvertices)
    pairs = points * covering
    per_pair = BYTES_PER_PAIR.get((dim, order))
    per_pair = 20 + 60 * comb(order + dim, dim) if per_pair is None else MARGIN * per_pair
    return pairs, pairs * per_pair, points


def available_bytes():
    """Memory this process may still use: the least of ``MemAvailable``, the
    cgroup's limit less its usage, and ``ulimit -v`` (None if none is known)."""
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            found.append(int(limit) - used)
    except (OSError, ValueError):
        pass
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        try:
            size = int(Path("/proc/self/statm").read_text().split()[0])
            found.append(soft - size * resource.getpagesize())
        except (OSError, ValueError):
            found.append(soft)
    return min(found) if found else None


def check_rk_memory(mesh, radius, order, support_shape, intorder, available=None):
    """Raise :class:`ProblemTooLarge` if the RK basis will not fit.

    ``available``: bytes (default :func:`available_bytes`)."""
    pairs, need, points = estimate_rk_bytes(mesh, radius, order, support_shape, intorder)
    available = available_bytes() if available is None else available
    if available is not None and need > available:
        raise ProblemTooLarge(
            f"the RK basis would need about {need / GiB:,.1f} GiB ({pairs:.3g} "
            f"point-particle pairs: {points:,} evaluation points, each inside about "
            f"{pairs / points:,.0f} of the {mesh.nvertices:,} particle supports), but only "
            f"{max(available, 0) / GiB:,.1f} GiB are available; use fewer cells "
            f"(geometry.divisions), a smaller support (discretization.support or "
            f"dilation), a lower discretization.quadrature, or --method fem")
    return pairs, need
