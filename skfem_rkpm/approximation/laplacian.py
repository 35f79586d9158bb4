"""Weighted graph Laplacians over particles: a semidefinite solve.

A symmetric matrix with zero row sums and non-positive off-diagonal entries
(the order-1 VCI balancing system of
:mod:`skfem_rkpm.approximation.integration`) is positive semidefinite, its
null space the vectors constant on each connected body.  It is solved as it
is, by conjugate gradients on its range, preconditioned by its diagonal plus
a coarse solve on aggregates of nearby particles: time and memory grow like
its nonzeros, and no fill is formed but the coarse one.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["AGGREGATE_SIDE", "laplacian_solve", "two_level_preconditioner"]

#: side of the grid cells whose particles (of one body) form one aggregate of
#: the coarse space of :func:`laplacian_solve`, in median support radii:
#: measured on the 17k rectangle of docs/benchmarks/basis_build.md, 1, 1.5
#: and 2 radii take 32-62, 40 and 48 iterations per right-hand side (Jacobi
#: alone 210-230)
AGGREGATE_SIDE = 1.5


def laplacian_solve(M, b, body, nbodies, nodes, radius, rtol, maxiter=1000):
    """Solve ``M x = b`` for a weighted graph Laplacian ``M`` over the
    particles: symmetric, positive semidefinite, its null space the vectors
    constant on each connected body (``body``, labels ``0 .. nbodies - 1``).

    Conjugate gradients on the semidefinite system itself, one right-hand
    side after the other, preconditioned by :func:`two_level_preconditioner`
    (the diagonal plus a coarse correction on aggregates of nearby
    particles): the part of ``b`` in the null space (zero up to round-off
    for a consistent system) is removed first, so that the iteration stays in
    the range of ``M``, and the solution is returned with zero mean on each
    body (any other constant per body solves it as well).  Each iteration is
    one product with ``M`` and one solve with the coarse matrix: time and
    memory grow like the nonzeros of ``M`` (about 40 iterations per
    right-hand side on the 17k rectangle of docs/benchmarks/basis_build.md),
    and no fill is formed but the coarse one.  The iteration
    stops at the relative residual ``rtol``, checked on ``b - M x`` itself.

    Raises
    ------
    RuntimeError
        If ``rtol`` is not reached in ``maxiter`` iterations (``M`` is then
        not a Laplacian with a positive diagonal).
    """
    n = M.shape[0]
    size = np.bincount(body, minlength=nbodies)

    def centred(v):  # the part of v orthogonal to the null space
        return v - (np.bincount(body, v, minlength=nbodies) / size)[body]

    precondition = two_level_preconditioner(M, body, nbodies, nodes,
                                            AGGREGATE_SIDE * np.median(radius))
    x = np.zeros(b.shape)
    for k in range(b.shape[1]):
        rhs = centred(b[:, k])
        target = rtol * np.sqrt(_inner(rhs, rhs))
        if target == 0.0:
            continue
        x[:, k] = _preconditioned_cg(M, rhs, precondition, target, maxiter)
        error = rhs - M @ x[:, k]
        residual = np.sqrt(_inner(error, error))
        # the true residual may exceed the recursive one CG stops on by a little
        if not residual <= 10 * target:
            raise RuntimeError(
                "VCI: conjugate gradients did not reach a relative residual of "
                f"{rtol:g} on the correction system ({n} unknowns, {maxiter} "
                f"iterations; reached {residual / target * rtol:.2g})")
        x[:, k] = centred(x[:, k])
    return x


def two_level_preconditioner(M, body, nbodies, nodes, side):
    """``r -> D⁻¹ r + Z E⁺ Zᵀ r`` for the Laplacian ``M``: its diagonal ``D``
    plus a coarse solve, ``Z`` the piecewise constant functions on
    aggregates (the particles of one body in one cell of a grid of the given
    ``side``), ``E = Zᵀ M Z`` the aggregates' Laplacian, factored (SuperLU)
    with one aggregate per body pinned (``E`` is singular like ``M``; ``E⁺``
    is then a symmetric generalized inverse, so the preconditioner stays
    symmetric positive definite on the range of ``M``).

    Raises
    ------
    RuntimeError
        If a diagonal entry of ``M`` is not positive.
    """
    diagonal = M.diagonal()
    if not np.all(diagonal > 0):
        I = int(np.flatnonzero(~(diagonal > 0))[0])
        raise RuntimeError(f"VCI: the correction system has a diagonal entry "
                           f"{diagonal[I]:g} <= 0 at unknown {I}")
    inverse_diagonal = 1.0 / diagonal
    n = M.shape[0]
    cell = np.floor((nodes - nodes.min(axis=1, keepdims=True)) / side).astype(np.int64)
    key = body.astype(np.int64)
    for k in range(nodes.shape[0]):
        key = key * (cell[k].max() + 1) + cell[k]
    _, aggregate = np.unique(key, return_inverse=True)
    aggregate = aggregate.ravel()
    naggregates = int(aggregate.max()) + 1
    Z = sp.csr_matrix((np.ones(n), aggregate, np.arange(n + 1)), shape=(n, naggregates))
    E = (Z.T @ (M @ Z)).tocsc()
    aggregate_body = np.zeros(naggregates, dtype=np.int64)
    aggregate_body[aggregate] = body
    free = np.ones(naggregates, dtype=bool)
    free[np.unique(aggregate_body, return_index=True)[1]] = False
    coarse = splu(E[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A") if free.any() \
        else None

    def precondition(r):
        z = inverse_diagonal * r
        if coarse is not None:
            y = np.zeros(naggregates)
            y[free] = coarse.solve(np.bincount(aggregate, r, minlength=naggregates)[free])
            z += y[aggregate]
        return z
    return precondition


def _preconditioned_cg(M, b, precondition, target, maxiter):
    """Conjugate gradients for ``M x = b`` from ``x = 0``, preconditioned by
    ``precondition`` (``r -> P⁻¹ r``), until the recursive residual's norm
    is at most ``target``.

    The inner products are numpy sums (:func:`_inner`), not BLAS dots, whose
    rounding depends on the number of threads: the result is the same
    whatever the threading, as with a factorization.
    """
    x = np.zeros_like(b)
    r = b.copy()
    z = precondition(r)
    direction = z.copy()
    rz = _inner(r, z)
    for _ in range(maxiter):
        q = M @ direction
        step = rz / _inner(direction, q)
        x += step * direction
        r -= step * q
        if np.sqrt(_inner(r, r)) <= target:
            break
        z = precondition(r)
        rz, previous = _inner(r, z), rz
        direction *= rz / previous
        direction += z
    return x


def _inner(u, v):
    """``u · v`` by numpy's pairwise sum: the same rounding on any number of
    threads (a BLAS dot splits the sum among its threads)."""
    return np.sum(u * v)
