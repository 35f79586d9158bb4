"""Interpolating reproducing kernel shape functions (Kronecker delta at the particles).

The interpolating RK approximation of Chen, Han, You & Meng (2003, "A
reproducing kernel method with nodal interpolation property", IJNME 56,
935-960) adds to a *primitive* function with the Kronecker-delta property an
*enrichment* reproducing kernel that reproduces what the primitive misses:

    N_I(X) = φ̂_I(X) + H(ξ_I)ᵀ c(X) φ_I(X),
    M(X) c(X) = r(X) = H(0) - Σ_K φ̂_K(X) H(ξ_K),             ξ_K = (X - X_K)/s(X),

with ``M(X) = Σ_I H(ξ_I) H(ξ_I)ᵀ φ_I(X)`` the moment matrix of the standard
basis (Eq. 3.17 of the paper of Chen et al. 1998) and ``H`` its monomials
(Eq. 3.18).  The primitive is the same window on a support smaller than the
distance to the nearest other particle,

    φ̂_K(X) = φ(|X - X_K| / â_K) / φ(0),   â_K = min(d_K, a_K),

so ``φ̂_K(X_J) = δ_KJ``.  The reproducing conditions
``Σ_I N_I(X) H(ξ_I) = H(0)`` (monomials up to the basis order) hold at every
point by construction of ``c``; at a particle ``X_J`` the primitive alone
reproduces them (``r(X_J) = H(0) - H(0) = 0``), so ``c(X_J) = 0`` and
``N_I(X_J) = δ_IJ`` exactly.  The support of ``N_I`` is that of the
standard window ``φ_I`` (``â_I ≤ a_I``): the functions stay local, and
their coefficients are the field's values at the particles.

Differentiating with ``s`` frozen (as in :mod:`.shape`),

    ∂c/∂X_k = M⁻¹ (∂r/∂X_k - ∂M/∂X_k c),
    ∂N_I/∂X_k = ∂φ̂_I/∂X_k + (∂H_Iᵀ/∂X_k c + H_Iᵀ ∂c/∂X_k) φ_I + H_Iᵀ c ∂φ_I/∂X_k.

The pairs, their order and the kernel stored in the table are those of the
standard basis, so VCI (:mod:`.integration`) corrects these functions
unchanged.  Only the numpy path exists; a point where ``M`` is singular is
reported by :func:`~.shape.rk_shape_functions` with its usual message.
"""

import numpy as np

from .kernels import get_kernel
from .shape import (RCOND_MIN, ShapeTable, _batched_inverse, _dot, _kernel_weights,
                    _moment_matrices, _monomial_recurrences, _rcond, blocked_pairs,
                    check_order, coordinates, find_pairs, monomial_exponents,
                    rk_shape_functions)

__all__ = ["primitive_radius", "basis_primitive_radius", "interpolating_shape_functions",
           "shape_functions"]


def primitive_radius(nodes, radius):
    """Support radius ``â_K = min(d_K, a_K)`` of the primitive functions.

    ``d_K`` is the distance from particle ``K`` to its nearest other
    particle: the primitive of ``K`` then vanishes at every other particle
    (the window is zero at ``z = 1``), which gives the Kronecker delta.

    Parameters
    ----------
    nodes : ndarray, shape (dim, nnodes)
    radius : ndarray, shape (nnodes,)
        Support radii ``a_K`` of the enrichment (standard) windows.

    Returns
    -------
    ndarray, shape (nnodes,)
    """
    from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

    if nodes.shape[1] < 2:
        return np.array(radius, dtype=float)
    distance, _ = cKDTree(nodes.T).query(nodes.T, k=2)
    return np.minimum(distance[:, 1], radius)


def basis_primitive_radius(interpolating, nodes, radius):
    """The primitive radii of ``RKBasis(..., interpolating=...)``: those of
    :func:`primitive_radius`, or None for the standard basis."""
    if not isinstance(interpolating, (bool, np.bool_)):
        raise ValueError(f"interpolating must be True or False, not {interpolating!r}")
    return primitive_radius(nodes, radius) if interpolating else None


