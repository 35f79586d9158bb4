"""What any mesh tells the RK approximation and the scene builder: the
vertices that serve as particles, the spacing at each vertex and the unit
normal of a flat named boundary.

These work on every scikit-fem mesh, generated here or not.
"""

import numpy as np

__all__ = ["mesh_vertices", "local_spacing", "plane_normal"]


def plane_normal(mesh, boundary, tol=1e-8):
    """Unit normal of a flat named boundary: a straight line in 2D, a plane
    in 3D (e.g. a symmetry plane at any angle).

    The normal is the direction in which the boundary's vertices spread
    least (the last right singular vector of their centred coordinates),
    signed so that its largest component is positive.

    Parameters
    ----------
    mesh : skfem.Mesh
    boundary : str
        Name in ``mesh.boundaries``.
    tol : float
        The vertices may lie off the plane by ``tol`` times the boundary's
        extent.

    Raises
    ------
    ValueError
        If the mesh has no such boundary, or it is not flat (naming how far
        its vertices lie off the best plane).
    """
    if boundary not in (mesh.boundaries or {}):
        raise ValueError(f"the mesh has no boundary {boundary!r}; it has "
                         f"{sorted(mesh.boundaries or {})}")
    points = mesh.p[:, np.unique(mesh.facets[:, mesh.boundaries[boundary]])]
    offsets = (points - points.mean(axis=1, keepdims=True)).T
    _, _, directions = np.linalg.svd(offsets, full_matrices=False)
    normal = directions[-1] * np.sign(directions[-1][np.argmax(np.abs(directions[-1]))])
    off = np.abs(offsets @ normal).max()
    extent = np.linalg.norm(offsets, axis=1).max()
    if off > tol * extent:
        what = "straight" if mesh.dim() == 2 else "flat"
        raise ValueError(f"boundary {boundary!r} is not {what}: its vertices lie up to "
                         f"{off:.3g} off the best {'line' if mesh.dim() == 2 else 'plane'} "
                         f"(extent {extent:.3g})")
    return normal


def mesh_vertices(mesh):
    """The vertex coordinates of a mesh, the default particles.

    ``mesh.p`` itself for linear meshes; for quadratic meshes (``MeshTri2``,
    ``MeshQuad2``, ...), whose ``p`` also holds the mid-edge (mid-face,
    centre) nodes after the vertices, only its first ``mesh.nvertices``
    columns: the extra nodes are no particles.
    """
    elem = type(mesh).elem()
    if elem.edge_dofs or elem.facet_dofs or elem.interior_dofs:
        return mesh.p[:, :mesh.nvertices]
    return mesh.p


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
