"""Internal force and consistent tangent of a finite-strain solid on one basis.

The residual of the quasi-static weak form (Eq. 3.4 without inertia) is
assembled in the reference configuration,

    f_int = ∫_Ω0 ∇̃_X Ψ_I · P dV,      K = ∫_Ω0 ∇̃_X Ψ_I · A · ∇_X Ψ_J dV,

which equals the paper's current-configuration form ``∫ σ : ∇_x δu dv``
(Eq. 3.4, 3.7, with ``∇_x`` from Eq. 3.29) since ``σ dv = P Fᵀ dV``, but
needs no spatial gradients: the material gradients of the Lagrangian RK
shape functions are built once and reused every iteration.  ``∇̃`` are the
test gradients (VCI-corrected for RK bases).  An FEM basis runs the same
code.  With nodal integration (``RKBasis(..., integration="scni")``) every
particle is one point and carries the material state; a modified SCNI
stabilization adds the Lagrangian stiffness ``α K_stab`` and its force
(:class:`~skfem_rkpm.mechanics.stabilization.Stabilization`), built with
the elastic moduli of the material, their shear part, or the material's
tangent at the particles.
"""

import numpy as np

from ..assembly import Assembler
from .kinematics import (deformation_gradient, entries, from_entries,
                         inverse_and_determinant)
from .materials import MaterialState, ReturnMapError
from .nodal_tangent import nodal_tangent
from .stabilization import Stabilization, checked_moduli
from .tangent_operator import TangentOperator

__all__ = ["InvertedElementError", "NonFiniteError", "Evaluation", "SolidProblem"]


class InvertedElementError(RuntimeError):
    """det F ≤ 0 at quadrature points: the discretization has inverted."""

    def __init__(self, message, points):
        super().__init__(message)
        self.points = points


class NonFiniteError(RuntimeError):
    """NaN or inf in a computed quantity; ``points`` are the flat indices of
    the quadrature points where it appears."""

    def __init__(self, message, points):
        super().__init__(message)
        self.points = points


class Evaluation:
    """One evaluation of the solid at coefficients ``d``: the internal force
    ``f_int``, ``F``, ``P``, ``tau`` and the trial material ``state`` at the
    quadrature points, and the tangent ``K``, formed when it is first read
    (a Newton line search rejects some states, and a converged state needs
    no tangent); ``K`` is None if the evaluation was asked for none.
    ``tangent_parts()`` gives what ``K`` is made of, ``∂P/∂F`` at the
    model's entries (n, m, m) and the F-bar rank-one factors (or None), for
    products without the matrix (:meth:`SolidProblem.tangent_operator`)."""

    def __init__(self, f_int, F, P, tau, state, form_tangent=None, point=None,
                 tangent_parts=None):
        self.f_int, self.F, self.P, self.tau, self.state = f_int, F, P, tau, state
        self.point = point  # the material's ReturnPoint (its tangent on demand)
        self.d = None  # the coefficients evaluated
        self._form_tangent = form_tangent
        self.tangent_parts = tangent_parts
        self._K = None

    @property
    def K(self):
        if self._form_tangent is not None:
            self._K, self._form_tangent = self._form_tangent(), None
        return self._K


