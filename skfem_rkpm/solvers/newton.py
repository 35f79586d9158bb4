"""Incremental-iterative Newton-Raphson with adaptive load steps.

Each step raises the load factor ``t`` (0 → 1) and solves

    f_int(d) = f_ext(t) + Cᵀ λ,      C d = g(t),

where ``C`` holds the rows of the transformation ``Λᵀ`` (Eq. 3.33) of the
prescribed nodal dofs, so displacements are prescribed on nodal values as in
Eq. (3.37).  Every iteration solves the linearized saddle-point system with
the consistent tangent.  A step that does not converge (too many
iterations, a diverging residual, an inverted element, a failed return map)
is cut in half and retried; everything converged so far is kept.
"""

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..approximation.constraints import ConstraintSet, nodal_constraint, weak_constraint
from .constrained import solve_constrained
from .linear import make_solver
from .low_rank import solve_updated
from .step_control import StepControl
from .time_integration import Quasistatic
from ..mechanics.problem import InvertedElementError, NonFiniteError

__all__ = ["Prescribed", "StepRecord", "Result", "NonConvergence", "StepperState",
           "newton_steps"]


@dataclass
class Prescribed:
    """A displacement component prescribed on a named boundary.

    Parameters
    ----------
    boundary : str
        Name in ``mesh.boundaries``.
    component : int or sequence of float
        Displacement component (0: x or r, 1: y or z, 2: z), or a direction
        ``n``: then ``n·u`` is prescribed (a symmetry plane with normal
        ``n`` not aligned with the axes).
    values : float or callable
        Final value, reached linearly in the load factor ``t``; or
        ``values(t, x)`` giving the value at node coordinates ``x`` (dim, n).
    method : {"nodal", "weak"}
        Nodal values through the transformation method (Eq. 3.37), or weakly
        along the boundary with boundary multipliers
        (:func:`skfem_rkpm.approximation.constraints.weak_constraint`).
    """

    boundary: str
    component: int
    values: object = 0.0
    method: str = "nodal"

    def __post_init__(self):
        if not callable(self.values) and not np.isfinite(float(self.values)):
            raise ValueError(f"Prescribed({self.boundary!r}, {self.component}): the "
                             f"value must be finite, not {self.values}")

    @property
    def name(self):
        if isinstance(self.component, (int, np.integer)):
            return f"{self.boundary}[{self.component}]"
        n = np.asarray(self.component, float)
        return f"{self.boundary}[n={' '.join(f'{c:.4g}' for c in n / np.linalg.norm(n))}]"

    def constraint(self, basis):
        if self.method == "nodal":
            return nodal_constraint(basis, self.boundary, self.component)
        if self.method == "weak":
            return weak_constraint(basis, self.boundary, self.component)
        raise ValueError(f"method must be 'nodal' or 'weak', not {self.method!r}")

    def at(self, t, x):
        if callable(self.values):
            values = np.broadcast_to(np.asarray(self.values(t, x), float), (x.shape[1],))
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                where = ", ".join(f"{c:.6g}" for c in x[:, bad[0]])
                raise ValueError(
                    f"prescribed values of {self.name} at t = {t:.6g} are not finite "
                    f"at {bad.size} of {len(values)} nodes; first {values[bad[0]]} at "
                    f"X = ({where}): check the function given as values")
            return values
        return np.full(x.shape[1], t * float(self.values))


@dataclass
class StepRecord:
    """What one converged step did; ``seconds`` counts every attempt."""

    step: int
    t: float
    iterations: int
    residuals: list
    energies: list
    seconds: float
    reactions: dict = field(default_factory=dict)
    cutbacks: int = 0
    #: Newton attempts of the step (failed ones, cut-backs and the converged one)
    attempts: int = 1
    #: iterations of all attempts (``iterations`` counts the converged one only)
    spent_iterations: int = 0
    #: contact nodes whose status (touching, slipping) the step changed
    contact_changes: int = 0


@dataclass
class Result:
    """Outcome of :func:`newton_steps`: converged steps, their solutions, status."""

    d: np.ndarray
    history: list
    solutions: list
    completed: bool
    message: str = ""
    #: the last error of the step that failed (None for a completed run)
    error: BaseException = None


