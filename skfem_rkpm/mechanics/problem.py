"""Internal force and consistent tangent of a finite-strain solid on one basis.

The residual of the quasi-static weak form (Eq. 3.4 without inertia) is
assembled in the reference configuration,

    f_int = ∫_Ω0 ∇̃_X Ψ_I · P dV,      K = ∫_Ω0 ∇̃_X Ψ_I · A · ∇_X Ψ_J dV,

which equals the paper's current-configuration form ``∫ σ : ∇_x δu dv``
(Eq. 3.4, 3.7, with ``∇_x`` from Eq. 3.29) since ``σ dv = P Fᵀ dV``, but
needs no spatial gradients: the material gradients of the Lagrangian RK
shape functions are built once and reused every iteration.  ``∇̃`` are the
test gradients (VCI-corrected for RK bases).  An FEM basis runs the same
code.
"""

from dataclasses import dataclass

import numpy as np

from ..assembly import Assembler
from .kinematics import deformation_gradient, to_assembler
from .materials import MaterialState

__all__ = ["InvertedElementError", "Evaluation", "SolidProblem"]


class InvertedElementError(RuntimeError):
    """det F ≤ 0 at quadrature points: the discretization has inverted."""

    def __init__(self, message, points):
        super().__init__(message)
        self.points = points


@dataclass
class Evaluation:
    """One evaluation of the solid at coefficients ``d``."""

    f_int: np.ndarray
    K: object
    F: np.ndarray
    P: np.ndarray
    tau: np.ndarray
    state: MaterialState


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
    """

    def __init__(self, basis, material, model="plane_strain"):
        self.basis, self.material, self.model = basis, material, model
        self.assembler = Assembler(basis, axisymmetric=model == "axisymmetric")
        self.shape = self.assembler.layout.dx.shape
        self.npoints = int(np.prod(self.shape))
        self.state = MaterialState.virgin(self.npoints)

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
        J = np.linalg.det(F)
        bad = np.flatnonzero(~(J > 0))
        if bad.size:
            x = np.asarray(self.basis.global_coordinates()).reshape(
                len(self.basis.global_coordinates()), -1)[:, bad[0]]
            cell, qp = np.divmod(bad[0], self.shape[1])
            raise InvertedElementError(
                f"det F = {J[bad[0]]:.3g} <= 0 at {bad.size} quadrature points; "
                f"first in cell {cell} (point {qp}) at X = "
                f"({', '.join(f'{v:.4g}' for v in x)})", bad)
        P, tau, new_state, A = self.material.update(F, state, tangent=tangent)
        P_ext, A_ext = to_assembler(P, A, self.model, self.shape)
        f_int = self.assembler.linear(P_ext)
        K = self.assembler.bilinear(A_ext) if tangent else None
        return Evaluation(f_int, K, F, P, tau, new_state)

    def commit(self, evaluation):
        """Accept the state of a converged evaluation."""
        self.state = evaluation.state

    def cauchy_stress(self, evaluation):
        """Cauchy stress ``σ = τ / det F`` at the quadrature points, (n, 3, 3)."""
        return evaluation.tau / np.linalg.det(evaluation.F)[:, None, None]
