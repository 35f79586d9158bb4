"""The tangent of a nodally integrated solid, summed over clusters of particles.

With nodal integration (SCNI, DNI) every particle ``L`` is one quadrature
point, and the tangent of :class:`~skfem_rkpm.mechanics.problem.SolidProblem`
is

    K = Σ_L w_L B_Lᵀ A_L B_L = Bᵀ D B,

``B`` the smoothed gradients of all points stacked (sparse, (points · c ·
dim) x dofs; ``B_smooth = A · B_boundary``, the boundary integrals of the
shape functions over the smoothing cells), ``D`` block diagonal with one
``(c dim)²`` block ``w_L A_L`` per point.  A smoothed gradient reaches every
particle whose support touches the smoothing cell: ``n_L`` = 49 on the ring
(box supports of 3 spacings), 87 in 3D (radial support 2).  Summed point by
point (the :class:`~skfem_rkpm.assembly.Assembler` with one point per cell)
every point makes ``(c n_L)²`` local entries: 1.69 M on the ring for the
67 k entries of ``K``, and their scatter into ``K`` costs more than the
products that make them.

Here the points are grouped into clusters of ``g`` neighbouring particles
(recursive coordinate bisection of their positions), and ``Bᵀ D B`` is formed
cluster by cluster with the union ``U_k`` of the particles its points reach
as the local functions: the rows of ``B`` of a point are zero at the
particles of ``U_k`` it does not reach.  This takes more multiplications,
``|U_k|² g`` against ``Σ n_L²``, in one batched dense product per cluster,
and leaves ``|U_k|²`` entries to scatter instead of ``g n_L²``.  The size
``g`` is chosen from the counts (:func:`cluster_cost`).  The scatter goes
into the sparsity pattern of the per-point assembler: an entry of a cluster
that couples two particles no point couples is exactly zero (every term has
a zero factor) and is dropped.  So the matrix has the per-point pattern and
its entries to round-off (the same terms, summed in another order).

A general sparse product ``Bᵀ (D B)`` (scipy) was measured as well: on the
ring it takes about as long as the per-point assembly (5-7 ms against
5-6.5 ms), as its symbolic phase and the accumulation of one product term at
a time do the work of the scatter again; the clusters take 1.5-2 ms.
"""

import numpy as np
import scipy.sparse as sp

from ..assembly import Assembler, Layout

__all__ = ["point_clusters", "cluster_cost", "best_cluster_size", "ClusteredTangent",
           "nodal_tangent", "CLUSTER_SIZES"]

#: the cluster sizes tried (1: the per-point assembly)
CLUSTER_SIZES = (1, 2, 4, 8, 16, 32)
#: cost of one scattered local entry in units of one multiply-add of the
#: batched products (measured on the ring and the 3D block, 2026-12-03:
#: about 2.5 ns per scattered entry, 0.1 ns per multiply-add in the
#: products of the cluster sizes that win)
SCATTER_WEIGHT = 25.0
#: no cluster layout with more local entries than this (float64 local
#: matrices and their scatter): the per-point assembly is used beyond
MAX_ENTRIES = 2**27
#: clusters whose unions differ by at most this ratio share one padded width
BUCKET_RATIO = 1.2


