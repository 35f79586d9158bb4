"""Eigenvalues and eigenvectors of many symmetric 3x3 matrices in closed form.

``np.linalg.eigh`` on thousands of 3x3 matrices makes one LAPACK call per
matrix; the return map of the finite-strain J2 model needs the spectral
decomposition of the trial ``b_e`` at every quadrature point and every
residual evaluation.  Here each step is a pass over arrays of the points:

1. the deviator ``A = b - m I`` (``m = tr b / 3``) and its scale
   ``p = sqrt(tr A² / 6)``;
2. Cardano's trigonometric solution ``e = 2 p cos(φ + 2πk/3)``,
   ``φ = acos(det(A/p)/2) / 3``, of which only the *isolated* root is kept:
   the largest if ``det A ≥ 0``, else the smallest; it lies at least
   ``√3 p`` from both others, so its value and its eigenvector (the
   largest cross product of two rows of ``A - e I``) are accurate to
   round-off of ``p`` even when the other two coincide;
3. the other two from the 2x2 matrix of ``A`` on an orthonormal basis of
   the plane orthogonal to that eigenvector, diagonalized by the rotation
   of angle ``½ atan2(2 a_uv, a_uu - a_vv)`` (Mohr's circle), which is exact
   for a repeated pair.

The vectors are orthonormal by construction, so isotropic functions
``Σ f(λ_A) n_A ⊗ n_A`` (the Kirchhoff stress, ``exp(2 ε_e)``) agree with
those of LAPACK's decomposition to round-off, whether eigenvalues are
distinct, nearly repeated or repeated (``tests/test_eigen3.py``).  The
order of the eigenvalues is not sorted.
"""

import numpy as np

__all__ = ["symmetric_eigen"]


def _cross(a, b):
    """Row-wise cross products of the component lists ``a``, ``b`` (3 arrays each)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def symmetric_eigen(b):
    """Eigenvalues (n, 3) and orthonormal eigenvectors (n, 3, 3) (columns)
    of symmetric ``b`` (n, 3, 3), as ``np.linalg.eigh`` gives them up to the
    order and the choice of vectors within repeated eigenvalues.

    Only the symmetric part is read (``b[:, i, j]`` for ``i <= j``).
    """
    b = np.asarray(b, dtype=float)
    n = b.shape[0]
    m = (b[:, 0, 0] + b[:, 1, 1] + b[:, 2, 2]) / 3.0
    a11, a22, a33 = b[:, 0, 0] - m, b[:, 1, 1] - m, b[:, 2, 2] - m
    a12, a13, a23 = b[:, 0, 1], b[:, 0, 2], b[:, 1, 2]
    p = np.sqrt((a11 * a11 + a22 * a22 + a33 * a33) / 6.0
                + (a12 * a12 + a13 * a13 + a23 * a23) / 3.0)
    flat = ~(p > 0.0)  # b = m I (or not finite): every vector is an eigenvector
    inv_p = 1.0 / np.where(flat, 1.0, p)
    # B = A / p, tr B² = 6: det B / 2 lies in [-1, 1] up to round-off
    b11, b22, b33 = a11 * inv_p, a22 * inv_p, a33 * inv_p
    b12, b13, b23 = a12 * inv_p, a13 * inv_p, a23 * inv_p
    det = (b11 * (b22 * b33 - b23 * b23) - b12 * (b12 * b33 - b23 * b13)
           + b13 * (b12 * b23 - b22 * b13))
    r = np.clip(0.5 * det, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    # the isolated root of B: the largest (2 cos φ) if r >= 0, else the smallest
    upper = r >= 0.0
    e = np.where(upper, 2.0 * np.cos(phi), 2.0 * np.cos(phi + 2.0 * np.pi / 3.0))
    # its eigenvector: the largest cross product of two rows of B - e I
    rows = ((b11 - e, b12, b13), (b12, b22 - e, b23), (b13, b23, b33 - e))
    candidates = [_cross(rows[0], rows[1]), _cross(rows[0], rows[2]),
                  _cross(rows[1], rows[2])]
    sizes = np.stack([_dot(c, c) for c in candidates])
    best = np.argmax(sizes, axis=0)
    size = np.sqrt(np.take_along_axis(sizes, best[None], axis=0)[0])
    lost = flat | ~(size > 0.0)
    scale = 1.0 / np.where(lost, 1.0, size)
    w = [np.choose(best, [c[k] for c in candidates]) * scale for k in range(3)]
    w[0] = np.where(lost, 1.0, w[0])
    w[1] = np.where(lost, 0.0, w[1])
    w[2] = np.where(lost, 0.0, w[2])
    # an orthonormal basis (u, v) of the plane orthogonal to w
    axis = np.argmin(np.abs(np.stack(w)), axis=0)
    unit = [(axis == k).astype(float) for k in range(3)]
    u = _cross(w, unit)
    u_size = 1.0 / np.sqrt(_dot(u, u))
    u = [c * u_size for c in u]
    v = _cross(w, u)

    def apply(x):  # A x, with A = p B
        return (a11 * x[0] + a12 * x[1] + a13 * x[2], a12 * x[0] + a22 * x[1] + a23 * x[2],
                a13 * x[0] + a23 * x[1] + a33 * x[2])

    Au, Av = apply(u), apply(v)
    a_uu, a_uv, a_vv = _dot(u, Au), _dot(u, Av), _dot(v, Av)
    half_difference = 0.5 * (a_uu - a_vv)
    angle = 0.5 * np.arctan2(a_uv, half_difference)
    c, s = np.cos(angle), np.sin(angle)
    mean = 0.5 * (a_uu + a_vv)
    radius = np.hypot(half_difference, a_uv)
    lam = np.empty((n, 3))
    lam[:, 0] = m + _dot(w, apply(w))
    lam[:, 1] = m + mean + radius
    lam[:, 2] = m + mean - radius
    vec = np.empty((n, 3, 3))
    for k in range(3):
        vec[:, k, 0] = w[k]
        vec[:, k, 1] = c * u[k] + s * v[k]
        vec[:, k, 2] = c * v[k] - s * u[k]
    return lam, vec
