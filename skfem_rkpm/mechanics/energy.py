"""Energy accounts of a dynamic run: kinetic, internal (elastic and plastic),
contact and external work.

The works are summed by the trapezoidal rule over each step,
``W += ½ Δdᵀ (f_n + f_(n+1))``.  For the trapezoidal Newmark rule
(``β = 1/4``, ``γ = 1/2``) this is exact bookkeeping: its updates give
``Δd = ½ Δt (v_n + v_(n+1))`` and ``M (v_(n+1) − v_n) = ½ Δt M (a_n + a_(n+1))``,
so that ``ΔT = ½ Δdᵀ M (a_n + a_(n+1))``; with the equation of motion
(Eq. 3.38) met at both ends of the step,

    T + W_int + W_contact − W_ext = const + Σ ½ Δdᵀ (r_n + r_(n+1)),

where ``r`` is what is left of the residual at convergence (the Newton
tolerance, and the reactions of the prescribed conditions, which do no
work on homogeneous conditions ``C Δd = 0``), for any internal force,
elastic, plastic or in contact.  The HHT-α method (``α < 0``) dissipates:
the balance falls by its numerical damping.

The internal work is the elastic energy stored plus the plastic
dissipation; :func:`stored_energy` gives the first for the hyperelastic
J2 material (Hencky's energy of the elastic log strains), and the
plastic dissipation is the rest.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["EnergyAccount", "EnergyState", "stored_energy"]


def stored_energy(problem, evaluation):
    """Elastic energy ``∫ ψ dΩ₀`` with Hencky's ``ψ = μ |dev ε_e|² + ½ κ (tr ε_e)²``
    of the principal elastic log strains ``ε_e`` after the return map, at an
    evaluation of a :class:`~skfem_rkpm.mechanics.problem.SolidProblem` with
    the J2 material (with F-bar, those of ``F̄``); NaN for a problem without
    them."""
    material = getattr(problem, "material", None)
    point = getattr(evaluation, "point", None)
    if material is None or not hasattr(point, "eps_trial"):
        return float("nan")
    vol = point.eps_trial.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.where(point.dgamma > 0,
                          1.0 - 3.0 * material.G * point.dgamma / point.q_trial, 1.0)
    dev = factor[:, None] * (point.eps_trial - vol[:, None] / 3.0)
    psi = material.G * np.sum(dev * dev, axis=1) + 0.5 * material.K * vol * vol
    return float(psi @ np.asarray(problem.whole_dx).reshape(-1))


@dataclass
class EnergyState:
    """The energies at one time (in the problem's units, e.g. N·mm = mJ)."""
    time: float
    kinetic: float
    internal: float
    contact: float
    external: float
    #: elastic energy stored (NaN when the material gives none)
    elastic: float
    #: Σ ½ |Δd| (|r_n| + |r_(n+1)|): a bound of what the residual left at
    #: convergence can change the balance by
    residual_bound: float

    @property
    def plastic(self):
        """Plastic dissipation: the internal work not stored elastically."""
        return self.internal - self.elastic

    @property
    def balance(self):
        """``T + W_int + W_contact − W_ext``: constant for an exact integration."""
        return self.kinetic + self.internal + self.contact - self.external


class EnergyAccount:
    """Running sums of the works of a dynamic run with mass ``M`` (sparse)."""

    def __init__(self, M):
        self.M = M

    def kinetic(self, v):
        return 0.5 * float(v @ (self.M @ v))

    def start(self, time, v, f_int, f_contact, f_ext, elastic, r=None):
        """The initial state: works zero, forces kept for the first increment."""
        self.time, self.v = time, v
        self.forces = (f_int, f_contact, f_ext)
        self.r = np.zeros_like(v) if r is None else r
        self.works = [0.0, 0.0, 0.0]
        self.elastic, self.bound = elastic, 0.0

    def advance(self, time, delta, v, f_int, f_contact, f_ext, elastic, r):
        """Add the step ``Δd = delta`` with the forces at its end."""
        new = (f_int, f_contact, f_ext)
        for k, (old, f) in enumerate(zip(self.forces, new)):
            self.works[k] += 0.5 * float(delta @ (old + f))
        size = np.linalg.norm(delta)
        self.bound += 0.5 * size * (np.linalg.norm(self.r) + np.linalg.norm(r))
        self.time, self.v, self.forces, self.r, self.elastic = time, v, new, r, elastic

    def record(self):
        internal, contact, external = self.works
        return EnergyState(self.time, self.kinetic(self.v), internal, contact, external,
                           self.elastic, self.bound)