def _solve(H, lowered, phi, dphi, phat, dphat, inv_s, starts, counts, gradients):
    """Batched solve of ``M c = r`` and its derivative for one block of points.

    Pair arrays are laid out (component, pair): ``H`` (m, n), ``phi`` (n,),
    ``dphi`` (dim, n), the primitive ``phat`` (n,) and ``dphat`` (dim, n).
    Returns the pair values ``N_I``, gradients and the reciprocal condition
    number of each point's moment matrix.
    """
    M = _moment_matrices(H, phi, starts)
    Minv = _batched_inverse(M)
    rcond = _rcond(M, Minv)
    r = -np.add.reduceat(H * phat, starts, axis=1)
    r[0] += 1.0
    c = np.einsum("ijp,jp->ip", Minv, r)
    cp = np.repeat(c, counts, axis=1)  # c(X) per pair
    Hc = _dot(H, cp)
    values = Hc * phi + phat
    if not gradients:
        return values, None, rcond
    grads = np.empty(dphi.shape)
    for k, terms in enumerate(lowered):
        # ∂H(ξ_I)/∂X_k, s frozen: nonzero in the rows j of the monomials with ξ_k
        dH = [(j, (e * inv_s) * H[low]) for j, e, low in terms]
        dHc = np.zeros(phi.shape)
        for j, d in dH:
            dHc += d * cp[j]
        # g = ∂φ̂ + (∂Hᵀ c) φ + (Hᵀ c) ∂φ, and, with N_I = values,
        # ∂M/∂X_k c - ∂r/∂X_k = Σ_I (∂H_I N_I + H_I g_I) summed over each point's pairs
        g = dphat[k] + dHc * phi + Hc * dphi[k]
        t = H * g
        for j, d in dH:
            t[j] += d * values
        ck = -np.einsum("ijp,jp->ip", Minv, np.add.reduceat(t, starts, axis=1))
        grads[k] = g + _dot(H, np.repeat(ck, counts, axis=1)) * phi
    return values, grads, rcond


