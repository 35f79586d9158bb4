"""scikit-fem's Dirichlet idioms with nodal values on RK bases.

scikit-fem's ``condense(A, b, x=x, D=D)`` and ``enforce`` fix the solution
vector's entries ``d_D``.  On an RK basis those are coefficients, not the
field's values: the nodal values are ``û = Λᵀ d`` (Eq. 3.32-3.34), and the
transformation method prescribes ``(Λᵀ d)_D = x_D`` (Eq. 3.37).  This module
gives :func:`condense`, :func:`enforce`, :func:`penalize` and :func:`eigen`
with scikit-fem's
signatures (plus ``basis``) that prescribe nodal values, and
:func:`coefficients`, the coefficients of given nodal values.  For a FEM basis
(or ``basis=None``) they are scikit-fem's own functions.

The conditions ``C d = g`` with ``C = Λᵀ[D]`` are eliminated by a null-space
basis that keeps every coefficient off ``D`` as an unknown:

    d = d₀ + Z z,   z = d_I,   Z = [1 ; -C_D⁻¹ C_I],   d₀ = [0 ; C_D⁻¹ g],

where ``C_D = Λᵀ[D][:, D]`` (the shape functions of the constrained
particles at those particles) and ``C_I = Λᵀ[D][:, I]``; ``C Z = 0`` and
``C d₀ = g``.  The reduced system ``Zᵀ K Z z = Zᵀ (f - K d₀)`` is the
Galerkin system on the constrained space, symmetric positive definite when
``K`` is (so conjugate gradients and ``eigsh`` apply), and its solution
minimizes the same energy as the saddle-point solve of
:func:`skfem_rkpm.solve`.  ``C_D⁻¹ C_I`` is dense on the particles within one
support of ``D``: up to ``len(D)`` rows by that many columns.  On the
whole boundary of a 2D square with ``n × n`` cells (``len(D) = 4n``) it has
about ``2n`` entries per constrained dof (7935 for n = 32, 32255 for
n = 64), and the reduced matrix about twice the entries of ``K``
(docs/rk_basis.md, ``benchmarks/dirichlet_idioms.py``).  scikit-fem's
:func:`skfem.solve` applies ``Z`` itself: ``condense`` returns
``I = (dofs, expand)``, the form its ``solve_linear`` and ``solve_eigen``
accept for a change of variables.
"""

import warnings

import numpy as np
import scipy.sparse as sp
import skfem
from scipy.sparse.linalg import eigs, eigsh, splu

from ..approximation.constraints import transformation

__all__ = ["condense", "enforce", "penalize", "eigen", "coefficients", "NodalElimination",
           "PartialSolutionWarning"]

#: dense entries of ``C_D⁻¹ C_I`` above which :func:`condense` refuses (160 MB)
DENSE_LIMIT = 20_000_000


class PartialSolutionWarning(UserWarning):
    """``condense(..., expand=False)`` on an RK basis: the reduced system's
    solution holds the coefficients off ``D`` only, and those at ``D`` are
    not zero (scikit-fem's ``x[I] = solve(...)`` would leave them zero)."""


def _is_rk(basis):
    return basis is not None and getattr(basis, "nodal_matrix", None) is not None


def _dofs(S, N, what):
    """A sorted unique integer array of dofs ``S`` (array, DofsView, RKDofs or
    a dict of them), checked against ``N``."""
    if isinstance(S, dict):
        S = np.concatenate([np.asarray(_dofs(v, N, what)) for v in S.values()] or [[]])
    elif not isinstance(S, np.ndarray) and hasattr(S, "flatten"):
        S = S.flatten()
    S = np.unique(np.asarray(S, dtype=np.int64).ravel())
    if S.size and (S[0] < 0 or S[-1] >= N):
        bad = S[0] if S[0] < 0 else S[-1]
        raise ValueError(f"{what} contains dof {bad}, outside 0..{N - 1} (the matrix "
                         f"has {N} rows); take the dofs from basis.get_dofs(...)")
    return S


def _split(N, I, D):
    if (I is None) == (D is None):
        raise ValueError("give either D (the dofs whose nodal values are prescribed) or "
                         "I (the dofs to keep), not both and not neither")
    everything = np.arange(N)
    if D is not None:
        D = _dofs(D, N, "D")
        return np.setdiff1d(everything, D), D
    I = _dofs(I, N, "I")
    return I, np.setdiff1d(everything, I)


def _values(x, N, D):
    """The prescribed nodal values at ``D``: ``x[D]`` of a full vector, as scikit-fem."""
    if x is None:
        return np.zeros(len(D))
    x = np.asarray(x, dtype=float)
    if x.shape != (N,):
        raise ValueError(f"x has shape {x.shape}: give a full vector of length {N} "
                         f"holding the prescribed nodal values at D (x[D]), as for "
                         f"skfem.condense")
    return x[D]


