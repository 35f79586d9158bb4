"""Compiled kernel of :func:`skfem_rkpm.approximation.shape.rk_shape_functions` (needs numba).

The same table as the numpy path in :mod:`skfem_rkpm.approximation.shape`, entry by entry:
the pairs of each point in increasing particle order, the same formulas for
the kernel, the monomials, the moment matrix, its Gauss-Jordan inverse, the
reciprocal condition number, the values and the gradients.  Only the order
of a few sums differs (numpy sums long segments pairwise), so values agree
to round-off, not bit for bit.

Two compiled passes, one point at a time:

1. :func:`_find_pairs` bins the particles on a uniform grid whose cells are
   at least as large as the largest support radius (a cell list); the
   particles that can cover a point lie in the 3^dim cells around it.  Each
   candidate is kept if the point lies strictly inside its own support, the
   kept particles are sorted by index, and the pair lists of all points go
   into one growing array; one search per pair.
2. :func:`_fill` computes, for each point, the kernel, ``H``, ``M`` and its
   inverse, the values and the gradients into arrays allocated once with
   the exact number of pairs.

Everything runs on one core.  ``cache=True`` stores the machine code next to
this file (``__pycache__``), so only the first call after installing pays
the compilation (see docs/benchmarks/shape_and_assembly.md, "Compiled kernel (optional)").
"""

import numpy as np
from numba import njit

__all__ = ["KERNEL_CODES", "SUPPORT_CODES", "pair_table", "build"]

#: kernels the compiled path knows, by name (see :mod:`skfem_rkpm.approximation.kernels`)
KERNEL_CODES = {"cubic": 0, "quartic": 1}
#: support shapes, as in :func:`skfem_rkpm.approximation.shape.find_pairs`
SUPPORT_CODES = {"radial": 0, "box": 1}

_OPTIONS = dict(cache=True, nogil=True, error_model="numpy")


@njit(**_OPTIONS)
def _kernel(z, code):
    """φ(z) and dφ/dz of :func:`~skfem_rkpm.approximation.kernels.cubic_spline` (code 0)
    or :func:`~skfem_rkpm.approximation.kernels.quartic_spline` (code 1)."""
    if code == 0:
        u = max(1.0 - z, 0.0)
        v = max(0.5 - z, 0.0)
        u2 = u * u
        v2 = v * v
        return (4.0 / 3.0) * (u2 * u - 4.0 * (v2 * v)), -4.0 * (u2 - 4.0 * v2)
    if z < 1.0:
        z2 = z * z
        z3 = z2 * z
        return (1.0 - 6.0 * z2 + 8.0 * z3 - 3.0 * (z2 * z2),
                -12.0 * z + 24.0 * z2 - 12.0 * z3)
    return 0.0, 0.0


