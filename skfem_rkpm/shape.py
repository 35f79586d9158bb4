"""Reproducing kernel shape functions, built once, batched over point-node pairs.

For evaluation points ``X`` (quadrature points, probes, nodes) and particles
``X_I`` with support radii ``a_I`` this module computes, Eq. (3.16)-(3.18),

    Ψ_I(X) = H(0)ᵀ M(X)⁻¹ H(ξ_I) φ(X - X_I; a_I),
    M(X)   = Σ_I H(ξ_I) H(ξ_I)ᵀ φ(X - X_I; a_I),       ξ_I = (X - X_I) / s(X),

and their material gradients by differentiating M (Eq. 2.30, 2.37).  The
basis ``H`` holds all monomials up to the basis order; shifting by ``X_I``
and scaling by the local length ``s(X)`` (the largest covering support)
keeps ``M`` well conditioned in any unit.  The shape functions do not depend
on ``s`` (the scaling is a diagonal change of basis that leaves ``H(0)``
fixed), so ``s`` is frozen when differentiating.

All work is vectorized over the (point, node) pairs, stored in CSR order
(sorted by point, then node): :class:`ShapeTable`.
"""

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .kernels import get_kernel

__all__ = [
    "ShapeTable",
    "SingularMomentError",
    "monomial_exponents",
    "find_pairs",
    "rk_shape_functions",
]

#: moment matrices with a reciprocal 1-norm condition number below this fail
RCOND_MIN = 1e-10
#: points per block in the batched solve (keeps the pair arrays in cache)
POINTS_PER_BLOCK = 4096


class SingularMomentError(ValueError):
    """A moment matrix M(X) is singular or too ill-conditioned to invert.

    Attributes
    ----------
    points : ndarray
        Indices of the failing evaluation points.
    coordinates : ndarray
        Their coordinates, shape (dim, n).
    covering : ndarray
        How many particles cover each failing point.
    factor : float or None
        The smallest factor by which the supports must grow for every
        failing point to work (None if even 10x does not help).
    """

    def __init__(self, message, points, coordinates, covering, factor):
        super().__init__(message)
        self.points = points
        self.coordinates = coordinates
        self.covering = covering
        self.factor = factor


@dataclass
class ShapeTable:
    """Shape function values and material gradients in CSR layout.

    Attributes
    ----------
    indptr : ndarray, shape (npoints + 1,)
        Pairs of point ``q`` are ``indptr[q]:indptr[q + 1]``.
    indices : ndarray, shape (npairs,)
        Node of each pair.
    values : ndarray, shape (npairs,)
        ``Ψ_I(X_q)``.
    grads : ndarray, shape (dim, npairs) or None
        ``∂Ψ_I/∂X_k(X_q)``.
    nnodes : int
        Number of particles (columns).
    """

    indptr: np.ndarray
    indices: np.ndarray
    values: np.ndarray
    grads: np.ndarray
    nnodes: int

    @property
    def npoints(self):
        return len(self.indptr) - 1

    @property
    def rows(self):
        """Point index of each pair, shape (npairs,)."""
        return np.repeat(np.arange(self.npoints), np.diff(self.indptr))

    def _csr(self, data):
        return sp.csr_matrix(
            (data, self.indices, self.indptr), shape=(self.npoints, self.nnodes)
        )

    def matrix(self):
        """Sparse matrix ``A[q, I] = Ψ_I(X_q)``."""
        return self._csr(self.values)

    def gradient_matrix(self, k):
        """Sparse matrix ``A[q, I] = ∂Ψ_I/∂X_k(X_q)``."""
        return self._csr(self.grads[k])


def monomial_exponents(dim, order):
    """Exponents of the monomial basis ``H`` of Eq. (2.24)/(3.18).

    Returns an int array of shape (m, dim), sorted by total degree, first row
    zero (the constant), so that ``H(0) = e_1``.
    """
    exps = []
    for degree in range(order + 1):
        for combo in combinations_with_replacement(range(dim), degree):
            e = np.zeros(dim, dtype=int)
            for k in combo:
                e[k] += 1
            exps.append(e)
    return np.array(exps, dtype=int).reshape(-1, dim)


