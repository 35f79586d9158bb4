"""Active-set prediction of the stick branch for the 2D rigid-tool contact.

A slipping contact node has no tangential stiffness along its slip in the
consistent tangent of Eq. (4.29): its traction is ``μ t_n sgn(T*)`` with the
trial ``T* = λ_t - ω_t φ Δĝ_t`` (Eq. 4.6, 4.11).  A Newton update computed
with that tangent moves the node as if it were free.  Near a neutral point of
the friction, where the slip of the step is small (the ring's top face, where
the material flow turns from inwards to outwards), a small part of the update
already carries ``T*`` through the stick cone ``|T*| ≤ μ t_n`` (of width
``2 μ t_n / ω_t`` in slip) and over to slip the other way: the nodal shear
jumps by ``2 μ t_n W``, the energy slope of the line search changes sign at
the jump, and the update is cut to a fraction, iteration after iteration
(measured on the ring at μ = 0.15 with SCNI: 20-40 iterations at steps of
0.03-0.5 in the six steps where a side particle reaches the platen).

:func:`sticking` linearizes the law about the last evaluation: with the
point displacements ``u = G δ`` of the update,

    Δĝ_t' δ = W⁻¹ M (a t · u),      ĝ' δ = W⁻¹ M (n · u),
    T*(δ) = T* - ω_t (φ Δĝ_t' δ + φ' Δĝ_t ĝ' δ),
    t_n(δ) = t_n - ω_n ĝ' δ,

(``a = 1 - κ Δξ·n`` from the rotation of the tangent, the same terms as the
stick part of the tangent, :func:`~skfem_rkpm.mechanics.rigid_contact._rigid_tangent`).
A slipping node whose linearized trial lands inside the linearized cone, or
turns against its present trial, takes its stick branch in the linear
model, and the update is solved again
(:func:`skfem_rkpm.solvers.newton._update`).  Only the linear model of the
update changes: the next iterate is evaluated with the law itself, so the
converged solution is the same (to the Newton tolerance).  The 3D surface
contact has its own (:meth:`~skfem_rkpm.mechanics.surface_contact.SurfaceContact.sticking`).
"""

import numpy as np

__all__ = ["linearized_law", "sticking"]


def linearized_law(contact, delta):
    """The trial shear ``T*(δ)`` (m,) and pressure ``t_n(δ)`` (m,) of the
    contact nodes of a :class:`~skfem_rkpm.mechanics.rigid_contact.RigidContact`
    after the update ``delta``, in the linear model of its last evaluation."""
    _, _, proj, slipped, law, _, _ = contact._linear
    pressure, slip_t, phi, dphi = law[0], law[4], law[5], law[6]
    pts = contact.points
    u = pts.displacements(delta).T  # (n, 2)
    normal, tangent = proj.normal.T, proj.tangent.T
    a = 1.0 - proj.curvature * np.einsum("ni,ni->n", slipped, normal)
    d_slip = pts.average(a * np.einsum("ni,ni->n", tangent, u))
    d_gap = pts.average(np.einsum("ni,ni->n", normal, u))
    trial = contact.multipliers[1] - contact.omega_t * phi * slip_t
    lin_trial = trial - contact.omega_t * (phi * d_slip + dphi * slip_t * d_gap)
    return trial, lin_trial, pressure - contact.omega_n * d_gap


def sticking(contact, delta):
    """``(nodes, f, K)``: the slipping nodes of ``contact`` that the update
    ``delta`` would bring into stick or turn (a boolean mask), and the
    changes of its force and tangent at the last evaluation when those
    nodes take the stick branch; None if there are none (or no tangent
    was formed, or ``μ`` is 0 or infinite)."""
    linear = contact._linear
    if linear is None or linear[6] is None or not 0.0 < contact.mu < np.inf:
        return None
    d, t, _, _, law, f0, K0 = linear
    candidates = law[2] & law[3] & ~contact._freeze.sliding
    if not candidates.any():
        return None
    trial, lin_trial, lin_pressure = linearized_law(contact, delta)
    inside = np.abs(lin_trial) <= contact.mu * np.maximum(lin_pressure, 0.0)
    turned = lin_trial * trial <= 0.0
    held = candidates & (inside | turned)
    if not held.any():
        return None
    saved = (contact.trial, contact._normals, contact._linear)
    contact._held_stick = held
    try:
        f1, K1 = contact.evaluate(d, t)
    finally:
        contact._held_stick = None
        contact.trial, contact._normals, contact._linear = saved
    return held, f1 - f0, (K1 - K0).tocsr()
