"""Central differences with a lumped mass: an elastic bar on a rigid wall
against d'Alembert's solution, the energy balance of a free elastic body, and
the stable step against the spectrum of M⁻¹K."""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

from skfem_rkpm import RKBasis
from skfem_rkpm.approximation.constraints import nodal_constraint
from skfem_rkpm.mechanics.mass import largest_eigenvalue, lumped_mass
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import InvertedElementError, SolidProblem
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.solvers.explicit import CentralDifference, EstimatePolicy

E, RHO = 200e3, 7.85e-9  # MPa, t/mm³ (steel)


def basis(mesh, method):
    if method == "fem":
        return Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    return RKBasis(mesh, vector=True, support=2.0, integration="gauss")


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_bar_on_a_rigid_wall_follows_dalembert(method):
    """A bar of length L hits a rigid wall at v0 (ν = 0: a uniaxial wave).
    d'Alembert: it stays in contact for 2L/c0 under the force ρ c0 v0 A,
    then leaves at -v0 with its kinetic energy given back."""
    L, v0 = 10.0, 1e4  # mm, mm/s
    c0 = np.sqrt(E / RHO)
    mesh = MeshQuad.init_tensor(np.linspace(0, 1, 3), np.linspace(0, L, 41)).with_defaults()
    b = basis(mesh, method)
    problem = SolidProblem(b, J2Material(E, 0.0), model="plane_strain")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=1.0)
    v = np.zeros(b.N)
    v[1::2] = -v0
    rows = []
    CentralDifference(problem, RHO, contacts=[wall]).run(
        np.zeros(b.N), v, duration=3 * L / c0, output_interval=0.01 * L / c0,
        on_output=lambda r: rows.append((r.time, r.forces["platen"][1], r.kinetic,
                                         r.balance)))
    time, force, kinetic, balance = np.array(rows).T
    touching = force > 1e-6 * force.max()
    # the penalty spring (factor 1: the stiffness of a layer h thick) and the
    # discrete wave front lengthen the contact by a few cells' transit time:
    # measured +4.5 % (FEM) and +6.5 % (RK), 10 % is a 2.5-cell transit
    contact_time = time[touching].max() / (2 * L / c0)
    assert 1.0 <= contact_time < 1.1
    # the impulse 2 ρ A L v0 over 2L/c0: the mean force is ρ c0 v0 A; the
    # kinetic energy left in vibration after the rebound (1.4 % for RK)
    # lowers the rebound velocity and with it the impulse
    mean_force = np.trapezoid(force, time) / (2 * L / c0)
    assert mean_force == pytest.approx(RHO * c0 * v0 * 1.0, rel=0.02)
    assert kinetic[-1] / kinetic[0] > 0.97
    # the energy balance closes within 1 % of the peak kinetic energy (the
    # penalty force switching on and off within a step: measured 5e-4)
    assert np.abs(balance - balance[0]).max() < 0.01 * kinetic.max()


def free_body(method, cells=(6, 3), speed=1e4):
    """A free 4 x 1 mm steel plate set in bending at ``speed`` mm/s."""
    mesh = MeshQuad.init_tensor(np.linspace(0, 4, cells[0] + 1),
                                np.linspace(0, 1, cells[1] + 1)).with_defaults()
    b = basis(mesh, method)
    problem = SolidProblem(b, J2Material(E, 0.3), model="plane_strain")
    v = np.zeros(b.N)
    x = b.nodes[0] if method == "rk" else b.doflocs[0, 1::2]
    v[1::2] = speed * np.sin(np.pi * x / 4.0)
    return problem, v


