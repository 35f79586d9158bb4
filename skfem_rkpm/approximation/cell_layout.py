"""The per-cell layout of an RK basis: for every background cell, the
particles whose supports reach its quadrature points (padded to a common
length), and the values and gradients of their shape functions there, in
the (nloc, nelems, nqp) arrays a scikit-fem form reads."""

import numpy as np
import scipy.sparse as sp

from .shape import ShapeTable

__all__ = ["table_rows", "cell_particles", "element_nodes", "padded", "scattered",
           "pair_entries", "pair_table", "gathered"]


def table_rows(table, start, stop, copy=False):
    """The rows ``start:stop`` (evaluation points) of a shape table: views of
    its arrays, or copies that keep nothing of ``table`` alive."""
    lo, hi = table.indptr[start], table.indptr[stop]
    take = (lambda a: a[..., lo:hi].copy()) if copy else (lambda a: a[..., lo:hi])
    return ShapeTable(table.indptr[start:stop + 1] - lo, take(table.indices),
                      take(table.values),
                      None if table.grads is None else take(table.grads),
                      table.nnodes,
                      None if table.kernel is None else take(table.kernel))


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


def element_nodes(cells, nelems):
    """The particle of each local slot (nloc, nelems) of the cells
    ``cells`` (:func:`cell_particles`); padding slots point at the cell's
    first particle."""
    indptr, indices = cells[0], cells[1]
    count = np.diff(indptr)
    nodes = np.repeat(indices[indptr[:-1]][None, :], int(count.max()), axis=0)
    nodes[np.arange(len(indices)) - np.repeat(indptr[:-1], count),
          np.repeat(np.arange(nelems), count)] = indices
    return nodes


def padded(table, nelems, nqp, cells=None, release=False):
    """Per-cell padded node lists and values from a pair table.

    ``cells``: :func:`cell_particles` of the table if already known.  With
    ``release`` the table's pair arrays are dropped (set to None) as soon as
    they are laid out, so that the pair and the padded copy of one array at
    most are held together.

    Returns ``element_nodes`` (nloc, nelems), ``values`` (nloc, nelems,
    nqp) and ``grads`` (dim, nloc, nelems, nqp) of the test functions
    (None if the table has no gradients), and, where the table has
    ``test_grads`` of its own (VCI), its exact gradients as they are, pairs
    (dim, npairs), else None: :func:`scattered` lays them out when needed.
    """
    cells = cells or cell_particles(table, nelems, nqp)
    # padding slots point at the cell's first particle and carry zeros
    nodes = element_nodes(cells, nelems)
    nloc = nodes.shape[0]
    flat = pair_entries(table.indptr, cells, nelems, nqp)[-1]
    if release:
        table.indices = None
    test = "grads" if table.test_grads is None else "test_grads"
    laid = {}
    # the gradients first: their pair array goes as the padded one comes
    for name in (test, "values"):
        pairs = getattr(table, name)
        laid[name] = None if pairs is None else scattered(pairs, flat, (nloc, nelems, nqp))
        if release:
            setattr(table, name, None)
        del pairs
    return (nodes, laid["values"], laid[test],
            None if test == "grads" else table.grads)


def scattered(pairs, flat, shape):
    """Pair values (or rows of them, one per gradient component) put at the
    entries ``flat`` (:func:`pair_entries`) of zero arrays of ``shape``."""
    if pairs.ndim == 1:
        out = np.zeros(shape)
        out.reshape(-1)[flat] = pairs
        return out
    out = np.zeros((pairs.shape[0],) + shape)
    for k in range(pairs.shape[0]):
        out[k].reshape(-1)[flat] = pairs[k]
    return out


def pair_entries(indptr, cells, nelems, nqp, rows=None):
    """Where the pairs of the points ``rows`` of a table (default: all, in
    order) sit in its padded layout.

    ``indptr``: the pairs of each quadrature point in that table; ``cells``:
    its :func:`cell_particles`.  Returns the CSR ``indptr`` of the selected
    points' pairs, their positions among the table's pairs (``pick``: a
    slice for all), their cells, and their entries ``slot nelems nqp + q``
    of the flattened (nloc, nelems, nqp) arrays (``q = cell nqp + qp``).
    """
    if rows is None:
        sub, pick = indptr, slice(None)
        point = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    else:
        start = indptr[rows]
        count = indptr[rows + 1] - start
        sub = np.concatenate([[0], np.cumsum(count)])
        pick = np.repeat(start - sub[:-1], count) + np.arange(sub[-1])
        point = np.repeat(rows, count)
    flat = cells[2][pick].astype(np.int64)
    flat *= nelems * nqp
    flat += point
    point //= nqp
    return sub, pick, point, flat


def pair_table(entries, nnodes, cells, element_nodes, values, grads, test_grads=None):
    """The pair (CSR) table of a padded layout, the pairs in the order of the
    table it was laid out from: the inverse of :func:`padded`.

    ``entries``: :func:`pair_entries` of the points wanted, ``cells`` as
    there; ``values`` (nloc, nelems, nqp), ``grads`` and ``test_grads``
    (dim, nloc, nelems, nqp) or None.
    """
    sub, pick, cell, flat = entries
    indices = element_nodes[cells[2][pick], cell]
    return ShapeTable(sub, indices, values.reshape(-1)[flat],
                      None if grads is None else gathered(grads, flat), nnodes,
                      test_grads=None if test_grads is None else gathered(test_grads, flat))


def gathered(grads, flat):
    """Padded gradients (dim, nloc, nelems, nqp) at the pairs ``flat``
    (:func:`pair_entries`), shape (dim, npairs)."""
    return np.stack([g.reshape(-1)[flat] for g in grads])