def _monomials(xi, exps):
    """``H(ξ)`` and ``∂H/∂ξ_k`` for ξ of shape (n, dim): (n, m), (dim, n, m)."""
    n, dim = xi.shape
    powers = np.ones((int(exps.max(initial=0)) + 1, n, dim))
    for p in range(1, len(powers)):
        powers[p] = powers[p - 1] * xi

    def product(e):
        out = np.ones((len(e), n))
        for k in range(dim):
            out *= powers[e[:, k], :, k]
        return out.T

    H = product(exps)
    dH = np.empty((dim, n, len(exps)))
    for k in range(dim):
        lowered = exps.copy()
        lowered[:, k] = np.maximum(lowered[:, k] - 1, 0)
        dH[k] = product(lowered) * exps[:, k]
    return H, dH


def find_pairs(points, nodes, radius, support="radial"):
    """All (point, node) pairs with the point strictly inside the node's support.

    Parameters
    ----------
    points : ndarray, shape (n, dim)
    nodes : ndarray, shape (N, dim)
    radius : ndarray, shape (N,)
        Support radius ``a_I`` of each node.
    support : {"radial", "box"}
        Circle/sphere (Euclidean distance) or box (max-norm) supports.

    Returns
    -------
    ipoint, inode : ndarray
        Pair lists sorted by point, then node.
    """
    p = {"radial": 2.0, "box": np.inf}[support]
    tree = cKDTree(points)
    # group nodes by radius (factor 1.5 per group) so that graded supports
    # are not all searched with the largest radius
    rmin = radius.min()
    group = np.floor(np.log(radius / rmin) / np.log(1.5)).astype(int)
    ipoint, inode = [], []
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        rg = radius[members]
        found = cKDTree(nodes[members]).sparse_distance_matrix(
            tree, rg.max(), p=p, output_type="ndarray"
        )
        keep = found["v"] < rg[found["i"]]
        inode.append(members[found["i"][keep]])
        ipoint.append(found["j"][keep])
    ipoint = np.concatenate(ipoint).astype(np.int64)
    inode = np.concatenate(inode).astype(np.int64)
    order = np.lexsort((inode, ipoint))
    return ipoint[order], inode[order]


def _window(diff, a, kernel, support):
    """Kernel φ and its gradient w.r.t. X for pair differences ``X - X_I``.

    Parameters
    ----------
    diff : ndarray, shape (n, dim)
    a : ndarray, shape (n,)
    """
    if support == "radial":
        r = np.sqrt(np.einsum("nk,nk->n", diff, diff))
        phi, dphi = kernel(r / a)
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.where(r[:, None] > 0, diff / r[:, None], 0.0)
        return phi, (dphi / a)[:, None] * direction
    # box: tensor product of one-dimensional windows
    phik, dphik = kernel(np.abs(diff) / a[:, None])
    phi = np.prod(phik, axis=1)
    grad = np.empty_like(diff)
    for k in range(diff.shape[1]):
        others = np.prod(np.delete(phik, k, axis=1), axis=1)
        grad[:, k] = dphik[:, k] * np.sign(diff[:, k]) / a * others
    return phi, grad


def _segment_sum(values, starts):
    """Sum consecutive pair rows into one row per point (non-empty segments)."""
    return np.add.reduceat(values, starts, axis=0)


