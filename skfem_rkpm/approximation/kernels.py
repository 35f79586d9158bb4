"""Kernel (window) functions of the reproducing kernel approximation.

A kernel is a function of the normalized distance ``z = |X - X_I| / a_I``
(radial support) or of each normalized coordinate difference
``z_k = |X_k - X_kI| / a_I`` (box, tensor-product support), zero for
``z >= 1``.  It returns the value and its derivative with respect to ``z``.

The amplitude factor ``1/a`` of Eq. (3.12) is left out: it cancels in the
shape functions when all supports are equal, and with graded supports it
would only reweight the neighbours without improving the approximation.
"""

import numpy as np

__all__ = ["cubic_spline", "quartic_spline", "KERNELS", "get_kernel"]


def cubic_spline(z):
    """Cubic B-spline window of Eq. (3.12), without its ``1/a`` factor.

    Parameters
    ----------
    z : ndarray
        Normalized distances, ``z >= 0``.

    Returns
    -------
    phi, dphi : ndarray
        ``φ(z)`` and ``dφ/dz``; both vanish for ``z >= 1``.
    """
    z = np.asarray(z, dtype=float)
    # Eq. (3.12) in truncated powers: φ = 4/3 [(1 - z)₊³ - 4 (1/2 - z)₊³]
    u = np.maximum(1.0 - z, 0.0)
    v = np.maximum(0.5 - z, 0.0)
    u2, v2 = u * u, v * v
    phi = (4.0 / 3.0) * (u2 * u - 4.0 * (v2 * v))
    dphi = -4.0 * (u2 - 4.0 * v2)
    return phi, dphi


def quartic_spline(z):
    """Quartic spline window ``φ(z) = 1 - 6z² + 8z³ - 3z⁴`` on ``z < 1``.

    It is C² at ``z = 1`` and C∞ inside, the common alternative to
    Eq. (3.12).

    Parameters
    ----------
    z : ndarray
        Normalized distances, ``z >= 0``.

    Returns
    -------
    phi, dphi : ndarray
        ``φ(z)`` and ``dφ/dz``; both vanish for ``z >= 1``.
    """
    z = np.asarray(z, dtype=float)
    inside = z < 1.0
    phi = np.where(inside, 1.0 - 6.0 * z**2 + 8.0 * z**3 - 3.0 * z**4, 0.0)
    dphi = np.where(inside, -12.0 * z + 24.0 * z**2 - 12.0 * z**3, 0.0)
    return phi, dphi


KERNELS = {"cubic": cubic_spline, "quartic": quartic_spline}


def get_kernel(name):
    """Return the kernel function registered under ``name``.

    Raises
    ------
    ValueError
        If ``name`` is unknown; the message lists the known kernels.
    """
    if callable(name):
        return name
    try:
        return KERNELS[name]
    except KeyError:
        raise ValueError(
            f"unknown kernel {name!r}; choose one of {sorted(KERNELS)} "
            "or pass a function z -> (phi, dphi)"
        ) from None
