"""Background quadrature and variationally consistent integration (VCI).

The mesh supplies only integration cells: Gauss points and weights come from
scikit-fem's own bases on the lowest-order Lagrange element of the mesh, so
RK and FEM bases on one mesh share the same quadrature points.

Gauss integration of RK shape functions on background cells violates the
integration constraint (the discrete divergence theorem), so the linear
patch test passes only approximately with the paper's scheme.  VCI (Chen,
Hillman & Rüter 2013) adds a small correction to the *test* function
gradients,

    ∇̃Ψ_I(x) = ∇Ψ_I(x) + φ_I(x) Σ_β ξ_Iβ p_β(x),

with the kernel φ_I as weight and ``p_β`` the monomials of degree below the
basis order ``n`` (shifted to the particle and scaled by its support), and
fixes the coefficients per particle so that, with the quadrature in use,

    ∫̂_Ω ∇̃Ψ_I p_α dΩ + ∫̂_Ω Ψ_I ∇p_α dΩ = ∫̂_Γ Ψ_I p_α n dΓ    for |α| ≤ n - 1.

The trial functions keep their exact gradients (they reproduce polynomials
of degree ``n``), so the Petrov-Galerkin system reproduces polynomial
solutions of degree ``n`` to round-off: the patch test passes on any mesh.
"""

import numpy as np
from skfem import CellBasis, FacetBasis

from .kernels import get_kernel
from .shape import _window, monomial_exponents

__all__ = ["cell_geometry", "facet_geometry", "vci_gradients"]


def _lagrange_element(mesh):
    return type(mesh).elem()


def cell_geometry(mesh, intorder):
    """A scikit-fem basis that supplies cell quadrature points and weights."""
    return CellBasis(mesh, _lagrange_element(mesh), intorder=intorder)


def facet_geometry(mesh, intorder, facets=None):
    """A scikit-fem facet basis supplying boundary quadrature and normals."""
    return FacetBasis(mesh, _lagrange_element(mesh), facets=facets,
                      intorder=intorder)


def _pair_monomials(table, x, nodes, scale, exps):
    """p_β((x_q - X_I)/s_I) and ∇p_β for every pair of ``table``: (n, m), (dim, n, m)."""
    rows, cols = table.rows, table.indices
    xi = (x[:, rows] - nodes[:, cols]) / scale[cols]
    n, dim = xi.shape[1], xi.shape[0]
    p = np.ones((n, len(exps)))
    dp = np.zeros((dim, n, len(exps)))
    for j, e in enumerate(exps):
        for k in range(dim):
            p[:, j] *= xi[k] ** e[k]
        for k in range(dim):
            if e[k] == 0:
                continue
            d = np.full(n, e[k] / scale[cols])
            for l in range(dim):
                d *= xi[l] ** (e[l] - (l == k))
            dp[k, :, j] = d
    return p, dp


def vci_gradients(table, x, weights, boundary_table, xb, wb, normals,
                  nodes, radius, order, kernel="cubic", support="radial",
                  axisymmetric=False):
    """Test-function gradients corrected for variational consistency.

    Parameters
    ----------
    table : ShapeTable
        Shape functions with gradients at the cell quadrature points.
    x, weights : ndarray, shapes (dim, nq), (nq,)
        Cell quadrature points and weights (``dx``), in table order.
    boundary_table : ShapeTable
        Shape function values at the boundary quadrature points.
    xb, wb, normals : ndarray, shapes (dim, nb), (nb,), (dim, nb)
        Boundary quadrature points, weights and outward unit normals.
    nodes, radius : ndarray
        Particle positions (dim, nnodes) and support radii (nnodes,).
    order : int
        Basis order ``n``; constraints are imposed for monomials of degree
        up to ``n - 1``.
    axisymmetric : bool
        Impose the constraints in the axisymmetric measure ``R dR dZ``
        (``x[0]`` is the radius): ``∫ ∇̃Ψ p R = ∫_Γ Ψ p n R - ∫ Ψ ∇(p R)``,
        which makes homogeneous axisymmetric stress states exact.

    Returns
    -------
    ndarray, shape (dim, npairs)
        Corrected gradients ∇̃Ψ_I at the pairs of ``table``.

    Raises
    ------
    ValueError
        If a particle's support holds too few quadrature points to fix its
        correction (increase the support or the quadrature order).
    """
    if order < 1:
        return table.grads
    dim, nnodes = nodes.shape
    exps = monomial_exponents(dim, order - 1)
    m = len(exps)
    scale = radius
    window = get_kernel(kernel)
    rows, cols = table.rows, table.indices

    phi, _ = _window((x[:, rows] - nodes[:, cols]).T, radius[cols], window, support)
    p, dp = _pair_monomials(table, x, nodes, scale, exps)
    if axisymmetric:
        weights, wb = weights * x[0], wb * xb[0]
    w = weights[rows]

    # A_I = ∫ φ_I p pᵀ
    A = np.zeros((nnodes, m * m))
    ppT = (p[:, :, None] * p[:, None, :]).reshape(-1, m * m)
    for ab in range(m * m):
        A[:, ab] = np.bincount(cols, w * phi * ppT[:, ab], minlength=nnodes)
    A = A.reshape(nnodes, m, m)

    # rhs_I,k,α = ∫_Γ Ψ_I p_α n_k - ∫_Ω Ψ_I ∂_k p_α - ∫_Ω ∂_k Ψ_I p_α
    rhs = np.zeros((nnodes, dim, m))
    brow, bcol = boundary_table.rows, boundary_table.indices
    pb, _ = _pair_monomials(boundary_table, xb, nodes, scale, exps)
    for k in range(dim):
        for a in range(m):
            rhs[:, k, a] = (
                np.bincount(bcol, wb[brow] * boundary_table.values
                            * pb[:, a] * normals[k, brow], minlength=nnodes)
                - np.bincount(cols, w * (table.values * dp[k, :, a]
                                         + table.grads[k] * p[:, a]),
                              minlength=nnodes)
            )
    if axisymmetric:  # ∂R/∂R = 1: the extra term -∫ Ψ_I p_α dR dZ
        w_plain = (weights / x[0])[rows]
        for a in range(m):
            rhs[:, 0, a] -= np.bincount(cols, w_plain * table.values * p[:, a],
                                        minlength=nnodes)
    covered = np.bincount(cols, minlength=nnodes)
    det = np.linalg.det(A)
    bad = np.flatnonzero((covered < m) | ~(np.abs(det) > 1e-14 * np.abs(A[:, 0, 0]) ** m))
    if bad.size:
        I = bad[0]
        raise ValueError(
            f"VCI: the support of particle {I} at {nodes[:, I]} contains "
            f"{covered[I]} quadrature points, too few to correct its gradient "
            f"({bad.size} particles affected); increase the support or the "
            "quadrature order"
        )
    xi = np.linalg.solve(A, rhs.transpose(0, 2, 1))  # (nnodes, m, dim)
    correction = np.einsum("na,nak->kn", p, xi[cols])
    return table.grads + phi[None, :] * correction