def point_clusters(x, size):
    """Groups of at most ``size`` neighbouring points, by recursive bisection.

    Each set is split across its widest coordinate, the first part holding
    half the set's clusters (rounded down) times ``size`` points, so that all
    clusters but one hold exactly ``size`` points.

    Parameters
    ----------
    x : ndarray, shape (dim, npoints)
    size : int

    Returns
    -------
    ndarray, shape (nclusters, size)
        Point numbers, ``-1`` where a cluster has fewer points.
    """
    x = np.asarray(x, float)
    n = x.shape[1]
    if size < 1:
        raise ValueError(f"clusters hold at least one point, not {size}")
    leaves, stack = [], [np.arange(n)]
    while stack:
        idx = stack.pop()
        if len(idx) <= size:
            leaves.append(idx)
            continue
        part = x[:, idx]
        axis = int(np.argmax(np.ptp(part, axis=1)))
        order = idx[np.argsort(part[axis], kind="stable")]
        first = (-(-len(idx) // size) // 2) * size
        stack += [order[first:], order[:first]]
    out = np.full((len(leaves), size), -1, dtype=np.intp)
    for k, leaf in enumerate(leaves):
        out[k, :len(leaf)] = leaf
    return out


def _unions(element_nodes, members):
    """The union of the particles of each cluster's points.

    Returns the particles (nunion, nclusters), padded with each cluster's
    first, the number of each cluster's particles, and for every (slot,
    point) of ``element_nodes`` its place in its cluster's union.
    """
    nloc, npoints = element_nodes.shape
    ncl, size = members.shape
    cluster = np.empty(npoints, dtype=np.int64)
    valid = members >= 0
    cluster[members[valid]] = np.nonzero(valid)[0]
    nodes = element_nodes.astype(np.int64)
    keys = cluster[None, :] * (int(nodes.max()) + 1) + nodes  # (nloc, npoints)
    unique, inverse = np.unique(keys, return_inverse=True)
    owner = unique // (int(nodes.max()) + 1)
    first = np.searchsorted(owner, np.arange(ncl))
    count = np.diff(np.append(first, len(unique)))
    place = inverse.reshape(keys.shape) - first[cluster][None, :]
    width = int(count.max())
    slot = np.arange(width)[:, None]
    index = first[None, :] + np.minimum(slot, count[None, :] - 1)
    union = (unique[index] % (int(nodes.max()) + 1)).astype(element_nodes.dtype)
    return union, count, place


def _buckets(count):
    """Clusters grouped by the size of their unions: sorted, a new group
    whenever a union is more than :data:`BUCKET_RATIO` times the group's
    first, so that padding every union of a group to the group's largest
    wastes little.  Returns a list of cluster numbers per group."""
    order = np.argsort(count, kind="stable")
    groups, first = [], 0
    for k in range(1, len(order) + 1):
        if k == len(order) or count[order[k]] > BUCKET_RATIO * count[order[first]]:
            groups.append(order[first:k])
            first = k
    return groups


def cluster_cost(element_nodes, x, size, ncomp, dim):
    """Estimated cost of the cluster assembly with clusters of ``size``:
    ``(local entries, multiply-adds, members)``; the time is taken as
    ``SCATTER_WEIGHT · entries + multiply-adds``."""
    members = point_clusters(x, size)
    _, count, _ = _unions(element_nodes, members)
    entries = sum(len(g) * (int(count[g].max()) * ncomp) ** 2 for g in _buckets(count))
    return entries, entries * dim * size, members


def best_cluster_size(element_nodes, x, ncomp, dim):
    """The size of :data:`CLUSTER_SIZES` of least estimated cost
    (:func:`cluster_cost`) within :data:`MAX_ENTRIES`, and its clusters
    (1 and None: the per-point assembly)."""
    nloc, npoints = element_nodes.shape
    single = npoints * (nloc * ncomp) ** 2
    best = (SCATTER_WEIGHT * single + single * dim, 1, None)
    for size in CLUSTER_SIZES[1:]:
        entries, products, members = cluster_cost(element_nodes, x, size, ncomp, dim)
        cost = SCATTER_WEIGHT * entries + products
        if entries <= MAX_ENTRIES and cost < best[0]:
            best = (cost, size, members)
    return best[1], best[2]


class _Group:
    """Clusters whose unions are padded to one width: their layout, the
    assembler of their local matrices and the scatter of these into the
    tangent's CSR data (a sparse 0/1 matrix, entries of no pattern place
    left out)."""

    def __init__(self, L, members, union, place, cluster, slot, clusters):
        ncl, size = len(clusters), members.shape[1]
        width = union.shape[0]
        dim = L.dim
        self.points = np.where(members[clusters] >= 0, members[clusters], 0)
        valid = members[clusters] >= 0
        dx = np.where(valid, L.dx[self.points, 0], 0.0)
        # the points of these clusters, their union places and slots
        local = np.full(members.shape[0], -1, dtype=np.intp)
        local[clusters] = np.arange(ncl)
        mine = local[cluster] >= 0
        flat = ((place[:, mine] * ncl + local[cluster[mine]][None, :]) * size
                + slot[mine][None, :]).ravel()

        def gather(grads):
            out = np.zeros((dim, width * ncl * size))
            for d in range(dim):
                out[d] = np.bincount(flat, weights=grads[d, :, mine, 0].T.ravel(),
                                     minlength=out.shape[1])
            return out.reshape(dim, width, ncl, size)

        trial = gather(L.trial_grads)
        test = trial if L.test_grads is L.trial_grads else gather(L.test_grads)
        self.union = np.ascontiguousarray(union[:, clusters])
        self.layout = Layout(self.union, np.zeros((width, ncl, size)), trial, test, dx,
                             L.ncomp, L.nscalar)
        self.assembler = Assembler(self.layout, pattern=False)
        self.local = None

    def set_scatter(self, keys, order, n, nnz):
        """The scatter into the CSR data whose sorted keys ``row n + col``
        are ``keys`` (``order``: their places, or None if in place)."""
        c = self.layout.ncomp
        dofs = c * self.union.T.astype(np.int64)[:, :, None] + np.arange(c)  # (ncl, w, c)
        ncl, width = dofs.shape[:2]
        # the order of the local matrices: (cluster, a, c_a, c_b, b)
        wanted = (dofs.reshape(ncl, width * c, 1) * n
                  + dofs.transpose(0, 2, 1).reshape(ncl, 1, c * width)).ravel()
        found = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
        hit = np.flatnonzero(keys[found] == wanted)
        found = found[hit] if order is None else order[found[hit]]
        self.entries = wanted.size
        self.scatter = sp.csr_matrix((np.ones(len(hit)), (found, hit)),
                                     shape=(nnz, wanted.size))

    def add_to(self, data, C):
        """Add this group's share of the tangent of ``C`` to ``data``."""
        Cg = C if C.ndim == 4 else C[..., 0][..., self.points]
        self.local = self.assembler.local_bilinear(Cg, out=self.local)
        data += self.scatter @ self.local.reshape(-1)


class ClusteredTangent:
    """``Bᵀ D B`` of a one-point-per-cell :class:`~skfem_rkpm.assembly.Assembler`,
    summed over clusters of points into that assembler's sparsity pattern.

    The clusters are grouped by the size of their unions (:func:`_buckets`),
    each group padded to its largest union.

    Parameters
    ----------
    assembler : Assembler
        Square, one quadrature point per cell (nodal integration).
    x : ndarray, shape (dim, ncells)
        Positions of the points (to group neighbours).
    size : int, optional
        Points per cluster; by default the one of :data:`CLUSTER_SIZES` with
        the least estimated cost (:func:`cluster_cost`).
    """

    def __init__(self, assembler, x, size=None):
        L = assembler.layout
        if not assembler.square or L.dx.shape[1] != 1:
            raise ValueError("ClusteredTangent needs a square assembler with one "
                             f"quadrature point per cell, not {L.dx.shape[1]}")
        self.assembler = assembler
        if size is None:
            size, members = best_cluster_size(L.element_nodes, x, L.ncomp, L.dim)
        else:
            members = point_clusters(x, size)
        self.size, self.members = size, members
        union, count, place = _unions(L.element_nodes, members)
        self.count = count
        npoints = L.dx.shape[0]
        cluster = np.empty(npoints, dtype=np.intp)
        slot = np.empty(npoints, dtype=np.intp)
        valid = members >= 0
        cluster[members[valid]] = np.nonzero(valid)[0]
        slot[members[valid]] = np.nonzero(valid)[1]
        self.groups = [_Group(L, members, union[:int(count[g].max())], place, cluster,
                              slot, g) for g in _buckets(count)]
        _, nnz, indptr, cols = assembler._pattern_parts()
        self._pattern = (nnz, indptr, cols)
        n = assembler.N
        rows = np.repeat(np.arange(len(indptr) - 1, dtype=np.int64), np.diff(indptr))
        keys = rows * n + cols
        order = None
        if np.any(np.diff(keys) <= 0):
            order = np.argsort(keys, kind="stable")
            keys = keys[order]
        for group in self.groups:
            group.set_scatter(keys, order, n, nnz)

    @property
    def entries(self):
        """Local entries computed per tangent (those of no pattern place included)."""
        return sum(g.entries for g in self.groups)

    def matrix(self, C):
        """The tangent ``∫ ∂_l N_a C_{c l d m} ∂_m N_b`` in the assembler's
        pattern; ``C`` as for :meth:`Assembler.bilinear`."""
        C = np.asarray(C, dtype=float)
        nnz, indptr, cols = self._pattern
        data = np.zeros(nnz)
        for group in self.groups:
            group.add_to(data, C)
        return sp.csr_matrix((data, cols, indptr), shape=self.assembler.shape)


def nodal_tangent(assembler, x):
    """A :class:`ClusteredTangent` of a one-point-per-cell ``assembler`` at
    point positions ``x`` if clusters of more than one point cost less, else
    None (the per-point assembly)."""
    L = assembler.layout
    if not assembler.square or L.dx.shape[1] != 1:
        return None
    size, _ = best_cluster_size(L.element_nodes, x, L.ncomp, L.dim)
    return None if size == 1 else ClusteredTangent(assembler, x, size)