def balance_errors(method, steps, speed, step_fraction=1.0, cells=(6, 3)):
    """|balance - balance₀| / T₀ every steps/50 steps of a free body."""
    problem, v = free_body(method, cells, speed)
    scheme = CentralDifference(problem, RHO)
    h = step_fraction * scheme.stable_step(np.zeros(problem.N))
    records = scheme.run(np.zeros(problem.N), v, duration=steps * h, dt=h,
                         output_interval=steps * h / 50)
    first = records[0]
    return np.array([abs(r.balance - first.balance) / first.kinetic for r in records])


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_small_vibrations_keep_the_leapfrog_invariant(method):
    """At 10 m/s (strains ~1e-4, the body is linear to 1e-4) the balance with
    the half-step kinetic energy is the invariant of central differences:
    constant up to the round-off of 600 work increments (≤ 600 · 16 ε)."""
    errors = balance_errors(method, 600, 1e4)
    assert errors.max() < 600 * 16 * np.finfo(float).eps


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_large_vibrations_close_the_energy_balance(method):
    """At 200 m/s (strains of a few %, hyperelastic) the trapezoidal work of
    the nonlinear forces differs from the stored energy by O(Δd³) per step:
    measured 2e-13 of T₀ over 1000 steps.  The bound 1e-8 is far below the
    O(Δt) error of a one-sided work sum (about 1e-3 here) or of a kinetic
    energy taken at the wrong half step."""
    assert balance_errors(method, 1000, 2e5).max() < 1e-8


@pytest.mark.slow
@pytest.mark.parametrize("method", ["fem", "rk"])
def test_ten_thousand_steps_do_not_drift(method):
    """10⁴ steps at the stable step, 200 m/s: no drift of the balance beyond
    1e-8 of T₀ (the target of 1e-3, with the margin measured above)."""
    assert balance_errors(method, 10_000, 2e5, cells=(4, 2)).max() < 1e-8


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_stable_step_is_the_critical_one(method):
    """The estimate equals safety · 2/ω_max with ω_max from the whole
    spectrum of M⁻¹K; 5 % above the critical step the body's energy blows
    up within 300 steps, 5 % below it does not."""
    problem, v = free_body(method, cells=(4, 2))
    scheme = CentralDifference(problem, RHO, safety=1.0)
    h = scheme.stable_step(np.zeros(problem.N))
    K = problem.evaluate(np.zeros(problem.N)).K
    m = lumped_mass(problem.assembler, RHO)
    assert h == pytest.approx(2.0 / np.sqrt(largest_eigenvalue(K, m)), rel=1e-8)
    # a kick of every mode: small random velocities on top of the bending
    v = v + 1e2 * np.random.default_rng(0).standard_normal(v.size)
    problem, _ = free_body(method, cells=(4, 2))
    run = CentralDifference(problem, RHO).run(np.zeros(problem.N), v, duration=285 * h,
                                              dt=0.95 * h)
    assert abs(run[-1].balance - run[0].balance) < 0.05 * run[0].kinetic
    problem, _ = free_body(method, cells=(4, 2))
    with pytest.raises(InvertedElementError, match=r"explicit step \d+ to t"):
        CentralDifference(problem, RHO).run(np.zeros(problem.N), v, duration=315 * h,
                                            dt=1.05 * h)


def test_explicit_refuses_augmented_contact_and_bad_settings():
    problem, _ = free_body("fem", cells=(2, 1))
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        enforcement="augmented")
    with pytest.raises(ValueError, match="penalty contact"):
        CentralDifference(problem, RHO, contacts=[wall])
    with pytest.raises(ValueError, match="safety"):
        CentralDifference(problem, RHO, safety=1.5)
    with pytest.raises(ValueError, match="density"):
        CentralDifference(problem, -1.0)


