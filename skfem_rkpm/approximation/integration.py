"""Background quadrature and variationally consistent integration (VCI).

The mesh supplies only integration cells: Gauss points and weights come from
scikit-fem's own bases on the lowest-order Lagrange element of the mesh, so
RK and FEM bases on one mesh share the same quadrature points.

Gauss integration of RK shape functions on background cells violates the
integration constraint (the discrete divergence theorem), so the linear
patch test passes only approximately with the paper's scheme.  VCI (Chen,
Hillman & Rüter 2013) adds a small correction to the *test* function
gradients,

    ∇̃Ψ_I(x) = ∇Ψ_I(x) + φ_I(x) (a_I(x) - Σ_J S_J(x) a_J(x)),
    a_I(x) = Σ_β ξ_Iβ p_β(x),   S_J = φ_J / Σ_K φ_K,

with the kernel φ_I as weight and ``p_β`` the monomials of degree below the
basis order ``n`` (shifted to the particle and scaled by its support).  The
Shepard-weighted mean subtracted from ``a_I`` keeps the derivative of the
partition of unity, Σ_I ∇̃Ψ_I = 0 at every point, so internal forces are
self-equilibrated for any stress.  The coefficients of all particles are
fixed together (one sparse symmetric positive semidefinite solve: for a
linear basis a graph Laplacian, by conjugate gradients with a coarse
correction, :mod:`.laplacian`) so that, with the quadrature in use,

    ∫̂_Ω ∇̃Ψ_I p_α dΩ + ∫̂_Ω Ψ_I ∇p_α dΩ = ∫̂_Γ Ψ_I p_α n dΓ    for |α| ≤ n - 1.

The trial functions keep their exact gradients (they reproduce polynomials
of degree ``n``), so the Petrov-Galerkin system reproduces polynomial
solutions of degree ``n`` to round-off: the patch test passes on any mesh.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu
from skfem import CellBasis, FacetBasis

from .kernels import get_kernel
from .laplacian import laplacian_solve
from .reduction import WHOLE
from .shape import _window, monomial_exponents
from .symmetric_cells import point_blocks, symmetric_correction_cells

__all__ = ["cell_geometry", "facet_geometry", "vci_gradients"]


def _lagrange_element(mesh):
    return type(mesh).elem()


def cell_geometry(mesh, intorder, elements=None):
    """A scikit-fem basis that supplies cell quadrature points and weights
    (on the cells ``elements`` only, if given)."""
    return CellBasis(mesh, _lagrange_element(mesh), intorder=intorder, elements=elements)


def facet_geometry(mesh, intorder, facets=None, quadrature=None):
    """A scikit-fem facet basis supplying boundary quadrature and normals
    (``quadrature = (X, W)`` on the reference facet overrides ``intorder``)."""
    return FacetBasis(mesh, _lagrange_element(mesh), facets=facets,
                      intorder=intorder, quadrature=quadrature)


def _pair_monomials(rows, cols, x, nodes, scale, exps):
    """p_β((x_q - X_I)/s_I) and ∇p_β for the pairs ``(rows, cols)``: (n, m), (dim, n, m).

    Only the constant (``exps`` one zero row, basis order 1): ones and zeros
    without touching the coordinates.
    """
    n, dim = len(rows), x.shape[0]
    p = np.ones((n, len(exps)))
    dp = np.zeros((dim, n, len(exps)))
    if not exps.any():
        return p, dp
    xi = (x[:, rows] - nodes[:, cols]) / scale[cols]
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


def _pair_kernel(table, x, nodes, radius, kernel, support):
    """The kernel φ_I(x_q) of every pair: the one the shape table was built
    with, or computed again for a table without it."""
    if table.kernel is not None:
        return table.kernel
    phi, _ = _window((x[:, table.rows] - nodes[:, table.indices]).T, radius[table.indices],
                     get_kernel(kernel), support)
    return phi


def vci_gradients(table, x, weights, boundary_table, xb, wb, normals,
                  nodes, radius, order, kernel="cubic", support="radial",
                  axisymmetric=False, symmetric=False, reduction=WHOLE, cells=None,
                  overwrite=False):
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
    symmetric : bool
        Correct so that the corrected gradients also reproduce the
        gradients of linear fields (:func:`_symmetric_correction`): then the
        same corrected gradients serve trial and test functions, the
        stiffness is symmetric and the linear patch test still passes.
        Basis order 1, not axisymmetric.
    reduction : optional
        For a basis on part of the cells (:mod:`.reduction`): the points of
        ``table`` and ``xb`` are this part's, and the moments, right-hand
        sides and balancing matrix, sums over the points, are added up over
        the parts before the coefficients are solved for (on every part
        alike).  Not for ``symmetric``.
    cells : tuple, optional
        ``(nqp, cell_particles)`` when the points of ``table`` are the
        ``nqp`` quadrature points of each cell in turn
        (:func:`.cell_layout.cell_particles`): the symmetric correction is
        then formed block by block of points and its system assembled cell
        by cell (:mod:`.symmetric_cells`), the same correction.
    overwrite : bool
        ``symmetric``: add the correction to ``table.grads`` in place (the
        exact gradients are not kept) instead of to a new array.

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
    cols = table.indices

    phi = _pair_kernel(table, x, nodes, radius, kernel, support)
    p = dp = None  # order 1: the constant alone, not stored at the pairs
    if m > 1:
        p, dp = _pair_monomials(table.rows, cols, x, nodes, scale, exps)
    if axisymmetric:
        weights, wb = weights * x[0], wb * xb[0]

    # φ_I(x_q) as a sparse (points × particles) matrix; its index arrays
    # (converted once) serve every other quantity given at the pairs
    kernel_matrix = _pair_matrix(table, phi)
    A = reduction.sum(_moment_integrals(kernel_matrix, p, weights, m))  # A_I = ∫ φ_I p pᵀ
    rhs = reduction.sum(_constraint_rhs(kernel_matrix, table, x, weights, boundary_table,
                                        xb, wb, normals, nodes, scale, exps, dp, p,
                                        axisymmetric))
    covered = reduction.sum(np.bincount(cols, minlength=nnodes))
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
    if symmetric:
        if reduction.parts > 1:
            raise ValueError("symmetric VCI is not built for a basis on part of the "
                             "cells; use integration='vci'")
        if order != 1 or axisymmetric:
            raise ValueError("symmetric VCI is built for basis order 1 in plane or 3D "
                             f"problems (here order {order}"
                             + (", axisymmetric" if axisymmetric else "")
                             + "); use integration='vci'")
        if cells is not None:
            return symmetric_correction_cells(
                table, x, weights, phi, rhs[:, :, 0], nodes, radius, *cells,
                solve=_pinned_spd_solve, frame=_affine_frame,
                grads=table.grads if overwrite else table.grads.copy())
        correction = _symmetric_correction(table, x, weights, phi, rhs[:, :, 0], nodes,
                                           radius)
        if overwrite:
            table.grads += correction
            return table.grads
        return table.grads + correction
    H = _weighted_kernel_matrix(kernel_matrix, p)
    Phi = kernel_matrix @ np.ones(nnodes)  # Φ_q = Σ_K φ_K(x_q)
    xi = _balanced_coefficients(H, Phi, weights, A, rhs, nodes, radius,
                                reduction)  # (nnodes, m, dim)
    counts = np.diff(table.indptr)
    # ā(x_q) = Σ_J S_J a_J = (H ξ)_q / Φ_q, with S_J = φ_J / Φ the Shepard functions
    mean = (H @ xi.reshape(nnodes * m, dim)) / Phi[:, None]  # (nq, dim)
    if m == 1:  # a_I = ξ_I
        return _constant_correction(table, xi[:, 0, :], mean, phi)
    else:  # a_I(x_q) = ξ_I · p(x_q) at the pairs
        correction = np.einsum("na,nak->kn", p, xi[cols])
    for k in range(dim):  # one row at a time: np.repeat of a 2D array is slow
        correction[k] -= np.repeat(mean[:, k], counts)
    correction *= phi
    correction += table.grads
    return correction


def _constant_correction(table, xi, mean, phi):
    """``∇Ψ_I + φ_I (ξ_I - ā(x_q))`` at the pairs of ``table`` (dim, npairs),
    for ``a_I = ξ_I`` (basis order 1; ``xi`` (nnodes, dim), ``mean`` (nq,
    dim)), block by block of points: no temporary as long as the pairs."""
    dim = xi.shape[1]
    out = np.empty((dim, len(phi)))
    xi, mean, indptr = np.ascontiguousarray(xi.T), np.ascontiguousarray(mean.T), table.indptr
    for q0, q1 in point_blocks(indptr):
        lo, hi = indptr[q0], indptr[q1]
        counts, cols = np.diff(indptr[q0:q1 + 1]), table.indices[lo:hi]
        for k in range(dim):
            c = np.take(xi[k], cols)
            c -= np.repeat(mean[k, q0:q1], counts)
            c *= phi[lo:hi]
            c += table.grads[k, lo:hi]
            out[k, lo:hi] = c
    return out


def _moment_integrals(kernel_matrix, p, weights, m):
    """``A_I = ∫̂ φ_I p pᵀ`` (nnodes, m, m), ``p ≡ 1`` if ``p`` is None (m = 1)."""
    phi = kernel_matrix.data
    A = np.empty((kernel_matrix.shape[1], m, m))
    for a in range(m):
        for b in range(a, m):
            data = phi if b == 0 else phi * p[:, a] * p[:, b]
            A[:, a, b] = A[:, b, a] = _integrate_pairs(kernel_matrix, data, weights)
    return A


def _integrate_pairs(pattern, data, weights):
    """``Σ_q w_q f_I(x_q)`` for every particle ``I``, ``f`` given at the pairs
    (in the order of ``pattern``, a :func:`_pair_matrix`): one pass over the
    pairs, the transposed CSR product (the same sums in the same order as
    ``np.bincount(cols, w[rows] * data)``)."""
    return sp.csr_matrix((data, pattern.indices, pattern.indptr),
                         shape=pattern.shape).T @ weights


def _pair_matrix(table, data):
    """The sparse matrix (points × particles) of ``data`` given at the pairs."""
    return sp.csr_matrix((data, table.indices, table.indptr),
                         shape=(table.npoints, table.nnodes))


def _weighted_kernel_matrix(kernel_matrix, p):
    """``H[q, (J, β)] = φ_J(x_q) p_Jβ(x_q)`` in CSR, shape (nq, nnodes m): row
    ``q`` holds the ``m`` unknowns of each pair of ``q``, in order
    (``p ≡ 1``, m = 1, if ``p`` is None: the kernel matrix itself)."""
    if p is None:
        return kernel_matrix
    m = p.shape[1]
    nq, nnodes = kernel_matrix.shape
    unknown = (kernel_matrix.indices[:, None].astype(np.int64) * m
               + np.arange(m)[None, :]).ravel()
    return sp.csr_matrix(((kernel_matrix.data[:, None] * p).ravel(), unknown,
                          kernel_matrix.indptr.astype(np.int64) * m),
                         shape=(nq, nnodes * m))


def _constraint_rhs(kernel_matrix, table, x, weights, boundary_table, xb, wb, normals,
                    nodes, scale, exps, dp, p, axisymmetric):
    """``r_I,k,α = ∫_Γ Ψ_I p_α n_k - ∫_Ω Ψ_I ∂_k p_α - ∫_Ω ∂_k Ψ_I p_α``, shape
    (nnodes, dim, m): what the corrections must integrate to.

    ``kernel_matrix`` (:func:`_pair_matrix`) gives the pattern of the pairs of
    ``table``; ``p`` and ``dp`` are the monomials and their gradients at the pairs (None
    for order 1: the constant alone, ``∂p = 0``).  ``weights`` and ``wb`` are
    already multiplied by the radius if ``axisymmetric`` (then ``-∫ Ψ_I p_α dR
    dZ`` is added to the radial row).
    """
    dim, nnodes = nodes.shape
    m = len(exps)
    rhs = np.empty((nnodes, dim, m))
    brow, bcol = boundary_table.rows, boundary_table.indices
    pb = (_pair_monomials(brow, bcol, xb, nodes, scale, exps)[0] if m > 1
          else np.ones((len(bcol), 1)))
    for k in range(dim):
        for a in range(m):
            integrand = table.grads[k] if a == 0 else table.grads[k] * p[:, a]
            if exps[a][k] > 0:  # ∂_k p_α = 0 otherwise
                integrand = integrand + table.values * dp[k, :, a]
            rhs[:, k, a] = (
                np.bincount(bcol, wb[brow] * boundary_table.values
                            * pb[:, a] * normals[k, brow], minlength=nnodes)
                - _integrate_pairs(kernel_matrix, integrand, weights)
            )
    if axisymmetric:  # ∂R/∂R = 1: the extra term -∫ Ψ_I p_α dR dZ
        for a in range(m):
            rhs[:, 0, a] -= _integrate_pairs(
                kernel_matrix, table.values if a == 0 else table.values * p[:, a],
                weights / x[0])
    return rhs


def _balanced_coefficients(H, Phi, weights, A, rhs, nodes, radius, reduction=WHOLE):
    """Coefficients ξ_I of the balanced correction (one sparse SPD solve).

    The correction ``c_I = φ_I (a_I - Σ_J S_J a_J)``, ``a_I = ξ_I · p_I`` and
    ``S_J = φ_J / Σ_K φ_K`` (Shepard functions), sums to zero at every
    point.  The constraints of all particles become one symmetric positive
    semidefinite system ``M ξ = r``,

        M = blockdiag(∫̂ φ_I p_I p_Iᵀ) - Hᵀ diag(w_q / Φ_q) H,
        H[q, (J, β)] = φ_J(x_q) p_Jβ(x_q),   Φ_q = Σ_K φ_K(x_q),

    whose null space holds the ``ξ`` with ``a_I`` one polynomial of degree
    ``n - 1`` on each connected body (they give ``c_I = 0``).  The right-hand
    side is orthogonal to it: summing the constraints over ``I`` gives the
    divergence theorem for that polynomial, exact for the quadrature.

    For order 1 (``m = 1``) ``M`` is a weighted graph Laplacian (zero row
    sums, off-diagonal entries ``-∫̂ φ_I φ_J / Φ ≤ 0``): above
    :data:`LAPLACIAN_DIRECT_MAX_UNKNOWNS` unknowns it is solved as it is,
    semidefinite, by :func:`laplacian_solve` (``nodes`` and ``radius``, the
    particles and their support radii, shape its coarse space).  Otherwise
    ``ξ`` of one particle per body is set to zero and its constraints,
    implied by the others, are dropped: the rest of ``M`` is positive
    definite, and is solved by :func:`_pinned_spd_solve`.  ``A`` and
    ``rhs`` are whole-domain sums; ``reduction`` adds up this part's
    ``Hᵀ diag(w_q / Φ_q) H``.
    """
    nnodes, m, _ = A.shape
    dim = rhs.shape[1]
    n = nnodes * m
    scaled = np.repeat(weights / Phi, np.diff(H.indptr))  # w_q / Φ_q at each entry
    scaled *= H.data
    WH = sp.csr_matrix((scaled, H.indices, H.indptr), shape=H.shape)
    M = reduction.sum_sparse(WH.T @ H)
    M = (sp.bsr_matrix((A, np.arange(nnodes), np.arange(nnodes + 1)), shape=(n, n))
         - M).tocsr()
    nbodies, body = connected_components(M, directed=False)
    b = rhs.transpose(0, 2, 1).reshape(n, dim)
    if m == 1 and n > LAPLACIAN_DIRECT_MAX_UNKNOWNS:
        return laplacian_solve(M, b, body, nbodies, nodes, radius, RTOL).reshape(
            nnodes, m, dim)
    _, pinned = np.unique(body[::m], return_index=True)  # first particle of each body
    block = np.arange(n).reshape(nnodes, m)
    # factored at every size: AMG + CG stall on the blocks of order 2 (17k
    # particles: 1e-3 after 500 iterations, 90 of the build's 129 CPU s)
    return _pinned_spd_solve(M, b, block[pinned].ravel(), iterative=False).reshape(
        nnodes, m, dim)


#: relative residual (2-norm, per right-hand side) at which the iterative VCI
#: solve stops: the integration constraints then hold to this fraction of
#: their right-hand side, round-off for the patch test
RTOL = 1e-13
#: up to this many unknowns the VCI systems of :func:`_pinned_spd_solve`
#: (order 2, symmetric VCI) are factored (SuperLU): measured on the order-1
#: system of the rectangle of docs/benchmarks/basis_build.md,
#: when it was solved that way, the factorization is as fast as AMG + CG at
#: 1.7e4 unknowns (0.8 against 0.9 s) and slower above (16 against 9 s at
#: 1.1e5), where its fill grows faster than the particles
DIRECT_MAX_UNKNOWNS = 20_000


#: up to this many unknowns the order-1 VCI system is factored like the
#: others (:func:`_pinned_spd_solve`) instead of solved by
#: :func:`laplacian_solve`: a factorization's result moves by round-off
#: when the shape functions do (the compiled and the numpy shape kernels
#: agree to round-off only), the point where conjugate gradients stop moves
#: by up to their tolerance.  Measured: the forces of the ring scene's
#: 6 x 4 test run (tests/test_sweep.py) differ between the two shape kernels
#: by 6e-14 of their size with the factorization, 3.5e-11 with CG; the
#: VCI correction on the benchmark rectangle takes 0.10 against 0.08 s at
#: 1.7e3 particles, 0.39 against 0.33 s at 5.0e3 and 0.85 against 0.61 s
#: at 9.8e3 (factored against CG, load 3-5)
LAPLACIAN_DIRECT_MAX_UNKNOWNS = 5_000

def _pinned_spd_solve(M, b, pinned, rtol=RTOL, iterative=True):
    """Solve ``M x = b`` with ``x = 0`` at the ``pinned`` unknowns (their
    equations dropped), ``M`` symmetric and positive definite on the rest.

    ``iterative``, above :data:`DIRECT_MAX_UNKNOWNS` unknowns and with pyamg
    installed (``pip install skfem-rkpm[amg]``): conjugate gradients
    preconditioned by smoothed-aggregation AMG (:func:`_amg_cg`); time and
    memory grow like the nonzeros of ``M``.  Otherwise, or where those do
    not reach ``rtol`` in 500 iterations, a sparse LU factorization
    (SuperLU) with one step of refinement, whose fill grows faster than the
    particles (it runs out of 20 GB near 7e5 particles in 2D).  Both agree
    to about ``rtol`` times the condition number of ``M``
    (docs/benchmarks/basis_build.md).
    """
    n = M.shape[0]
    free = np.ones(n)
    free[pinned] = 0.0
    # the pinned rows and columns become rows of the identity (x = 0 there)
    Mf = M.tocsr(copy=True)
    row = np.repeat(np.arange(n), np.diff(Mf.indptr))
    Mf.data *= free[row] * free[Mf.indices]
    Mf.eliminate_zeros()
    Mf = Mf + sp.diags(1.0 - free, format="csr")
    b = b * free[:, None]
    if iterative and n > DIRECT_MAX_UNKNOWNS:
        x = _amg_cg(Mf, b, rtol, maxiter=500)
        if x is not None:
            return x
    lu = splu(Mf.tocsc(), permc_spec="MMD_AT_PLUS_A")
    x = lu.solve(b)
    return x + lu.solve(b - Mf @ x)  # one step of refinement


def _amg_cg(M, b, rtol, maxiter):
    """Conjugate gradients preconditioned by smoothed-aggregation AMG, one
    right-hand side after the other, to the relative residual ``rtol``
    (checked on ``b - M x`` itself); None without pyamg or where it is not
    reached in ``maxiter`` iterations."""
    try:
        import pyamg
    except ImportError:
        return None
    solver = pyamg.smoothed_aggregation_solver(
        M, symmetry="symmetric", smooth="jacobi", improve_candidates=None,
        presmoother=("jacobi", {"iterations": 2}),
        postsmoother=("jacobi", {"iterations": 2}))
    x = np.zeros_like(b)
    for k in range(b.shape[1]):
        if np.any(b[:, k]):
            x[:, k] = solver.solve(b[:, k], tol=rtol, accel="cg", maxiter=maxiter)
    # the true residual may exceed the recursive one CG stops on by a little
    residual = np.linalg.norm(b - M @ x, axis=0)
    return x if np.all(residual <= 10 * rtol * np.linalg.norm(b, axis=0)) else None


def _symmetric_correction(table, x, weights, phi, r, nodes, radius):
    """Gradient corrections that keep linear reproduction: symmetric VCI.

    With ``P_J(x) = [1, (X_J - x)/s(x)]`` and ``G(x) = Σ_J φ_J P_J P_Jᵀ`` (the
    moment matrix of the kernel, Eq. 3.17 with the same window), the
    correction of particle ``I`` is the kernel-weighted residual of the
    linear least-squares fit of the coefficients ``ξ_J`` around ``x``,

        c_I(x) = φ_I(x) (ξ_I - P_I(x)ᵀ G(x)⁻¹ Σ_J P_J(x) φ_J(x) ξ_J),

    so that ``Σ_I c_I p(X_I) = 0`` for every linear ``p``: the corrected
    gradients ``∇Ψ_I + c_I`` still give the exact gradient of a linear
    field from its nodal values, and serve as trial *and* test gradients
    (a symmetric stiffness).  The first-order integration constraints
    ``∫̂ c_I = r_I`` (:func:`_constraint_rhs`) become one symmetric system
    ``M ξ = r``,

        M = diag(∫̂ φ_I) - Bᵀ diag(w) B,   B[(q, α), J] = (L_q⁻¹ P_J φ_J)_α,

    with ``G = L Lᵀ``; its null space holds the ``ξ`` linear in ``X`` on each
    connected body (they give ``c = 0``), to which ``r`` is orthogonal (the
    divergence theorem for linear fields, exact for the quadrature).  ``ξ`` of
    ``dim + 1`` particles spanning each body is set to zero and their
    constraints, implied by the others, are dropped: the rest of ``M`` is
    positive definite, and is solved by :func:`_pinned_spd_solve`.

    Returns
    -------
    ndarray, shape (dim, npairs)
    """
    rows, cols = table.rows, table.indices
    dim, nnodes = nodes.shape
    nq, m = table.npoints, dim + 1
    weight_sum = np.bincount(rows, phi, minlength=nq)
    size = np.bincount(rows, phi * radius[cols], minlength=nq) / weight_sum
    P = np.ones((len(rows), m))
    P[:, 1:] = ((nodes[:, cols] - x[:, rows]) / size[rows]).T
    G = np.empty((nq, m, m))
    for a in range(m):
        for b in range(a, m):
            G[:, a, b] = G[:, b, a] = np.bincount(rows, phi * P[:, a] * P[:, b],
                                                  minlength=nq)
    Linv = np.linalg.inv(np.linalg.cholesky(G))  # G⁻¹ = Linvᵀ Linv
    phiP = phi[:, None] * P
    B_pairs = np.zeros((len(rows), m))
    for a in range(m):  # (L⁻¹ φ P)_a without an (npairs, m, m) gather; L⁻¹ is lower
        for b in range(a + 1):
            B_pairs[:, a] += Linv[:, a, b][rows] * phiP[:, b]
    # B in CSR directly: row (q, α) holds the pairs of point q in table order
    start, count = table.indptr[:-1], np.diff(table.indptr)
    place = (m * start[rows] + np.arange(len(rows)) - start[rows])[:, None] \
        + np.arange(m)[None, :] * count[rows][:, None]  # (npairs, m)
    data = np.empty(len(rows) * m)
    data[place] = B_pairs
    indices = np.empty(len(rows) * m, dtype=cols.dtype)
    indices[place] = cols[:, None]
    indptr = np.append(m * start[:, None] + np.arange(m)[None, :] * count[:, None],
                       m * len(rows))
    B = sp.csr_matrix((data, indices, indptr), shape=(nq * m, nnodes))
    # weights may be negative (some Gauss rules on tetrahedra): W B, not √W B
    WB = sp.csr_matrix((data * np.repeat(weights, m * count), indices, indptr),
                       shape=B.shape)
    M = (sp.diags(np.bincount(cols, weights[rows] * phi, minlength=nnodes))
         - (WB.T.tocsr() @ B)).tocsr()

    nbodies, body = connected_components(M, directed=False)
    xi = _pinned_spd_solve(M, r, _affine_frame(nodes, body, nbodies))

    # t(x_q) = Σ_J P_J φ_J ξ_J, then c_I = φ_I (ξ_I - P_Iᵀ G⁻¹ t)
    t = np.stack([np.bincount(rows, phi * P[:, a] * xi[cols, k], minlength=nq)
                  for a in range(m) for k in range(dim)], axis=1).reshape(nq, m, dim)
    fit = np.einsum("qba,qbc,qck->qak", Linv, Linv, t)  # G⁻¹ t, (nq, m, dim)
    correction = xi[cols].T.copy()  # (dim, npairs)
    for a in range(m):
        correction -= P[:, a] * fit[rows, a, :].T
    return phi * correction


def _affine_frame(nodes, body, nbodies):
    """``dim + 1`` particles per body at which no nonzero linear function
    vanishes: the first particle, the farthest from it, then each time the
    one farthest from the line (plane) through those chosen."""
    dim = nodes.shape[0]
    chosen = []
    for b in range(nbodies):
        members = np.flatnonzero(body == b)
        if len(members) <= dim + 1:
            chosen.extend(members)
            continue
        X = nodes[:, members]
        frame = [0]
        for _ in range(dim):
            base = X[:, frame[0]][:, None]
            rel = X - base
            if len(frame) > 1:  # distance from the span of the chosen edges
                Q, _ = np.linalg.qr(X[:, frame[1:]] - base)
                rel = rel - Q @ (Q.T @ rel)
            frame.append(int(np.argmax(np.sum(rel ** 2, axis=0))))
        chosen.extend(members[frame])
    return np.array(chosen, dtype=np.int64)