@dataclass
class StepperState:
    """What the next step of :func:`newton_steps` depends on besides the
    coefficients and the problem's own state: the load factor reached
    ``t``, the number of converged steps ``step`` (cut-back sub-steps
    included), the predictor ``rate``, ``dd/dt`` of the last step (``None``
    before the first), and the step size ``control``.  Checkpoint it to
    resume a run exactly."""

    t: float = 0.0
    step: int = 0
    rate: np.ndarray = None
    control: StepControl = None


class NonConvergence(RuntimeError):
    """A step failed even after the allowed cut-backs."""


class _Reactions:
    """Least-squares split of a force into reactions ``Cᵀ λ`` and the rest."""

    def __init__(self, C):
        self.C, self.CT = sp.csr_matrix(C), sp.csr_matrix(C.T)
        try:
            self.lu = splu((C @ C.T).tocsc()) if C.shape[0] else None
        except RuntimeError as err:
            raise ValueError(f"the prescribed conditions are linearly dependent ({err}): "
                             "two of them constrain the same motion; prescribe each "
                             "component of a node once") from None

    def multipliers(self, force):
        """λ with ``Cᵀ λ`` closest to ``force``."""
        return self.lu.solve(self.C @ force) if self.lu else np.zeros(0)

    def out_of_balance(self, force):
        """``force`` minus its reaction part."""
        return force - self.CT @ self.multipliers(force) if self.lu else force


#: a step also converges when the update's energy ``|δ·r|`` has fallen to this
#: fraction of the step's first one and the residual is below
#: ``SETTLED_RESIDUAL * tol``: the corrections are then at round-off while a
#: contact node at zero gap flips in and out of contact by 1e-9 of the
#: spacing, and its penalty keeps the residual from falling further
#: (measured on the punch stretch at 29 mm: residuals 4e-6..5e-5 for 12
#: iterations with energies 1e-15..1e-17)
ROUND_OFF_ENERGY = 1e-14
SETTLED_RESIDUAL = 100.0

#: an update whose energy ``|δ·r|`` is below this fraction of the step's
#: first one is taken whole: the line search would compare slopes ``δ·r`` at
#: the level of their round-off (measured: a damped update at 8.5e-14 that
#: cost an iteration more with one linear solver than with another)
FULL_STEP_ENERGY = 1e-10