@pytest.mark.parametrize("method", ["fem", "rk"])
def test_axisymmetric_rod_on_a_wall_keeps_its_axis(method):
    """A round rod (ν = 0, axisymmetric) on a rigid wall: d'Alembert's
    contact time 2L/c0 as for the plane bar, with the axis condition u_r = 0
    held by the projection to round-off (the nodal values of u_r there are
    rows of Λᵀ, Eq. 3.32)."""
    L, R, v0 = 10.0, 1.0, 1e4
    c0 = np.sqrt(E / RHO)
    mesh = MeshQuad.init_tensor(np.linspace(0, R, 3), np.linspace(0, L, 41)).with_defaults()
    if method == "fem":
        b = basis(mesh, method)
    else:
        b = RKBasis(mesh, vector=True, support=2.0, integration="gauss", axisymmetric=True)
    problem = SolidProblem(b, J2Material(E, 0.0), model="axisymmetric")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=1.0)
    axis = nodal_constraint(b, "left", 0)
    v = np.zeros(b.N)
    v[1::2] = -v0
    rows = []
    records = CentralDifference(problem, RHO, contacts=[wall], constraints=[axis]).run(
        np.zeros(b.N), v, duration=2.5 * L / c0, output_interval=0.01 * L / c0,
        on_output=lambda r: rows.append((r.time, r.forces["platen"][1])))
    time, force = np.array(rows).T
    contact_time = time[force > 1e-6 * force.max()].max() / (2 * L / c0)
    assert 1.0 <= contact_time < 1.1  # as for the plane bar
    # the force on the full circumference, ρ c0 v0 π R², on average
    mean_force = np.trapezoid(force, time) / (2 * L / c0)
    assert mean_force == pytest.approx(RHO * c0 * v0 * np.pi * R**2, rel=0.03)
    scale = np.abs(records[-1].d).max()
    for r in records:  # C d = 0: round-off of the projection's solve
        assert np.abs(axis.C @ r.d).max() < 1e3 * np.finfo(float).eps * scale


def drive(policy, omega2_at, until):
    """Estimates of ``policy`` on ``omega2_at(step)`` up to ``until`` steps:
    (step, ω² used, interval) of each."""
    out, step = [], 0
    while step < until:
        used, n = policy.after_estimate(step, omega2_at(step))
        out.append((step, used, n))
        step += n
    return out


def test_a_constant_frequency_lengthens_the_interval_to_the_longest():
    """ω² that does not change: intervals 5, 10, 20, 40, then 50 (twice the
    last at most), each step from the estimate itself."""
    runs = drive(EstimatePolicy(50), lambda step: 4.0e14, 400)
    assert [n for _, _, n in runs[:6]] == [5, 10, 20, 40, 50, 50]
    assert all(used == 4.0e14 for _, used, _ in runs)


@pytest.mark.parametrize("rate", [1e-4, 3e-3, 0.05])
def test_a_growing_frequency_is_extrapolated_to_the_next_estimate(rate):
    """ω² = ω0² e^(r step): from the second estimate on, the ω² a step uses
    is the value at the next estimate (to round-off), the interval
    ln(1.1) / r steps (floored, at most 50 and twice the last); so no step
    of the interval is above safety · 2/ω(t) at its end."""
    omega2 = lambda step: 1e14 * np.exp(rate * step)  # noqa: E731
    runs = drive(EstimatePolicy(50), omega2, 300)
    for (step, used, n), (following, _, _) in zip(runs[1:], runs[2:]):
        assert following == step + n
        assert used == pytest.approx(omega2(following), rel=1e-12)
        assert n <= max(1, int(np.log(1.1) / rate)) and n <= 50
    assert max(used / omega2(step) for step, used, _ in runs) <= 1.1 * (1 + 1e-12)


def test_an_estimate_log_shows_the_step_against_the_critical_one():
    """A free elastic body: every estimate's critical step is 2/ω of the
    body, and the step taken up to it is the safety times that."""
    problem, v = free_body("fem", cells=(4, 2))
    scheme = CentralDifference(problem, RHO, safety=0.9, estimate_every=20)
    scheme.run(np.zeros(problem.N), 0.01 * v, duration=60 * scheme.stable_step(
        np.zeros(problem.N)))
    log = scheme.estimates
    assert [e.step for e in log[:4]] == [0, 2, 6, 14]
    for e in log[1:]:
        assert e.taken / e.critical == pytest.approx(0.9, rel=1e-6)
