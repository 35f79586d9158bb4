"""Small-strain linear elasticity on any basis, and its error norms.

The same functions run an :class:`~skfem_rkpm.RKBasis` and a scikit-fem
``Basis(mesh, ElementVector(...))``: the stiffness comes from the vectorized
:class:`~skfem_rkpm.Assembler`, tractions from the matching facet basis,
nodal displacements through the transformation method
(:func:`skfem_rkpm.solve`).  Used by the verification tests, the RKPM-vs-FEM
comparison example and the benchmarks.
"""

import numpy as np
from skfem import BilinearForm, LinearForm
from skfem.helpers import dot, sym_grad, trace

from ..assembly import Assembler, facet_basis, isotropic_tangent
from ..forms import asm
from ..solvers.constrained import solve

__all__ = ["lame", "stress_from_voigt", "nitsche_terms",
           "solve_elasticity", "error_norms"]


def lame(E, nu, plane="strain"):
    """Lamé constants (λ, μ) of the 2D model (``"strain"``, ``"stress"``) or 3D."""
    if not E > 0:
        raise ValueError(f"Young's modulus must be positive, not {E}")
    if not -1.0 < nu < 0.5:
        raise ValueError(f"Poisson's ratio must lie in (-1, 0.5), not {nu}")
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    if plane == "stress":
        lam = 2.0 * lam * mu / (lam + 2.0 * mu)
    elif plane not in ("strain", "3d"):
        raise ValueError(f"plane must be 'strain', 'stress' or '3d', not {plane!r}")
    return lam, mu


def stress_from_voigt(s):
    """(sxx, syy, sxy) of shape (3, ...) to the tensor of shape (2, 2, ...)."""
    return np.array([[s[0], s[2]], [s[2], s[1]]])


def _traction(u, lam, mu, n):
    """σ(u)·n for a DiscreteField ``u`` with gradient."""
    eps = sym_grad(u)
    sig = lam * trace(eps) * np.eye(2)[:, :, None, None] + 2.0 * mu * eps
    return np.einsum("ij...,j...->i...", sig, n)


def nitsche_terms(facet_basis, lam, mu, g, penalty=100.0):
    """Symmetric Nitsche terms that impose ``u = g`` weakly on a boundary.

    ``a(u, v) += -∫(σ(u)n)·v - ∫(σ(v)n)·u + β ∫ u·v`` and
    ``l(v) += -∫(σ(v)n)·g + β ∫ g·v`` with ``β = penalty (λ + 2μ) / h``.
    Unlike nodal prescription (transformation method), the test functions
    need not vanish on the boundary, so the method stays consistent.
    """
    def beta(w):
        return penalty * (lam + 2.0 * mu) / w.h

    @BilinearForm
    def a(u, v, w):
        return (-dot(_traction(u, lam, mu, w.n), v) - dot(_traction(v, lam, mu, w.n), u)
                + beta(w) * dot(u, v))

    @LinearForm
    def l(v, w):
        gx = g(np.asarray(w.x))
        return -dot(_traction(v, lam, mu, w.n), gx) + beta(w) * dot(gx, v)

    return asm(a, facet_basis), asm(l, facet_basis)


