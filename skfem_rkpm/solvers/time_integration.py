"""Implicit time integration of Eq. (3.38) inside the Newton loop.

The paper's incremental equation with inertia,
``M Δd̈ + K Δd = f_ext,n+1 − f_int,n+1`` (Eq. 3.38; with contact, Eq. 4.24),
is solved one time step at a time by the Newton iterations of
:func:`~skfem_rkpm.solvers.newton.newton_steps`.  Newton sees a step through
one object, an *increment*, that turns the forces it has evaluated into the
residual and the tangent of the step:

- :class:`Quasistatic` (the default): ``r = f_ext − f_int`` and ``K``
  (Eq. 4.25), unchanged;
- :class:`Newmark`: the HHT-α method (Hilber, Hughes & Taylor 1977) with
  the Newmark updates; ``α = 0`` is the trapezoidal rule (``β = 1/4``,
  ``γ = 1/2``), unconditionally stable and without numerical damping.

An increment has four methods, all that Newton calls,

``begin(t_done, t)``
    before each attempt of the step from load factor ``t_done`` to ``t``
    (after a cut-back with the shorter step: nothing is changed before a
    step converges, so that a cut-back restores the state by itself);
``residual(d, f_ext, f_int, evaluation, ref)``
    the residual at coefficients ``d`` from the external force, the internal
    force with the contributions (contact) added, the solid's
    :class:`~skfem_rkpm.mechanics.problem.Evaluation` and the force scale
    ``ref`` of the convergence test; returns ``(r, ref)``;
``tangent(K)``
    the tangent of that residual from the solid's and contributions' ``K``;
``commit()``
    accept the last evaluated state (after the solid and the contributions);

and an attribute ``force_weight``, the factor of the step's forces in the
residual (``1 + α``), by which Newton scales the contact forces it predicts
within an update (nodes brought into touch).

Load factors are times: ``time = t · duration``, so the load, the tools'
motion and the prescribed values are functions of ``t = time / duration``,
and the step control of Newton (cut-backs halve the step) controls ``Δt``.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mechanics.energy import EnergyAccount, stored_energy
from .constrained import solve_constrained

__all__ = ["Quasistatic", "Newmark", "hht_parameters"]


class Quasistatic:
    """The quasi-static increment (Eq. 4.25): ``r = f_ext − f_int``, tangent ``K``."""

    force_weight = 1.0

    def begin(self, t_done, t):
        pass

    def residual(self, d, f_ext, f_int, evaluation, ref):
        return f_ext - f_int, ref

    def tangent(self, K):
        return K

    def commit(self):
        pass


def hht_parameters(alpha):
    """``(β, γ)`` of the HHT-α method: ``β = (1 − α)²/4``, ``γ = 1/2 − α``
    (second order accurate, unconditionally stable for ``α ∈ [−1/3, 0]``)."""
    alpha = float(alpha)
    if not -1.0 / 3.0 - 1e-12 <= alpha <= 0.0:
        raise ValueError(f"HHT-α needs α in [-1/3, 0] (0: trapezoidal, -1/3: the most "
                         f"damping of high modes), not {alpha!r}")
    return 0.25 * (1.0 - alpha) ** 2, 0.5 - alpha


@dataclass
class _Trial:
    """What the last residual evaluated: the state that ``commit`` accepts."""
    d: np.ndarray
    a: np.ndarray
    f_int: np.ndarray
    f_ext: np.ndarray
    evaluation: object
    r: np.ndarray


class Newmark:
    """The HHT-α method with Newmark's updates for Eq. (3.38), as a Newton increment.

    Each step solves for ``d_(n+1)``

        M a_(n+1) + (1 + α) f_int(d_(n+1)) − α f_int(d_n)
            = (1 + α) f_ext(t_(n+1)) − α f_ext(t_n)

    with ``a_(n+1) = (d_(n+1) − d_n − Δt v_n − Δt² (½ − β) a_n) / (β Δt²)``;
    ``f_int`` includes the contact forces (Eq. 4.24).  The tangent is
    ``(1 + α) (K + K_c) + M / (β Δt²)``.  After convergence
    ``v_(n+1) = v_n + Δt ((1 − γ) a_n + γ a_(n+1))``.

    Parameters
    ----------
    problem : SolidProblem
        The solid (its ``evaluate`` gives the forces at the initial state).
    mass : sparse matrix or ndarray
        The mass of the coefficients: consistent
        (:func:`~skfem_rkpm.mechanics.mass.consistent_mass`) or lumped (a
        vector, :func:`~skfem_rkpm.mechanics.mass.lumped_mass`).
    duration : float
        Seconds that the load factor 0 → 1 of Newton spans.
    v0, d0 : ndarray, optional
        Initial velocities and coefficients (default zero); ``d0`` must be
        the ``d0`` given to Newton.
    alpha : float
        HHT-α parameter in ``[−1/3, 0]``; 0 gives the trapezoidal rule.
    contributions, load : as for :func:`~skfem_rkpm.solvers.newton.newton_steps`
        Only to evaluate the forces at the initial state.
    constraints : sequence of Constraint
        Homogeneous conditions ``C d = 0`` that the initial acceleration keeps.
    a0 : ndarray, optional
        Initial acceleration (default: solved from ``M a0 = f_ext − f_int``
        at ``d0`` under the constraints).
    """

    def __init__(self, problem, mass, duration, v0=None, d0=None, alpha=0.0,
                 contributions=(), load=None, constraints=(), a0=None):
        self.beta, self.gamma = hht_parameters(alpha)
        self.alpha = float(alpha)
        self.force_weight = 1.0 + self.alpha
        if not (np.isfinite(duration) and duration > 0):
            raise ValueError(f"duration must be a positive number of seconds, not "
                             f"{duration!r}")
        N = problem.N
        self.duration, self.problem = float(duration), problem
        self.M = sp.diags(_vector(mass, N, "mass"), format="csr") if np.ndim(mass) == 1 \
            else sp.csr_matrix(mass)
        if self.M.shape != (N, N):
            raise ValueError(f"the mass has shape {self.M.shape}; the problem has {N} "
                             "coefficients")
        self.d = np.zeros(N) if d0 is None else _vector(d0, N, "d0").copy()
        self.v = np.zeros(N) if v0 is None else _vector(v0, N, "v0").copy()
        evaluation = problem.evaluate(self.d, tangent=False)
        # every contribution's evaluate(d, t) (contact, follower loads, force control)
        f_contact = sum((c.evaluate(self.d, 0.0)[0] for c in contributions), np.zeros(N))
        self.f_int = evaluation.f_int + f_contact
        self.f_ext = np.zeros(N) if load is None else _vector(load(0.0), N, "load(0)")
        if a0 is None:
            C = (sp.vstack([sp.csr_matrix(c.C) for c in constraints]).tocsr()
                 if len(constraints) else sp.csr_matrix((0, N)))
            a0, _ = solve_constrained(self.M, self.f_ext - self.f_int, C, np.zeros(C.shape[0]))
        self.a = _vector(a0, N, "a0").copy()
        self.time, self.dt, self._trial = 0.0, None, None
        self.account = EnergyAccount(self.M)
        self.account.start(0.0, self.v, evaluation.f_int, f_contact, self.f_ext,
                           stored_energy(problem, evaluation),
                           self.f_ext - self.f_int - self.M @ self.a)
        #: energy records of the initial and every converged state
        self.records = [self.account.record()]

    @classmethod
    def trapezoidal(cls, *args, **kwargs):
        """The trapezoidal rule (average acceleration), ``α = 0``."""
        return cls(*args, alpha=0.0, **kwargs)

    # -- the increment Newton drives --------------------------------------------
    def begin(self, t_done, t):
        """Prepare the step from ``t_done`` to ``t`` (load factors)."""
        if abs(t_done * self.duration - self.time) > 1e-9 * self.duration:
            raise ValueError(f"the step starts at {t_done * self.duration:.6g} s but the "
                             f"integrator is at {self.time:.6g} s: give Newton the "
                             "integrator's d0 and start")
        self.dt = (t - t_done) * self.duration
        self.t_new = t
        h, b = self.dt, self.beta
        self._predicted = self.d + h * self.v + h * h * (0.5 - b) * self.a
        self._c = 1.0 / (b * h * h)
        self._scale = max(np.linalg.norm(self.M @ self.v) / h, np.linalg.norm(self.M @ self.a),
                          np.linalg.norm(self.f_int), np.linalg.norm(self.f_ext))
        self._trial = None

    def residual(self, d, f_ext, f_int, evaluation, ref):
        """``(1 + α)(f_ext − f_int)_(n+1) − α (f_ext − f_int)_n − M a_(n+1)``.

        The force scale of the convergence test adds the inertia force
        ``|M a_(n+1)|``, the forces at the start of the step (``|M a_n|``,
        ``|f_int,n|``, ``|f_ext,n|``) and ``|M v_n| / Δt`` (the force that
        stops the body in one step): a body in free flight, or passing
        through its rest state, where ``f_int`` and ``f_ext`` vanish, has a
        scale."""
        a = self._c * (d - self._predicted)
        Ma = self.M @ a
        r = (1.0 + self.alpha) * (f_ext - f_int) - self.alpha * (self.f_ext - self.f_int) - Ma
        self._trial = _Trial(d, a, f_int, f_ext, evaluation, r)
        ref = max(ref, np.linalg.norm(Ma), self._scale)
        return r, ref

    def tangent(self, K):
        """``(1 + α) K + M / (β Δt²)``."""
        return (1.0 + self.alpha) * K + self._c * self.M

    def commit(self):
        """Accept the last evaluated state: Newmark's velocity update and the
        energy account (:class:`~skfem_rkpm.mechanics.energy.EnergyAccount`)."""
        trial = self._trial
        if trial is None:
            raise RuntimeError("commit() before a residual of the step was evaluated")
        h, g = self.dt, self.gamma
        self.v = self.v + h * ((1.0 - g) * self.a + g * trial.a)
        self.a, self.time = trial.a, self.t_new * self.duration
        f_solid = trial.evaluation.f_int
        self.account.advance(self.time, trial.d - self.d, self.v, f_solid,
                             trial.f_int - f_solid, trial.f_ext,
                             stored_energy(self.problem, trial.evaluation), trial.r)
        self.d, self.f_int, self.f_ext = trial.d, trial.f_int, trial.f_ext
        self.records.append(self.account.record())
        self._trial = None


    # -- checkpoints --------------------------------------------------------------
    def snapshot(self):
        """The state the next step depends on, as arrays and numbers (for
        ``numpy.savez``; nothing to unpickle): time, ``d``, ``v``, ``a``, the
        forces at ``t_n`` and the running energy account."""
        acc = self.account
        f_int, f_contact, f_ext = acc.forces
        return dict(time=self.time, d=self.d, v=self.v, a=self.a, f_int=self.f_int,
                    f_ext=self.f_ext, solid_force=f_int, contact_force=f_contact,
                    residual=acc.r, works=np.array(acc.works), elastic=acc.elastic,
                    residual_bound=acc.bound, alpha=self.alpha)

    def restore(self, snapshot):
        """Continue from a :meth:`snapshot` (of an integrator with the same
        α and problem size); ``records`` restarts with the restored state."""
        N = self.problem.N
        if float(snapshot["alpha"]) != self.alpha:
            raise ValueError(f"the snapshot was taken with α = {float(snapshot['alpha'])}, "
                             f"this integrator has α = {self.alpha}")
        arrays = {k: _vector(snapshot[k], N, f"snapshot {k!r}")
                  for k in ("d", "v", "a", "f_int", "f_ext", "solid_force",
                            "contact_force", "residual")}
        self.time = float(snapshot["time"])
        self.d, self.v, self.a = arrays["d"], arrays["v"], arrays["a"]
        self.f_int, self.f_ext = arrays["f_int"], arrays["f_ext"]
        acc = self.account
        acc.time, acc.v, acc.r = self.time, self.v, arrays["residual"]
        acc.forces = (arrays["solid_force"], arrays["contact_force"], self.f_ext)
        acc.works = [float(w) for w in np.asarray(snapshot["works"], float)]
        acc.elastic, acc.bound = float(snapshot["elastic"]), float(snapshot["residual_bound"])
        self.records = [acc.record()]
        self._trial = None


def _vector(x, N, name):
    x = np.asarray(x, dtype=float)
    if x.shape != (N,) or not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be {N} finite numbers (one per coefficient), "
                         f"not an array of shape {x.shape}")
    return x
