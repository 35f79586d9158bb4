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
(sorted by point, then node): :class:`ShapeTable`.  Points are processed in
blocks; inside a block the pair arrays are laid out (component, pair) and
the small moment matrices (m, m, point), so that every operation runs over
long contiguous rows.

An optional compiled kernel (:mod:`skfem_rkpm.approximation._shape_numba`, needs numba:
``pip install skfem-rkpm[fast]``) builds the same table, with a cell-list
neighbour search instead of KD-trees; ``backend`` (or the environment
variable ``SKFEM_RKPM_SHAPE_BACKEND``) chooses between the two.  The numpy
path stays the reference: it handles every case, and every error is
reported by it.
"""

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np
import scipy.sparse as sp

from .kernels import get_kernel
from .neighbours import grouped_pairs
from .shape_backend import BackendUnavailableError, compiled_backend, kernel_name

__all__ = [
    "BackendUnavailableError",
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
    kernel : ndarray, shape (npairs,) or None
        The kernel (window) ``φ(X_q - X_I; a_I)`` of each pair, Eq. (3.12),
        as the shape functions were built with it (VCI weights its
        corrections with it).
    test_grads : ndarray, shape (dim, npairs) or None
        The gradients of the test functions where they are not ``grads``:
        the corrected ones of variationally consistent integration (VCI).
    """

    indptr: np.ndarray
    indices: np.ndarray
    values: np.ndarray
    grads: np.ndarray
    nnodes: int
    kernel: np.ndarray = None
    test_grads: np.ndarray = None

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


def _monomial_recurrences(exps):
    """Recurrences that build ``H`` and its derivatives from lower monomials.

    The basis is sorted by degree, so every monomial ``j > 0`` is a lower
    one times one coordinate.

    Returns
    -------
    build : list of (j, k, l)
        ``H_j = ξ_k H_l`` for ``j = 1 .. m-1`` in order (``l < j``).
    lowered : list over k of lists of (j, e_jk, l)
        ``∂H_j/∂ξ_k = e_jk H_l``, only for the monomials that contain ``ξ_k``.
    """
    index = {tuple(e): j for j, e in enumerate(exps)}

    def lower(e, k):
        low = e.copy()
        low[k] -= 1
        return index[tuple(low)]

    build = []
    for j in range(1, len(exps)):
        k = int(np.flatnonzero(exps[j])[0])
        build.append((j, k, lower(exps[j], k)))
    lowered = [[(j, float(e[k]), lower(e, k)) for j, e in enumerate(exps) if e[k] > 0]
               for k in range(exps.shape[1])]
    return build, lowered


def _monomials(xi, build, m):
    """``H(ξ)`` of Eq. (2.24) for ξ of shape (dim, n): shape (m, n)."""
    H = np.empty((m, xi.shape[1]))
    H[0] = 1.0
    for j, k, low in build:
        np.multiply(H[low], xi[k], out=H[j])
    return H


def find_pairs(points, nodes, radius, support="radial", groups=None):
    """All (point, node) pairs with the point strictly inside the node's support.

    Parameters
    ----------
    points : ndarray, shape (n, dim)
    nodes : ndarray, shape (N, dim)
    radius : ndarray, shape (N,)
        Support radius ``a_I`` of each node.
    support : {"radial", "box"}
        Circle/sphere (Euclidean distance) or box (max-norm) supports.
    groups : ndarray, optional
        Pointers (CSR) of groups of consecutive, nearby points (the
        quadrature points of a cell): the particles are then searched once
        per group (:func:`~.neighbours.grouped_pairs`), the same pairs.

    Returns
    -------
    ipoint, inode : ndarray
        Pair lists sorted by point, then node.
    """
    from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

    p = {"radial": 2.0, "box": np.inf}[support]
    if groups is not None:
        return grouped_pairs(points, nodes, radius, p, groups)
    tree = cKDTree(points, balanced_tree=False)
    # group nodes by radius (factor 1.5 per group) so that graded supports
    # are not all searched with the largest radius
    rmin = radius.min()
    group = np.floor(np.log(radius / rmin) / np.log(1.5)).astype(int)
    nnodes = len(nodes)
    keys = []
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        rg = radius[members]
        found = cKDTree(nodes[members], balanced_tree=False).sparse_distance_matrix(
            tree, rg.max(), p=p, output_type="ndarray"
        )
        keep = found["v"] < rg[found["i"]]
        # one int64 key per pair orders by point, then node
        keys.append(found["j"][keep].astype(np.int64) * nnodes
                    + members[found["i"][keep]])
    key = np.sort(keys[0] if len(keys) == 1 else np.concatenate(keys))
    ipoint, inode = np.divmod(key, nnodes)
    return ipoint, inode


