"""A material on a later reference configuration (updated Lagrangian).

When the RK functions are rebuilt on the current configuration (see
:mod:`skfem_rkpm.runs.rereference`), the deformation gradient the solid
computes is the increment ``F_incr = ∂x/∂x_ref`` since that reference, and
the total one is composed, ``F = F_incr · F_ref`` (``F_ref`` the total
deformation gradient at the reference, carried to the new material points;
:func:`total_deformation_gradient`).

The J2 material of :mod:`skfem_rkpm.mechanics.materials` needs no ``F_ref``
for its stress: its state ``C_p⁻¹`` enters only through the elastic left
Cauchy-Green tensor ``b_e = F C_p⁻¹ Fᵀ``, and the state on the new
reference is ``C_p,ref⁻¹ = b_e`` at the reference (:func:`rebased_state`),
so that ``F_incr C_p,ref⁻¹ F_incrᵀ = F C_p⁻¹ Fᵀ`` exactly.  Its Kirchhoff
stress ``τ = J σ`` then refers to the original volume, ``J = √det b_e``
(plastic flow keeps ``det C_p⁻¹ = 1``); the weak form on the new reference
(Eq. 3.4 pulled back to it) needs ``P_ref = J_incr σ F_incr⁻ᵀ = τ F_incr⁻ᵀ /
J_ref`` with ``J_ref = √det C_p,ref⁻¹`` the volume ratio of the reference, so
:class:`ReferencedMaterial` scales the stress, ``τ`` and the tangent of the
material by ``1 / J_ref`` at every point (under F-bar, ``F`` is the F-bar
gradient the material sees).  ``σ = τ_ref / det F_incr`` is the
Cauchy stress again, as :meth:`SolidProblem.cauchy_stress` computes it.
"""

import numpy as np

from .materials import MaterialState

__all__ = ["ReferencedMaterial", "elastic_left_cauchy_green", "rebased_state",
           "reference_volume_ratio", "total_deformation_gradient"]


def elastic_left_cauchy_green(F, state):
    """``b_e = F C_p⁻¹ Fᵀ`` (n, 3, 3), symmetrized, at deformation gradients ``F``."""
    b = F @ state.Cp_inv @ F.transpose(0, 2, 1)
    return 0.5 * (b + b.transpose(0, 2, 1))


def rebased_state(b_e, alpha):
    """The material state on a reference where ``F_incr = I``: ``C_p⁻¹ = b_e``."""
    b_e = np.asarray(b_e, float)
    return MaterialState(0.5 * (b_e + b_e.transpose(0, 2, 1)), np.asarray(alpha, float).copy())


def total_deformation_gradient(F_incr, F_ref):
    """``F = F_incr · F_ref`` (n, 3, 3); ``F_ref`` None: the first reference."""
    return F_incr if F_ref is None else F_incr @ F_ref


def reference_volume_ratio(state):
    """``J_ref = √det C_p⁻¹`` (n,) of a state rebased by :func:`rebased_state`:
    the volume ratio that the material's Kirchhoff stress refers to."""
    return np.sqrt(np.linalg.det(state.Cp_inv))


class ReferencedMaterial:
    """``material`` on a reference with volume ratios ``J_ref`` (n,) at the
    material points (:func:`reference_volume_ratio`): stress, Kirchhoff
    stress and tangent divided by ``J_ref`` point by point (see the module
    text).

    Every other attribute (moduli ``E``, ``G``, ``K``; ``return_map``) is the
    material's own.
    """

    def __init__(self, material, J_ref):
        if isinstance(material, ReferencedMaterial):
            material = material.material
        J_ref = np.asarray(J_ref, float)
        if J_ref.ndim != 1:
            raise ValueError(f"J_ref must have shape (n,), not {J_ref.shape}")
        bad = np.flatnonzero(~(J_ref > 0) | ~np.isfinite(J_ref))
        if bad.size:
            raise ValueError(f"J_ref = {J_ref[bad[0]]:.3g} at material point {bad[0]} "
                             f"({bad.size} points): a reference must be a valid "
                             f"deformation (0 < J_ref < inf)")
        self.material = material
        self.scale = 1.0 / J_ref

    def __getattr__(self, name):
        if name in ("material", "scale"):
            raise AttributeError(name)
        return getattr(self.material, name)

    def _scaled(self, values):
        return values * self.scale.reshape((-1,) + (1,) * (values.ndim - 1))

    def stress(self, F, state):
        """``P_ref``, ``τ_ref``, the new state and the return point, for the
        increments ``F`` since the reference."""
        if len(F) != len(self.scale):
            raise ValueError(f"{len(F)} deformation gradients for a reference of "
                             f"{len(self.scale)} material points")
        P, tau, new_state, point = self.material.stress(F, state)
        return self._scaled(P), self._scaled(tau), new_state, point

    def tangent(self, point, entries=None):
        """``∂P_ref/∂F_incr = A / J_ref``."""
        return self._scaled(self.material.tangent(point, entries))

    def update(self, F, state, tangent=True, entries=None):
        P, tau, new_state, point = self.stress(F, state)
        return P, tau, new_state, self.tangent(point, entries) if tangent else None
