"""Sums over the parts of a partitioned domain.

A basis built on part of the background cells (one MPI rank's cells,
:mod:`skfem_rkpm.solvers.partitioned`) integrates only over its own
quadrature points.  The quantities that integrate over a particle's whole
support (the VCI moments and constraint right-hand sides of
:mod:`.integration`) are then partial sums, and a *reduction* adds them up
over all parts, so that every part continues with the whole-domain sums.

A reduction has three methods, all collective (every part calls them in
the same order); the two sums take arrays of the same shape on every part
and return the same result on every part:

``sum(array)``
    The elementwise sum of a dense array over the parts.
``sum_sparse(matrix)``
    The sum of a scipy sparse matrix over the parts, in CSR.
``gather(values, rows, total)``
    Each part's ``values`` placed at its ``rows`` of one array of
    ``total`` rows, on part 0 (the others get None): the parts' rows are
    disjoint, and nothing of the whole array is held by the other parts.

:data:`WHOLE` is the reduction of an unpartitioned domain: one part,
nothing to add.
"""

import numpy as np

__all__ = ["WholeDomain", "WHOLE"]


class WholeDomain:
    """The reduction of a domain in one part: sums are what they are."""

    parts = 1

    def sum(self, array):
        return array

    def sum_sparse(self, matrix):
        return matrix.tocsr()

    def gather(self, values, rows, total):
        values = np.asarray(values)
        whole = np.zeros((total,) + values.shape[1:], dtype=values.dtype)
        whole[rows] = values
        return whole


WHOLE = WholeDomain()