def _moment_solve(H, dH, phi, dphi, starts, counts, gradients):
    """Batched solve of Eq. (3.16)-(3.17) and (2.30), (2.37) for one block.

    ``dH`` holds ∂H/∂X (the caller folds in the 1/s scaling).  Returns the
    pair values, the pair gradients and the reciprocal condition number of
    each point's moment matrix.
    """
    HHt = H[:, :, None] * H[:, None, :]
    M = _segment_sum(HHt * phi[:, None, None], starts)
    try:
        Minv = np.linalg.inv(M)
        norm = np.abs(M).sum(axis=1).max(axis=1)
        norm_inv = np.abs(Minv).sum(axis=1).max(axis=1)
        rcond = 1.0 / (norm * norm_inv)
    except np.linalg.LinAlgError:  # some M exactly singular: flag, keep finite
        Minv = np.linalg.pinv(M, hermitian=True)
        eig = np.linalg.eigvalsh(M)
        rcond = eig[:, 0] / eig[:, -1]
    b = np.repeat(Minv[:, :, 0], counts, axis=0)  # M⁻¹ H(0), per pair
    c = np.einsum("nm,nm->n", H, b)  # H_Iᵀ b
    values = c * phi
    if not gradients:
        return values, None, rcond
    dim = dH.shape[0]
    grads = np.empty((dim, len(phi)))
    for k in range(dim):
        ck = np.einsum("nm,nm->n", dH[k], b)  # H_I,kᵀ b
        v = _segment_sum(
            dH[k] * (c * phi)[:, None] + H * (ck * phi + c * dphi[:, k])[:, None],
            starts,
        )
        bk = -np.einsum("pij,pj->pi", Minv, v)  # b_,k = -M⁻¹ M_,k b
        bk = np.repeat(bk, counts, axis=0)
        grads[k] = np.einsum("nm,nm->n", H, bk) * phi + ck * phi + c * dphi[:, k]
    return values, grads, rcond