def interpolating_shape_functions(x, nodes, radius, order=1, kernel="cubic",
                                  support="radial", gradients=True, dilation=None,
                                  rcond_min=RCOND_MIN, primitive=None,
                                  primitive_window=None, groups=None):
    """Interpolating RK shape functions ``N_I(X)`` and ``∂N_I/∂X``.

    The construction of Chen, Han, You & Meng (2003) (see the module
    docstring): ``N_I(X_J) = δ_IJ`` and reproduction of all monomials up to
    ``order``, on the supports of the standard functions of
    :func:`~.shape.rk_shape_functions` (Eq. 3.16-3.19), whose table layout it
    shares.

    Parameters
    ----------
    x : ndarray, shape (dim, npoints)
        Evaluation points.
    nodes : ndarray, shape (dim, nnodes)
        Particle positions ``X_I``.
    radius : float or ndarray, shape (nnodes,)
        Support radius ``a_I`` of each enrichment window.
    order, kernel, support, gradients, dilation, rcond_min
        As in :func:`~.shape.rk_shape_functions`.  The primitive always has
        a radial support.
    primitive : ndarray, shape (nnodes,), optional
        Support radii ``â_I`` of the primitive functions, each at most the
        distance to the nearest other particle and at most ``a_I``; default
        :func:`primitive_radius`.
    primitive_window : str or callable, optional
        Window of the primitive functions (default ``kernel``); any window
        positive at 0 and zero from ``z = 1`` on keeps the delta property.
    groups : ndarray, optional
        Groups of nearby points for the pair search, as in
        :func:`~.shape.rk_shape_functions`.

    Returns
    -------
    ShapeTable
        Its ``kernel`` holds the enrichment window ``φ_I(X_q)`` of each pair.

    Raises
    ------
    SingularMomentError
        Where the standard basis would fail (same message).
    ValueError
        If a primitive radius reaches another particle or exceeds ``a_I``.
    """
    x = coordinates(x, "evaluation point")
    nodes = coordinates(nodes, "particle")
    check_order(order)
    dim, npoints = x.shape
    nnodes = nodes.shape[1]
    if nodes.shape[0] != dim or nnodes == 0:
        # the standard builder phrases these errors
        return rk_shape_functions(x, nodes, radius, order, kernel, support, gradients,
                                  dilation, rcond_min, backend="numpy")
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (nnodes,)).copy()
    if not np.all((radius > 0) & np.isfinite(radius)) or support not in ("radial", "box"):
        return rk_shape_functions(x, nodes, radius, order, kernel, support, gradients,
                                  dilation, rcond_min, backend="numpy")
    primitive = (primitive_radius(nodes, radius) if primitive is None
                 else np.broadcast_to(np.asarray(primitive, float), (nnodes,)))
    _check_primitive(nodes, radius, primitive)
    window = get_kernel(kernel)
    bump = get_kernel(kernel if primitive_window is None else primitive_window)
    phi0 = float(bump(np.zeros(1))[0][0])
    if not phi0 > 0:
        raise ValueError(f"the primitive window is {phi0} at z = 0; an interpolating "
                         "basis needs a window that is positive there")
    exps = monomial_exponents(dim, order)
    m = len(exps)
    build, lowered = _monomial_recurrences(exps)

    ipoint, inode = find_pairs(x.T.copy(), nodes.T.copy(), radius, support, groups)
    counts = np.bincount(ipoint, minlength=npoints)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    if np.any(counts < m):
        return rk_shape_functions(x, nodes, radius, order, kernel, support, gradients,
                                  dilation, rcond_min, backend="numpy")

    def solve(diff, I, phi, dphi, H, inv_s, starts, block_counts):
        phat, dphat = _kernel_weights(diff, primitive[I], bump, "radial")
        return _solve(H, lowered, phi, dphi, phat / phi0, dphat / phi0, inv_s, starts,
                      block_counts, gradients)

    values, grads, kernel_values, rcond = blocked_pairs(
        x, nodes, radius, ipoint, inode, indptr, counts, window, support, build, m,
        gradients, solve)
    if not np.all(rcond >= rcond_min):
        # the moment matrix is the standard one: its builder reports the points
        rk_shape_functions(x, nodes, radius, order, kernel, support, False,
                           dilation, rcond_min, backend="numpy")
        raise ValueError(f"moment matrix M(X) is singular or ill-conditioned at "
                         f"{np.sum(~(rcond >= rcond_min))} points; increase the support")
    return ShapeTable(indptr, inode, values, grads, nnodes, kernel_values)


def shape_functions(*args, primitive=None, **kwargs):
    """Interpolating shape functions with primitive radii ``primitive``, or
    the standard ones of :func:`~.shape.rk_shape_functions` if it is None
    (same arguments)."""
    if primitive is None:
        return rk_shape_functions(*args, **kwargs)
    return interpolating_shape_functions(*args, primitive=primitive, **kwargs)


def _check_primitive(nodes, radius, primitive):
    """Refuse primitive radii that would break the Kronecker delta or locality."""
    from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

    bad = np.flatnonzero(~((primitive > 0) & (primitive <= radius)))
    if bad.size:
        I = bad[0]
        raise ValueError(f"primitive radius of particle {I} is {primitive[I]}, not in "
                         f"(0, a_I = {radius[I]}]: the interpolating functions must "
                         "stay inside the standard supports")
    if nodes.shape[1] < 2:
        return
    distance, _ = cKDTree(nodes.T).query(nodes.T, k=2)
    bad = np.flatnonzero(primitive > distance[:, 1] * (1 + 1e-12))
    if bad.size:
        I = bad[0]
        raise ValueError(f"primitive radius of particle {I} is {primitive[I]}, more than "
                         f"the distance {distance[I, 1]} to its nearest particle: "
                         "N_I would not vanish there; use at most that distance")