def _kernel_weights(diff, a, kernel, support):
    """Kernel φ and its gradient w.r.t. X for pair differences ``X - X_I``.

    Parameters
    ----------
    diff : ndarray, shape (dim, n)
    a : ndarray, shape (n,)

    Returns
    -------
    phi : ndarray, shape (n,)
    dphi : ndarray, shape (dim, n)
    """
    if support == "radial":
        r = np.sqrt(np.einsum("kn,kn->n", diff, diff))
        phi, dphi_dz = kernel(r / a)
        # ∂φ/∂X = φ'(z) / a · (X - X_I) / r, zero at the node itself
        scale = np.zeros_like(r)
        np.divide(dphi_dz, a * r, out=scale, where=r > 0)
        return phi, scale * diff
    # box: tensor product of one-dimensional windows
    phik, dphik = kernel(np.abs(diff) / a)
    phi = np.prod(phik, axis=0)
    grad = np.empty_like(diff)
    for k in range(diff.shape[0]):
        others = np.prod(np.delete(phik, k, axis=0), axis=0)
        grad[k] = dphik[k] * np.sign(diff[k]) / a * others
    return phi, grad


def _window(diff, a, kernel, support):
    """:func:`_kernel_weights` for pair-major differences ``diff`` (n, dim).

    Returns φ (n,) and its gradient (n, dim).
    """
    phi, grad = _kernel_weights(np.asarray(diff).T, a, kernel, support)
    return phi, grad.T


def _moment_matrices(H, phi, starts):
    """``M(X) = Σ_I H H^T φ`` of Eq. (3.17) per point, shape (m, m, npoints).

    Only the upper triangle is summed; the lower one is its mirror.
    """
    m = len(H)
    iu, ju = np.triu_indices(m)
    Hphi = H * phi
    products = np.empty((len(iu), H.shape[1]))
    for row, (i, j) in enumerate(zip(iu, ju)):
        np.multiply(H[i], Hphi[j], out=products[row])
    upper = np.add.reduceat(products, starts, axis=1)
    M = np.empty((m, m, upper.shape[1]))
    M[iu, ju] = upper
    M[ju, iu] = upper
    return M