def rk_shape_functions(
    x,
    nodes,
    radius,
    order=1,
    kernel="cubic",
    support="radial",
    gradients=True,
    dilation=None,
    rcond_min=RCOND_MIN,
):
    """Reproducing kernel shape functions Ψ_I(X) and ∂Ψ_I/∂X, Eq. (3.16)-(3.19).

    Parameters
    ----------
    x : ndarray, shape (dim, npoints)
        Evaluation points (material coordinates).
    nodes : ndarray, shape (dim, nnodes)
        Particle positions ``X_I``.
    radius : float or ndarray, shape (nnodes,)
        Support radius ``a_I`` of each particle.
    order : int
        Order ``N`` of the monomial basis (0: Shepard, Eq. 2.32; 1; 2).
    kernel : str or callable
        Window name (see :mod:`skfem_rkpm.kernels`) or ``z -> (φ, φ')``.
    support : {"radial", "box"}
        Circular/spherical or tensor-product supports.
    gradients : bool
        Also compute the material gradients (Eq. 2.30 with Eq. 2.37).
    dilation : float, optional
        The normalized support ``c`` the radii were made from; only used to
        phrase the error message in the user's terms.
    rcond_min : float
        Smallest accepted reciprocal condition number of ``M(X)``.

    Returns
    -------
    ShapeTable

    Raises
    ------
    SingularMomentError
        If a point is covered by too few particles or their arrangement makes
        ``M(X)`` singular; the message names the point, how many particles
        cover it and the smallest support that would work.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    nodes = np.atleast_2d(np.asarray(nodes, dtype=float))
    dim, npoints = x.shape
    if nodes.shape[0] != dim:
        raise ValueError(
            f"points have dimension {dim} but nodes have dimension {nodes.shape[0]}"
        )
    nnodes = nodes.shape[1]
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (nnodes,)).copy()
    if not np.all(radius > 0):
        bad = int(np.flatnonzero(~(radius > 0))[0])
        raise ValueError(
            f"support radius of particle {bad} at {nodes[:, bad]} is {radius[bad]}; "
            "radii must be positive"
        )
    if support not in ("radial", "box"):
        raise ValueError(f"support must be 'radial' or 'box', not {support!r}")
    window = get_kernel(kernel)
    exps = monomial_exponents(dim, order)
    table, bad, why = _build(x, nodes, radius, exps, window, support,
                             gradients, rcond_min)
    if bad.size:
        _raise_singular(bad, np.diff(table.indptr), x, nodes, radius, order,
                        window, support, dilation, rcond_min, why)
    return table


def _build(x, nodes, radius, exps, window, support, gradients, rcond_min):
    """Compute the table; return it with the failing points and the reason."""
    dim, npoints = x.shape
    m = len(exps)
    pts, nds = x.T.copy(), nodes.T.copy()
    ipoint, inode = find_pairs(pts, nds, radius, support)
    counts = np.bincount(ipoint, minlength=npoints)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    table = ShapeTable(indptr, inode, None, None, nodes.shape[1])
    too_few = np.flatnonzero(counts < m)
    if too_few.size:
        return table, too_few, "too few particles cover it"

    values = np.empty(len(inode))
    grads = np.empty((dim, len(inode))) if gradients else None
    rcond = np.empty(npoints)
    for start in range(0, npoints, POINTS_PER_BLOCK):
        stop = min(start + POINTS_PER_BLOCK, npoints)
        lo, hi = indptr[start], indptr[stop]
        q, I = ipoint[lo:hi], inode[lo:hi]
        starts = indptr[start:stop] - lo
        diff = pts[q] - nds[I]
        phi, dphi = _window(diff, radius[I], window, support)
        # local length s(X): the largest support covering the point
        s = np.maximum.reduceat(radius[I], starts)
        s_pair = np.repeat(s, counts[start:stop])
        H, dH = _monomials(diff / s_pair[:, None], exps)
        dH /= s_pair[None, :, None]
        v, g, rc = _moment_solve(H, dH, phi, dphi, starts, counts[start:stop],
                                 gradients)
        values[lo:hi] = v
        if gradients:
            grads[:, lo:hi] = g
        rcond[start:stop] = rc
    table.values, table.grads = values, grads
    bad = np.flatnonzero(~(rcond >= rcond_min))
    return table, bad, ("the covering particles do not span the basis "
                        "(moment matrix singular or ill-conditioned)")


def _points_ok(x, nodes, radius, exps, window, support, rcond_min):
    """True if every point's moment matrix is invertible with these radii."""
    _, bad, _ = _build(x, nodes, radius, exps, window, support, False, rcond_min)
    return bad.size == 0


def _smallest_factor(x, nodes, radius, exps, window, support, rcond_min):
    """Smallest support growth factor (1.02 steps up to 10) that fixes ``x``."""
    for factor in 1.02 ** np.arange(1, 118):
        if _points_ok(x, nodes, radius * factor, exps, window, support, rcond_min):
            return float(factor)
    return None


def _raise_singular(bad, counts, x, nodes, radius, order, window, support,
                    dilation, rcond_min, why):
    xb = x[:, bad]
    exps = monomial_exponents(x.shape[0], order)
    factor = _smallest_factor(xb[:, :50], nodes, radius, exps, window,
                              support, rcond_min)
    first = bad[0]
    coords = ", ".join(f"{c:.6g}" for c in x[:, first])
    m = len(exps)
    msg = (
        f"moment matrix M(X) cannot be inverted at {bad.size} of {x.shape[1]} "
        f"points: {why}. First: point {first} at ({coords}) is covered by "
        f"{counts[first]} particles (order {order} needs at least {m} not all "
        f"on one {'line' if x.shape[0] > 1 else 'point'})."
    )
    if factor is None:
        msg += " Even supports 10x larger do not help: check the particle positions."
    elif dilation is not None:
        msg += (f" The smallest normalized support that works there is "
                f"{dilation * factor:.3g} (now {dilation:.3g}).")
    else:
        msg += f" Supports must grow by a factor of at least {factor:.3g}."
    raise SingularMomentError(msg, bad, xb, counts[bad], factor)
