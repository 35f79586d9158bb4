"""Deformation gradients of plane strain, axisymmetric and 3D models.

The assembler delivers the (extended) displacement gradient ``H[c, l]`` at
every quadrature point from the material gradients of the shape functions,
built once (Eq. 3.30: ``F = I + Σ_I d_I ⊗ ∂Ψ_I/∂X``).  Every model is carried
in 3x3 algebra:

* ``plane_strain``: ``F = [[F_2x2, 0], [0, 1]]``;
* ``axisymmetric`` (x = R, y = Z): ``F_θθ = 1 + u_r/R`` from the hoop row;
* ``3d``: the full 3x3 gradient.

:func:`entries` lists which 3x3 entry ``(i, J)`` each assembler entry
``(c, l)`` stands for, so stresses and tangents go back the same way.
"""

import numpy as np

__all__ = ["MODELS", "entries", "deformation_gradient", "inverse_and_determinant",
           "to_assembler", "from_entries", "spatial_gradients"]

MODELS = ("plane_strain", "axisymmetric", "3d")


def entries(model):
    """Pairs ``((c, l), (i, J))``: assembler entry and the 3x3 entry it holds."""
    if model == "plane_strain":
        return [((c, l), (c, l)) for c in range(2) for l in range(2)]
    if model == "axisymmetric":
        return [((c, l), (c, l)) for c in range(2) for l in range(2)] + [((0, 2), (2, 2))]
    if model == "3d":
        return [((c, l), (c, l)) for c in range(3) for l in range(3)]
    raise ValueError(f"model must be one of {MODELS}, not {model!r}")


def deformation_gradient(H, model):
    """``F = I + H`` in 3x3 form, shape (n, 3, 3), from ``H`` (c, l, nelems, nqp)."""
    n = H[0, 0].size
    F = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    for (c, l), (i, J) in entries(model):
        F[:, i, J] += H[c, l].ravel()
    return F


def inverse_and_determinant(F):
    """Inverses (n, 3, 3) and determinants (n,) of 3x3 matrices ``F`` (n, 3, 3).

    By cofactors, ``F⁻¹ = adj(F) / det F`` with ``det F`` expanded along the
    first row: a few passes over arrays of the points instead of one LAPACK
    call per matrix (``np.linalg.inv`` and ``det`` cost 5-10 times more on
    thousands of 3x3 matrices).  For the deformation gradients of a
    simulation (``det F`` well away from 0) the results agree with LU to
    round-off; a singular ``F`` gives inf or NaN in its own entries.
    """
    f = F.transpose(1, 2, 0)  # entry (i, j) as an array over the points
    adj = np.empty_like(F)
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            # cofactor of entry (j, i) is the (i, j) entry of the adjugate
            adj[:, i, j] = f[j1, i1] * f[j2, i2] - f[j1, i2] * f[j2, i1]
    det = f[0, 0] * adj[:, 0, 0] + f[0, 1] * adj[:, 1, 0] + f[0, 2] * adj[:, 2, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        adj /= det[:, None, None]
    return adj, det


def to_assembler(P, A, model, shape):
    """Stress (n, 3, 3) and tangent (n, 3, 3, 3, 3) in assembler layout.

    Returns ``P_ext`` (c, l, nelems, nqp) and ``A_ext`` (c, l, c, l, nelems, nqp)
    (``A_ext`` is None if ``A`` is).
    """
    pairs = entries(model)
    ncomp = 3 if model == "3d" else 2
    nrows = 3 if model != "plane_strain" else 2
    P_ext = np.zeros((ncomp, nrows) + shape)
    for (c, l), (i, J) in pairs:
        P_ext[c, l] = P[:, i, J].reshape(shape)
    if A is None:
        return P_ext, None
    A_ext = np.zeros((ncomp, nrows, ncomp, nrows) + shape)
    for (c, l), (i, J) in pairs:
        for (d, m), (k, L) in pairs:
            A_ext[c, l, d, m] = A[:, i, J, k, L].reshape(shape)
    return P_ext, A_ext


def from_entries(P, A, model, shape):
    """Stress and tangent given at the model's entries, in assembler layout.

    ``P`` (n, m) and ``A`` (n, m, m) hold the 3x3 entries ``(i, J)`` of
    :func:`entries` in its order (``A[(i, J), (k, L)] = ∂P_iJ/∂F_kL``).
    Returns ``P_ext`` (c, l, nelems, nqp) and ``A_ext`` (c, l, c, l, nelems,
    nqp), the latter a transposed view of an array stored per point as
    (nelems, nqp, l, c, c, l), the layout :meth:`Assembler.local_bilinear`
    reads without a copy (``A_ext`` is None if ``A`` is).
    """
    pairs = entries(model)
    ncomp = 3 if model == "3d" else 2
    nrows = 3 if model != "plane_strain" else 2
    m = len(pairs)
    slot = np.full((ncomp, nrows), m)  # slot m holds a zero
    for k, ((c, l), _) in enumerate(pairs):
        slot[c, l] = k
    n = P.shape[0]
    P_pad = np.concatenate([P, np.zeros((n, 1))], axis=1)
    P_ext = P_pad[:, slot].reshape(shape + (ncomp, nrows)).transpose(2, 3, 0, 1)
    if A is None:
        return P_ext, None
    if m == ncomp * nrows and np.array_equal(slot.ravel(), np.arange(m)):
        # every (c, l) an entry, in row-major order (plane strain, 3D): a view
        # of A, copied once by the assembler, not padded and gathered
        A_points = A.reshape(n, ncomp, nrows, ncomp, nrows).transpose(0, 2, 1, 3, 4)
        return P_ext, A_points.reshape(shape + (nrows, ncomp, ncomp, nrows)).transpose(
            3, 2, 4, 5, 0, 1)
    A_pad = np.zeros((n, m + 1, m + 1))
    A_pad[:, :m, :m] = A
    rows = slot.T[:, :, None, None]  # (l, c) -> entry (c, l)
    cols = slot[None, None]  # (d, m) -> entry (d, m)
    A_points = A_pad[:, rows, cols].reshape(shape + (nrows, ncomp, ncomp, nrows))
    return P_ext, A_points.transpose(3, 2, 4, 5, 0, 1)


def spatial_gradients(grad_X, F):
    """Spatial gradients of Lagrangian shape functions, Eq. (3.29).

    ``∂Ψ/∂x_i = ∂Ψ/∂X_j F⁻¹_ji`` with ``F⁻¹`` from Eq. (3.30).

    Parameters
    ----------
    grad_X : ndarray, shape (dim, ..., n)
        Material gradients at n points.
    F : ndarray, shape (n, dim, dim)
    """
    return np.einsum("j...n,nji->i...n", grad_X, np.linalg.inv(F))