class SolidProblem:
    """A finite-strain elasto-plastic solid discretized by one basis.

    Parameters
    ----------
    basis : RKBasis or skfem vector CellBasis
    material : J2Material
    model : {"plane_strain", "axisymmetric", "3d"}
        For ``axisymmetric`` x is the radius, forces and volumes refer to the
        full ring (2π), and RK bases should be built with
        ``RKBasis(..., axisymmetric=True)`` for exact homogeneous states.
    locking : {None, "fbar"}
        Volumetric locking control for nearly isochoric (plastic) flow:
        ``"fbar"`` replaces the volume change of ``F`` at every quadrature
        point by its average over the background cell (F-bar, de Souza Neto
        et al. 1996), with the consistent (non-symmetric) tangent.
    stabilization_moduli : {"elastic", "shear", "tangent"}
        Moduli of the SCNI stabilization of a basis with ``stabilization > 0``
        (:mod:`skfem_rkpm.mechanics.stabilization`).
    """

    def __init__(self, basis, material, model="plane_strain", locking=None,
                 stabilization_moduli="elastic"):
        if locking not in (None, "fbar"):
            raise ValueError(f"locking must be None or 'fbar', not {locking!r}")
        checked_moduli(stabilization_moduli)
        if stabilization_moduli != "elastic" and not getattr(basis, "stabilization", 0.0):
            raise ValueError(f"stabilization_moduli={stabilization_moduli!r} chooses the "
                             "moduli of the SCNI stabilization, but this basis has none: "
                             "build it with RKBasis(..., integration='scni', "
                             "stabilization=alpha), alpha > 0")
        self.stabilization_moduli = stabilization_moduli
        self.basis, self.material, self.model = basis, material, model
        self.locking = locking
        self.assembler = Assembler(basis, axisymmetric=model == "axisymmetric")
        self.shape = self.assembler.layout.dx.shape
        self.npoints = int(np.prod(self.shape))
        self.state = MaterialState.virgin(self.npoints)
        # the 3x3 entries (i, J) of F and P that the model uses
        self.entries = [e for _, e in entries(model)]
        self._rows = np.array([i for i, _ in self.entries])
        self._cols = np.array([J for _, J in self.entries])
        self._local = None  # local tangent matrices, reused by every evaluation
        self._clusters = None  # the nodal tangent by clusters of points (False: none)
        self._operator_tables = {}  # the gradient tables of tangent_operator, kept
        self.stabilization = self._stabilization()

    def _stabilization(self):
        """The :class:`Stabilization` of a stabilized SCNI basis, or None."""
        if not getattr(self.basis, "stabilization", 0.0):
            return None
        return Stabilization(self.basis, self.material, self.stabilization_moduli,
                             self.entries)

    @property
    def N(self):
        return self.assembler.N

    def evaluate(self, d, state=None, tangent=True):
        """Internal force, tangent and trial state at coefficients ``d``.

        ``state`` is the converged state of the last step (default: the
        problem's committed state); it is not modified.

        Raises
        ------
        InvertedElementError
            If ``det F ≤ 0`` at any quadrature point (names the first one).
        """
        state = self.state if state is None else state
        F = deformation_gradient(self.assembler.gradient(d), self.model)
        self._check_finite(F, "the deformation gradient F")
        Finv, J = inverse_and_determinant(F)
        bad = np.flatnonzero(~(J > 0))
        if bad.size:
            raise InvertedElementError(
                f"det F = {J[bad[0]]:.3g} <= 0 at {bad.size} quadrature points; "
                f"first {self._where(bad[0])}", bad)
        if self.locking == "fbar":
            evaluation = self._evaluate_fbar(F, Finv, J, state, tangent)
        else:
            evaluation = self._evaluate_plain(F, state, tangent)
        return self._stabilized(evaluation, d)

    def _evaluate_plain(self, F, state, tangent):
        """Internal force ``∫ ∇̃Ψ · P dV`` and tangent ``∫ ∇̃Ψ · A · ∇Ψ dV``."""
        P, tau, new_state, point = self._stress(F, state)
        P_at = self._at_entries(P)
        P_ext, _ = from_entries(P_at, None, self.model, self.shape)

        def parts():
            return self._material_tangent(point), None

        def form_tangent():
            A, _ = parts()
            return self._tangent_matrix(from_entries(P_at, A, self.model, self.shape)[1])

        return Evaluation(self.assembler.linear(P_ext), F, P, tau, new_state,
                          form_tangent if tangent else None, point,
                          parts if tangent else None)

    def _stabilized(self, evaluation, d):
        """Add the stabilization force and stiffness, if any."""
        evaluation.d = d
        if self.stabilization is not None:
            evaluation.f_int = evaluation.f_int + self.stabilization.force(d)
            form = evaluation._form_tangent
            if form is not None:
                evaluation._form_tangent = lambda: self.stabilization.add_to(form())
        return evaluation

    def _stress(self, F, state):
        """``material.stress`` with failures named by quadrature point."""
        try:
            P, tau, new_state, point = self.material.stress(F, state)
        except ReturnMapError as err:
            raise ReturnMapError(f"{err} at {len(err.points)} quadrature points; first "
                                 f"{self._where(err.points[0])}", err.points) from None
        self._check_finite(P, "the stress P (return map)")
        return P, tau, new_state, point

    def _material_tangent(self, point):
        """``material.tangent`` at the model's entries, checked to be finite."""
        A = self.material.tangent(point, self.entries)
        self._check_finite(A, "the consistent tangent A")
        return A

    def _where(self, point):
        """``cell c (point q) at X = (...)`` for a flat quadrature point index
        (``c`` numbers the mesh's cells, also on a basis of some of them)."""
        X = np.asarray(self.basis.global_coordinates())
        x = X.reshape(len(X), -1)[:, point]
        if getattr(self.basis, "nodal_quadrature", None) is not None:
            return f"at particle {point} (X = ({', '.join(f'{v:.4g}' for v in x)}))"
        cell, qp = np.divmod(point, self.shape[1])
        tind = getattr(self.basis, "tind", None)  # a basis on some of the cells
        cell = cell if tind is None else tind[cell]
        return f"in cell {cell} (point {qp}) at X = ({', '.join(f'{v:.4g}' for v in x)})"

    def _check_finite(self, values, what):
        """Raise :class:`NonFiniteError` naming the first quadrature point
        where ``values`` (leading axis: points) has NaN or inf.  A finite sum
        has no NaN or inf in it: one pass (the point-wise search runs only if
        the sum is not finite, e.g. when it overflows)."""
        if np.isfinite(np.sum(values)):
            return
        finite = np.isfinite(values.reshape(len(values), -1)).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite)
            raise NonFiniteError(f"{what} is not finite at {bad.size} quadrature points; "
                                 f"first {self._where(bad[0])}", bad)

    def _evaluate_fbar(self, F, Finv, J, state, tangent):
        """F-bar: ``F̄ = F + (β^{1/n} - 1) F_M`` with ``β = J̄_e / J``.

        ``J̄_e`` is the volume average of ``J`` over the cell, ``n = 2`` with
        ``F_M`` the in-plane part of ``F`` (plane strain), ``n = 3`` with
        ``F_M = F`` otherwise, so that ``det F̄ = J̄_e``.  The stress
        ``P̃ = β^{1/n - 1} P(F̄)`` is work-conjugate to ``F`` for the Cauchy
        stress of ``F̄``; its linearization has a local part
        ``Â = γ s [A - (1/n) (A:F_M) ⊗ F⁻ᵀ] + (1 - 1/n) γ P̄ ⊗ F⁻ᵀ`` and a
        per-cell rank-one part through ``∂P̃/∂J̄ = (γ/J̄)[(s/n) A:F_M - (1 - 1/n) P̄]``
        and ``∂J̄/∂d = ∫_e J F⁻ᵀ : ∇N / V_e`` (``s = β^{1/n}``, ``γ = β^{1/n-1}``).

        The tangents are formed at the model's entries only: ``F_M`` is zero
        outside them, so ``A:F_M`` needs no others.  The rank-one part is added
        to the local matrices before they are summed.
        """
        n = 2 if self.model == "plane_strain" else 3
        Fbar, Jbar, FM, s, beta = self._fbar(F, J)
        gamma = beta ** (1.0 / n - 1.0)
        Pbar, taubar, new_state, point = self._stress(Fbar, state)
        P = gamma[:, None, None] * Pbar
        tau = (J / Jbar)[:, None, None] * taubar  # J σ with σ the Cauchy stress of F̄
        P_at = self._at_entries(P)
        P_ext, _ = from_entries(P_at, None, self.model, self.shape)

        def parts():
            A = self._material_tangent(point)
            FinvT = self._at_entries(Finv.transpose(0, 2, 1))
            Pbar_at = self._at_entries(Pbar)
            AF = (A @ self._at_entries(FM)[:, :, None])[:, :, 0]
            # Â = γ s A + [(1 - 1/n) γ P̄ - (γ s / n) A:F_M] ⊗ F⁻ᵀ, in place of A
            u = (((1.0 - 1.0 / n) * gamma)[:, None] * Pbar_at
                 - (gamma * s / n)[:, None] * AF)
            A_hat = A
            A_hat *= (gamma * s)[:, None, None]
            A_hat += u[:, :, None] * FinvT[:, None, :]
            dP_dJbar = (gamma / Jbar)[:, None] * ((s / n)[:, None] * AF
                                                  - (1.0 - 1.0 / n) * Pbar_at)
            dP_ext, _ = from_entries(dP_dJbar, None, self.model, self.shape)
            dJ_ext, _ = from_entries(J[:, None] * FinvT, None, self.model, self.shape)
            u = self.assembler.cell_vectors(dP_ext)
            w = (self.assembler.cell_vectors(dJ_ext, test=False)
                 / np.sum(self.assembler.layout.dx, axis=1))
            return A_hat, (u, w)

        def form_tangent():
            A_hat, rank_one = parts()
            _, A_ext = from_entries(P_at, A_hat, self.model, self.shape)
            return self._tangent_matrix(A_ext, rank_one)

        return Evaluation(self.assembler.linear(P_ext), F, P, tau, new_state,
                          form_tangent if tangent else None, point,
                          parts if tangent else None)

    def _fbar(self, F, J):
        """``F̄ = F + (β^{1/n} - 1) F_M``, ``J̄_e`` per point, ``F_M``,
        ``s = β^{1/n}`` and ``β = J̄_e / J`` (see :meth:`_evaluate_fbar`)."""
        dV = self.assembler.layout.dx
        Jq = J.reshape(self.shape)
        Jbar = np.repeat(np.sum(Jq * dV, axis=1) / np.sum(dV, axis=1), self.shape[1])
        n = 2 if self.model == "plane_strain" else 3
        FM = F.copy()
        if n == 2:
            FM[:, 2, :] = 0.0
            FM[:, :, 2] = 0.0
        beta = Jbar / J
        s = beta ** (1.0 / n)
        return F + (s - 1.0)[:, None, None] * FM, Jbar, FM, s, beta

    def material_gradient(self, F):
        """The deformation gradients the material sees at ``F``: ``F̄`` with
        F-bar, ``F`` otherwise."""
        if self.locking != "fbar":
            return F
        return self._fbar(F, np.linalg.det(F))[0]

    def tangent_operator(self, evaluation):
        """The tangent of ``evaluation`` (asked with ``tangent=True``) as a
        :class:`~skfem_rkpm.mechanics.tangent_operator.TangentOperator`:
        products ``K v`` without the matrix, equal to ``evaluation.K @ v`` to
        round-off (stabilization included)."""
        if evaluation.tangent_parts is None:
            raise ValueError("this evaluation has no tangent: evaluate(d, tangent=True)")
        A, rank_one = evaluation.tangent_parts()
        extra = None if self.stabilization is None else self.stabilization.matrix
        return TangentOperator(self.assembler, self.model, A, rank_one, extra,
                               tables=self._operator_tables)

    def _tangent_matrix(self, A_ext, rank_one=None):
        """Sparse tangent of ``A_ext`` plus the per-cell blocks ``u ⊗ w`` (summed
        inside the products of :meth:`Assembler.local_bilinear`).

        The local matrices are written into the same buffer every time:
        fresh memory of that size costs more to touch than to compute.  With
        nodal integration (one point per particle) the tangent is summed over
        clusters of particles (:mod:`~skfem_rkpm.mechanics.nodal_tangent`),
        where that costs less: the same matrix to round-off.
        """
        if rank_one is None and self._nodal_clusters():
            return self._clusters.matrix(A_ext)
        self._local = self.assembler.local_bilinear(A_ext, out=self._local,
                                                    rank_one=rank_one)
        return self.assembler.matrix(self._local)

    def _nodal_clusters(self):
        """The :class:`~skfem_rkpm.mechanics.nodal_tangent.ClusteredTangent`
        of a nodally integrated basis, built at the first tangent, or None."""
        if self._clusters is None:
            self._clusters = False
            if getattr(self.basis, "nodal_quadrature", None) is not None:
                x = np.asarray(self.basis.global_coordinates()).reshape(
                    -1, self.shape[0])
                self._clusters = nodal_tangent(self.assembler, x) or False
        return self._clusters or None

    def _at_entries(self, T):
        """The model's entries of 3x3 tensors (n, 3, 3), shape (n, m)."""
        return T[:, self._rows, self._cols]

    def commit(self, evaluation):
        """Accept the state of a converged evaluation (and move an incremental
        stabilization on to it)."""
        self.state = evaluation.state
        if self.stabilization is not None:
            self.stabilization.commit(
                evaluation.d, lambda: self._material_tangent(evaluation.point))

    def cauchy_stress(self, evaluation):
        """Cauchy stress ``σ = τ / det F`` at the quadrature points, (n, 3, 3)."""
        return evaluation.tau / np.linalg.det(evaluation.F)[:, None, None]

    # -- the whole domain, which this problem is (a partitioned solid,
    #    skfem_rkpm.solvers.partitioned.PartitionedSolid, gathers it from its ranks)
    partitioned = False

    @property
    def whole_points(self):
        """Material points of the whole domain."""
        return self.state.alpha.shape[0]

    @property
    def whole_dx(self):
        """Quadrature weights of the whole domain's points (nelems, nqp)."""
        return self.assembler.layout.dx

    @property
    def whole_state(self):
        """The committed material state of the whole domain."""
        return self.state

    def gather_points(self, values):
        """Values at the material points (n, ...) of the whole domain: ``values``."""
        return values

    def gathered_state(self):
        """The committed material state of the whole domain."""
        return self.state

    def restore_state(self, whole):
        """Take a material state of the whole domain (a checkpoint's)."""
        self.state = whole