@njit(**_OPTIONS)
def _find_pairs(x, nodes, radius, box, axes):
    """CSR pair lists of points ``x`` (n, dim) in the supports of particles
    ``nodes`` (N, dim), indices sorted per point.

    ``axes`` is ``tuple(range(dim))``: its length, known when compiling,
    makes ``dim`` a constant.  Returns ``(indptr, indices)``.
    """
    dim = len(axes)
    npoints = x.shape[0]
    nnodes = nodes.shape[0]
    # cells of side bs >= the largest radius over the particles' bounding
    # box; the margin keeps round-off in (X - lo) / bs from moving a
    # particle closer than bs out of the 3^dim cells around a point
    bs = radius.max() * (1.0 + 1e-4)
    lo = np.zeros(3)
    span = np.zeros(3)
    for k in range(dim):
        lo[k] = nodes[0, k]
        hi = nodes[0, k]
        for i in range(nnodes):
            lo[k] = min(lo[k], nodes[i, k])
            hi = max(hi, nodes[i, k])
        span[k] = hi - lo[k]
    # at most about two cells per particle: coarser cells when the
    # particles are sparse compared to their supports
    cap = 2.0 * nnodes + 8.0
    for k in range(dim):
        bs = max(bs, span[k] / cap)
    for _ in range(10000):  # bounded: extents are finite (see build)
        total = 1.0
        for k in range(dim):
            total *= np.floor(span[k] / bs) + 1.0
        if total <= cap:
            break
        bs *= 1.25
    nb = np.ones(3, np.int64)
    for k in range(dim):
        nb[k] = np.int64(np.floor(span[k] / bs)) + 1
    ncells = nb[0] * nb[1] * nb[2]

    # counting sort of the particles by cell (stable: by index in a cell)
    cell = np.empty(nnodes, np.int64)
    start = np.zeros(ncells + 1, np.int64)
    for i in range(nnodes):
        c = 0
        for k in range(3):
            ck = 0
            if k < dim:
                ck = min(max(np.int64((nodes[i, k] - lo[k]) / bs), 0), nb[k] - 1)
            c = c * nb[k] + ck
        cell[i] = c
        start[c + 1] += 1
    for c in range(ncells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(nnodes, np.int64)
    for i in range(nnodes):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    # the particles in cell order, one row each: coordinates, radius,
    # squared radius with a margin (r² above it means sqrt(r²) >= a for
    # sure), index; one cache line holds all a candidate needs
    packed = np.empty((nnodes, dim + 3))
    for s in range(nnodes):
        i = order[s]
        for k in range(dim):
            packed[s, k] = nodes[i, k]
        packed[s, dim] = radius[i]
        packed[s, dim + 1] = radius[i] * radius[i] * (1.0 + 1e-12)
        packed[s, dim + 2] = i

    indptr = np.empty(npoints + 1, np.int64)
    indptr[0] = 0
    capacity = max(16 * npoints, 1024)
    indices = np.empty(capacity, np.int64)
    found = np.empty(nnodes, np.int64)
    first = np.zeros(3, np.int64)
    last = np.zeros(3, np.int64)
    d = np.zeros(3)
    n = 0
    for q in range(npoints):
        cnt = 0
        empty = False
        for k in range(dim):
            f = (x[q, k] - lo[k]) / bs
            if not (f > -2.0 and f < nb[k] + 1.0):
                empty = True  # far outside (or NaN): no cell in reach
                break
            ck = np.int64(np.floor(f))
            first[k] = max(ck - 1, 0)
            last[k] = min(ck + 1, nb[k] - 1)
            if first[k] > last[k]:
                empty = True
        if not empty:
            for c0 in range(first[0], last[0] + 1):
                for c1 in range(first[1], last[1] + 1):
                    base = (c0 * nb[1] + c1) * nb[2]
                    for c2 in range(first[2], last[2] + 1):
                        c = base + c2
                        for s in range(start[c], start[c + 1]):
                            for k in range(dim):
                                d[k] = x[q, k] - packed[s, k]
                            if box:
                                r = 0.0
                                for k in range(dim):
                                    r = max(r, abs(d[k]))
                            else:
                                # the distance as the KD-tree of the numpy
                                # path computes it: sqrt of the sum in order
                                r2 = 0.0
                                for k in range(dim):
                                    r2 += d[k] * d[k]
                                if r2 > packed[s, dim + 1]:
                                    continue
                                r = np.sqrt(r2)
                            if r < packed[s, dim]:
                                # insertion into the sorted list of the point
                                i = np.int64(packed[s, dim + 2])
                                j = cnt
                                while j > 0 and found[j - 1] > i:
                                    found[j] = found[j - 1]
                                    j -= 1
                                found[j] = i
                                cnt += 1
        if n + cnt > capacity:
            capacity = max(2 * capacity, n + cnt)
            grown = np.empty(capacity, np.int64)
            grown[:n] = indices[:n]
            indices = grown
        for j in range(cnt):
            indices[n + j] = found[j]
        n += cnt
        indptr[q + 1] = n
    return indptr, indices[:n].copy()


@njit(**_OPTIONS)
def _fill(x, particles, indptr, indices, kcode, box, axes, basis, build,
          lptr, lj, le, llow, gradients, values, grads, rcond, window):
    """Values, gradients, kernel weights and reciprocal condition numbers per point.

    The formulas and the order of the operations are those of
    :func:`skfem_rkpm.approximation.shape._build` (``_kernel_weights``, ``_monomials``,
    ``_moment_matrices``, ``_batched_inverse``, ``_rcond``,
    ``_moment_solve``), one point at a time.  The points are taken in their
    own order: the result is written as it is laid out in memory.  Row ``I``
    of ``particles`` is ``X_I`` followed by ``a_I``.

    ``axes = tuple(range(dim))`` and ``basis = tuple(range(m))``: their
    lengths are constants of the compiled code (one specialization per
    dimension and basis size, so that the short loops unroll).  Row ``j`` of
    ``build`` is ``(j, k, l)``, ``H_j = ξ_k H_l`` (row 0 unused); the terms
    ``∂H_j/∂ξ_k = e H_l`` are ``lj, le, llow[lptr[k]:lptr[k + 1]]``.
    """
    npoints = x.shape[0]
    dim = len(axes)
    m = len(basis)
    maxc = 0
    for q in range(npoints):
        maxc = max(maxc, indptr[q + 1] - indptr[q])
    phi = np.empty(maxc)
    dphi = np.empty((maxc, dim))
    diff = np.empty((maxc, dim))
    H = np.empty((maxc, m))
    c = np.empty(maxc)
    d = np.empty(3)
    pk = np.empty(3)
    dpk = np.empty(3)
    A = np.empty((m, 2 * m))
    b = np.empty(m)
    v = np.empty((dim, m))
    V = np.empty(m)
    bk = np.empty((dim, m))
    for q in range(npoints):
        lo = indptr[q]
        cnt = indptr[q + 1] - lo
        # kernel and its gradient (_kernel_weights); s = largest support
        s = particles[indices[lo], dim]
        for p in range(cnt):
            node = indices[lo + p]
            a = particles[node, dim]
            s = max(s, a)
            for k in range(dim):
                d[k] = x[q, k] - particles[node, k]
            if box:
                for k in range(dim):
                    pk[k], dpk[k] = _kernel(abs(d[k]) / a, kcode)
                ph = pk[0]
                for k in range(1, dim):
                    ph = ph * pk[k]
                phi[p] = ph
                window[lo + p] = ph
                for k in range(dim):
                    others = 1.0
                    first = True
                    for l in range(dim):
                        if l != k:
                            others = pk[l] if first else others * pk[l]
                            first = False
                    sign = 1.0 if d[k] > 0 else (-1.0 if d[k] < 0 else 0.0)
                    dphi[p, k] = dpk[k] * sign / a * others
            else:
                r2 = 0.0
                for k in range(dim):
                    r2 += d[k] * d[k]
                r = np.sqrt(r2)
                ph, dph = _kernel(r / a, kcode)
                phi[p] = ph
                window[lo + p] = ph
                scale = dph / (a * r) if r > 0 else 0.0
                for k in range(dim):
                    dphi[p, k] = scale * d[k]
            for k in range(dim):
                diff[p, k] = d[k]
        inv_s = 1.0 / s
        # monomials (_monomials): H_j = H_l ξ_k, ξ = (X - X_I) / s
        for p in range(cnt):
            H[p, 0] = 1.0
            for j in range(1, m):
                H[p, j] = H[p, build[j, 2]] * (diff[p, build[j, 1]] * inv_s)
        # moment matrix (_moment_matrices): the upper triangle summed over
        # the pairs in order (all entries at once), then mirrored
        for i in range(m):
            for j in range(2 * m):
                A[i, j] = 1.0 if j == m + i else 0.0
        for p in range(cnt):
            for i in range(m):
                hi = H[p, i]
                for j in range(i, m):
                    A[i, j] += hi * (H[p, j] * phi[p])
        for i in range(m):
            for j in range(i + 1, m):
                A[j, i] = A[i, j]
        # 1-norm of M before the elimination overwrites it (_rcond)
        norm = 0.0
        for j in range(m):
            col = 0.0
            for i in range(m):
                col += abs(A[i, j])
            if col > norm or col != col:
                norm = col
            if norm != norm:
                break
        # Gauss-Jordan without pivoting (_batched_inverse)
        for i in range(m):
            pivot = A[i, i]
            for j in range(2 * m):
                A[i, j] = A[i, j] / pivot
            for r in range(m):
                if r != i:
                    f = A[r, i]
                    for j in range(2 * m):
                        A[r, j] -= f * A[i, j]
        inorm = 0.0
        for j in range(m):
            col = 0.0
            for i in range(m):
                col += abs(A[i, m + j])
            if col > inorm or col != col:
                inorm = col
            if inorm != inorm:
                break
        rcond[q] = 1.0 / (norm * inorm)
        # values (_moment_solve): b = M⁻¹ H(0), Ψ_I = H_Iᵀ b φ_I
        for j in range(m):
            b[j] = A[j, m]
        for p in range(cnt):
            acc = 0.0
            for j in range(m):
                acc += H[p, j] * b[j]
            c[p] = acc
            values[lo + p] = acc * phi[p]
        if not gradients:
            continue
        # gradients: t = ∂(H_Iᵀ b)/∂X_k φ_I + H_Iᵀ b ∂φ_I/∂X_k with b fixed,
        # v = M_,k b summed over the pairs, then b_,k = -M⁻¹ v
        for k in range(dim):
            for j in range(m):
                v[k, j] = 0.0
        for p in range(cnt):
            cphi_s = values[lo + p] * inv_s
            for k in range(dim):
                ck = 0.0
                for t in range(lptr[k], lptr[k + 1]):
                    ck += (le[t] * b[lj[t]]) * H[p, llow[t]]
                ck *= inv_s
                tk = ck * phi[p] + c[p] * dphi[p, k]
                for j in range(m):
                    V[j] = H[p, j] * tk
                for t in range(lptr[k], lptr[k + 1]):
                    V[lj[t]] += (le[t] * cphi_s) * H[p, llow[t]]
                for j in range(m):
                    v[k, j] += V[j]
                grads[k, lo + p] = tk
        for k in range(dim):
            for i in range(m):
                acc = 0.0
                for j in range(m):
                    acc += A[i, m + j] * v[k, j]
                bk[k, i] = -acc
        for p in range(cnt):
            for k in range(dim):
                acc = 0.0
                for j in range(m):
                    acc += H[p, j] * bk[k, j]
                grads[k, lo + p] = acc * phi[p] + grads[k, lo + p]


def _recurrences(build, lowered):
    """:func:`~skfem_rkpm.approximation.shape._monomial_recurrences` as arrays for
    :func:`_fill`."""
    build = np.array([(0, 0, 0)] + list(build), dtype=np.int64).reshape(-1, 3)
    assert np.array_equal(build[:, 0], np.arange(len(build)))
    lptr = np.cumsum([0] + [len(terms) for terms in lowered]).astype(np.int64)
    flat = [term for terms in lowered for term in terms] or [(0, 0.0, 0)]
    lj = np.array([j for j, _, _ in flat], dtype=np.int64)
    le = np.array([e for _, e, _ in flat], dtype=float)
    llow = np.array([low for _, _, low in flat], dtype=np.int64)
    return build, lptr, lj, le, llow


def build(x, nodes, radius, build, lowered, kernel, support, gradients):
    """Table arrays of :func:`~skfem_rkpm.approximation.shape.rk_shape_functions`.

    ``x`` (dim, npoints), ``nodes`` (dim, nnodes), ``radius`` (nnodes,);
    ``build, lowered`` from :func:`~skfem_rkpm.approximation.shape._monomial_recurrences`.
    Returns ``(indptr, indices, values, grads, rcond, kernel)`` (``kernel``:
    the window φ of each pair), or ``(indptr, indices, None, None, None,
    None)`` if a point is covered by fewer than ``m``
    particles (the numpy path then reports it), or None if the particles
    span more than the float range (the numpy path then handles them).
    """
    dim = x.shape[0]
    m = len(build) + 1
    with np.errstate(over="ignore"):
        cells_ok = (np.isfinite(np.ptp(nodes, axis=1)).all()
                    and np.isfinite(radius.max() * (1.0 + 1e-4)))
    if not cells_ok:
        return None  # extents beyond the float range: the numpy path
    xt = np.ascontiguousarray(x.T, dtype=float)
    nt = np.ascontiguousarray(nodes.T, dtype=float)
    radius = np.ascontiguousarray(radius, dtype=float)
    indptr, indices = find_pairs(xt, nt, radius, support)
    if np.diff(indptr).min(initial=m) < m:
        return indptr, indices, None, None, None, None
    npoints, npairs = x.shape[1], len(indices)
    values = np.empty(npairs)
    grads = np.empty((dim, npairs) if gradients else (dim, 0))
    rcond = np.empty(npoints)
    window = np.empty(npairs)
    _fill(xt, np.column_stack([nt, radius]), indptr, indices, KERNEL_CODES[kernel],
          SUPPORT_CODES[support] == 1, tuple(range(dim)), tuple(range(m)),
          *_recurrences(build, lowered), gradients, values, grads, rcond, window)
    return indptr, indices, values, grads if gradients else None, rcond, window


def find_pairs(x, nodes, radius, support):
    """The compiled neighbour search on pair-major arrays ``x`` (n, dim),
    ``nodes`` (N, dim): CSR ``(indptr, indices)`` (a module attribute so
    that benchmarks can time it)."""
    return _find_pairs(x, nodes, radius, SUPPORT_CODES[support] == 1,
                       tuple(range(x.shape[1])))


def pair_table(x, nodes, radius, support="radial"):
    """CSR pairs ``(indptr, indices)`` as the numpy path finds them.

    ``x`` (dim, npoints) and ``nodes`` (dim, nnodes) as in
    :func:`~skfem_rkpm.approximation.shape.rk_shape_functions`, ``radius`` (nnodes,).
    """
    return find_pairs(np.ascontiguousarray(np.asarray(x, dtype=float).T),
                      np.ascontiguousarray(np.asarray(nodes, dtype=float).T),
                      np.ascontiguousarray(radius, dtype=float), support)
