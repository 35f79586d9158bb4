"""The mass of a solid and the stable time step of central differences.

The paper's incremental equation of motion (Eq. 3.38),
``M̂ Δd̈ + K̂ Δd = f̂ext − f̂int``, carries the mass at nodal coordinates,
``M̂ = Λ⁻¹ M Λ⁻ᵀ``, where ``M = ∫ ρ Ψ_I Ψ_J dΩ δ_ij`` is the mass of the
generalized coordinates and ``Λᵀ`` maps coefficients to nodal values
(Eq. 3.32-3.34; :attr:`RKBasis.nodal_matrix`).  This module computes:

- the consistent mass ``M`` on any basis the :class:`Assembler` reads (RK,
  FEM; plane strain, axisymmetric with the ``2πR`` measure, 3D);
- two lumped (diagonal) masses: the row sums of ``M`` (generalized
  coordinates) and the row sums of ``M̂`` (nodal coordinates);
- the critical time step ``2 / ω_max`` of the central-difference scheme
  with a lumped mass, exactly (the largest eigenvalue of ``M⁻¹K``) and as
  a safe bound that needs no eigenvalue solve (Gershgorin).

Everything here is Lagrangian: the mass is computed once in the reference
configuration, where ``ρ₀ dΩ₀`` is conserved.
"""

import numpy as np
import scipy.sparse as sp
from scipy.linalg import eigh, eigvals
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs, eigsh, splu

__all__ = ["consistent_mass", "lumped_mass", "nodal_lumped_mass", "dilatational_wave_speed",
           "largest_eigenvalue", "scaled_largest", "nodal_mass_matrix", "critical_time_step",
           "gershgorin_time_step"]


def _density(assembler, density):
    """``ρ`` at the quadrature points, checked positive and finite."""
    rho = np.broadcast_to(np.asarray(density, dtype=float), assembler.layout.dx.shape)
    bad = np.flatnonzero(~(np.isfinite(rho) & (rho > 0)))
    if bad.size:
        cell, point = np.unravel_index(bad[0], rho.shape)
        raise ValueError(f"density must be positive and finite; it is "
                         f"{rho[cell, point]!r} at point {point} of cell {cell} "
                         f"({bad.size} points in all)")
    return rho


def consistent_mass(assembler, density):
    """The consistent mass ``M_(Ii)(Jj) = ∫ ρ Ψ_I Ψ_J dΩ δ_ij`` of Eq. (3.38),
    in generalized coordinates.

    ``assembler`` is the :class:`~skfem_rkpm.assembly.Assembler` of the solid
    (``SolidProblem.assembler``: axisymmetric solids weigh ``dΩ`` by ``2πR``);
    ``density`` is a number or an array over its quadrature points.  Sparse,
    shape (N, N), symmetric positive definite for a basis whose functions are
    independent on the quadrature points.
    """
    return assembler.mass(_density(assembler, density))


def lumped_mass(assembler, density):
    """Row sums of the consistent mass: ``m_(Ii) = ∫ ρ Ψ_I dΩ`` (Eq. 3.38's
    ``M`` lumped in generalized coordinates).

    Since ``Σ_J Ψ_J = 1`` (the reproducing conditions, Eq. 2.29), the row sum
    ``Σ_J M_IJ`` is the integral of ``ρ Ψ_I``: computed here without forming
    ``M``.  It conserves the total mass, and a uniform body force gives the
    uniform acceleration exactly.  Shape (N,).
    """
    rho = _density(assembler, density)
    L = assembler.layout
    c, nloc, nelems = L.ncomp, *L.element_nodes.shape
    scalar = np.einsum("aeq,eq->ea", L.values, rho * L.dx)  # ∫_e ρ Ψ_a
    local = np.repeat(scalar[:, :, None], c, axis=2)        # the same for each component
    return assembler.scatter(local.reshape(nelems, nloc * c).T)


def nodal_lumped_mass(basis, assembler, density):
    """Row sums of the mass at nodal coordinates, ``M̂ = Λ⁻¹ M Λ⁻ᵀ`` (Eq. 3.38).

    ``Λᵀ 1 = 1`` because the functions sum to one at every particle
    (Eq. 3.34, ``Σ_I Ψ_I(X_J) = 1``), so ``M̂ 1 = Λ⁻¹ M 1``: the nodal lumped
    mass solves ``Λ m̂ = m`` with the generalized row sums ``m``
    (:func:`lumped_mass`).  For a FEM basis ``Λ = 1`` and the two agree.
    The total mass is conserved (``1ᵀ m̂ = (Λ⁻ᵀ 1)ᵀ m = 1ᵀ m``), but single
    entries may be small or negative where ``Λ`` is far from the identity:
    the caller checks (:func:`critical_time_step` refuses such a mass).
    """
    m = lumped_mass(assembler, density)
    nodal = getattr(basis, "nodal_matrix", None)  # Λᵀ
    if nodal is None:
        return m
    return splu(sp.csc_matrix(nodal.T)).solve(m)


def dilatational_wave_speed(material, density):
    """``c_d = sqrt((λ + 2μ) / ρ)``, the fastest elastic wave in an isotropic
    solid (the speed that bounds the explicit time step)."""
    if not (np.isfinite(density) and density > 0):
        raise ValueError(f"density must be positive and finite, not {density!r}")
    lam_2mu = material.K + 4.0 * material.G / 3.0
    return float(np.sqrt(lam_2mu / density))


def _checked_mass(m, N):
    m = np.asarray(m, dtype=float)
    if m.shape != (N,):
        raise ValueError(f"the lumped mass has shape {m.shape}; the stiffness has {N} rows")
    bad = np.flatnonzero(~(m > 0))
    if bad.size:
        raise ValueError(f"the lumped mass must be positive: dof {bad[0]} has "
                         f"{m[bad[0]]:.3g} ({bad.size} dofs in all); lump in generalized "
                         "coordinates (lumped_mass) or use the consistent mass")
    return m