class NodalElimination:
    """The null-space basis ``Z`` and particular solution of ``(Λᵀ d)_D = g``.

    Parameters
    ----------
    basis : RKBasis
        Supplies ``Λᵀ`` (``basis.nodal_matrix``, Eq. 3.33).
    I, D : array of int
        Free and constrained dofs (a partition of ``0..N-1``).

    Attributes
    ----------
    C : sparse matrix, shape (len(D), N)
        The conditions' rows ``Λᵀ[D]``.
    Z : sparse matrix, shape (N, len(I))
        ``Z = [1 ; -C_D⁻¹ C_I]`` (rows ``I`` the identity), ``Λᵀ[D] Z = 0``.
    """

    def __init__(self, basis, I, D, N=None):
        T = transformation(basis, N)
        N = T.shape[0]
        self.N, self.I, self.D = N, I, D
        self.C = C = T[D]
        C_D = C[:, D].tocsc()
        C_I = C[:, I].tocsc()
        near = np.flatnonzero(np.diff(C_I.indptr))
        if len(D) * len(near) > DENSE_LIMIT:
            raise MemoryError(
                f"eliminating the nodal values of {len(D)} dofs couples them with "
                f"{len(near)} coefficients ({len(D) * len(near):.2e} dense entries); "
                f"solve the saddle-point system with skfem_rkpm.solve(K, f, basis, D=D, "
                f"x=x) instead")
        try:
            self._lu = splu(C_D) if len(D) else None
        except RuntimeError:
            raise np.linalg.LinAlgError(
                f"the shape functions of the {len(D)} constrained dofs at their own "
                f"particles (Λᵀ[D][:, D]) form a singular matrix, so their nodal values "
                f"cannot be eliminated; prescribe them with the saddle-point solve "
                f"skfem_rkpm.solve(K, f, basis, D=D, x=x)") from None
        W = -self._lu.solve(C_I[:, near].toarray()) if len(D) and len(near) else \
            np.zeros((len(D), len(near)))
        r, c = np.nonzero(W)
        E = sp.csr_matrix((W[r, c], (D[r], near[c])), shape=(N, len(I)))
        P = sp.csr_matrix((np.ones(len(I)), (I, np.arange(len(I)))), shape=(N, len(I)))
        self.Z = (P + E).tocsr()

    def particular(self, g):
        """``d₀`` with ``d₀_I = 0`` and ``(Λᵀ d₀)_D = g``."""
        d0 = np.zeros(self.N)
        if len(self.D):
            d0[self.D] = self._lu.solve(np.asarray(g, dtype=float))
        return d0

    def expand(self, z):
        """``Z z``: coefficients from the free unknowns (the constrained part of ``d``)."""
        return self.Z @ z

    def reduce(self, A):
        """``Zᵀ A Z``."""
        return (self.Z.T @ sp.csr_matrix(A) @ self.Z).tocsr()