def newton_steps(problem, prescribed=(), load=None, steps=10, tol=1e-6,
                 max_iterations=20, max_cutbacks=8, log=None, d0=None,
                 contributions=(), start=0.0, on_step=None, extrapolate=True,
                 linear_solver="auto", control=None, max_augmentations=30,
                 stepper=None, increment=None):
    """Drive ``problem`` from ``t = 0`` to ``t = 1`` in load steps.

    Parameters
    ----------
    problem : SolidProblem
    prescribed : sequence of Prescribed
        Nodal displacement conditions.
    load : callable, optional
        ``t -> f_ext`` (generalized load vector of length ``problem.N``).
    steps : int or sequence of float
        Number of equal steps, or the increasing load factors to reach.
    tol : float
        Relative residual tolerance (the paper's 1e-6): the out-of-balance
        force, reactions removed, over the largest of ``|f_int|``,
        ``|f_ext|`` and each contribution's ``|f_c|``.  A step whose
        updates have reached round-off (energy ``ROUND_OFF_ENERGY`` of the
        first) converges with a residual up to ``SETTLED_RESIDUAL * tol``.
    max_iterations : int
        Newton iterations before a step is cut back.
    max_cutbacks : int
        Halvings allowed per step.  The step size is remembered and grows
        again after easy steps (:class:`~skfem_rkpm.solvers.step_control.StepControl`).
    log : callable, optional
        Called with one line of text per iteration and per step.
    d0 : ndarray, optional
        Initial coefficients (default zero).
    contributions : sequence, optional
        Extra nonlinear forces such as contact.  Each has
        ``evaluate(d, t) -> (f, K)`` (a force added to the internal force and
        its tangent), ``commit()`` (accept the last evaluated state) and
        ``resultants() -> dict`` (named force vectors, e.g. tool reactions,
        recorded with each step).
    start : float
        Load factor of ``d0`` (to resume a run): only later targets are run.
    on_step : callable, optional
        ``on_step(record, d, evaluation)`` after every converged step (the
        problem's state is committed), e.g. to write results as they come.
    extrapolate : bool
        Start each step's iterations from the last step's rate of change,
        ``d + Δt (Δd/Δt)_last``, instead of from ``d``: the predictor then
        starts close to the new state, in particular with a moving tool,
        whose penalty would otherwise see the whole step's penetration.
        If that start fails, the step is retried from ``d`` before it is cut.
    linear_solver : str or skfem_rkpm.solvers.linear.Solver
        Backend of the linearized solves (:func:`skfem_rkpm.solvers.linear.make_solver`):
        ``"auto"``, ``"dense"``, ``"superlu"``, ``"pardiso"``, ``"cholmod"``
        or ``"amg"``; one instance serves the whole run, so that its
        symbolic analysis is reused while the sparsity pattern stays.
    max_augmentations : int
        Multiplier updates of augmented-Lagrangian contributions (contact
        with ``augment()``) per step before the attempt counts as failed.
    control : StepControl, optional
        Step size control; default: steps up to the largest spacing of the
        targets, down to 1e-6 of the smallest (``max_cutbacks`` halvings
        per step stop a run first).  A contribution with
        ``status_changes()`` reports the contact nodes whose status changed
        in the step.
    stepper : StepperState, optional
        Start from it (the load factor, step count, predictor and step
        control of a checkpoint: ``start`` is then ignored, and its
        ``control``, if set, replaces ``control``) and keep it up to date: it
        is updated in place after every converged step, before ``on_step``.
    increment : optional
        What a step solves, given the forces Newton evaluates
        (:mod:`skfem_rkpm.solvers.time_integration`): quasi-static by
        default (:class:`~skfem_rkpm.solvers.time_integration.Quasistatic`),
        or a time step with inertia
        (:class:`~skfem_rkpm.solvers.time_integration.Newmark`, Eq. 3.38),
        whose load factor is ``time / duration``.

    Returns
    -------
    Result
        ``completed`` is False if a step failed; ``history`` and
        ``solutions`` then hold everything converged before.
    """
    targets = (np.linspace(0.0, 1.0, steps + 1)[1:] if np.isscalar(steps)
               else np.asarray(steps, dtype=float))
    log = log or (lambda line: None)
    groups = [p.constraint(problem.basis) for p in prescribed]
    rows = ConstraintSet(groups, problem.N, [p.name for p in prescribed])
    C = rows.C  # shared corners: dependent rows removed
    reactions_fit = _Reactions(C)
    linear_solver = make_solver(linear_solver)
    if hasattr(linear_solver, "follow_newton"):  # a reused factorization's GMRES
        linear_solver.follow_newton(tol)
    increment = Quasistatic() if increment is None else increment
    described = None
    if control is None:
        spacing = np.diff(np.concatenate([[0.0], targets]))
        control = StepControl(float(spacing.max()), 1e-6 * float(spacing.min()))

    def g(t):
        return rows.values(np.concatenate([c.R @ p.at(t, c.coordinates)
                                           for p, c in zip(prescribed, groups)]
                                          or [np.zeros(0)]))

    def f_ext(t):
        return np.zeros(problem.N) if load is None else load(t)

    d = np.zeros(problem.N) if d0 is None else np.array(d0, dtype=float)
    rate = None  # dd/dt of the last converged step
    history, solutions = [], []
    t_done = float(start)
    step_index = int(np.sum(targets <= t_done + 1e-14))
    if stepper is not None:
        t_done, step_index, rate = float(stepper.t), int(stepper.step), stepper.rate
        control = stepper.control = stepper.control or control
    for target in targets[targets > t_done + 1e-14]:
        while t_done < target - 1e-14:
            clock = time.perf_counter()
            tally = dict(attempts=0, iterations=0)
            for cut in range(max_cutbacks + 1):
                dt = control.next(t_done, target)
                t = t_done + dt
                g_t, f_t = g(t), f_ext(t)
                starts = ([d + dt * rate, d] if extrapolate and rate is not None else [d])
                increment.begin(t_done, t)
                for guess in starts:
                    tally["attempts"] += 1
                    try:
                        d_new, ev, lam, its, res, en = _augmented_newton(
                            problem, guess, t, C, g_t, f_t, reactions_fit, tol,
                            max_iterations, log, contributions, linear_solver, tally,
                            max_augmentations, increment)
                    except (NonConvergence, InvertedElementError, RuntimeError,
                            np.linalg.LinAlgError) as err:
                        log(f"step {step_index + 1}: t = {t:.6g} failed ({err})")
                        last_error = err
                        continue
                    break
                else:
                    if control.failed(dt) and cut < max_cutbacks:
                        log(f"step {step_index + 1}: cutting the step")
                        continue
                    message = (f"step {step_index + 1} to t = {target:.6g} failed after "
                               f"{cut} cut-backs: {last_error} (last try: t = {t:.6g})")
                    log(message)
                    return Result(d, history, solutions, False, message, last_error)
                break
            problem.commit(ev)
            if _solver_line(linear_solver) != described:
                described = _solver_line(linear_solver)
                log(f"linear solver: {described}")
            reactions = _reactions(prescribed, groups, rows.expand(lam))
            changes = sum(c.status_changes() for c in contributions
                          if hasattr(c, "status_changes"))
            for contribution in contributions:
                contribution.commit()
                reactions.update(contribution.resultants())
            increment.commit()
            control.converged(dt, its, changes, cut=cut > 0)
            rate = (d_new - d) / (t - t_done)
            d, t_done = d_new, t
            step_index += 1
            record = StepRecord(step_index, t, its, res, en,
                                time.perf_counter() - clock, reactions, cut,
                                tally["attempts"], tally["iterations"], changes)
            history.append(record)
            solutions.append(d.copy())
            if stepper is not None:
                stepper.t, stepper.step, stepper.rate = t, step_index, rate
            if on_step is not None:
                on_step(record, d, ev)
            log(f"step {step_index}: t = {t:.6g} converged in {its} iterations "
                f"(residual {res[-1]:.2e}, {record.seconds:.3f} s; next step "
                f"{control.size:.3g})")
    return Result(d, history, solutions, True, "completed")


