"""Closed-form solutions used as references: Poisson on the unit square,
plane linear elasticity (Timoshenko's cantilever, Kirsch's plate with a
hole) and the homogeneous uniaxial compression of the finite-strain J2
model.

All functions take coordinates ``x`` of shape ``(2, ...)`` (``x[0]`` and
``x[1]`` may have any common shape, e.g. the ``(nelems, nqp)`` quadrature
points of a scikit-fem form) and return arrays whose first axis holds the
components: ``(ux, uy)`` for displacements and ``(sxx, syy, sxy)`` for the
in-plane stresses.  The thickness is 1.

``plane="stress"`` or ``plane="strain"`` selects the two-dimensional model.
Plane strain is obtained from the plane stress formulas with the effective
constants ``E' = E / (1 - nu**2)`` and ``nu' = nu / (1 - nu)``.  The in-plane
stresses of these solutions do not depend on the material.

References
----------
S. P. Timoshenko and J. N. Goodier, *Theory of Elasticity*, 3rd ed.,
McGraw-Hill, 1970, sections 21 (cantilever) and 35 (circular hole).
"""

from collections import namedtuple

import numpy as np
from scipy.optimize import brentq

__all__ = [
    "UniaxialState",
    "uniaxial_compression",
    "effective_constants",
    "timoshenko_displacement",
    "timoshenko_stress",
    "kirsch_displacement",
    "kirsch_stress",
    "sine_poisson",
]


def sine_poisson(x):
    """``(u, f)`` of ``-Δu = f`` on the unit square with ``u = 0`` on its
    boundary: ``u = sin πx sin πy``, ``f = 2π² u``."""
    u = np.sin(np.pi * x[0]) * np.sin(np.pi * x[1])
    return u, 2.0 * np.pi ** 2 * u


def effective_constants(E, nu, plane="stress"):
    """Young's modulus and Poisson's ratio of the plane stress formulas.

    Parameters
    ----------
    E, nu : float
        Young's modulus and Poisson's ratio of the material.
    plane : {"stress", "strain"}
        Two-dimensional model.

    Returns
    -------
    E_eff, nu_eff : float
        ``(E, nu)`` for plane stress, ``(E / (1 - nu**2), nu / (1 - nu))``
        for plane strain.
    """
    if plane == "stress":
        return E, nu
    if plane == "strain":
        return E / (1.0 - nu**2), nu / (1.0 - nu)
    raise ValueError(f"plane must be 'stress' or 'strain', got {plane!r}")


def _coordinates(x):
    return np.asarray(x[0], dtype=float), np.asarray(x[1], dtype=float)


# ---------------------------------------------------------------------------
# cantilever beam
# ---------------------------------------------------------------------------


def timoshenko_displacement(x, L, D, P, E, nu, plane="stress"):
    """Displacement of the Timoshenko cantilever beam.

    The beam occupies ``0 <= x <= L``, ``-D/2 <= y <= D/2``.  It is clamped
    at ``x = 0`` and loaded at its free end ``x = L`` by a parabolic shear
    traction ``t_y = P / (2 I) (D**2 / 4 - y**2)`` with resultant ``P``
    along ``+y`` (``I = D**3 / 12``); the edges ``y = +-D/2`` are traction
    free.  For ``P > 0`` the beam bends upwards.

    The displacement is

    ``ux = -P y / (6 E I) [(6 L - 3 x) x + (2 + nu) (y**2 - D**2 / 4)]``

    ``uy = P / (6 E I) [3 nu y**2 (L - x) + (4 + 5 nu) D**2 x / 4
    + (3 L - x) x**2]``

    The clamp is the classical one of the exact solution: at ``x = 0`` the
    centre point is fixed (``ux = uy = 0`` at ``y = 0``) and the top and
    bottom points do not move horizontally (``ux = 0`` at ``y = +-D/2``).
    The rest of the end section warps, so a numerical model must prescribe
    this exact displacement on the whole edge ``x = 0`` to reproduce it.

    Parameters
    ----------
    x : array_like
        Coordinates, shape ``(2, ...)``.
    L, D : float
        Length and depth of the beam.
    P : float
        Resultant of the end load (along ``+y``).
    E, nu : float
        Young's modulus and Poisson's ratio.
    plane : {"stress", "strain"}
        Two-dimensional model.

    Returns
    -------
    ndarray
        ``(ux, uy)``, shape ``(2, ...)``.
    """
    E, nu = effective_constants(E, nu, plane)
    X, Y = _coordinates(x)
    c = P / (6.0 * E * D**3 / 12.0)
    ux = -c * Y * ((6.0 * L - 3.0 * X) * X + (2.0 + nu) * (Y**2 - D**2 / 4.0))
    uy = c * (
        3.0 * nu * Y**2 * (L - X)
        + (4.0 + 5.0 * nu) * D**2 * X / 4.0
        + (3.0 * L - X) * X**2
    )
    return np.stack((ux, uy))