def condense(A, b=None, x=None, I=None, D=None, expand=True, basis=None):
    """Eliminate prescribed *nodal values* from a linear system or eigenproblem.

    scikit-fem's :func:`skfem.condense` with ``x[D]`` the prescribed nodal
    values ``(Λᵀ d)_D`` (Eq. 3.37) on an RK ``basis``; for a FEM basis or
    ``basis=None`` it is :func:`skfem.condense` itself.  On an RK basis the
    result passes to :func:`skfem.solve` (any of its solvers, iterative
    ones too) and that returns the RK coefficients ``d``.

    Parameters
    ----------
    A : sparse matrix, shape (N, N)
        The system matrix.
    b : ndarray (N,) or sparse matrix, optional
        Right-hand side, or the mass matrix of an eigenproblem (then the
        conditions are homogeneous and ``x`` is not used).
    x : ndarray, shape (N,), optional
        Prescribed nodal values, read at ``D``.  Default zero.
    I, D : array of int or dofs, optional
        The dofs to keep, or those whose nodal values are prescribed
        (``basis.get_dofs(...)``); give one of them.
    expand : bool
        Return also ``x`` and ``I`` for :func:`skfem.solve`.
    basis : RKBasis or skfem basis, optional
        The basis of ``A``.

    Returns
    -------
    tuple
        ``(A_r, b_r, x_r, I_r)`` (or ``(A_r, b_r)`` with ``expand=False``):
        on an RK basis ``A_r = Zᵀ A Z``, ``b_r = Zᵀ (b - A d₀)`` (``Zᵀ b Z``
        for a mass matrix), ``x_r = d₀`` and ``I_r = (arange(N), Z @)``, so
        that ``skfem.solve`` returns ``d = d₀ + Z z``
        (:class:`NodalElimination`).  With ``expand=False`` the caller
        expands a solution ``z`` itself: ``d = x_r + I_r[1](z)`` of the
        expanded call; a :class:`PartialSolutionWarning` says so, since
        scikit-fem's ``x[I] = z`` would leave the coefficients at ``D``
        zero and miss the prescribed nodal values.
    """
    if not _is_rk(basis):
        return skfem.condense(A, b, x=x, I=I, D=D, expand=expand)
    N = A.shape[0]
    I, D = _split(N, I, D)
    elim = NodalElimination(basis, I, D, N)
    if not expand and len(D):
        warnings.warn(
            f"condense(..., expand=False) on an RK basis: the solution z of the reduced "
            f"system holds the coefficients of the {len(I)} dofs I only; the {len(D)} "
            f"coefficients at D are not zero but follow from z, so x[I] = z in a zero "
            f"vector misses the prescribed nodal values.  Keep the expanded result, "
            f"A, b, x0, I = condense(..., basis=basis), and call skfem.solve(A, b, x0, "
            f"I, solver=...), which returns all coefficients",
            PartialSolutionWarning, stacklevel=2)
    if b is None:
        if x is None:
            reduced = (elim.reduce(A),)
            return reduced + (np.zeros(N), (np.arange(N), elim.expand)) if expand \
                else reduced[0]
        b = np.zeros(N)
    if sp.issparse(b):
        out, d0 = (elim.reduce(A), elim.reduce(b)), np.zeros(N)
    else:
        d0 = elim.particular(_values(x, N, D))
        out = (elim.reduce(A), elim.Z.T @ (np.asarray(b, dtype=float) - A @ d0))
    if expand:
        out += (d0, (np.arange(N), elim.expand))
    return out


def enforce(A, b=None, x=None, I=None, D=None, diag=1.0, overwrite=False, basis=None):
    """Replace the rows of prescribed *nodal values* in a linear system.

    scikit-fem's :func:`skfem.enforce` with ``x[D]`` the prescribed nodal
    values; for a FEM basis or ``basis=None`` it is :func:`skfem.enforce`.
    On an RK basis the rows ``D`` become ``diag · Λᵀ[D]`` with right-hand
    side ``diag · x[D]`` (the conditions of Eq. 3.37), and the rows ``I``
    become ``Zᵀ A`` with ``Zᵀ b``: the equilibrium equations in the
    directions that keep the nodal values at ``D``
    (:class:`NodalElimination`).  ``solve(A_e, b_e)`` is then the
    constrained solution ``d``.  Unlike the FEM case rows ``I`` change too,
    so the matrices are always new: ``overwrite`` is ignored on RK bases.
    For a mass matrix ``b`` its rows ``D`` are zero and rows ``I`` are
    ``Zᵀ b``, so the eigenpairs of finite eigenvalue honour the conditions.

    Returns
    -------
    (A_e, b_e), or A_e when ``b`` is None.
    """
    if not _is_rk(basis):
        return skfem.enforce(A, b, x=x, I=I, D=D, diag=diag, overwrite=overwrite)
    N = A.shape[0]
    I, D = _split(N, I, D)
    elim = NodalElimination(basis, I, D, N)
    rows = sp.csr_matrix((np.ones(N), (np.concatenate([I, D]), np.arange(N))),
                         shape=(N, N))
    A_e = (rows @ sp.vstack([elim.Z.T @ sp.csr_matrix(A), diag * elim.C])).tocsr()
    if b is None:
        return A_e
    if sp.issparse(b):
        b_e = (rows @ sp.vstack([elim.Z.T @ sp.csr_matrix(b),
                                 sp.csr_matrix((len(D), N))])).tocsr()
    else:
        b_e = np.empty(N)
        b_e[I] = elim.Z.T @ np.asarray(b, dtype=float)
        b_e[D] = diag * _values(x, N, D)
    return A_e, b_e


