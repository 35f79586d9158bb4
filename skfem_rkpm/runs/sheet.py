"""Strains of a formed sheet from the current particle positions.

A sheet discretized by a tensor-product mesh (rows of particles through the
thickness, e.g. the punch stretch scenes) is measured the way a forming
experiment measures it: along the mid-surface row of particles

    ε_l = ln(|x_{k+1} - x_k| / |X_{k+1} - X_k|)        (longitudinal true strain)

between neighbouring particles, and through the thickness

    ε_t = ln(|x_top - x_bottom| / |X_top - X_bottom|)  (thickness true strain)

at every column of particles.  Positions are the nodal values
``x = X + Λᵀ d`` (Eq. 3.32) for RK bases, the nodal dofs for finite
elements.  In an axisymmetric model the hoop strain of a mid-surface
particle is ``ε_θ = ln(r / R)``; plastic incompressibility then reads
``ε_l + ε_θ + ε_t ≈ 0`` (``ε_θ = 0`` in plane strain).
"""

from dataclasses import dataclass

import numpy as np

from .io import nodal_displacements

__all__ = ["SheetStrains", "sheet_strains"]


@dataclass
class SheetStrains:
    """Strains of a sheet along its mid-surface.

    Attributes
    ----------
    X : ndarray (m,)
        Reference x (or radius) of the particle columns.
    x : ndarray (2, m)
        Current positions of the mid-surface particles.
    longitudinal_X : ndarray (m - 1,)
        Reference x of the segment midpoints where ``longitudinal`` lives.
    longitudinal : ndarray (m - 1,)
        Longitudinal true strain between neighbouring columns.
    thickness : ndarray (m,)
        Thickness true strain of each column.
    hoop : ndarray (m,)
        Hoop true strain ``ln(r / R)`` of the mid-surface particles
        (axisymmetric models; zero in plane strain and on the axis).
    """

    X: np.ndarray
    x: np.ndarray
    longitudinal_X: np.ndarray
    longitudinal: np.ndarray
    thickness: np.ndarray
    hoop: np.ndarray


def sheet_strains(basis, d, axisymmetric=False):
    """:class:`SheetStrains` of a sheet meshed with columns of particles.

    Parameters
    ----------
    basis : RKBasis or skfem vector basis
        Basis on a tensor-product mesh whose vertices are the particles.
    d : ndarray
        Coefficients (generalized displacements).
    axisymmetric : bool
        Also compute the hoop strain (x is the radius).

    Raises
    ------
    ValueError
        If the particles do not form columns with an odd number of rows
        (a mid-surface row is needed).
    """
    mesh = basis.mesh
    P = mesh.p
    x = P + nodal_displacements(basis, d).T
    columns = np.unique(np.round(P[0], 12))
    rows = np.unique(np.round(P[1], 12))
    if len(columns) * len(rows) != mesh.nvertices or len(rows) % 2 == 0:
        raise ValueError("sheet_strains needs a tensor-product mesh with an odd number "
                         f"of particle rows; got {len(columns)} columns, {len(rows)} rows "
                         f"and {mesh.nvertices} particles")
    col = np.searchsorted(columns, np.round(P[0], 12))
    row = np.searchsorted(rows, np.round(P[1], 12))
    index = np.empty((len(rows), len(columns)), dtype=int)
    index[row, col] = np.arange(mesh.nvertices)
    mid = index[len(rows) // 2]
    xm, Xm = x[:, mid], P[:, mid]
    stretch = (np.linalg.norm(np.diff(xm, axis=1), axis=0)
               / np.linalg.norm(np.diff(Xm, axis=1), axis=0))
    top, bottom = index[-1], index[0]
    thick = (np.linalg.norm(x[:, top] - x[:, bottom], axis=0)
             / np.linalg.norm(P[:, top] - P[:, bottom], axis=0))
    hoop = np.zeros(len(columns))
    if axisymmetric:
        off_axis = Xm[0] > 0
        hoop[off_axis] = np.log(xm[0, off_axis] / Xm[0, off_axis])
    return SheetStrains(columns, xm, 0.5 * (columns[1:] + columns[:-1]), np.log(stretch),
                        np.log(thick), hoop)
