"""Symmetric VCI on the cells of a basis: the correction of
:func:`~.integration._symmetric_correction`, computed block by block of
quadrature points, its system matrix assembled cell by cell.

The correction (symmetric VCI, Chen, Hillman & Rüter 2013, in the form of
:func:`~.integration._symmetric_correction`) is, with ``P_J(x) = [1, (X_J -
x)/s(x)]``, ``G(x) = Σ_J φ_J P_J P_Jᵀ = L Lᵀ`` and ``B[(q, α), J] = (L_q⁻¹ P_J
φ_J)_α``,

    c_I(x) = φ_I(x) (ξ_I - P_I(x)ᵀ G(x)⁻¹ Σ_J P_J(x) φ_J(x) ξ_J),
    M ξ = r,    M = diag(∫̂ φ_I) - Bᵀ diag(w) B.

Everything at the pairs is formed per block of points, so that the
temporaries stay the size of a block (the pair-wide arrays of the general
path took 5.7 GB on ex09's 16³ vertices).  ``Bᵀ diag(w) B``, a sum over the
points of outer products of the ``m = dim + 1`` rows of ``B`` (3.5e9
multiply-adds on ex09), is assembled like a stiffness matrix, block by
block of cells as the frames of their points are formed: ``B`` of the block
laid out per cell (:mod:`.cell_layout`), the local matrices by batched dense
products, summed into one sparsity pattern
(:meth:`~skfem_rkpm.assembly.Assembler.streamed`), so that no layout of
``B`` for all cells is held (826 MB on ex09).  The same matrix as the sparse
product of the general path up to the order of the sums.  The correction is
added to the exact gradients in place.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..assembly import Assembler, Layout
from . import cell_layout

__all__ = ["point_blocks", "symmetric_correction_cells"]

#: pairs per block of points (the block temporaries: about 10 arrays of
#: ``m`` rows of this length)
PAIRS_PER_BLOCK = 2**17


def point_blocks(indptr):
    """Slices of points whose pairs number about :data:`PAIRS_PER_BLOCK`."""
    npoints = len(indptr) - 1
    q0 = 0
    while q0 < npoints:
        q1 = int(np.searchsorted(indptr, indptr[q0] + PAIRS_PER_BLOCK, "right")) - 1
        q1 = min(max(q1, q0 + 1), npoints)
        yield q0, q1
        q0 = q1


def _point_sums(values, starts):
    """Sums over the pairs of each point (``values`` (..., pairs), the pairs
    of each point consecutive from ``starts``, every point with at least
    one): a segmented sum, several times faster than ``np.bincount``."""
    return np.add.reduceat(values, starts, axis=-1)


def _frame(table, x, phi, nodes, radius, q0, q1, Linv=None):
    """``rows`` (block-local point of each pair), ``P`` (m, pairs) and
    ``L⁻¹`` (points, m, m) of the points ``q0:q1`` (``Linv`` if given): the
    arithmetic of the general path, per point the same sums up to their
    order (:func:`_point_sums`)."""
    lo, hi = table.indptr[q0], table.indptr[q1]
    nb, m = q1 - q0, nodes.shape[0] + 1
    starts = table.indptr[q0:q1] - lo
    counts = np.diff(table.indptr[q0:q1 + 1])
    if not counts.all():
        raise ValueError("symmetric VCI: a quadrature point is reached by no particle")
    rows = np.repeat(np.arange(nb), counts)
    cols, ph = table.indices[lo:hi], phi[lo:hi]
    weight_sum = _point_sums(ph, starts)
    size = _point_sums(ph * radius[cols], starts) / weight_sum
    P = np.ones((m, hi - lo))
    P[1:] = np.take(nodes, cols, axis=1)
    P[1:] -= np.repeat(x[:, q0:q1], counts, axis=1)
    P[1:] /= np.repeat(size, counts)
    if Linv is not None:
        return rows, P, Linv
    upper = [(a, b) for a in range(m) for b in range(a, m)]
    products = np.empty((len(upper), hi - lo))
    phiP = ph * P
    for j, (a, b) in enumerate(upper):
        np.multiply(phiP[a], P[b], out=products[j])
    sums = _point_sums(products, starts)
    G = np.empty((nb, m, m))
    for j, (a, b) in enumerate(upper):
        G[:, a, b] = G[:, b, a] = sums[j]
    return rows, P, np.linalg.inv(np.linalg.cholesky(G))


def symmetric_correction_cells(table, x, weights, phi, r, nodes, radius, nqp, cells,
                               solve, frame, grads):
    """The gradients ``grads`` (dim, npairs) of ``table`` with the symmetric
    VCI correction added in place, the points of ``table`` the ``nqp``
    quadrature points of each cell in turn.

    ``cells``: :func:`.cell_layout.cell_particles` of the table; ``solve``
    and ``frame``: the pinned solve and the affine frame of the general
    path (:func:`~.integration._pinned_spd_solve`,
    :func:`~.integration._affine_frame`).  See the module docstring.
    """
    dim, nnodes = nodes.shape
    m, nq = dim + 1, table.npoints
    nelems = nq // nqp
    cols, slot = table.indices, cells[2]
    element_nodes = cell_layout.element_nodes(cells, nelems)
    nloc = element_nodes.shape[0]
    w = weights.reshape(nelems, nqp)
    Linv = np.empty((nq, m, m))
    diagonal = np.zeros(nnodes)

    def local_of(s):
        """``Bᵀ diag(w) B`` of the cells ``s``, (cells, nloc, nloc): B laid
        out per cell, (cell, slot, (α, quadrature point)), as it is formed."""
        q0, q1 = s.start * nqp, s.stop * nqp
        lo, hi = table.indptr[q0], table.indptr[q1]
        rows, P, Linv[q0:q1] = _frame(table, x, phi, nodes, radius, q0, q1)
        phiP = phi[lo:hi] * P
        L = Linv[q0:q1].reshape(q1 - q0, m * m).T.copy()  # entry (a, b) in row m a + b
        laid = np.zeros((s.stop - s.start, nloc, m, nqp))
        # the entry of (pair, α = 0): ((cell nloc + slot) m) nqp + point of the cell
        cell, point = np.divmod(rows, nqp)
        flat = (cell * nloc + slot[lo:hi]) * (m * nqp) + point
        for a in range(m):  # L⁻¹ is lower triangular
            block = L[m * a][rows] * phiP[0]
            for b in range(1, a + 1):
                block += L[m * a + b][rows] * phiP[b]
            laid.reshape(-1)[flat + a * nqp] = block
        diagonal[:] += np.bincount(cols[lo:hi], weights[q0 + rows] * phi[lo:hi],
                                   minlength=nnodes)
        laid = laid.reshape(s.stop - s.start, nloc, m * nqp)
        return np.matmul(laid * np.tile(w[s], m)[:, None, :], laid.transpose(0, 2, 1))

    layout = Layout(element_nodes, None, None, None, w, 1, nnodes)
    product = Assembler(layout).streamed(local_of, nloc * nloc)
    M = (sp.diags(diagonal) - product).tocsr()
    del product
    nbodies, body = connected_components(M, directed=False)
    xi = solve(M, r, frame(nodes, body, nbodies))
    del M

    # t(x_q) = Σ_J P_J φ_J ξ_J, then c_I = φ_I (ξ_I - P_Iᵀ G⁻¹ t)
    xi = np.ascontiguousarray(xi.T)  # (dim, nnodes)
    for q0, q1 in point_blocks(table.indptr):
        lo, hi = table.indptr[q0], table.indptr[q1]
        rows, P, L = _frame(table, x, phi, nodes, radius, q0, q1, Linv[q0:q1])
        ph = phi[lo:hi]
        xc = np.take(xi, cols[lo:hi], axis=1)  # (dim, pairs)
        phiP = ph * P
        t = _point_sums(phiP[:, None, :] * xc[None, :, :], table.indptr[q0:q1] - lo)
        fit = np.einsum("qba,qbc,ckq->akq", L, L, t, optimize=True)  # G⁻¹ t, (m, dim, nb)
        for k in range(dim):
            c = xc[k]
            for a in range(m):
                c -= P[a] * fit[a, k][rows]
            c *= ph
            grads[k, lo:hi] += c
    return grads