def _solver_line(linear_solver):
    """The linear solver and the matrix it factors, for the log."""
    system = getattr(linear_solver, "system", None)
    return linear_solver.describe() + (f", factoring {system}" if system else "")


def _augmented_newton(problem, d, t, C, g, f_ext, fit, tol, max_iterations, log,
                      contributions, linear_solver, tally, max_augmentations,
                      increment=None):
    """Newton solves of one step, each followed by an update of the
    multipliers of the contributions with ``augment()`` (Uzawa), until none
    needs one and none has a frozen contact status to correct
    (``review_status()``, see :mod:`skfem_rkpm.mechanics.contact_status`);
    ``iterations`` and the residual history count all solves."""
    for c in contributions:
        if hasattr(c, "restart"):
            c.restart(t)
    augmenting = [c for c in contributions if hasattr(c, "augment")]
    reviewing = [c for c in contributions if hasattr(c, "review_status")]
    its = 0
    residuals, energies = [], []
    solid = {}  # the solid's last evaluation: the multiplier updates keep d
    for update in range(max_augmentations + 1):
        d, ev, lam, k, res, en = _newton(problem, d, t, C, g, f_ext, fit, tol,
                                         max_iterations, log, contributions,
                                         linear_solver, tally, solid, increment)
        its, residuals, energies = its + k, residuals + res, energies + en
        worst = max((c.violation() for c in augmenting), default=0.0)
        augmented = any([c.augment() for c in augmenting])
        corrected = sum(c.review_status() for c in reviewing)
        if not augmented and not corrected:
            return d, ev, lam, its, residuals, energies
        if augmented:
            log(f"    augmentation {update + 1}: violation {worst:.3g} x tolerance")
        if corrected:
            log(f"    {corrected} frozen contact statuses corrected, solving again")
    raise NonConvergence(f"the augmented Lagrangian needs more than {max_augmentations} "
                         f"multiplier updates or contact status corrections")


