"""The per-cell layout of an RK basis: for every background cell, the
particles whose supports reach its quadrature points (padded to a common
length), and the values and gradients of their shape functions there, in
the (nloc, nelems, nqp) arrays a scikit-fem form reads."""

import numpy as np
import scipy.sparse as sp

from .shape import ShapeTable

__all__ = ["table_rows", "cell_particles", "padded"]


def table_rows(table, start, stop):
    """The rows ``start:stop`` (evaluation points) of a shape table."""
    lo, hi = table.indptr[start], table.indptr[stop]
    return ShapeTable(table.indptr[start:stop + 1] - lo, table.indices[lo:hi],
                      table.values[lo:hi],
                      None if table.grads is None else table.grads[:, lo:hi],
                      table.nnodes,
                      None if table.kernel is None else table.kernel[lo:hi])


def cell_particles(table, nelems, nqp):
    """The particles of each cell and the slot of every pair among them.

    The particles of a cell are those of its ``nqp`` quadrature points
    (consecutive rows of ``table``), each once, in increasing order: the
    cell-particle incidence in CSR with its duplicates merged, a sort of each
    cell's own pairs rather than of all pairs together.

    Returns
    -------
    indptr, indices : ndarray
        Particles of cell ``e``: ``indices[indptr[e]:indptr[e + 1]]``.
    slot : ndarray, shape (npairs,)
        Position of each pair's particle in the list of its cell.
    """
    cell_pairs = table.indptr[::nqp]  # pairs of cell e: cell_pairs[e]:cell_pairs[e + 1]
    incidence = sp.csr_matrix((np.ones(len(table.indices), dtype=np.int32),
                               table.indices, cell_pairs),
                              shape=(nelems, table.nnodes))
    incidence.sum_duplicates()  # sorts and merges each row
    indptr = incidence.indptr.astype(np.int64)
    indices = incidence.indices.astype(np.int64)
    count = np.diff(indptr)
    # each entry holds its position in its row; the pairs read it there
    incidence.data = (np.arange(len(indices)) - np.repeat(indptr[:-1], count)
                      ).astype(incidence.data.dtype)
    cell = np.repeat(np.arange(nelems), np.diff(cell_pairs))
    slot = np.asarray(incidence[cell, table.indices]).ravel()
    return indptr, indices, slot


def padded(table, nelems, nqp, grads, cells=None):
    """Per-cell padded node lists and values from a pair table.

    ``cells``: :func:`cell_particles` of the table if already known.
    Returns ``element_nodes`` (nloc, nelems), ``values`` (nloc, nelems, nqp)
    and ``grads`` (dim, nloc, nelems, nqp) (None if ``grads`` is None).
    """
    indptr, indices, slot = cells or cell_particles(table, nelems, nqp)
    count = np.diff(indptr)
    nloc = int(count.max())
    # padding slots point at the cell's first particle and carry zeros
    element_nodes = np.repeat(indices[indptr[:-1]][None, :], nloc, axis=0)
    element_nodes[np.arange(len(indices)) - np.repeat(indptr[:-1], count),
                  np.repeat(np.arange(nelems), count)] = indices
    # pair (slot, point q = cell nqp + qp) goes to entry slot nq + q of the
    # flattened (nloc, nelems, nqp) arrays
    npoints = nelems * nqp
    flat = slot * npoints
    flat += table.rows
    values = np.zeros((nloc, nelems, nqp))
    values.reshape(-1)[flat] = table.values
    g = None
    if grads is not None:
        g = np.zeros((grads.shape[0], nloc, nelems, nqp))
        for k in range(grads.shape[0]):
            g[k].reshape(-1)[flat] = grads[k]
    return element_nodes, values, g