def solve_elasticity(basis, E, nu, plane="strain", displacement=None,
                     traction=None, body=None, dirichlet="nodal"):
    """Solve a small-strain elasticity problem; return the coefficients.

    Parameters
    ----------
    basis : RKBasis or skfem vector CellBasis
        A vector basis on a mesh with named boundaries.
    E, nu : float
        Young's modulus and Poisson's ratio.
    plane : {"strain", "stress"}
    displacement : dict, optional
        ``{boundary name: u(x)}``; ``u`` maps coordinates (2, n) to nodal
        values (2, n), prescribed at every particle/node of that boundary.
        A value ``(u(x), component)`` prescribes one component only.
    traction : dict, optional
        ``{boundary name: t(x)}`` with ``t`` mapping quadrature coordinates
        (2, ...) to the traction vector (2, ...).
    body : callable, optional
        Body force ``b(x)``, same shapes as a traction.
    dirichlet : {"nodal", "nitsche"}
        Prescribe displacements at the boundary particles (transformation
        method, Eq. 3.37) or weakly along the boundary (Nitsche; all
        components only).

    Returns
    -------
    ndarray
        The coefficient vector (generalized displacements for RK bases).
    """
    lam, mu = lame(E, nu, plane)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2))
    f = np.zeros(basis.N)
    for name, t in (traction or {}).items():
        load = LinearForm(lambda v, w, t=t: dot(t(np.asarray(w.x)), v))
        f += asm(load, facet_basis(basis, name))
    if body is not None:
        f += asm(LinearForm(lambda v, w: dot(body(np.asarray(w.x)), v)), basis)
    if dirichlet == "nitsche":
        for name, u in (displacement or {}).items():
            A, b = nitsche_terms(facet_basis(basis, name), lam, mu, u)
            K, f = K + A, f + b
        return solve(K, f, basis)
    if dirichlet != "nodal":
        raise ValueError(f"dirichlet must be 'nodal' or 'nitsche', not {dirichlet!r}")
    dofs, values = [], []
    for name, spec in (displacement or {}).items():
        u, comps = spec if isinstance(spec, tuple) else (spec, (0, 1))
        D = _boundary_dofs(basis, name, comps)
        node, comp = np.divmod(D, 2)
        x = basis.doflocs[:, D]
        dofs.append(D)
        values.append(np.asarray(u(x))[comp, np.arange(len(D))])
    if dofs:
        return solve(K, f, basis, D=np.concatenate(dofs), x=np.concatenate(values))
    return solve(K, f, basis)


def _boundary_dofs(basis, name, comps):
    comps = np.atleast_1d(comps)
    if hasattr(basis, "element_nodes"):
        return basis.get_dofs(name, component=comps)
    return np.sort(basis.get_dofs(name).all([f"u^{c + 1}" for c in comps]))


def _without_rigid_motion(e, x, dx):
    """``e`` minus its L²-best rigid motion ``t + θ (-y, x)``."""
    modes = np.array([[np.ones_like(x[0]), np.zeros_like(x[0])],
                      [np.zeros_like(x[0]), np.ones_like(x[0])],
                      [-x[1], x[0]]])  # (3, 2, ...)
    G = np.einsum("acEq,bcEq,Eq->ab", modes, modes, dx)
    r = np.einsum("acEq,cEq,Eq->a", modes, e, dx)
    return e - np.einsum("a,ac...->c...", np.linalg.solve(G, r), modes)


def error_norms(basis, d, u_exact, stress_exact, E, nu, plane="strain",
                modulo_rigid=False):
    """Relative L² displacement and energy-norm errors at the quadrature points.

    Parameters
    ----------
    basis : RKBasis or skfem vector CellBasis
    d : ndarray
        Solution coefficients.
    u_exact : callable
        ``x -> (ux, uy)`` for coordinates (2, ...).
    stress_exact : callable
        ``x -> (sxx, syy, sxy)``.
    modulo_rigid : bool
        Remove the best-fitting rigid motion from the displacement error
        first (for problems loaded by tractions only, whose rigid motion is
        fixed arbitrarily at three dofs).

    Returns
    -------
    l2, energy : float
        ``‖u_h - u‖ / ‖u‖`` and ``‖σ_h - σ‖_E / ‖σ‖_E`` with the energy norm
        ``‖σ‖_E² = ∫ σ : C⁻¹ : σ``.
    """
    lam, mu = lame(E, nu, plane)
    field = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    dx = basis.dx
    u = np.asarray(u_exact(x))
    e = np.asarray(field) - u
    if modulo_rigid:
        e = _without_rigid_motion(e, x, dx)
    l2 = np.sqrt(np.sum(e**2 * dx) / np.sum(u**2 * dx))
    G = field.grad
    eps_h = 0.5 * (G + G.transpose(1, 0, 2, 3))
    sig = stress_from_voigt(np.asarray(stress_exact(x)))
    # strain of the exact stress: ε = (σ - λ/(2λ+2μ) tr σ I) / 2μ  (2D)
    tr = sig[0, 0] + sig[1, 1]
    eps = (sig - lam / (2.0 * lam + 2.0 * mu) * tr * np.eye(2)[:, :, None, None]) / (2 * mu)
    de = eps_h - eps
    tr_de = de[0, 0] + de[1, 1]
    energy_err = np.sum((lam * tr_de**2 + 2 * mu * np.einsum("ij...,ij...->...", de, de)) * dx)
    energy_ref = np.sum(np.einsum("ij...,ij...->...", sig, eps) * dx)
    return float(l2), float(np.sqrt(energy_err / energy_ref))