def timoshenko_stress(x, L, D, P):
    """Stress of the Timoshenko cantilever beam.

    Same setup as :func:`timoshenko_displacement`:

    ``sxx = -P (L - x) y / I``, ``syy = 0``,
    ``sxy = P / (2 I) (D**2 / 4 - y**2)``, with ``I = D**3 / 12``.

    Parameters
    ----------
    x : array_like
        Coordinates, shape ``(2, ...)``.
    L, D : float
        Length and depth of the beam.
    P : float
        Resultant of the end load (along ``+y``).

    Returns
    -------
    ndarray
        ``(sxx, syy, sxy)``, shape ``(3, ...)``.
    """
    X, Y = _coordinates(x)
    inertia = D**3 / 12.0
    sxx = -P * (L - X) * Y / inertia
    sxy = P / (2.0 * inertia) * (D**2 / 4.0 - Y**2)
    return np.stack((sxx, np.zeros_like(sxx), sxy))


# ---------------------------------------------------------------------------
# infinite plate with a circular hole
# ---------------------------------------------------------------------------


def _polar(x):
    X, Y = _coordinates(x)
    return np.hypot(X, Y), np.arctan2(Y, X)


def kirsch_stress(x, a, T):
    """Stress in an infinite plate with a circular hole (Kirsch).

    The hole of radius ``a`` is centred at the origin and traction free;
    far away the stress is a uniaxial tension ``sxx = T``.  With polar
    coordinates ``(r, theta)``:

    ``sxx = T [1 - a**2 / r**2 (3/2 cos 2θ + cos 4θ) + 3 a**4 / (2 r**4) cos 4θ]``

    ``syy = T [-a**2 / r**2 (1/2 cos 2θ - cos 4θ) - 3 a**4 / (2 r**4) cos 4θ]``

    ``sxy = T [-a**2 / r**2 (1/2 sin 2θ + sin 4θ) + 3 a**4 / (2 r**4) sin 4θ]``

    The values are meaningless inside the hole (``r < a``).

    Parameters
    ----------
    x : array_like
        Coordinates, shape ``(2, ...)``.
    a : float
        Radius of the hole.
    T : float
        Remote tension along x.

    Returns
    -------
    ndarray
        ``(sxx, syy, sxy)``, shape ``(3, ...)``.
    """
    r, theta = _polar(x)
    q2, q4 = (a / r) ** 2, 1.5 * (a / r) ** 4
    c2, c4 = np.cos(2.0 * theta), np.cos(4.0 * theta)
    s2, s4 = np.sin(2.0 * theta), np.sin(4.0 * theta)
    sxx = T * (1.0 - q2 * (1.5 * c2 + c4) + q4 * c4)
    syy = T * (-q2 * (0.5 * c2 - c4) - q4 * c4)
    sxy = T * (-q2 * (0.5 * s2 + s4) + q4 * s4)
    return np.stack((sxx, syy, sxy))


