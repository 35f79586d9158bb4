"""Implicit dynamics (Eq. 3.38) inside the Newton loop: Newmark's trapezoidal
rule and HHT-α on spring-mass systems against their exact discrete
solutions, the energy of elastic bodies, a bar on a rigid wall against
d'Alembert, plastic dissipation, and the quasi-static limit."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.mass import consistent_mass, lumped_mass
from skfem_rkpm.mechanics.materials import J2Material, linear, perfect
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.newton import Prescribed, StepperState, newton_steps
from skfem_rkpm.solvers.time_integration import Newmark, Quasistatic
from skfem_rkpm.verification.oscillators import (LinearSprings as Springs, principal_root,
                                                  prony)

E, RHO = 200e3, 7.85e-9  # MPa, t/mm³ (steel)
EPS = np.finfo(float).eps


def run_springs(K, m, d0, v0, dt, steps, alpha=0.0):
    """Coefficients at every step (the first row ``d0``) and the integrator."""
    problem = Springs(K)
    scheme = Newmark(problem, np.asarray(m, float), steps * dt, v0=v0, d0=d0, alpha=alpha)
    result = newton_steps(problem, steps=steps, tol=1e-12, d0=d0, increment=scheme)
    assert result.completed, result.message
    return np.vstack([d0] + result.solutions), scheme, result


@pytest.mark.parametrize("Omega", [0.1, 0.5, 1.0, 2.0])
def test_trapezoidal_period_and_amplitude_of_a_single_spring(Omega):
    """The trapezoidal rule on ``d̈ + ω² d = 0``: the discrete frequency is
    ``Ω̄ = 2 arctan(Ω/2)`` (period elongation ``T̄/T = Ω / (2 arctan(Ω/2))``)
    and the amplitude does not decay (``|λ| = 1``).  The springs are linear,
    so each step converges in one Newton iteration to the linear solve's
    round-off: the samples obey the recurrence to ~1e-15 and the fit
    recovers ``Ω̄`` to 1e-10."""
    omega = 2 * np.pi
    d, scheme, result = run_springs([[omega**2]], [1.0], np.array([1.0]), np.array([0.0]),
                                    Omega / omega, 400)
    assert all(r.iterations == 1 for r in result.history)
    measured, xi = prony(d[:, 0], skip=0)
    assert measured == pytest.approx(2 * np.arctan(Omega / 2), rel=1e-10)
    assert abs(xi) < 1e-12
    # the energy ½ v² + ½ ω² d² is an invariant of the trapezoidal rule
    kinetic = np.array([r.kinetic for r in scheme.records])  # ½ v², m = 1
    total = kinetic + 0.5 * omega**2 * d[:, 0] ** 2
    assert np.abs(total / total[0] - 1).max() < 400 * 8 * EPS


def test_trapezoidal_periods_of_a_two_mass_chain():
    """Two masses and three springs (wall-m1-m2-wall): each mode's discrete
    frequency is ``2 arctan(ω_k Δt / 2)``, measured in the modal coordinates
    of the response to a start that excites both."""
    k, m = np.array([4.0, 1.0, 9.0]), np.array([1.0, 2.0])
    K = np.array([[k[0] + k[1], -k[1]], [-k[1], k[1] + k[2]]])
    w2, modes = np.linalg.eigh(np.diag(m**-0.5) @ K @ np.diag(m**-0.5))
    modes = np.diag(m**-0.5) @ modes  # M-orthonormal
    dt = 0.3
    d, scheme, _ = run_springs(K, m, np.array([1.0, 0.0]), np.array([0.0, 0.5]), dt, 500)
    q = d @ (m[:, None] * modes)  # modal coordinates qₖ = φₖᵀ M d
    for j, omega in enumerate(np.sqrt(w2)):
        measured, xi = prony(q[:, j], skip=0)
        assert measured == pytest.approx(2 * np.arctan(omega * dt / 2), rel=1e-10)
        assert abs(xi) < 1e-12
    # the balance T + W_int − W_ext of the account is the total energy
    balance = np.array([r.balance for r in scheme.records])
    assert np.abs(balance / balance[0] - 1).max() < 500 * 8 * EPS


@pytest.mark.parametrize("alpha", [-0.05, -0.1, -0.3])
@pytest.mark.parametrize("Omega", [0.1, 0.5, 1.0])
def test_hht_damping_and_period_follow_the_amplification_matrix(alpha, Omega):
    """HHT-α on ``d̈ + ω² d = 0``: the damping ratio ``ξ̄`` and frequency
    ``Ω̄`` measured from the response are those of the complex pair of the
    amplification matrix, ``λ = exp(Ω̄ (−ξ̄ ± i))`` (HHT 1977).  The third
    root (real, |λ₃| ≤ 0.03 here) has decayed to below 1e-15 after the
    first 50 steps the fit skips; the fit then is exact to round-off:
    1e-6 relative for ξ̄ (ξ̄ Ω̄ is down to 2e-6 per step at Ω = 0.1, read
    from samples exact to 1e-15) and 1e-10 for Ω̄."""
    omega = 2 * np.pi
    d, _, _ = run_springs([[omega**2]], [1.0], np.array([1.0]), np.array([0.0]),
                          Omega / omega, 400, alpha=alpha)
    measured, xi = prony(d[:, 0])
    expected, xi_expected = principal_root(Omega, alpha)
    assert measured == pytest.approx(expected, rel=1e-10)
    assert xi == pytest.approx(xi_expected, rel=1e-6)
    # the leading terms of the expansion in Ω of the pair's ξ̄ and period:
    # ξ̄ = −α (1 + α)² Ω³ / 8 and T̄/T − 1 = (1/12 − α/4 − 3α²/8) Ω²
    # (α = 0: the trapezoidal Ω²/12), relative errors O(Ω²): measured
    # up to 0.54 Ω² (ξ̄, α = −0.3)
    assert xi == pytest.approx(-alpha * (1 + alpha) ** 2 * Omega**3 / 8, rel=Omega**2)
    assert Omega / measured - 1 == pytest.approx(
        (1 / 12 - alpha / 4 - 3 * alpha**2 / 8) * Omega**2, rel=Omega**2)


@pytest.mark.parametrize("alpha", [0.0, -0.1, -0.2])
def test_hht_spectral_radius_at_infinity(alpha):
    """At ``Ω → ∞`` the complex pair of HHT-α tends to ``−(1 + α)/(1 − α)``:
    no damping for the trapezoidal rule, 0.82 per step at α = −0.1.
    Measured by the fit of :func:`prony` on a spring at ``Ω = 10⁴`` after
    the third root (|λ₃| ≤ 0.25 here, against 0.67 of the pair) has decayed: the modulus of the pair
    approaches its limit as O(1/Ω²) = 1e-8 (α = −1/3, where the three
    roots meet at −1/2, converges as O(Ω^(−2/3)) and is left out)."""
    omega, Omega = 1.0, 1e4
    d, _, _ = run_springs([[omega**2]], [1.0], np.array([1.0]), np.array([0.0]),
                          Omega / omega, 80, alpha=alpha)
    frequency, xi = prony(d[:, 0], skip=40)
    radius = np.exp(-xi * frequency)
    assert radius == pytest.approx((1 + alpha) / (1 - alpha), abs=1e-6)


def bar(method, cells=40, nu=0.0, law=None, locking=None, length=10.0):
    """A 1 mm wide plane-strain bar of ``cells`` cells along its length."""
    mesh = MeshQuad.init_tensor(np.linspace(0, 1, 3),
                                np.linspace(0, length, cells + 1)).with_defaults()
    basis = (Basis(mesh, ElementVector(ElementQuad1()), intorder=2) if method == "fem"
             else RKBasis(mesh, vector=True, support=2.0, integration="gauss"))
    return SolidProblem(basis, J2Material(E, nu, law), model="plane_strain", locking=locking)


@pytest.mark.parametrize("method, mass", [("fem", "lumped"), ("rk", "lumped"),
                                          ("rk", "consistent")])
def test_linear_elastic_bar_keeps_its_energy(method, mass):
    """Linear elastodynamics of the discretized bar (its stiffness at the
    reference state, K₀, and its mass) set vibrating at random velocities:
    the trapezoidal rule keeps ``½ vᵀ M v + ½ dᵀ K₀ d`` to the round-off of
    its linear solves, ~N ε per step (200 steps)."""
    problem = bar(method, cells=10)
    K0 = problem.evaluate(np.zeros(problem.N)).K
    M = (lumped_mass(problem.assembler, RHO) if mass == "lumped"
         else consistent_mass(problem.assembler, RHO))
    v0 = 1e3 * np.random.default_rng(1).standard_normal(problem.N)
    # about the cells' transit time, h / c0 (the scheme is stable at any step)
    dt = 0.25 / np.sqrt(E / RHO)
    springs = Springs(K0)
    scheme = Newmark(springs, M, 200 * dt, v0=v0)
    result = newton_steps(springs, steps=200, tol=1e-12, increment=scheme)
    assert result.completed
    d = np.vstack([np.zeros(problem.N)] + result.solutions)
    energy = np.array([r.kinetic for r in scheme.records]) + 0.5 * np.einsum(
        "ni,ni->n", d, (K0 @ d.T).T)
    assert np.abs(energy / energy[0] - 1).max() < 200 * problem.N * EPS


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_nonlinear_elastic_bar_closes_the_balance_to_the_newton_tolerance(method):
    """A free hyperelastic bar stretched by an initial velocity field of
    200 m/s (strains of a few %): the trapezoidal balance
    ``T + W_int − W_ext`` changes only by the work of what Newton leaves of
    the residual, which the account bounds by ``Σ ½ |Δd| (|r_n| + |r_(n+1)|)``
    (mechanics/energy.py); the bound itself is at the Newton tolerance
    (1e-10 of the forces) times the work scale: measured 1.2e-9 T₀ over
    80 steps (and the drift 3e-12 T₀)."""
    problem = bar(method, cells=10, nu=0.3)
    M = lumped_mass(problem.assembler, RHO)
    v = np.zeros(problem.N)
    y = problem.basis.nodes[1] if method == "rk" else problem.basis.doflocs[1, 1::2]
    v[1::2] = 2e5 * np.sin(np.pi * y / 10.0)
    c0 = np.sqrt(E / RHO)
    duration = 4 * 10.0 / c0
    scheme = Newmark(problem, M, duration, v0=v)
    result = newton_steps(problem, steps=80, tol=1e-10, increment=scheme)
    assert result.completed, result.message
    records = scheme.records
    T0 = records[0].kinetic
    drift = max(abs(r.balance - records[0].balance) for r in records)
    assert drift <= records[-1].residual_bound + 80 * 64 * EPS * T0
    assert records[-1].residual_bound < 1e-8 * T0
    # elastic: the stored energy is the internal work, up to the trapezoidal
    # error of the work of a nonlinear force, O(Δd³): measured 3e-5 of T₀
    # with an elastic energy of up to 0.2 T₀
    assert max(abs(r.plastic) for r in records) < 1e-3 * T0


def impact(method, steps=120, alpha=0.0, **bar_options):
    """The bar of :func:`bar` at 10 m/s onto a rigid wall, over 3 L/c0."""
    L, v0 = 10.0, 1e4
    c0 = np.sqrt(E / RHO)
    problem = bar(method, **bar_options)
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=1.0)
    v = np.zeros(problem.N)
    v[1::2] = -v0
    duration = 3 * L / c0
    scheme = Newmark(problem, lumped_mass(problem.assembler, RHO), duration, v0=v,
                     alpha=alpha, contributions=[wall])
    rows = [(0.0, 0.0)]
    result = newton_steps(problem, steps=steps, tol=1e-10, contributions=[wall],
                          increment=scheme, on_step=lambda r, d, ev: rows.append(
                              (r.t * duration, r.reactions["platen"][1])))
    assert result.completed, result.message
    time, force = np.array(rows).T
    return time, force, scheme, L / c0, RHO * c0 * v0 * 1.0


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_bar_on_a_rigid_wall_follows_dalembert(method):
    """The bar of tests/test_explicit.py, implicit at the cells' transit
    time (Courant number 1, 120 steps): d'Alembert's contact time 2L/c0
    and mean force ρ c0 v0 A, and the energy balance closed to the Newton
    tolerance, far inside the 1 % of the peak kinetic energy asked for."""
    time, force, scheme, transit, plateau = impact(method)
    touching = force > 1e-6 * force.max()
    # the penalty spring and the discrete front lengthen the contact by a
    # few cells' transit: measured +5.0 % (FEM), +6.3 % (RK), as explicit
    contact_time = time[touching].max() / (2 * transit)
    assert 1.0 <= contact_time < 1.1
    mean_force = np.trapezoid(force, time) / (2 * transit)
    assert mean_force == pytest.approx(plateau, rel=0.02)  # measured 0.3 % / 0.8 %
    records = scheme.records
    peak = max(r.kinetic for r in records)
    drift = max(abs(r.balance - records[0].balance) for r in records)
    assert drift < 0.01 * peak
    assert drift <= records[-1].residual_bound + 120 * 64 * EPS * peak
    # the kinetic energy given back: the rest stays in vibration (1.5 % RK)
    assert records[-1].kinetic / records[0].kinetic > 0.97


def test_hht_damps_the_bar_ringing_after_the_rebound():
    """α = −0.3 removes energy of the high modes excited by the impact: the
    balance falls (the numerical dissipation, measured 0.7 % of T₀) while
    the rebound keeps d'Alembert's contact time."""
    time, force, scheme, transit, _ = impact("fem", alpha=-0.3)
    touching = force > 1e-6 * force.max()
    assert 1.0 <= time[touching].max() / (2 * transit) < 1.1
    records = scheme.records
    lost = records[0].balance - records[-1].balance
    assert 0 < lost < 0.05 * records[0].kinetic


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_plastic_dissipation_is_the_yield_stress_times_the_plastic_strain(method):
    """A perfectly plastic bar (σy = 200 MPa, F-bar, ν = 0.3) at 20 m/s on
    the wall: the impact stress ρ c v0 ≈ 900 MPa yields the foot.  The
    dissipation ``W_int − ψ`` of the account equals ``∫ σy ε̄ᵖ dΩ₀`` of the
    material state (perfect J2 plasticity in Kirchhoff stress).  The
    trapezoidal work sum differs from it by O(Δt²): measured 1.1 % (FEM),
    1.3 % (RK) at 40 steps and 0.27 % / 0.34 % at 80."""
    errors = []
    for steps in (40, 80):
        problem = bar(method, cells=20, nu=0.3, law=perfect(200.0), locking="fbar")
        wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                            factor=1.0)
        v = np.zeros(problem.N)
        v[1::2] = -2e4
        scheme = Newmark(problem, lumped_mass(problem.assembler, RHO),
                         2 * 10.0 / np.sqrt(E / RHO), v0=v, contributions=[wall])
        result = newton_steps(problem, steps=steps, tol=1e-10, contributions=[wall],
                              increment=scheme)
        assert result.completed, result.message
        last = scheme.records[-1]
        dissipated = 200.0 * problem.state.alpha @ problem.whole_dx.reshape(-1)
        assert dissipated > 0.5 * scheme.records[0].kinetic  # most of it
        errors.append(abs(last.plastic / dissipated - 1))
        assert abs(last.balance - scheme.records[0].balance) <= \
            last.residual_bound + steps * 64 * EPS * scheme.records[0].kinetic
    assert errors[0] < 0.02
    assert errors[1] < errors[0] / 2.5  # second order: 4x measured


def scene(locking="fbar"):
    """The quasi-static scene of the comparison below: a hardening block
    pressed 25 % by a platen with Coulomb friction (F-bar), in 3 steps of
    at most 6 iterations, so that the step control cuts back."""
    problem = SolidProblem(RKBasis(rectangle(1.0, 1.0, 5, 5), vector=True),
                           J2Material(200e3, 0.3, linear(300.0, 1000.0)), "plane_strain",
                           locking=locking)
    platen = RigidContact(problem, Platen((0, 1), (0, -1), motion=lambda t: (0.0, -0.25 * t),
                                          name="platen"), "top", friction=0.2)
    return problem, platen, [Prescribed("bottom", 1, 0.0), Prescribed("left", 0, 0.0)]


def test_without_mass_the_dynamic_step_is_the_quasi_static_one():
    """Eq. (3.38) with ``M = 0`` is Eq. (4.25): a Newmark increment with a
    zero mass gives the quasi-static run bit for bit (the same residuals,
    tangents, cut-backs and contact states: ``(1 + 0) x − 0 = x`` exactly),
    on a scene with friction, F-bar and cut-backs."""
    results = []
    for dynamic in (False, True):
        problem, platen, conditions = scene()
        increment = (Newmark(problem, sp.csr_matrix((problem.N, problem.N)), 1.0,
                             a0=np.zeros(problem.N), contributions=[platen])
                     if dynamic else Quasistatic())
        results.append(newton_steps(problem, conditions, steps=3, max_iterations=6,
                                    contributions=[platen], increment=increment))
    static, dynamic = results
    assert static.completed and sum(r.cutbacks for r in static.history) >= 2
    assert [r.t for r in static.history] == [r.t for r in dynamic.history]
    assert [r.iterations for r in static.history] == [r.iterations for r in dynamic.history]
    for a, b in zip(static.solutions, dynamic.solutions):
        assert np.array_equal(a, b)
    assert np.array_equal(static.history[-1].reactions["platen"],
                          dynamic.history[-1].reactions["platen"])


def test_cut_backs_restore_the_dynamic_state():
    """Steps that fail (at most 2 iterations per attempt while the foot
    yields) are halved and retried from the last converged d, v, a: the run
    equals one given those halved steps from the start, to the Newton
    tolerance."""
    def run(steps, max_iterations):
        problem = bar("fem", cells=10, nu=0.3, law=perfect(200.0))
        wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                            factor=1.0)
        v = np.zeros(problem.N)
        v[1::2] = -2e4
        scheme = Newmark(problem, lumped_mass(problem.assembler, RHO),
                         10.0 / np.sqrt(E / RHO), v0=v, contributions=[wall])
        result = newton_steps(problem, steps=steps, tol=1e-10, contributions=[wall],
                              increment=scheme, max_iterations=max_iterations)
        assert result.completed, result.message
        return result, scheme

    cut, cut_scheme = run(10, 2)
    assert sum(r.cutbacks for r in cut.history) >= 1
    times = [r.t for r in cut.history]
    direct, direct_scheme = run(times, 30)
    scale = np.abs(direct.d).max()
    assert np.abs(cut.d - direct.d).max() < 1e-8 * scale
    assert cut_scheme.v == pytest.approx(direct_scheme.v, rel=1e-6, abs=1e-6 * 2e4)


def test_bad_settings_are_refused():
    problem = Springs([[1.0]])
    with pytest.raises(ValueError, match=r"α in \[-1/3, 0\]"):
        Newmark(problem, np.ones(1), 1.0, alpha=-0.5)
    with pytest.raises(ValueError, match="duration"):
        Newmark(problem, np.ones(1), 0.0)
    with pytest.raises(ValueError, match="v0 must be 1 finite"):
        Newmark(problem, np.ones(1), 1.0, v0=np.ones(2))
    with pytest.raises(ValueError, match="the mass has shape"):
        Newmark(problem, sp.eye(2), 1.0)
    scheme = Newmark(problem, np.ones(1), 1.0, v0=np.ones(1))
    with pytest.raises(ValueError, match="starts at"):
        newton_steps(problem, steps=2, start=0.5, increment=scheme)


def test_axisymmetric_rod_with_its_axis_prescribed():
    """A round RK rod (ν = 0) on the wall, its axis u_r = 0 prescribed on
    nodal values through Newton (Eq. 3.37): d'Alembert's contact time and
    the force ρ c0 v0 π R² on average, as for the explicit scheme; the axis
    condition holds to Newton's gap tolerance (1e-12 of the scale) and the
    balance closes, since the axis reactions do no work (C Δd = 0)."""
    L, R, v0 = 10.0, 1.0, 1e4
    c0 = np.sqrt(E / RHO)
    mesh = MeshQuad.init_tensor(np.linspace(0, R, 3), np.linspace(0, L, 41)).with_defaults()
    b = RKBasis(mesh, vector=True, support=2.0, integration="gauss", axisymmetric=True)
    problem = SolidProblem(b, J2Material(E, 0.0), model="axisymmetric")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=1.0)
    v = np.zeros(b.N)
    v[1::2] = -v0
    duration = 2.5 * L / c0
    axis = Prescribed("left", 0, 0.0)
    scheme = Newmark(problem, lumped_mass(problem.assembler, RHO), duration, v0=v,
                     contributions=[wall], constraints=[axis.constraint(b)])
    forces = [0.0]
    result = newton_steps(problem, [axis], steps=100, tol=1e-10, contributions=[wall],
                          increment=scheme,
                          on_step=lambda *_: forces.append(wall.resultants()["platen"][1]))
    assert result.completed, result.message
    time = np.array([r.time for r in scheme.records])
    force = np.array(forces)
    assert 1.0 <= time[force > 1e-6 * force.max()].max() / (2 * L / c0) < 1.1
    mean_force = np.trapezoid(force, time) / (2 * L / c0)
    assert mean_force == pytest.approx(RHO * c0 * v0 * np.pi * R**2, rel=0.03)
    C = axis.constraint(b).C
    assert np.abs(C @ result.d).max() < 1e-12 * max(np.abs(result.d).max(), 1.0)
    records = scheme.records
    peak = max(r.kinetic for r in records)
    assert max(abs(r.balance - records[0].balance) for r in records) < 1e-6 * peak


def test_a_snapshot_resumes_the_run_exactly():
    """A run stopped after 6 of 12 steps and resumed in new objects (the
    integrator from its snapshot, the solid's and the wall's committed
    states, Newton's stepper) ends bit for bit where the run without a stop
    ends: HHT-α on the yielding bar on the wall, whose plastic state and
    d, v, a and forces at t_n all enter the next step (the frictionless
    penalty wall keeps no history; it is restored as a run would)."""
    def build():
        problem = bar("fem", cells=10, nu=0.3, law=perfect(200.0))
        wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                            factor=1.0)
        v = np.zeros(problem.N)
        v[1::2] = -2e4
        scheme = Newmark(problem, lumped_mass(problem.assembler, RHO),
                         10.0 / np.sqrt(E / RHO), v0=v, alpha=-0.1, contributions=[wall])
        return problem, wall, scheme

    def run(problem, wall, scheme, targets, **options):
        result = newton_steps(problem, steps=targets, tol=1e-10, contributions=[wall],
                              increment=scheme, **options)
        assert result.completed, result.message
        return result

    targets = np.linspace(0, 1, 13)[1:]
    problem, wall, uninterrupted = build()
    whole = run(problem, wall, uninterrupted, targets)
    problem, wall, scheme = build()
    stepper = StepperState()
    half = run(problem, wall, scheme, targets[:6], stepper=stepper)
    saved = ({k: np.copy(v) for k, v in scheme.snapshot().items()},
             problem.state.copy(), wall.get_state())
    problem, wall, scheme = build()
    scheme.restore(saved[0])
    problem.state = saved[1]
    wall.set_state(saved[2])
    rest = run(problem, wall, scheme, targets, d0=half.d, stepper=stepper)
    assert len(half.history) + len(rest.history) == len(whole.history)
    assert np.array_equal(rest.d, whole.d)
    assert np.array_equal(scheme.v, uninterrupted.v)
    assert np.array_equal(scheme.a, uninterrupted.a)
    assert scheme.records[-1] == uninterrupted.records[-1]  # the energy account