def _newton(problem, d, t, C, g, f_ext, fit, tol, max_iterations, log,
            contributions=(), linear_solver="auto", tally=None, solid=None,
            increment=None):
    """Newton iterations of one step; returns the converged data or raises.

    Once the prescribed values are met, each update ``δ`` is scaled by the
    energy line search of :func:`_line_search`; near the solution the full
    step is taken and convergence stays quadratic.  ``tally["iterations"]``
    counts the iterations, also those of an attempt that fails.  ``solid``
    (a dict) keeps the solid's last evaluation: a state asked for again at
    the same ``d`` (after a multiplier update or a contact status freeze,
    which change the contributions only) reuses it, tangent included.
    """
    tally = {"iterations": 0} if tally is None else tally
    solid = {} if solid is None else solid
    increment = Quasistatic() if increment is None else increment

    def state(d):
        """``(evaluation, tangent, r, relative residual)`` at ``d``; ``tangent()``
        forms the solid's tangent (only for the states that need an update)
        and adds the contributions' ones."""
        if "d" in solid and np.array_equal(solid["d"], d):
            ev = solid["evaluation"]
        else:
            ev = problem.evaluate(d)
            solid["d"], solid["evaluation"] = d.copy(), ev
        f_int, K_extra = ev.f_int, []
        # each force on its own sets the scale: internal and contact forces
        # may cancel each other when no load is prescribed
        ref = max(np.linalg.norm(f_int), np.linalg.norm(f_ext), 1e-300)
        for contribution in contributions:
            f_c, K_c = contribution.evaluate(d, t)
            ref = max(ref, np.linalg.norm(f_c))
            f_int = f_int + f_c
            K_extra.append(K_c)

        def tangent():
            return increment.tangent(sum(K_extra, ev.K))

        r, ref = increment.residual(d, f_ext, f_int, ev, ref)
        rel = np.linalg.norm(fit.out_of_balance(r)) / ref
        if not np.isfinite(rel):
            bad = np.flatnonzero(~np.isfinite(r))
            where = f"first at unknown {bad[0]}" if bad.size else "its norm overflows"
            raise NonFiniteError(f"the out-of-balance force is not finite ({where})",
                                 bad)
        return ev, tangent, r, rel

    gap_tol = 1e-12 * max(np.abs(g).max(initial=0), 1.0)
    d = d.copy()
    current = state(d)
    residuals, energies = [current[3]], []
    first_energy = None
    for it in range(1, max_iterations + 1):
        tally["iterations"] += 1
        gap = g - C @ d
        delta = _update(current[1](), current[2], C, gap, linear_solver, contributions,
                        getattr(increment, "force_weight", 1.0))
        energy = abs(delta @ current[2])
        first_energy = energy if first_energy is None else first_energy
        energies.append(energy / first_energy if first_energy > 0 else 0.0)
        if (np.abs(gap).max(initial=0.0) <= gap_tol
                and energies[-1] > FULL_STEP_ENERGY):
            step, trial = _line_search(state, d, delta, current[2])
        else:  # meets the prescribed values, or a correction at round-off
            step, trial = 1.0, state(d + delta)
        d, current = d + step * delta, trial
        if _watch_status(contributions, log):
            current = state(d)  # the frozen statuses change the contact law
        rel = current[3]
        residuals.append(rel)
        log(f"    iteration {it}: residual {rel:.3e}, energy {energies[-1]:.3e}"
            + (f", step {step:.3g}" if step < 1 else ""))
        settled = energies[-1] <= ROUND_OFF_ENERGY and rel <= SETTLED_RESIDUAL * tol
        if (rel <= tol or settled) and np.abs(g - C @ d).max(initial=0.0) <= gap_tol:
            ev, _, r, _ = current
            return d, ev, fit.multipliers(-r), it, residuals, energies
        if it > 3 and rel > 1e3 * residuals[1]:
            raise NonConvergence(f"residual diverges ({rel:.3e})")
    raise NonConvergence(f"no convergence in {max_iterations} iterations "
                         f"(residual {residuals[-1]:.3e})")