def _batched_inverse(M):
    """Inverses of the symmetric positive (semi)definite ``M[:, :, p]``.

    Gauss-Jordan elimination without pivoting, vectorized over the last
    axis (pivots of a positive definite matrix are positive).  An exactly
    singular matrix gives inf/NaN entries in its own inverse only, which
    the condition estimate then flags.
    """
    m = M.shape[0]
    A = np.concatenate([M, np.broadcast_to(np.eye(m)[:, :, None], M.shape)], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(m):
            A[i] /= A[i, i]
            for r in range(m):
                if r != i:
                    A[r] -= A[r, i] * A[i]
    return A[:, m:]


def _rcond(M, Minv):
    """Reciprocal 1-norm condition number of each ``M[:, :, p]`` (NaN if singular)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 1.0 / (np.abs(M).sum(axis=0).max(axis=0)
                      * np.abs(Minv).sum(axis=0).max(axis=0))


def _dot(u, v):
    """Column-wise dot product of two (m, n) arrays."""
    return np.einsum("jn,jn->n", u, v)


def _moment_solve(H, lowered, phi, dphi, inv_s, starts, counts, gradients):
    """Batched solve of Eq. (3.16)-(3.17) and (2.30), (2.37) for one block.

    Pair arrays are laid out (component, pair): ``H`` (m, n), ``dphi``
    (dim, n).  The monomial derivatives are ``∂H_j/∂X_k = e_jk H_l / s``
    (``lowered``, see :func:`_monomial_recurrences`; ``s`` frozen, its
    inverse per pair in ``inv_s``).  Returns the pair values, the pair
    gradients and the reciprocal condition number of each point's moment
    matrix.
    """
    M = _moment_matrices(H, phi, starts)
    Minv = _batched_inverse(M)
    rcond = _rcond(M, Minv)
    b = np.repeat(Minv[:, 0], counts, axis=1)  # M⁻¹ H(0), per pair
    c = _dot(H, b)  # H_Iᵀ b
    cphi = c * phi
    if not gradients:
        return cphi, None, rcond
    grads = np.empty(dphi.shape)
    cphi_s = cphi * inv_s
    for k, terms in enumerate(lowered):
        ck = np.zeros_like(phi)  # H_I,kᵀ b
        for j, e, low in terms:
            ck += (e * b[j]) * H[low]
        ck *= inv_s
        t = ck * phi + c * dphi[k]
        # M_,k b = Σ_I [H_I,k (c φ) + H_I (c_k φ + c φ_,k)]
        V = H * t
        for j, e, low in terms:
            V[j] += (e * cphi_s) * H[low]
        v = np.add.reduceat(V, starts, axis=1)
        bk = -np.einsum("ijp,jp->ip", Minv, v)  # b_,k = -M⁻¹ M_,k b
        grads[k] = _dot(H, np.repeat(bk, counts, axis=1)) * phi + t
    return cphi, grads, rcond


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
    backend=None,
    groups=None,
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
        Window name (see :mod:`skfem_rkpm.approximation.kernels`) or ``z -> (φ, φ')``.
    support : {"radial", "box"}
        Circular/spherical or tensor-product supports.
    gradients : bool
        Also compute the material gradients (Eq. 2.30 with Eq. 2.37).
    dilation : float, optional
        The normalized support ``c`` the radii were made from; only used to
        phrase the error message in the user's terms.
    rcond_min : float
        Smallest accepted reciprocal condition number of ``M(X)``.
    backend : {"auto", "numpy", "numba"}, optional
        ``"numpy"``: the vectorized numpy/scipy path; ``"numba"``: the
        compiled kernel (needs numba, ``pip install skfem-rkpm[fast]``; cubic
        and quartic kernels, 1 to 3 dimensions); ``"auto"``: the compiled
        kernel when numba is installed, the case is covered and either the
        kernel is already loaded or the call has at least
        :data:`AUTO_MIN_POINTS` points, else numpy.  Both give the same
        table (the same pairs in the same order, values equal to round-off).
        Default: the environment variable ``SKFEM_RKPM_SHAPE_BACKEND``, or
        ``"auto"``.
    groups : ndarray, optional
        Pointers (CSR) of groups of consecutive, nearby points, such as the
        quadrature points of one cell: the numpy path then searches the
        particles once per group (:func:`find_pairs`); the same table.

    Returns
    -------
    ShapeTable

    Raises
    ------
    SingularMomentError
        If a point is covered by too few particles or their arrangement makes
        ``M(X)`` singular; the message names the point, how many particles
        cover it and the smallest support that would work.
    BackendUnavailableError
        If ``backend="numba"`` and numba is not installed.
    """
    x = coordinates(x, "evaluation point")
    nodes = coordinates(nodes, "particle")
    dim, npoints = x.shape
    if nodes.shape[0] != dim:
        raise ValueError(
            f"points have dimension {dim} but nodes have dimension {nodes.shape[0]}"
        )
    nnodes = nodes.shape[1]
    if nnodes == 0:
        raise ValueError("there are no particles (nodes has shape "
                         f"{nodes.shape}); give at least one")
    check_order(order)
    try:
        radius = np.broadcast_to(np.asarray(radius, dtype=float), (nnodes,)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"support radii must be one positive number or one per "
                         f"particle ({nnodes}), not {radius!r}") from None
    if not np.all((radius > 0) & np.isfinite(radius)):
        bad = int(np.flatnonzero(~((radius > 0) & np.isfinite(radius)))[0])
        raise ValueError(
            f"support radius of particle {bad} at {nodes[:, bad]} is {radius[bad]}; "
            "radii must be positive and finite"
        )
    if support not in ("radial", "box"):
        raise ValueError(f"support must be 'radial' or 'box', not {support!r}")
    window = get_kernel(kernel)
    exps = monomial_exponents(dim, order)
    compiled = compiled_backend(backend, window, dim, npoints)
    if compiled is not None:
        table = _build_compiled(compiled, x, nodes, radius, exps, window,
                                support, gradients, rcond_min)
        if table is not None:
            return table
        # a point is not covered well enough: the numpy path reports it
    table, bad, why = _build(x, nodes, radius, exps, window, support,
                             gradients, rcond_min, groups)
    if bad.size:
        _raise_singular(bad, np.diff(table.indptr), x, nodes, radius, order,
                        window, support, dilation, rcond_min, why)
    return table


def _build_compiled(module, x, nodes, radius, exps, window, support, gradients,
                    rcond_min):
    """The table from the compiled kernel, or None if a point fails.

    None also when a moment matrix comes within a factor 2 of ``rcond_min``:
    the sums run in another order than numpy's, so near the limit only the
    numpy path decides (and reports) which points fail.
    """
    build, lowered = _monomial_recurrences(exps)
    arrays = module.build(x, nodes, radius, build, lowered, kernel_name(window),
                          support, gradients)
    if arrays is None:
        return None
    indptr, indices, values, grads, rcond, kernel = arrays
    if values is None or not np.all(rcond >= 2.0 * rcond_min):
        return None
    return ShapeTable(indptr, indices, values, grads, nodes.shape[1], kernel)


def coordinates(x, what):
    """Points as a float array (dim, n), refusing non-finite coordinates."""
    try:
        x = np.atleast_2d(np.asarray(x, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"{what} coordinates must be an array of numbers of shape "
                         f"(dim, n), not {x!r}") from None
    if x.ndim != 2:
        raise ValueError(f"{what} coordinates must have shape (dim, n), not {x.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(x), axis=0))
    if bad.size:
        where = ", ".join(f"{c:g}" for c in x[:, bad[0]])
        raise ValueError(f"{what} {bad[0]} has non-finite coordinates ({where}) "
                         f"({bad.size} such {what}s); every coordinate must be finite")
    return x


def check_order(order):
    """Refuse basis orders other than non-negative integers."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) \
            or order < 0:
        raise ValueError(f"basis order must be a non-negative integer, not {order!r}")


def blocked_pairs(x, nodes, radius, ipoint, inode, indptr, counts, window, support, build,
                  m, gradients, solve):
    """Shape functions at the point-particle pairs (Eq. 3.16-3.19), block by
    block of ``POINTS_PER_BLOCK`` points, with the moment solve ``solve``.

    Per block the pairs' offsets ``diff = x - X_I``, the kernel ``φ`` and its
    derivative, the local length ``s(X)`` (the largest support covering the
    point) and the monomials ``H((x - X_I)/s)`` are formed and passed to
    ``solve(diff, I, phi, dphi, H, inv_s, starts, block_counts)``, which
    returns the block's values, gradients and reciprocal condition numbers.

    Returns ``values`` (npairs,), ``grads`` (dim, npairs) or None, the kernel
    values (npairs,) and ``rcond`` (npoints,).
    """
    dim, npoints = x.shape
    values = np.empty(len(inode))
    kernel = np.empty(len(inode))
    grads = np.empty((dim, len(inode))) if gradients else None
    rcond = np.empty(npoints)
    x, nodes = np.ascontiguousarray(x), np.ascontiguousarray(nodes)
    for start in range(0, npoints, POINTS_PER_BLOCK):
        stop = min(start + POINTS_PER_BLOCK, npoints)
        lo, hi = indptr[start], indptr[stop]
        I = inode[lo:hi]
        starts = indptr[start:stop] - lo
        diff = np.take(x, ipoint[lo:hi], axis=1) - np.take(nodes, I, axis=1)
        a = radius[I]
        phi, dphi = _kernel_weights(diff, a, window, support)
        s = np.maximum.reduceat(a, starts)
        inv_s = np.repeat(1.0 / s, counts[start:stop])
        H = _monomials(diff * inv_s, build, m)
        v, g, rc = solve(diff, I, phi, dphi, H, inv_s, starts, counts[start:stop])
        values[lo:hi] = v
        kernel[lo:hi] = phi
        if gradients:
            grads[:, lo:hi] = g
        rcond[start:stop] = rc
    return values, grads, kernel, rcond


def _build(x, nodes, radius, exps, window, support, gradients, rcond_min, groups=None):
    """Compute the table; return it with the failing points and the reason."""
    dim, npoints = x.shape
    m = len(exps)
    ipoint, inode = find_pairs(x.T.copy(), nodes.T.copy(), radius, support, groups)
    counts = np.bincount(ipoint, minlength=npoints)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    table = ShapeTable(indptr, inode, None, None, nodes.shape[1])
    too_few = np.flatnonzero(counts < m)
    if too_few.size:
        return table, too_few, "too few particles cover it"

    build, lowered = _monomial_recurrences(exps)

    def solve(diff, I, phi, dphi, H, inv_s, starts, block_counts):
        return _moment_solve(H, lowered, phi, dphi, inv_s, starts, block_counts, gradients)

    values, grads, kernel, rcond = blocked_pairs(x, nodes, radius, ipoint, inode, indptr,
                                                 counts, window, support, build, m,
                                                 gradients, solve)
    table.values, table.grads, table.kernel = values, grads, kernel
    bad = np.flatnonzero(~(rcond >= rcond_min))
    return table, bad, ("the covering particles do not span the basis "
                        "(moment matrix singular or ill-conditioned)")


def _points_ok(x, nodes, radius, exps, window, support, rcond_min):
    """True if every point's moment matrix is invertible with these radii."""
    _, bad, _ = _build(x, nodes, radius, exps, window, support, False, rcond_min)
    return bad.size == 0


def _smallest_factor(x, nodes, radius, exps, window, support, rcond_min):
    """Smallest support growth factor (1.02 steps up to 10) that fixes ``x``.

    A sample of 50 points gives a lower bound cheaply; the scan then goes on
    from there with every point, so that the factor works for all of them.
    """
    factors = 1.02 ** np.arange(1, 118)
    for points in (x[:, :50], x):
        for k, factor in enumerate(factors):
            if _points_ok(points, nodes, radius * factor, exps, window, support,
                          rcond_min):
                factors = factors[k:]
                break
        else:
            return None
    return float(factors[0])


def _raise_singular(bad, counts, x, nodes, radius, order, window, support,
                    dilation, rcond_min, why):
    xb = x[:, bad]
    exps = monomial_exponents(x.shape[0], order)
    factor = _smallest_factor(xb, nodes, radius, exps, window,
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
