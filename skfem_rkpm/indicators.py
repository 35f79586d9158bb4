"""A-posteriori error indicators for RK fields, where facet jumps read zero.

scikit-fem's adaptive examples (ex22) estimate the error of a P1 solution
from the jumps of its gradient across interior facets,
``InteriorFacetBasis(m, e, side=i).interpolate(u)`` for ``i = 0, 1``.  RK
functions are smooth across facets: both sides give the same field, the
jumps are zero to round-off, and an indicator built on them says nothing
(``adaptive_theta`` then marks the cells by the interior residual
``h² f²`` alone, which is blind to a corner singularity).
:meth:`RKInteriorFacetBasis.interpolate` warns with
:class:`ZeroJumpWarning` and names :func:`recovery_indicator`.

:func:`recovery_indicator` is a recovery (Zienkiewicz-Zhu type) indicator:
the gradient of the RK solution is projected (L², :meth:`RKBasis.project`)
onto the RK space itself, and the indicator of a cell is the L² norm over
it of the difference,

    η_K = ‖∇u_h - Π_h ∇u_h‖_(L²(K)),

which is small where the particles resolve the gradient (a smooth solution:
the difference falls as the particles get denser) and large where they do
not (the re-entrant corner of an L-shaped domain).  ``η_K²`` summed over the
cells is returned per cell, the form scikit-fem's ``adaptive_theta`` takes.
"""

import numpy as np

__all__ = ["ZeroJumpWarning", "recovery_indicator", "ZERO_JUMP_MESSAGE"]

ZERO_JUMP_MESSAGE = (
    "RK fields are smooth across facets: interpolated from side 0 and from side 1 they "
    "are the same, so a jump of the field or of its gradient reads zero everywhere and "
    "an error indicator built on it (scikit-fem's ex22) marks cells by the rest alone; "
    "use skfem_rkpm.recovery_indicator(basis, u) (one value per cell, for "
    "adaptive_theta), with basis the cell basis of u")


class ZeroJumpWarning(UserWarning):
    """A field of an RK basis was interpolated on interior facets, where its
    jumps are zero: a jump indicator would read nothing."""


def recovery_indicator(basis, u):
    """Per cell ``η_K²`` of the recovered gradient, ``‖∇u_h - Π_h ∇u_h‖²_K``.

    Parameters
    ----------
    basis : RKBasis
        The (scalar) cell basis of ``u``.
    u : ndarray, shape (N,)
        Its coefficients.

    Returns
    -------
    ndarray, shape (nelems,)
        One value per cell of the basis (``adaptive_theta(eta)`` marks the
        largest ones).
    """
    if not hasattr(basis, "project") or not hasattr(basis, "element_nodes"):
        raise TypeError("recovery_indicator takes an RK cell basis (RKBasis); for an "
                        f"FEM basis use scikit-fem's jump indicator, not {basis!r}")
    if getattr(basis, "nodal_quadrature", None) is not None:
        raise ValueError("recovery_indicator needs the Gauss points of the cells: build "
                         "the basis with integration='vci', 'vci_symmetric' or 'gauss'")
    if basis.ncomp != 1:
        raise ValueError("recovery_indicator takes a scalar basis: for a vector field "
                         "sum it over basis.split_bases() with the coefficients "
                         "u[basis.split_indices()[c]]")
    gradient = basis.interpolate(u).grad  # (dim, nelems, nqp)
    squared = np.zeros(gradient.shape[1:])
    for k in range(gradient.shape[0]):
        recovered = np.asarray(basis.interpolate(basis.project(gradient[k])))
        squared += (gradient[k] - recovered) ** 2
    return np.sum(squared * basis.dx, axis=1)