def kirsch_displacement(x, a, T, E, nu, plane="stress"):
    """Displacement in an infinite plate with a circular hole (Kirsch).

    Same setup as :func:`kirsch_stress`.  With the shear modulus
    ``mu = E / (2 (1 + nu))`` and Kolosov's constant
    ``kappa = (3 - nu) / (1 + nu)`` (plane stress; ``3 - 4 nu`` in plane
    strain):

    ``ux = T a / (8 mu) [r/a (kappa + 1) cos θ + 2 a/r ((1 + kappa) cos θ
    + cos 3θ) - 2 a**3 / r**3 cos 3θ]``

    ``uy = T a / (8 mu) [r/a (kappa - 3) sin θ + 2 a/r ((1 - kappa) sin θ
    + sin 3θ) - 2 a**3 / r**3 sin 3θ]``

    The solution has no rigid body motion: ``uy = 0`` on ``y = 0`` and
    ``ux = 0`` on ``x = 0``, the symmetry conditions of a quarter model.

    Parameters
    ----------
    x : array_like
        Coordinates, shape ``(2, ...)``.
    a : float
        Radius of the hole.
    T : float
        Remote tension along x.
    E, nu : float
        Young's modulus and Poisson's ratio.
    plane : {"stress", "strain"}
        Two-dimensional model.

    Returns
    -------
    ndarray
        ``(ux, uy)``, shape ``(2, ...)``.
    """
    E, nu = effective_constants(E, nu, plane)
    mu = E / (2.0 * (1.0 + nu))
    kappa = (3.0 - nu) / (1.0 + nu)
    r, theta = _polar(x)
    c1, c3 = np.cos(theta), np.cos(3.0 * theta)
    s1, s3 = np.sin(theta), np.sin(3.0 * theta)
    k = T * a / (8.0 * mu)
    ux = k * (
        r / a * (kappa + 1.0) * c1
        + 2.0 * a / r * ((1.0 + kappa) * c1 + c3)
        - 2.0 * (a / r) ** 3 * c3
    )
    uy = k * (
        r / a * (kappa - 3.0) * s1
        + 2.0 * a / r * ((1.0 - kappa) * s1 + s3)
        - 2.0 * (a / r) ** 3 * s3
    )
    return np.stack((ux, uy))


UniaxialState = namedtuple("UniaxialState", "cauchy nominal alpha lateral_stretch")


def uniaxial_compression(reduction, E, nu, hardening):
    """Homogeneous uniaxial compression by ``reduction`` (0 ≤ δ < 1) of the
    log-strain J2 model of :class:`skfem_rkpm.mechanics.materials.J2Material`.

    Axial log strain ε = ln(1 - δ).  Elastic: τ = E ε.  Plastic: τ = -σ_y(ε̄ᵖ)
    with ε̄ᵖ + σ_y(ε̄ᵖ)/E = -ε.  Lateral log strain -ν τ/E + ε̄ᵖ/2 (isochoric
    plastic flow), so the volume change is J = exp((1 - 2ν) τ / E).

    Returns
    -------
    UniaxialState
        ``cauchy``: axial Cauchy stress τ/J; ``nominal``: axial force per unit
        initial area, τ/(1 - δ); ``alpha``: ε̄ᵖ; ``lateral_stretch``: the
        stretch of every lateral fibre (radius of a cylinder or ring).
    """
    eps = np.log(1.0 - reduction)
    if E * abs(eps) <= hardening.stress(0.0):
        tau, alpha = E * eps, 0.0
    else:
        alpha = brentq(lambda a: a + hardening.stress(a) / E + eps, 0.0, 5.0, xtol=1e-15)
        tau = -hardening.stress(alpha)
    lateral = -nu * tau / E + alpha / 2
    return UniaxialState(tau / np.exp(eps + 2 * lateral), tau / (1.0 - reduction), alpha,
                         np.exp(lateral))

