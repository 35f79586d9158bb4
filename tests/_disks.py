"""Disks of concentric materials, meshed along their interfaces, for the
tests that follow scikit-fem's published examples on disks (ex17's insulated
wire, ex35's coaxial cable), whose meshes scikit-fem ships as files.

The square ``[-1, 1]²`` of ``2n × 2n`` cells is mapped level set by level
set of ``ρ = max(|ξ|, |η|)``: up to the first interface the squares are
blended into circles (a square at the centre, the circle of radius
``radii[0]`` at ``ρ = rings[0] / n``), after it every level set is a circle,
the radius linear in ``ρ`` between the interfaces.  Every interface and the
perimeter are circles along cell edges (polygons through their vertices).
"""

import numpy as np
from skfem import MeshQuad

__all__ = ["concentric_disk"]


def concentric_disk(radii, rings, names, interfaces, kind="quad"):
    """A disk of radius ``radii[-1]`` in rings of materials.

    Parameters
    ----------
    radii : sequence of float
        Outer radius of each material, increasing.
    rings : sequence of int
        Cells across each material (``n = sum(rings)``).
    names : sequence of str
        Subdomain name of each material.
    interfaces : dict
        Boundary name -> index ``k`` of the circle ``radii[k]`` (interior
        interfaces too, as scikit-fem's meshes name them); the perimeter is
        ``"perimeter"`` unless named here.
    kind : {"quad", "tri"}
        Quadrilaterals, or each split into two triangles.
    """
    n = int(sum(rings))
    ref = MeshQuad.init_tensor(*[np.linspace(-1.0, 1.0, 2 * n + 1)] * 2)
    rho = np.max(np.abs(ref.p), axis=0)
    levels = np.concatenate([[0.0], np.cumsum(rings) / n])
    r = np.interp(rho, levels, np.concatenate([[0.0], radii]))
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(rho > 0, ref.p / rho, 0.0)
        circle = np.where(rho > 0, q / np.linalg.norm(q, axis=0), 0.0)
    beta = np.clip(rho / levels[1], 0.0, 1.0)
    p = r * ((1.0 - beta) * q + beta * circle)
    mesh = MeshQuad(p, ref.t)
    if kind == "tri":
        mesh = mesh.to_meshtri()
    elif kind != "quad":
        raise ValueError(f"kind is 'quad' or 'tri', not {kind!r}")
    # materials from the level of the cell centroids, interfaces from those of
    # the vertices (the radius mapped back to rho: monotone, and below
    # levels[1] inside the first circle)
    def level(x):
        return np.interp(np.linalg.norm(x, axis=0), np.concatenate([[0.0], radii]), levels)

    at = level(mesh.p)
    which = np.searchsorted(levels[1:], level(mesh.p[:, mesh.t].mean(axis=1)))
    subdomains = {name: np.flatnonzero(which == k) for k, name in enumerate(names)}
    lo, hi = at[mesh.facets].min(axis=0), at[mesh.facets].max(axis=0)
    left, right = mesh.f2t
    between = (right < 0) | (which[left] != which[np.maximum(right, 0)])
    boundaries = {name: np.flatnonzero(np.isclose(lo, levels[k + 1])
                                       & np.isclose(hi, levels[k + 1]) & between)
                  for name, k in {"perimeter": len(radii) - 1, **interfaces}.items()}
    return mesh.with_subdomains(subdomains).with_boundaries(boundaries)

