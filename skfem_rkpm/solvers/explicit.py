"""Explicit dynamics: the central-difference scheme for Eq. (3.38) with a
lumped mass.

With a diagonal mass ``m`` (:func:`skfem_rkpm.mechanics.mass.lumped_mass`,
the row sums in generalized coordinates) the equation of motion
``M d̈ = f_ext − f_int − f_contact`` needs no linear solve: each step
evaluates the internal and contact forces once and divides by ``m``, for RK
and FEM bases alike.  The loop never enters Newton.

The stable step ``2 / ω_max`` is estimated on the current configuration
and recomputed as the body deforms (:class:`EstimatePolicy`: at most every
``estimate_every`` steps, sooner while ``ω²`` grows fast, with the step
taken from ``ω²`` extrapolated to the next estimate):

- the body's ``ω²`` is the largest eigenvalue of ``M⁻¹K`` with the tangent
  ``K`` of the current state (Lanczos, started from the last eigenvector,
  with the products of the tangent formed without its matrix);
- the penalty contact adds at most the Gershgorin bound of
  ``Gᵀ diag(ω w) G`` over ``m`` (Weyl's inequality: the largest eigenvalue
  of a sum is at most the sum of the largest ones), computed once, as if
  every slave point were closed.

Energies are accounted at every step (trapezoidal work increments): the
kinetic energy ``½ vᵀ M v``, the internal work ``∫ f_int · dd`` (elastic
energy and plastic dissipation), the contact work and the external work;
their balance (:attr:`EnergyRecord.balance`, with the kinetic energy of the
half-step velocities) measures the error of the integration.
"""

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, splu

from ..mechanics.mass import lumped_mass, scaled_largest
from ..mechanics.problem import InvertedElementError, NonFiniteError

__all__ = ["CentralDifference", "EnergyRecord", "EstimatePolicy", "StepEstimate",
           "contact_frequency_bound"]

#: relative accuracy of the Lanczos estimate of ω²_max (ARPACK's ``tol``)
LANCZOS_TOLERANCE = 1e-6
#: Lanczos vectors of an estimate (ARPACK's ``ncv``)
LANCZOS_VECTORS = 10
#: growth of ω²_max that the extrapolation may predict between two estimates
GROWTH_PER_ESTIMATE = 0.1