def penalize(A, b=None, x=None, I=None, D=None, epsilon=None, overwrite=False,
             basis=None):
    """Penalize prescribed *nodal values* in a linear system.

    scikit-fem's :func:`skfem.penalize` with ``x[D]`` the prescribed nodal
    values; for a FEM basis or ``basis=None`` it is :func:`skfem.penalize`.
    On an RK basis the penalty acts on the nodal values ``C d``,
    ``C = Λᵀ[D]`` (Eq. 3.37): ``A + CᵀC/ε`` and ``b + Cᵀ x[D]/ε`` (a mass
    matrix ``b`` is returned unchanged).  The nodal values then miss
    ``x[D]`` by O(ε |A|).  Default ``ε = 1e-10 / max |diag A[D]|`` as in
    scikit-fem.  The matrices are new (``overwrite`` is ignored on RK bases).

    Returns
    -------
    (A_p, b_p), or A_p when ``b`` is None.
    """
    if not _is_rk(basis):
        return skfem.penalize(A, b, x=x, I=I, D=D, epsilon=epsilon, overwrite=overwrite)
    N = A.shape[0]
    I, D = _split(N, I, D)
    C = transformation(basis, N)[D]
    if epsilon is None:
        epsilon = 1e-10 / np.abs(A.diagonal()[D]).max(initial=0.0)
    if not (np.isfinite(epsilon) and epsilon > 0):
        raise ValueError(f"epsilon must be positive and finite, not {epsilon!r} (the "
                         f"default needs a nonzero diagonal of A at D)")
    A_p = (sp.csr_matrix(A) + (C.T @ C) / epsilon).tocsr()
    if b is None:
        return A_p
    if sp.issparse(b):
        return A_p, b
    return A_p, np.asarray(b, dtype=float) + C.T @ _values(x, N, D) / epsilon


def eigen(K, M, basis=None, D=None, k=6, sigma=0.0, symmetric=None):
    """The ``k`` eigenpairs of ``K d = λ M d`` nearest ``sigma`` with the
    nodal values at ``D`` zero (``(Λᵀ d)_D = 0``, Eq. 3.37).

    The conditions are eliminated as in :func:`condense`; the reduced
    pencil ``(Zᵀ K Z, Zᵀ M Z)`` goes to :func:`scipy.sparse.linalg.eigsh`
    when both matrices are symmetric (``integration="vci_symmetric"`` or
    ``"gauss"``, and FEM) and to ``eigs`` otherwise (the default VCI
    stiffness is not symmetric), in shift-invert mode about ``sigma``.

    Parameters
    ----------
    K, M : sparse matrix, shape (N, N)
    basis : RKBasis or skfem basis, optional
        ``None`` or a FEM basis: ``D`` are dofs fixed to zero.
    D : array of int or dofs, optional
        Dofs whose nodal values vanish; default none.
    k : int
        Number of eigenpairs.
    sigma : float
        Shift: the eigenvalues nearest it are returned.
    symmetric : bool, optional
        Use ``eigsh``; default: when ``|A - Aᵀ| ≤ 1e-12 |A|`` for both.

    Returns
    -------
    w : ndarray, shape (k,)
        Eigenvalues, ascending (real parts; ``eigs`` returns complex ones).
    d : ndarray, shape (N, k)
        Coefficient vectors; ``basis.nodal_values(d)`` are the mode shapes.
    """
    N = K.shape[0]
    I, D = _split(N, None, np.zeros(0, np.int64) if D is None else D)
    if _is_rk(basis):
        elim = NodalElimination(basis, I, D, N)
        Kr, Mr, expand = elim.reduce(K), elim.reduce(M), elim.expand
    else:
        Kr = sp.csr_matrix(K)[I][:, I]
        Mr = sp.csr_matrix(M)[I][:, I]

        def expand(z):
            d = np.zeros((N,) + z.shape[1:])
            d[I] = z
            return d
    if k >= Kr.shape[0] - 1:
        raise ValueError(f"asked for {k} eigenpairs of a problem with {Kr.shape[0]} "
                         f"free unknowns; ask for fewer than {Kr.shape[0] - 1}")
    if symmetric is None:
        symmetric = all(abs(A - A.T).max() <= 1e-12 * abs(A).max() for A in (Kr, Mr))
    if symmetric:
        w, z = eigsh(Kr, k=k, M=Mr, sigma=sigma)
    else:
        w, z = eigs(Kr, k=k, M=Mr, sigma=sigma)
        w, z = w.real, z.real
    order = np.argsort(w)
    return w[order], expand(z[:, order])


def coefficients(basis, values):
    """RK coefficients ``d`` of given nodal values: the solution of
    ``Λᵀ d = values`` (Eq. 3.32-3.33).

    ``values`` has shape (N,) or (N, k), ordered as the dofs of ``basis``
    (interleaved ``ncomp*I + c`` for vector fields).  For a FEM basis
    (``Λ = 1``) this is a copy of ``values``.  The field of the result
    takes the given values at the particles (it interpolates them); it is
    not the L² projection (:meth:`RKBasis.project`).
    """
    values = np.asarray(values, dtype=float)
    if values.ndim not in (1, 2) or values.shape[0] != basis.N:
        raise ValueError(f"values have shape {values.shape}; give one value per dof "
                         f"({basis.N},) or several columns ({basis.N}, k)")
    if not _is_rk(basis):
        return values.copy()
    return splu(sp.csc_matrix(basis.nodal_matrix)).solve(values)