def _watch_status(contributions, log):
    """Let the contributions with ``watch_status()`` freeze the contact
    status of grazing nodes at the accepted iterate (their last
    evaluation); returns the number of nodes newly frozen."""
    frozen = sum(c.watch_status() for c in contributions if hasattr(c, "watch_status"))
    if frozen:
        log(f"    {frozen} grazing contact nodes frozen closed")
    return frozen


def _update(K, r, C, gap, linear_solver, contributions, weight=1.0, rounds=4):
    """Newton update ``δ`` with the contact nodes it brings into touch (and,
    through ``sticking(δ)``, the slipping nodes it brings back into stick).

    A contribution with a ``touching(δ)`` method (rigid contact) reports
    the nodes that ``δ`` would push into the tool although they are apart
    now, with the force and stiffness of their penalty in the linear model;
    the system is solved again with them, until the touching set repeats
    (at most ``rounds`` solves more).  Without this, a node apart at the
    start of an iteration has no stiffness, the update drives it deep into
    the tool and the line search can only take a tiny part of it.  The
    step's ``weight`` of the forces (``1 + α`` of an HHT-α increment)
    scales their force and stiffness.
    """
    delta, _ = solve_constrained(K, r, C, gap, solver=linear_solver)
    if not np.all(np.isfinite(delta)):
        raise NonFiniteError("the Newton update is not finite (a singular tangent?)",
                             np.flatnonzero(~np.isfinite(delta)))
    predictions = [getattr(c, name) for c in contributions
                   for name in ("touching", "sticking") if hasattr(c, name)]
    previous = None
    for _ in range(rounds):
        found = [predict(delta) for predict in predictions]
        found = [x for x in found if x is not None]
        if weight != 1.0:
            found = [(x[0], weight * x[1], weight * x[2]) for x in found]
        key = [x[0].tobytes() for x in found]
        if not found or key == previous:
            break
        previous = key
        r_touch = r - sum(x[1] for x in found)
        # K's factors with the few rows the found nodes change (low_rank)
        delta, _ = solve_updated(K, sum(x[2] for x in found), r_touch, C, gap,
                                 linear_solver)
    return delta


def _line_search(state, d, delta, r, tries=5, ratio=0.5):
    """Step length ``s`` along the Newton update ``δ`` and the state there.

    The energy line search: ``G(s) = δ · r(d + s δ)`` is minus the slope
    of the potential along ``δ`` (``r`` the out-of-balance force), and
    ``G(0) = δᵀ K δ > 0``.  The full step is kept when ``|G(1)| ≤ ratio ·
    G(0)``, i.e. when it lands near the minimum along ``δ``; otherwise
    ``s`` moves to the zero of ``G`` by regula falsi between the last
    bracketing pair.  Unlike the size of the residual, ``G`` does not
    depend on which force dominates: a penalty contact force that falls
    from a deep penetration shows as progress.  An inverted element
    halves the step.  Constrained directions (``C δ = 0``) do no work
    against the reactions, so ``δ · r`` needs no reaction correction.
    """
    g0 = delta @ r
    lo, g_lo = 0.0, g0
    hi, g_hi = None, None
    s = 1.0
    for attempt in range(tries):
        try:
            trial = state(d + s * delta)
        except InvertedElementError:
            if attempt == tries - 1:
                raise
            hi, g_hi = None, None
            s = 0.5 * (lo + s)
            continue
        g_s = delta @ trial[2]
        if not g0 > 0 or abs(g_s) <= ratio * abs(g0) or attempt == tries - 1:
            return s, trial
        if g_s > 0:  # still downhill: the zero lies beyond s
            if s == 1.0 or hi is None:
                return s, trial
            lo, g_lo = s, g_s
        else:
            hi, g_hi = s, g_s
        s = lo + (hi - lo) * g_lo / (g_lo - g_hi)
        s = min(max(s, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
    raise AssertionError("unreachable: the last trial returns or raises")


def _reactions(prescribed, groups, lam):
    """Resultant reaction force of each prescribed condition (its component)."""
    out, start = {}, 0
    for p, c in zip(prescribed, groups):
        out[p.name] = float(lam[start:start + len(c)] @ c.weights)
        start += len(c)
    return out