class EstimatePolicy:
    """When to estimate ``ω²_max`` again, and the ``ω²`` a step uses until then.

    After two estimates, ``ω²`` is taken to grow at the rate between them,
    ``r = ln(ω²_k / ω²_(k-1)) / steps`` (no less than 0).  The next estimate
    comes ``n = ln(1 + g) / r`` steps later (``g``: ``GROWTH_PER_ESTIMATE``),
    at least one step, at most ``longest`` and at most twice the last
    interval, and the steps until then use ``ω²_k e^(r n)``, the value
    extrapolated to the next estimate (at most ``(1 + g) ω²_k``: a step at
    most 5 % shorter).  The first interval is ``longest // 10`` steps, to
    measure a rate.

    A step ``safety · 2/ω`` stays below the critical ``2/ω(t)`` while ``ω²``
    grows by at most ``(1 + g) / safety²`` (1.36 with 0.9 and 0.1) over an
    interval, that is while the growth rate does not triple from one
    interval to the next.  At an impact's onset it does, from nearly zero:
    on the 3D Taylor bar it rose 3.8 times between the first two 10-step
    intervals; the short first interval and the doubling limit keep the
    step within ``(1 + g)`` of the rate then (docs/dynamics.md,
    "The stable step").
    """

    def __init__(self, longest, growth=GROWTH_PER_ESTIMATE):
        self.longest, self.growth = int(longest), float(growth)
        self.last = None  # (step, ω², steps to it) of the last estimate

    def after_estimate(self, step, omega2):
        """``(ω² for the steps, steps to the next estimate)`` after an
        estimate ``omega2`` at ``step``."""
        if self.last is None:
            n, rate = max(1, self.longest // 10), 0.0
        else:
            before, value, interval = self.last
            rate = max(np.log(omega2 / value) / (step - before), 0.0)
            n = self.longest if rate * self.longest <= np.log1p(self.growth) else \
                max(1, int(np.log1p(self.growth) / rate))
            n = min(n, 2 * interval)
        self.last = (step, omega2, n)
        return omega2 * np.exp(rate * n), n


@dataclass
class StepEstimate:
    """An estimate of the stable step during a run (``CentralDifference.estimates``):
    the step and time, the body's ``ω²_max``, the critical step
    ``2 / sqrt(ω²_body + ω²_contact)`` and the step taken up to here (0 at
    the first); ``taken / critical`` above 1 means the last interval ran
    above the stable step at its end."""
    step: int
    time: float
    omega2: float
    critical: float
    taken: float


@dataclass
class EnergyRecord:
    """Time, coefficients, velocities and energies at one output time."""
    time: float
    step: int
    d: np.ndarray
    v: np.ndarray
    kinetic: float
    leapfrog_kinetic: float
    internal: float
    contact: float
    external: float
    dt: float
    forces: dict = field(default_factory=dict)

    @property
    def balance(self):
        """``T̃ + W_int + W_contact − W_ext`` with the leapfrog kinetic energy
        ``T̃ = ½ v_(n-½)ᵀ M v_(n+½)``.

        For a linear elastic body at a constant step this sum is the
        invariant of central differences, constant to round-off (the
        trapezoidal internal work is ``½ dᵀ K d`` exactly); what it changes
        by measures nonlinearity, contact and plastic work errors.  The
        kinetic energy ``½ v_nᵀ M v_n`` differs from ``T̃`` by
        ``⅛ Δt² aᵀ M a``, an O((ω Δt)²) share of each mode's energy.
        """
        return self.leapfrog_kinetic + self.internal + self.contact - self.external


def contact_frequency_bound(contact, m):
    """Upper bound of ``ω²`` that the penalty contact can add: the largest
    Gershgorin row sum of ``|G|ᵀ diag(ω w) |G|`` over ``m``.

    The penalty energy of a slave point, ``½ ω w (n · u)²`` (normal) plus the
    tangential one, is at most ``½ max(ω_n, ω_t) w |u|²``; the hat-weighted
    averages of ``collocation="quadrature"`` do not exceed it (Jensen).  So
    the contact stiffness is bounded by ``Gᵀ diag(ω w) G`` with
    ``ω = max(ω_n, ω_t)``.
    """
    pts = contact.points
    G = abs(sp.csr_matrix(pts.G))
    omega = max(contact.omega_n, contact.omega_t)
    W = np.repeat(omega * pts.weights, pts.dim)
    row = G.T @ (W * (G @ np.ones(G.shape[1])))
    return float((row / m).max())


class CentralDifference:
    """Central differences with a lumped mass for a :class:`SolidProblem`.

    Parameters
    ----------
    problem : SolidProblem
    density : float or array over the quadrature points
        Reference density ``ρ₀`` (t/mm³ in mm, N, MPa, s units).
    contacts : sequence of RigidContact
        Penalty contacts with rigid tools (``enforcement="penalty"``); their
        tools move with the load factor ``t = time / duration``.
    safety : float
        The step is ``safety · 2 / ω_max``.
    estimate_every : int
        Most steps between two estimates of ``ω_max`` on the current
        configuration (:class:`EstimatePolicy`: fewer while it grows fast).
    mass : ndarray, optional
        A lumped mass of the problem's coefficients (default: the row sums).
    constraints : sequence of Constraint
        Homogeneous kinematic conditions ``C d = 0`` (an axis, a symmetry
        plane, a fixed face: :func:`~skfem_rkpm.approximation.constraints.nodal_constraint`,
        the rows of ``Λᵀ`` of Eq. 3.32-3.34), held by projecting velocities
        and accelerations (:meth:`project`).
    """

    def __init__(self, problem, density, contacts=(), safety=0.9, estimate_every=50,
                 mass=None, constraints=()):
        if not 0.0 < safety <= 1.0:
            raise ValueError(f"safety must lie in (0, 1], not {safety!r}")
        if int(estimate_every) < 1:
            raise ValueError(f"estimate_every must be a positive number of steps, "
                             f"not {estimate_every!r}")
        for contact in contacts:
            if getattr(contact, "enforcement", "penalty") != "penalty":
                raise ValueError(f"explicit dynamics needs penalty contact; tool "
                                 f"{contact.name!r} uses {contact.enforcement!r}")
        self.problem, self.contacts = problem, list(contacts)
        self.mass = lumped_mass(problem.assembler, density) if mass is None else \
            np.asarray(mass, dtype=float)
        if self.mass.shape != (problem.N,) or not np.all(self.mass > 0):
            raise ValueError("the lumped mass must be positive, one entry per coefficient")
        self.safety, self.estimate_every = float(safety), int(estimate_every)
        self._contact_omega2 = sum(contact_frequency_bound(c, self.mass)
                                   for c in self.contacts)
        self._mode = self._random = None
        self._ncv = LANCZOS_VECTORS
        self.estimates, self.products = [], 0  # of the last run; tangent products in all
        self._constraint = None
        if len(constraints):
            C = sp.vstack([sp.csr_matrix(c.C) for c in constraints]).tocsr()
            CMinv = (C @ sp.diags(1.0 / self.mass)).tocsr()
            self._constraint = (C, CMinv.T.tocsr(), splu((CMinv @ C.T).tocsc()))

    def project(self, x):
        """``x − M⁻¹Cᵀ (C M⁻¹ Cᵀ)⁻¹ C x``: the part of a velocity or an
        acceleration that keeps ``C d = 0``, nearest in the mass's norm.

        ``C M⁻¹ Cᵀ`` has one row per constrained node and is factored once
        (the functions and the mass are those of the reference
        configuration).  The reactions do no work on the projected motion.
        """
        if self._constraint is None:
            return x
        C, MinvCT, S = self._constraint
        return x - MinvCT @ S.solve(C @ x)

    def body_frequency2(self, d, state=None):
        """Largest ``ω²`` of ``M⁻¹K`` with the tangent at coefficients ``d``
        (Lanczos on ``M^(-1/2) K_sym M^(-1/2)``; the symmetric part bounds the
        real parts of a non-symmetric tangent's eigenvalues).

        ``K_sym`` is applied without the matrix
        (:meth:`SolidProblem.tangent_operator`): a product costs about a
        force evaluation, the assembled matrix of an RK basis far more than
        all the products of a Lanczos run.  The first estimate starts from a
        fixed random vector (ARPACK's own is random: a run would not
        repeat); each later one from the last eigenvector plus a tenth of
        that random vector, so that a mode the last eigenvector misses is
        still in the start.  From there ``LANCZOS_VECTORS`` vectors mostly
        suffice (11 products an estimate on the 3D RKPM Taylor bar, where
        ARPACK's default 20 takes 21); an estimate that needed a restart
        doubles them for the next one (FEM's clustered top of the spectrum
        took 30 products with 10 vectors), one that did not halves them
        again, down to ``LANCZOS_VECTORS``.
        """
        evaluation = self.problem.evaluate(d, state)
        product = self.problem.tangent_operator(evaluation).symmetric
        count = [0]

        def counted(x):
            count[0] += 1
            return product(x)
        K = LinearOperator((self.problem.N,) * 2, matvec=counted, dtype=float)
        if self._random is None:
            r = np.random.default_rng(0).standard_normal(K.shape[0])
            self._random = r / np.linalg.norm(r)
        warm = self._mode is not None
        start = self._mode + 0.1 * self._random if warm else self._random
        omega2, self._mode = scaled_largest(K, self.mass, start, tol=LANCZOS_TOLERANCE,
                                            ncv=self._ncv)
        if warm:  # restarted: twice the vectors next time, else back towards the fewest
            self._ncv = (min(2 * self._ncv, 4 * LANCZOS_VECTORS) if count[0] > self._ncv + 1
                         else max(self._ncv // 2, LANCZOS_VECTORS))
        self.products += count[0]
        return omega2

    def stable_step(self, d, state=None):
        """``safety · 2 / sqrt(ω²_body + ω²_contact)`` at coefficients ``d``."""
        omega2 = self.body_frequency2(d, state) + self._contact_omega2
        return self.safety * 2.0 / np.sqrt(omega2)

    def _forces(self, d, t):
        """Internal and contact forces at ``d`` (trial states kept)."""
        evaluation = self.problem.evaluate(d, tangent=False)
        contact = np.zeros_like(d)
        for c in self.contacts:
            contact += c.evaluate(d, t, tangent=False)[0]
        return evaluation, contact

    def _commit(self, evaluation):
        self.problem.commit(evaluation)
        for c in self.contacts:
            c.commit()

    def run(self, d, v, duration, dt=None, output_interval=None, external=None,
            on_output=None):
        """Integrate from coefficients ``d`` and velocities ``v`` over
        ``duration`` seconds.

        ``dt`` fixes the step (default: the stable step, re-estimated as
        :class:`EstimatePolicy` says).  ``external(time)`` gives the external
        force vector (default none).  Returns the :class:`EnergyRecord` list
        at the start, every ``output_interval`` (default: the end only) and
        the end; ``on_output(record)`` sees each one as it is made.  A step
        whose forces fail raises the problem's error with the last finished
        step's coefficients, time and step number (``error.d``, ``.time``,
        ``.step``).
        """
        d, v = np.array(d, dtype=float), self.project(np.array(v, dtype=float))
        m, time, step = self.mass, 0.0, 0
        f_ext = (lambda _: np.zeros_like(d)) if external is None else external
        evaluation, f_c = self._forces(d, 0.0)
        self._commit(evaluation)
        f_int, fe = evaluation.f_int, f_ext(0.0)
        a = self.project((fe - f_int - f_c) / m)
        W_int = W_c = W_ext = 0.0
        records, next_output = [], 0.0
        policy, h = EstimatePolicy(self.estimate_every), None
        self.estimates = []  # the StepEstimate of each estimate of this run

        def estimate():
            body = self.body_frequency2(d)
            omega2, n = policy.after_estimate(step, body)
            critical = 2.0 / np.sqrt(body + self._contact_omega2)
            self.estimates.append(StepEstimate(step, time, body, critical,
                                               h if self.estimates else 0.0))
            return self.safety * 2.0 / np.sqrt(omega2 + self._contact_omega2), step + n

        h, next_estimate = (dt, None) if dt is not None else estimate()
        h_last = h

        def record():
            # the leapfrog kinetic energy ½ v_(n-½)ᵀ M v_(n+½), with the
            # half-step velocities around v_n (see EnergyRecord.leapfrog_kinetic)
            before, after = v - 0.5 * h_last * a, v + 0.5 * h * a
            out = EnergyRecord(time, step, d.copy(), v.copy(), 0.5 * v @ (m * v),
                               0.5 * before @ (m * after), W_int, W_c, W_ext, h,
                               {k: f for c in self.contacts
                                for k, f in c.resultants().items()})
            records.append(out)
            if on_output is not None:
                on_output(out)

        while True:
            if step == next_estimate and step:
                h, next_estimate = estimate()
            end = time >= duration * (1.0 - 1e-12)
            if end or time >= next_output * (1.0 - 1e-12):
                record()
                if end:
                    return records
                while next_output <= time * (1.0 + 1e-12):
                    next_output = duration if output_interval is None else \
                        next_output + output_interval
            h_step = min(h, duration - time)
            v_half = v + 0.5 * h_step * a
            d_new = d + h_step * v_half
            t_new = time + h_step
            try:
                evaluation, f_c_new = self._forces(d_new, t_new / duration)
            except (InvertedElementError, NonFiniteError) as failure:
                error = type(failure)(
                    f"explicit step {step + 1} to t = {t_new:.4g} s (Δt = {h_step:.3g} s, "
                    f"stable estimate {h:.3g} s): {failure}", failure.points)
                # where the run got to: the last finished step
                error.d, error.time, error.step = d.copy(), time, step
                raise error from None
            self._commit(evaluation)
            fe_new = f_ext(t_new)
            delta = d_new - d
            W_int += 0.5 * delta @ (f_int + evaluation.f_int)
            W_c += 0.5 * delta @ (f_c + f_c_new)
            W_ext += 0.5 * delta @ (fe + fe_new)
            a = self.project((fe_new - evaluation.f_int - f_c_new) / m)
            v = v_half + 0.5 * h_step * a
            d, f_int, f_c, fe, time = d_new, evaluation.f_int, f_c_new, fe_new, t_new
            h_last = h_step
            step += 1
