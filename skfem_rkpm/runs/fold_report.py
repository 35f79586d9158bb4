"""Which cells fold: the drawn cells and the deformation map itself.

A drawn cell (the straight-edged cell through the moved particles,
:func:`~skfem_rkpm.runs.io.corner_jacobians`) may fold while the map of the
discretization stays one to one, and the map may fold between the Gauss
points that Newton checks.  :func:`fold_columns` gives ``history.csv`` both
counts after every step; :func:`map_sentence` says in the final message and
the stop report whether the map or only the drawn cells folded
(:class:`~skfem_rkpm.mechanics.map_validity.MapSampler`, built once per
basis: a re-referenced run samples the map since its last reference).
"""

import weakref

import numpy as np

from ..mechanics.map_validity import MapSampler
from .io import corner_jacobians, nodal_displacements

__all__ = ["map_sampler", "map_check", "fold_columns", "drawn_cells", "last_state"]

#: the sampler of each basis (the shape functions at the samples are kept)
_SAMPLERS = weakref.WeakKeyDictionary()


def map_sampler(sim):
    """The :class:`MapSampler` of the simulation's current basis (None for a
    partitioned problem, whose ranks hold parts of the cells)."""
    if getattr(sim.problem, "partitioned", False):
        return None
    basis = sim.basis
    sampler = _SAMPLERS.get(basis)
    if sampler is None:
        sampler = _SAMPLERS[basis] = MapSampler(basis, sim.problem.model)
    return sampler


def map_check(sim, d):
    """:class:`~skfem_rkpm.mechanics.map_validity.MapValidity` of ``d``, or None."""
    sampler = map_sampler(sim)
    return None if sampler is None else sampler.check(d)


def fold_columns(sim, d):
    """The ``history.csv`` columns of a converged state: ``drawn folded
    cells`` (cells with a corner at ``det F <= 0``), ``map folded cells``
    (cells with a sample of the map at ``det F <= 0``) and ``map det F min``."""
    check = map_check(sim, d)
    if check is None:
        return {}
    return {"drawn folded cells": int(drawn_cells(sim, d)[0].size),
            "map folded cells": int(check.folded_cells.size),
            "map det F min": check.min_det}


def drawn_cells(sim, d):
    """``(folded, sentence)``: the drawn cells of ``d`` with a corner at
    ``det F <= 0``, and where the smallest corner ``det F`` is ("" if none)."""
    mesh = sim.basis.mesh
    J = corner_jacobians(mesh, nodal_displacements(sim.basis, d))
    folded = np.flatnonzero((J <= 0).any(axis=1))
    if not folded.size:
        return folded, ""
    cell, corner = np.unravel_index(np.argmin(J), J.shape)
    X = mesh.p[:, mesh.t[corner, cell]]
    return folded, (f"det F = {J[cell, corner]:.3g} <= 0 at the corner X = "
                    f"({', '.join(f'{v:.4g}' for v in X)}) of cell {cell} ({folded.size} "
                    f"of {J.shape[0]} cells folded)")


def last_state(sim, d):
    """The folds of the last converged state in one line: the drawn cells
    and the map (for the stop report)."""
    folded, where = drawn_cells(sim, d)
    drawn = (f"drawn cells folded: {where}" if folded.size
             else f"no drawn cell folded (of {sim.basis.mesh.t.shape[1]})")
    check = map_check(sim, d)
    return drawn if check is None else f"{drawn}; {check.describe()}"
