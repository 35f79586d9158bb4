"""The modified SCNI stabilization of a solid: its moduli, force and stiffness.

Modified SCNI (Puso, Chen, Zywicz & Elmer 2008, IJNME 74) adds the energy of
the differences between the piece (sub-cell) gradients of the smoothing
cells and the cell gradient,

    Π_stab = (α/2) Σ_L Σ_{k ⊂ Ω_L} A_k (H_k - H_L) : C : (H_k - H_L),

``H = ∂u/∂X`` (total Lagrangian), built by
:func:`~skfem_rkpm.approximation.nodal_integration.stabilization_matrix`.
It vanishes on linear fields (the patch test and rigid rotations are
untouched).  Three choices of the moduli ``C`` (:data:`STABILIZATION_MODULI`):

``"elastic"``
    the isotropic elastic moduli: a constant matrix ``α K_stab``, force
    ``α K_stab d``;
``"shear"``
    their deviatoric part only (:func:`stabilization_moduli`): constant too,
    blind to sub-cell volume changes;
``"tangent"``
    the material's consistent tangent ``A = ∂P/∂F`` at each particle, taken
    from the converged state of the last step and used on the pieces of its
    cell, in the spirit of naturally stabilized nodal integration (Hillman &
    Chen 2016, IJNME 107, which scales its stabilization by the material
    tangent).  Incremental, so that force and stiffness stay exact partners:
    within a step the stiffness ``α K_n`` is constant and the force is
    ``f_n + α K_n (d - d_n)``; at the end of the step ``f_n``, ``d_n`` and
    ``K_n`` (from the new tangent) are updated.  The elastic moduli start it.
"""

import numpy as np
import scipy.sparse as sp

from ..approximation.nodal_integration import jump_operator, stabilization_matrix
from ..assembly import isotropic_tangent

__all__ = ["STABILIZATION_MODULI", "checked_moduli", "stabilization_moduli", "Stabilization"]

#: the moduli ``C`` of the SCNI stabilization energy
STABILIZATION_MODULI = ("elastic", "shear", "tangent")


def checked_moduli(moduli):
    """``moduli`` if it names one of :data:`STABILIZATION_MODULI`, else a ValueError."""
    if moduli not in STABILIZATION_MODULI:
        raise ValueError(f"stabilization_moduli must be one of {STABILIZATION_MODULI}, "
                         f"not {moduli!r}")
    return moduli


def stabilization_moduli(material, kind, dim):
    """The constant moduli ``C_{c l d m}`` of the modified SCNI stabilization.

    ``"elastic"``: the isotropic elastic moduli ``λ δ_cl δ_dm + μ (δ_cd δ_lm
    + δ_cm δ_ld)``.  ``"shear"``: their deviatoric part only, ``λ`` replaced
    by ``-2μ/3``: the energy ``½ ε:C:ε = μ |dev ε|²`` of the
    (three-dimensional) deviator of the in-plane strain, blind to sub-cell
    volume changes (which the nearly isochoric plastic flow of metals makes
    at no cost in the material itself).  Positive semi-definite: in 3D its
    null space is the volumetric strain; in 2D (``ε_zz = 0``) an in-plane
    dilatation keeps the energy ``μ/6 (tr ε)²``.

    Parameters
    ----------
    material : J2Material
        Gives the shear and bulk moduli ``G``, ``K``.
    kind : {"elastic", "shear"}
    dim : int
        Dimension of the gradients (2 or 3).
    """
    if kind not in ("elastic", "shear"):
        raise ValueError(f"constant stabilization moduli are 'elastic' or 'shear', "
                         f"not {kind!r}")
    mu = material.G
    lam = material.K - 2.0 * mu / 3.0
    return isotropic_tangent(lam if kind == "elastic" else -2.0 * mu / 3.0, mu, dim)