def largest_eigenvalue(K, M, constrained=None):
    """Largest ``ω²`` of ``K x = ω² M x``: the square of the highest frequency
    of the discrete body.

    ``M`` is a lumped mass (a vector, the diagonal) or a sparse mass matrix:
    the nodal lumped mass ``m̂`` acts on coefficients as ``Λ diag(m̂) Λᵀ``
    (:func:`nodal_mass_matrix`).  ``constrained`` lists dofs held fixed (rows
    and columns dropped).  Small systems are solved densely; larger ones by
    Lanczos (symmetric ``K``) or Arnoldi (VCI, friction: the real part).
    """
    K = sp.csr_matrix(K)
    lumped = np.ndim(M) == 1
    M = sp.diags(_checked_mass(M, K.shape[0])) if lumped else sp.csr_matrix(M)
    if constrained is not None:
        keep = np.setdiff1d(np.arange(K.shape[0]), np.asarray(constrained, dtype=int))
        K, M = K[keep][:, keep], M[keep][:, keep]
    symmetric = abs(K - K.T).max() <= 1e-12 * abs(K).max()
    if K.shape[0] <= 600:
        if symmetric:
            return float(eigh(K.toarray(), M.toarray(), eigvals_only=True)[-1])
        return float(eigvals(K.toarray(), M.toarray()).real.max())
    if lumped and symmetric:
        return scaled_largest(K, M.diagonal())[0]
    if lumped:  # the symmetric scaling M^(-1/2) K M^(-1/2) needs no factorization
        scale = sp.diags(1.0 / np.sqrt(M.diagonal()))
        A = (scale @ K @ scale).tocsr()
        return float(eigs(A, k=1, which="LR", return_eigenvectors=False, tol=1e-10)[0].real)
    solve = splu(sp.csc_matrix(M)).solve
    A = LinearOperator(K.shape, matvec=lambda x: solve(K @ x), dtype=float)
    return float(eigs(A, k=1, which="LR", return_eigenvectors=False, tol=1e-10)[0].real)


def scaled_largest(K, m, start=None, tol=1e-10, ncv=None):
    """Largest eigenvalue and its eigenvector of ``M^(-1/2) K M^(-1/2)`` for a
    symmetric ``K`` and a lumped mass ``m`` (the largest ``ω²`` of ``M⁻¹K``):
    densely up to 600 rows, else by Lanczos started from ``start`` with
    ``ncv`` Lanczos vectors (ARPACK's default 20 if None; fewer cost fewer
    products from a start near the answer) (the best Ritz pair where it
    stops short of ``tol``).

    ``K`` is a sparse or dense matrix or a scipy ``LinearOperator`` (e.g.
    :meth:`~skfem_rkpm.mechanics.tangent_operator.TangentOperator.symmetric_operator`:
    the products without the matrix).
    """
    scale = 1.0 / np.sqrt(m)
    if isinstance(K, LinearOperator):
        A = LinearOperator(K.shape, matvec=lambda x: scale * (K @ (scale * np.ravel(x))),
                           dtype=float)
        dense = (lambda: A @ np.eye(K.shape[0]))
    else:
        A = (sp.diags(scale) @ sp.csr_matrix(K) @ sp.diags(scale)).tocsr()
        dense = A.toarray
    if A.shape[0] <= 600:
        w, V = np.linalg.eigh(dense())
        return float(w[-1]), V[:, -1]
    try:
        w, V = eigsh(A, k=1, which="LA", v0=start, tol=tol, ncv=ncv)
    except ArpackNoConvergence as failure:
        w, V = failure.eigenvalues, failure.eigenvectors
    return float(w[0]), V[:, 0]


def nodal_mass_matrix(basis, m_hat):
    """``Λ diag(m̂) Λᵀ``: the nodal lumped mass ``m̂`` acting on coefficients.

    With ``d̂ = Λᵀ d`` the kinetic energy ``½ d̂̇ᵀ diag(m̂) d̂̇`` is
    ``½ ḋᵀ Λ diag(m̂) Λᵀ ḋ``: the mass of the generalized coordinates that a
    nodal lumping implies.  Sparse, shape (N, N).
    """
    nodal = getattr(basis, "nodal_matrix", None)
    if nodal is None:
        return sp.diags(np.asarray(m_hat, dtype=float), format="csr")
    T = sp.csr_matrix(nodal)  # Λᵀ
    return (T.T @ sp.diags(np.asarray(m_hat, dtype=float)) @ T).tocsr()


def critical_time_step(K, M, constrained=None):
    """``Δt_crit = 2 / ω_max`` of the undamped central-difference scheme with
    the mass ``M`` (:func:`largest_eigenvalue`)."""
    return 2.0 / np.sqrt(largest_eigenvalue(K, M, constrained))


def gershgorin_time_step(K, m):
    """A stable step that needs no eigenvalue solve: ``2 / sqrt(max_I Σ_J
    |K_IJ| / m_I)``.

    Every eigenvalue of ``M⁻¹K`` lies in one of its Gershgorin discs, centred
    at ``K_II / m_I`` with radius ``Σ_(J≠I) |K_IJ| / m_I``; so ``ω²_max`` is at
    most the largest row sum and this step is never above
    :func:`critical_time_step`.
    """
    K = sp.csr_matrix(K)
    m = _checked_mass(m, K.shape[0])
    row = np.asarray(abs(K).sum(axis=1)).ravel()
    return float(2.0 / np.sqrt((row / m).max()))
