"""The tangent of a solid applied to vectors, without assembling it.

The consistent tangent of :class:`~skfem_rkpm.mechanics.problem.SolidProblem`
is (Eq. 3.7 linearized, in the reference configuration)

    K = ∫_Ω0 ∇̃_X Ψ_I · A · ∇_X Ψ_J dV  (+ Σ_e u_e ⊗ w_e with F-bar)  (+ α K_stab),

with ``A = ∂P/∂F`` per quadrature point (material and geometric stiffness
at once), the per-cell rank-one blocks of F-bar and the SCNI stabilization
stiffness.  :class:`TangentOperator` applies it to a vector as the force
evaluation does: ``v → ∇v`` at the points, ``A : ∇v``, scattered back
through the test gradients, so a product costs about one force evaluation
without the return map, where the assembled matrix costs hundreds of them
for an RK basis (its local matrices hold ``(3 nloc)²`` entries a cell).
``Kᵀ v`` swaps the roles of the test and trial gradients (they differ
with VCI) and transposes ``A`` and the rank-one blocks; the symmetric part
``½ (K + Kᵀ)`` is what the stable-step estimate needs
(:meth:`~skfem_rkpm.solvers.explicit.CentralDifference.body_frequency2`).
"""

import numpy as np
from scipy.sparse.linalg import LinearOperator

from .kinematics import entries, from_entries

__all__ = ["TangentOperator"]


class TangentOperator:
    """``K v``, ``Kᵀ v`` and ``½ (K + Kᵀ) v`` of a solid's tangent.

    Parameters
    ----------
    assembler : Assembler
        The solid's (square) assembler.
    model : {"plane_strain", "axisymmetric", "3d"}
    A : ndarray, shape (n, m, m)
        ``∂P/∂F`` at the model's entries (:func:`~skfem_rkpm.mechanics.kinematics.entries`)
        at the ``n`` quadrature points.
    rank_one : (u, w), optional
        Per-cell blocks ``u_e ⊗ w_e``, each (nloc * c, nelems), as in
        :meth:`Assembler.local_bilinear`.
    extra : sparse matrix, optional
        A stiffness added as it is (the SCNI stabilization ``α K_stab``).
    """

    def __init__(self, assembler, model, A, rank_one=None, extra=None):
        self.assembler, self.model = assembler, model
        self.shape = assembler.layout.dx.shape
        pairs = entries(model)
        self._c = np.array([c for (c, _), _ in pairs])
        self._l = np.array([l for (_, l), _ in pairs])
        A = np.asarray(A, dtype=float)
        n, m = int(np.prod(self.shape)), len(pairs)
        if A.shape != (n, m, m):
            raise ValueError(f"the tangent has shape {A.shape}; this solid needs "
                             f"{(n, m, m)} (points, entries, entries)")
        self.A, self.rank_one, self.extra = A, rank_one, extra
        self.N = assembler.N
        self._A_sym = None

    def _gradients(self, v, test):
        """``∇v`` at the model's entries, shape (n, m)."""
        H = self.assembler.gradient(v, test=test)
        return H[self._c, self._l].reshape(len(self._c), -1).T

    def _scatter(self, P, test):
        """``∫ ∇Ψ · P`` of ``P`` (n, m) at the entries, through the test
        (``test=True``) or the trial gradients."""
        P_ext, _ = from_entries(P, None, self.model, self.shape)
        a = self.assembler
        return a.scatter(a.cell_vectors(P_ext, test=test))

    def _rank_one(self, v, transpose):
        """``Σ_e u_e (w_e · v_e)`` (or ``w_e (u_e · v_e)`` transposed)."""
        u, w = self.rank_one
        if transpose:
            u, w = w, u
        local = v[self.assembler.element_dofs]  # (nloc * c, nelems)
        return self.assembler.scatter(u * np.sum(w * local, axis=0))

    def matvec(self, v, transpose=False):
        """``K v`` (``Kᵀ v`` with ``transpose=True``)."""
        v = np.asarray(v, dtype=float)
        h = self._gradients(v, test=transpose)
        A = self.A.transpose(0, 2, 1) if transpose else self.A
        out = self._scatter(np.matmul(A, h[:, :, None])[:, :, 0], test=not transpose)
        if self.rank_one is not None:
            out += self._rank_one(v, transpose)
        if self.extra is not None:
            out += (self.extra.T if transpose else self.extra) @ v
        return out

    def rmatvec(self, v):
        """``Kᵀ v``."""
        return self.matvec(v, transpose=True)

    def symmetric(self, v):
        """``½ (K + Kᵀ) v``: with equal test and trial gradients one pass
        through ``½ (A + Aᵀ)``, else ``½ (K v + Kᵀ v)``."""
        if not self.assembler.same_gradients:
            return 0.5 * (self.matvec(v) + self.matvec(v, transpose=True))
        v = np.asarray(v, dtype=float)
        if self._A_sym is None:
            self._A_sym = 0.5 * (self.A + self.A.transpose(0, 2, 1))
        out = self._scatter(np.matmul(self._A_sym, self._gradients(v, False)[:, :, None])
                            [:, :, 0], test=True)
        if self.rank_one is not None:
            out += 0.5 * (self._rank_one(v, False) + self._rank_one(v, True))
        if self.extra is not None:
            out += 0.5 * (self.extra @ v + self.extra.T @ v)
        return out

    def symmetric_operator(self):
        """``½ (K + Kᵀ)`` as a scipy ``LinearOperator``."""
        return LinearOperator((self.N, self.N), matvec=self.symmetric,
                              rmatvec=self.symmetric, dtype=float)

    def operator(self):
        """``K`` as a scipy ``LinearOperator``."""
        return LinearOperator((self.N, self.N), matvec=self.matvec, rmatvec=self.rmatvec,
                              dtype=float)