class Stabilization:
    """``α`` times the stabilization of an SCNI basis, for a :class:`SolidProblem`.

    Parameters
    ----------
    basis : RKBasis
        With ``integration="scni"`` and ``stabilization = α > 0``.
    material : J2Material
    moduli : {"elastic", "shear", "tangent"}
        See the module docstring.
    entries : list of (i, J)
        The 3x3 entries of ``F`` the model uses (the tangent's rows and
        columns); the in-plane ones ``(c, l)``, ``c, l < dim``, are taken.
    """

    def __init__(self, basis, material, moduli, entries):
        self.alpha = float(basis.stabilization)
        self.moduli = checked_moduli(moduli)
        self.quadrature = basis.nodal_quadrature
        self.ncomp = basis.ncomp
        self.dim = basis.nodes.shape[0]
        self._planar = [k for k, (i, J) in enumerate(entries) if i < self.dim and J < self.dim]
        C = stabilization_moduli(material, "shear" if moduli == "shear" else "elastic",
                                 self.dim)
        self._jumps = jump_operator(self.quadrature, self.ncomp) if moduli == "tangent" else None
        self._set_matrix(stabilization_matrix(self.quadrature, C, self.ncomp))
        n = self.matrix.shape[0]
        self.d_ref, self.f_ref = np.zeros(n), np.zeros(n)

    def _set_matrix(self, K):
        S = (self.alpha * K).tocsr()
        S.sum_duplicates()
        S.sort_indices()
        self.matrix = S
        self._slots = None  # where S's entries sit in the tangent

    def force(self, d):
        """The stabilization force at coefficients ``d``."""
        d = np.asarray(d)
        if self.moduli != "tangent":
            return self.matrix @ d
        return self.f_ref + self.matrix @ (d - self.d_ref)

    def commit(self, d, tangent):
        """End of a converged step at ``d`` (``"tangent"`` only: otherwise
        nothing changes): keep its force and build the stiffness of the next
        step from ``tangent()``, the material tangent at the particles at the
        model's entries, shape (nparticles, m, m)."""
        if self.moduli != "tangent":
            return
        self.f_ref = self.force(d)
        self.d_ref = np.array(d, float)
        A = tangent()[:, self._planar][:, :, self._planar]
        n, dim = len(A), self.dim
        C = A.reshape(n, dim, dim, dim, dim)
        self._set_matrix(stabilization_matrix(self.quadrature, C, self.ncomp, self._jumps))

    def get_state(self):
        """What a checkpoint keeps: the arrays of the incremental form."""
        if self.moduli != "tangent":
            return {}
        return {"d_ref": self.d_ref, "f_ref": self.f_ref, "data": self.matrix.data,
                "indices": self.matrix.indices, "indptr": self.matrix.indptr}

    def set_state(self, state):
        """Restore :meth:`get_state` (a ValueError if it does not fit)."""
        if self.moduli != "tangent":
            return
        n = self.matrix.shape[0]
        if state["d_ref"].shape != (n,) or state["f_ref"].shape != (n,) or \
                state["indptr"].shape != (n + 1,):
            raise ValueError("the stabilization state has the wrong size")
        self.d_ref, self.f_ref = state["d_ref"].astype(float), state["f_ref"].astype(float)
        self.matrix = sp.csr_matrix((state["data"], state["indices"], state["indptr"]),
                                    shape=(n, n))
        self._slots = None

    def add_to(self, K):
        """``K + α K_stab``, in place in ``K``'s sparsity pattern when it holds
        the stabilization's (found once per matrix; a general sparse sum
        otherwise)."""
        S = self.matrix
        if self._slots is None:
            # the tangent's pattern is the assembler's, the same every time
            # (its index arrays are shared with the assembler: not sorted here)
            n = K.shape[1]
            rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr)).astype(np.int64)
            keys = rows * n + K.indices
            order = np.argsort(keys, kind="stable")
            S_rows = np.repeat(np.arange(S.shape[0]), np.diff(S.indptr)).astype(np.int64)
            wanted = S_rows * n + S.indices
            found = np.minimum(np.searchsorted(keys[order], wanted), len(keys) - 1)
            slots = order[found]
            self._slots = slots if np.array_equal(keys[slots], wanted) else False
        if self._slots is False:
            return K + S
        K.data[self._slots] += S.data
        return K
