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
(:meth:`~skfem_rkpm.solvers.explicit.CentralDifference.body_frequency2`);
with VCI it is one pass through the trial and test gradient tables stacked
(``[∇Ψ; ∇̃Ψ] v``, then ``[∇̃Ψ, ∇Ψ] · [A ∇v; Aᵀ ∇̃v] / 2``), without it one
pass through ``½ (A + Aᵀ)``.
"""

import numpy as np
from scipy.sparse.linalg import LinearOperator

from .kinematics import entries

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
    tables : dict, optional
        Where the gradient tables of the products are kept between operators
        of the same assembler (they do not change; stacking them for VCI
        copies 2 x 2.4 million entries on the 3D Taylor bar).
    """

    def __init__(self, assembler, model, A, rank_one=None, extra=None, tables=None):
        self.assembler, self.model = assembler, model
        L = assembler.layout
        self.N, (nloc, self._nelems) = assembler.N, L.element_nodes.shape
        self._ncomp, self._nqp, self._dim = L.ncomp, L.dx.shape[1], L.dim
        pairs = entries(model)
        # entry k is (c, l) of the gradient: column l * ncomp + c of a point's rows
        self._slots = np.array([l * L.ncomp + c for (c, l), _ in pairs])
        A = np.asarray(A, dtype=float)
        n, m = L.dx.size, len(pairs)
        if A.shape != (n, m, m):
            raise ValueError(f"the tangent has shape {A.shape}; this solid needs "
                             f"{(n, m, m)} (points, entries, entries)")
        self.A, self.extra = A, extra
        self._nodes = np.ascontiguousarray(L.element_nodes.T)  # (nelems, nloc)
        self._dofs = np.ascontiguousarray(assembler.element_dofs.T)  # (nelems, nloc * c)
        self._rank_one = None
        if rank_one is not None:  # as (nelems, nloc, c), the layout of a cell's coefficients
            self._rank_one = tuple(np.ascontiguousarray(f.T).reshape(self._nelems, nloc, -1)
                                   for f in rank_one)
        self._plans, self._tables = {}, {} if tables is None else tables

    def _plan(self, kind):
        """Gradient table (nelems, k * nqp * dim, nloc), weighted table
        (nelems, nloc, k * nqp * dim), the ``k`` tangents (n, m, m) they
        carry and the rank-one and extra terms as ``(factor, transposed)``
        pairs, for ``kind`` "K", "KT" or "sym"."""
        if kind in self._plans:
            return self._plans[kind]
        A = self.A
        AT = A.transpose(0, 2, 1)
        stacked = kind == "sym" and not self.assembler.same_gradients
        if kind == "sym":
            plan = ([0.5 * A, 0.5 * AT] if stacked else [0.5 * (A + AT)],
                    [(0.5, False), (0.5, True)])
        else:
            plan = ([A], [(1.0, False)]) if kind == "K" else ([AT], [(1.0, True)])
        key = "stacked" if stacked else kind if kind != "sym" else "K"
        self._plans[kind] = plan = self._tables_of(key) + plan
        return plan

    def _tables_of(self, key):
        """Gradient and weighted tables: "K" trial and test, "KT" test and
        trial, "stacked" both."""
        if key not in self._tables:
            a = self.assembler
            if key == "stacked":
                tables = (np.concatenate([a.gradient_table(), a.gradient_table(test=True)],
                                         axis=1),
                          np.concatenate([a.weighted_table(), a.weighted_table(test=False)],
                                         axis=2))
            elif key == "K":
                tables = (a.gradient_table(), a.weighted_table())
            else:
                tables = (a.gradient_table(test=True), a.weighted_table(test=False))
            self._tables[key] = tables
        return self._tables[key]

    def _apply(self, v, kind):
        G, W, tangents, terms = self._plan(kind)
        v = np.asarray(v, dtype=float).ravel()
        E, q, width = self._nelems, self._nqp, self._dim * self._ncomp
        U = v.reshape(-1, self._ncomp)[self._nodes]  # (nelems, nloc, c)
        H = np.matmul(G, U).reshape(E, len(tangents), q, width)
        P = np.zeros_like(H)
        for k, T in enumerate(tangents):
            h = H[:, k][..., self._slots].reshape(E * q, -1, 1)
            P[:, k][..., self._slots] = np.matmul(T, h).reshape(E, q, -1)
        local = np.matmul(W, P.reshape(E, -1, self._ncomp))  # (nelems, nloc, c)
        if self._rank_one is not None:
            u, w = self._rank_one
            for factor, transposed in terms:
                left, right = (w, u) if transposed else (u, w)
                local += left * (factor * np.einsum("eac,eac->e", right, U))[:, None, None]
        out = np.bincount(self._dofs.ravel(), weights=local.ravel(), minlength=self.N)
        if self.extra is not None:
            for factor, transposed in terms:
                out += factor * ((self.extra.T if transposed else self.extra) @ v)
        return out

    def matvec(self, v):
        """``K v``."""
        return self._apply(v, "K")

    def rmatvec(self, v):
        """``Kᵀ v``."""
        return self._apply(v, "KT")

    def symmetric(self, v):
        """``½ (K + Kᵀ) v``."""
        return self._apply(v, "sym")

    def symmetric_operator(self):
        """``½ (K + Kᵀ)`` as a scipy ``LinearOperator``."""
        return LinearOperator((self.N, self.N), matvec=self.symmetric,
                              rmatvec=self.symmetric, dtype=float)

    def operator(self):
        """``K`` as a scipy ``LinearOperator``."""
        return LinearOperator((self.N, self.N), matvec=self.matvec, rmatvec=self.rmatvec,
                              dtype=float)
