"""Carry point values (a material state) from one set of material points to
the quadrature points of another RK basis.

When the RK functions are rebuilt on the current configuration, the
history variables live at the old quadrature points (at their current
positions ``x_q``, with current volumes ``w_q``) and are needed at the new
basis's points.  :class:`PointTransfer` fits them with the new basis's
scalar RK functions ``Ψ_I`` (Eq. 2.27-2.38) by least squares in the current
configuration,

    (Σ_q w_q Ψ_I(x_q) Ψ_J(x_q)) c_J = Σ_q w_q Ψ_I(x_q) v_q,

and evaluates the fit ``Σ_J Ψ_J(y_p) c_J`` at the new points ``y_p``: an L²
projection onto the RK space, so a field the basis reproduces (a constant,
and a linear field for order ≥ 1) is carried exactly (up to round-off);
other fields with the projection's error, of the order of the support size
times the field's gradient.  With nodal integration, when the new points
are the old ones (the particles), the values are copied as they are.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .shape import rk_shape_functions

__all__ = ["PointTransfer", "TransferError", "local_radius"]


class TransferError(ValueError):
    """The old points do not determine the fit (a particle sees none)."""


def local_radius(mesh, factor=1.6):
    """``factor`` times the longest mesh edge at each vertex: supports of a
    local linear fit that reach the neighbours of a particle in every
    direction (the edges of a compressed body differ by direction)."""
    dim = mesh.p.shape[0]
    edges = (mesh.facets if dim == 2 else mesh.edges)[:2]
    lengths = np.linalg.norm(mesh.p[:, edges[0]] - mesh.p[:, edges[1]], axis=0)
    longest = np.zeros(mesh.p.shape[1])
    np.maximum.at(longest, edges[0], lengths)
    np.maximum.at(longest, edges[1], lengths)
    return factor * longest


class PointTransfer:
    """L² projection from points ``x_from`` (dim, n) with weights ``w_from``
    (n,) onto the scalar RK functions of ``basis``, evaluated at its
    quadrature points (``basis.global_coordinates()``, flat).

    ``radius``: support radii of the fit's functions (one per particle of
    ``basis``), by default the basis's own; smaller ones (a few particle
    spacings, :func:`local_radius`) keep peaks of the state that the wide
    supports of a forming basis would smear.  ``same_points``: the points of
    ``basis`` are ``x_from`` in the same order (nodal integration rebuilt on
    the same particles): values are copied.
    """

    def __init__(self, basis, x_from, w_from, same_points=False, radius=None):
        x_from = np.asarray(x_from, float)
        w_from = np.asarray(w_from, float).ravel()
        dim = basis.nodes.shape[0]
        if x_from.ndim != 2 or x_from.shape[0] != dim or x_from.shape[1] != w_from.size:
            raise ValueError(f"x_from must have shape ({dim}, n) and w_from (n,); got "
                             f"{x_from.shape} and {w_from.shape}")
        y = np.asarray(basis.global_coordinates()).reshape(dim, -1)
        self.npoints_from, self.npoints_to = x_from.shape[1], y.shape[1]
        self.identity = bool(same_points)
        if self.identity:
            if y.shape != x_from.shape:
                raise ValueError(f"same_points: the basis has {y.shape[1]} points, "
                                 f"not {x_from.shape[1]}")
            return
        if radius is None:
            def table(x):
                return basis._shape_table(x, gradients=False).matrix().tocsr()
        else:
            radius = np.broadcast_to(np.asarray(radius, float), (basis.nodes.shape[1],))

            def table(x):
                return rk_shape_functions(x, basis.nodes, radius, max(basis.order, 1),
                                          basis.kernel, basis.support_shape,
                                          gradients=False).matrix().tocsr()
        T_from = table(x_from)
        self.T_to = table(y)
        self.TW = (T_from.T @ sp.diags(w_from)).tocsr()
        M = (self.TW @ T_from).tocsc()
        diagonal = M.diagonal()
        empty = np.flatnonzero(~(diagonal > 0))
        if empty.size:
            X = basis.nodes[:, empty[0]]
            raise TransferError(f"{empty.size} particles see none of the old points "
                                f"(first at ({', '.join(f'{v:.4g}' for v in X)})): the "
                                f"old points do not cover the new basis")
        # a relative shift at round-off keeps the factorization regular where
        # the old points barely determine a function, and constants exact
        # to that level
        M = M + sp.diags(1e-13 * diagonal)
        self._lu = splu(M.tocsc())

    def __call__(self, values):
        """Values (n_from, ...) at the old points -> (n_to, ...) at the new ones."""
        values = np.asarray(values, float)
        if values.shape[0] != self.npoints_from:
            raise ValueError(f"{values.shape[0]} values for {self.npoints_from} points")
        if self.identity:
            return values.copy()
        flat = values.reshape(self.npoints_from, -1)
        coefficients = self._lu.solve(np.asarray(self.TW @ flat))
        return np.asarray(self.T_to @ coefficients).reshape((self.npoints_to,)
                                                              + values.shape[1:])
