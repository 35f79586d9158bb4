"""Re-referencing (updated Lagrangian RK): the material on a later reference
against the total-Lagrangian update, the transfer of point values against
fields the RK functions reproduce, and whole runs rebuilt mid-way against
the same runs without a rebuild and the closed form of uniaxial
compression."""

import numpy as np
import pytest

from skfem_rkpm import RKBasis
from skfem_rkpm.approximation.transfer import PointTransfer, local_radius
from skfem_rkpm.mechanics.materials import J2Material, MaterialState, linear
from skfem_rkpm.mechanics.referenced import (ReferencedMaterial, elastic_left_cauchy_green,
                                             rebased_state, reference_volume_ratio,
                                             total_deformation_gradient)
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.rereference import Rebuild, Rereferencing, solve_segments
from skfem_rkpm.runs.scene import SceneError, parse_scene
from skfem_rkpm.solvers.newton import ConstraintSet, StepperState, _Reactions, newton_steps
from skfem_rkpm.verification.exact import uniaxial_compression

E, NU, YIELD, H = 200e3, 0.3, 300.0, 2000.0


def test_material_on_a_later_reference_is_the_total_update():
    """σ, ε̄ᵖ and b_e from the rebased state and F_incr equal those of the
    total F = F_incr F_ref from the original state (exact algebra: round-off),
    and P_ref = J_incr σ F_incr⁻ᵀ, whose derivative is the scaled tangent."""
    rng = np.random.default_rng(3)
    n = 6
    material = J2Material(E, NU, linear(YIELD, H))
    F_ref = np.eye(3) + 0.2 * rng.normal(size=(n, 3, 3))
    F_ref[np.linalg.det(F_ref) < 0] *= -1.0
    F_incr = np.eye(3) + 0.15 * rng.normal(size=(n, 3, 3))
    F_incr[np.linalg.det(F_incr) < 0] *= -1.0
    _, _, state_ref, _ = material.stress(F_ref, MaterialState.virgin(n))
    assert state_ref.alpha.min() > 0  # plastic at the reference
    F = F_incr @ F_ref
    _, tau, direct, _ = material.stress(F, state_ref)
    sigma = tau / np.linalg.det(F)[:, None, None]

    rebased = rebased_state(elastic_left_cauchy_green(F_ref, state_ref), state_ref.alpha)
    J_ref = reference_volume_ratio(rebased)
    assert J_ref == pytest.approx(np.linalg.det(F_ref), rel=1e-12)
    referenced = ReferencedMaterial(material, J_ref)
    P_ref, tau_ref, state, point = referenced.stress(F_incr, rebased)
    sigma_ref = tau_ref / np.linalg.det(F_incr)[:, None, None]
    scale = np.abs(sigma).max()
    assert np.abs(sigma_ref - sigma).max() <= 1e-12 * scale
    assert state.alpha == pytest.approx(direct.alpha, rel=1e-12)
    assert np.allclose(elastic_left_cauchy_green(F_incr, state),
                       elastic_left_cauchy_green(F, direct), rtol=0, atol=1e-12)
    J_incr = np.linalg.det(F_incr)[:, None, None]
    expected_P = J_incr * sigma @ np.linalg.inv(F_incr).transpose(0, 2, 1)
    assert np.abs(P_ref - expected_P).max() <= 1e-12 * scale
    # the tangent: central differences of P_ref (error h² |P'''| ~ 1e-8 scale)
    A = referenced.tangent(point)
    h = 1e-6
    for k, L in [(0, 0), (1, 2), (2, 1)]:
        dF = np.zeros((3, 3))
        dF[k, L] = h
        plus = referenced.stress(F_incr + dF, rebased)[0]
        minus = referenced.stress(F_incr - dF, rebased)[0]
        assert np.abs((plus - minus) / (2 * h) - A[:, :, :, k, L]).max() <= 1e-5 * E


def test_referenced_material_refuses_invalid_volume_ratios():
    material = J2Material(E, NU)
    with pytest.raises(ValueError, match="J_ref = -1 at material point 1"):
        ReferencedMaterial(material, np.array([1.0, -1.0]))
    referenced = ReferencedMaterial(material, np.ones(2))
    assert referenced.E == E  # the material's own moduli
    with pytest.raises(ValueError, match="3 deformation gradients for a reference of 2"):
        referenced.stress(np.broadcast_to(np.eye(3), (3, 3, 3)), MaterialState.virgin(3))


@pytest.mark.parametrize("local", [False, True])
def test_transfer_carries_linear_fields_exactly(local):
    """Old points (a perturbed Gauss cloud) to the Gauss points of a basis:
    constants and linear fields are in the RK space of order 1, so the L²
    fit returns them to round-off; a quadratic field with the fit's error."""
    mesh = rectangle(2.0, 1.0, 8, 4)
    basis = RKBasis(mesh, vector=True, support=2.0, order=1)
    old = RKBasis(rectangle(2.0, 1.0, 7, 5), vector=True, support=2.0, order=1)
    x = np.asarray(old.global_coordinates()).reshape(2, -1)
    w = np.asarray(old.geometry.dx).ravel()
    transfer = PointTransfer(basis, x, w, radius=local_radius(mesh) if local else None)
    y = np.asarray(basis.global_coordinates()).reshape(2, -1)
    values = np.stack([np.full(x.shape[1], 3.0), 1.0 + 2.0 * x[0] - 0.5 * x[1]], axis=1)
    carried = transfer(values)
    assert carried.shape == (y.shape[1], 2)
    assert np.abs(carried[:, 0] - 3.0).max() <= 1e-10
    assert np.abs(carried[:, 1] - (1.0 + 2.0 * y[0] - 0.5 * y[1])).max() <= 1e-10
    quadratic = transfer(x[0] ** 2)
    error = np.abs(quadratic - y[0] ** 2).max()
    assert 1e-6 < error < 0.05  # h = 0.25: the fit's error of x², not exact
    copy = PointTransfer(old, x, w, same_points=True)
    assert np.array_equal(copy(values), values)


AXISYMMETRIC = """
[model]
type = "axisymmetric"

[geometry]
x = [0.5, 1.0]
y = [0.0, 1.0]
divisions = [4, 6]

[discretization]
integration = "{integration}"
rereference = 0.5

[material]
E = 200e3
nu = 0.3
yield = 300.0
hardening = "linear"
H = 2000.0

[boundary.bottom]
fix = ["y"]
method = "weak"

[boundary.top]
displacement = {{ y = -0.4 }}
method = "weak"

[steps]
count = 8
"""


class _At(Rereferencing):
    """Rebuilds after the converged steps at the given load factors."""

    def __init__(self, sim, at, **kw):
        super().__init__(sim, 0.5, **kw)
        self.at = list(at)

    def after_step(self, record, d, evaluation):
        if self.at and abs(record.t - self.at[0]) < 1e-9:
            self.at.pop(0)
            raise Rebuild("forced", d)


def _result_d(chain):
    return chain.d


def _residual(sim, d, t):
    """Relative out-of-balance force of ``sim`` at ``d`` (Newton's measure)."""
    ev = sim.problem.evaluate(d)
    rows = ConstraintSet([p.constraint(sim.basis) for p in sim.prescribed],
                         sim.problem.N, [p.name for p in sim.prescribed])
    return np.linalg.norm(_Reactions(rows.C).out_of_balance(-ev.f_int)) / np.linalg.norm(ev.f_int)


def _run(sim, at=None, transfer="local", residuals=None):
    stepper = StepperState()
    steps = sim.scene["steps"]

    def solve(d0):
        return newton_steps(sim.problem, sim.prescribed, steps=steps["count"],
                            tol=steps["tolerance"], d0=d0, stepper=stepper,
                            contributions=sim.contributions, on_step=on_step)

    chain = _At(sim, at or [], transfer=transfer)
    rebuild = chain.rebuild

    def checked(d, t, reason, stepper_):
        d_new = rebuild(d, t, reason, stepper_)
        if residuals is not None:
            residuals.append(_residual(sim, d_new, t))
        return d_new

    chain.rebuild = checked

    def on_step(record, d, ev):
        chain.after_step(record, d, ev)

    result = solve_segments(chain, solve, stepper)
    assert result.completed, result.message
    chain.d = result.d
    ev = sim.problem.evaluate(result.d, tangent=False)
    return sim.problem.cauchy_stress(ev), sim.problem.state.alpha, chain, result


@pytest.mark.parametrize("integration", ["vci", "scni"])
@pytest.mark.parametrize("transfer", ["local", "points"])
def test_uniform_compression_rebuilt_midway_keeps_the_stress(integration, transfer):
    """Homogeneous compression to 40 %, rebuilt after steps 3 and 6 (t =
    0.375, 0.75): the state is uniform, so the transfer is exact, the rebuild
    keeps equilibrium (residual at the Newton tolerance) and the final stress
    and plastic strain are those of the run without a rebuild and of the
    closed form (to the solver tolerance: 1e-6 of the stress)."""
    if integration == "scni" and transfer == "local":
        pytest.skip("nodal integration carries the state particle by particle")
    scene = parse_scene(AXISYMMETRIC.format(integration=integration), "block.toml")
    sigma0, alpha0, _, _ = _run(build(scene))
    residuals = []
    sim = build(scene)
    sigma1, alpha1, chain, _ = _run(sim, at=[0.375, 0.75], transfer=transfer,
                                    residuals=residuals)
    assert [t for t, _ in chain.events] == pytest.approx([0.375, 0.75])
    assert sim.rereferenced is chain and chain.t_ref == pytest.approx(0.75)
    assert max(residuals) <= scene["steps"]["tolerance"]
    exact = uniaxial_compression(0.4, E, NU, linear(YIELD, H))
    for sigma, alpha in ((sigma0, alpha0), (sigma1, alpha1)):
        assert np.abs(sigma[:, 1, 1] - exact.cauchy).max() <= 1e-6 * abs(exact.cauchy)
        assert np.abs(alpha - exact.alpha).max() <= 1e-8
    assert np.abs(sigma1 - sigma0).max() <= 1e-6 * abs(exact.cauchy)
    # the total deformation gradient, composed over the rebuilds: axial
    # stretch 1 - 0.4 t (the lateral one follows the volume change)
    assert np.abs(chain.F_ref[:, 1, 1] - (1.0 - 0.75 * 0.4)).max() <= 1e-9
    F_end = total_deformation_gradient(
        sim.problem.evaluate(_result_d(chain), tangent=False).F, chain.F_ref)
    assert np.abs(F_end[:, 1, 1] - 0.6).max() <= 1e-9


def test_scene_checks_the_threshold():
    text = AXISYMMETRIC.format(integration="vci")
    with pytest.raises(SceneError, match="rereference.*must lie in \\(0, 1\\)"):
        parse_scene(text.replace("rereference = 0.5", "rereference = 1.5"), "block.toml")
    with pytest.raises(SceneError, match="rereference: only for method rkpm"):
        from skfem_rkpm.runs.rereference import rereferencing_of
        rereferencing_of(build(parse_scene(text, "block.toml"), method="fem"))


def _ring(transfer):
    """The coarse stick ring (6 x 4 cells) pressed 17 mm in 10 steps, rebuilt
    on the converged state of t = 0.2 (17 % height reduction); returns what
    the rebuild kept."""
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()["ring"], [
        "geometry.divisions=[6,4]", "steps.count=10", "tools.platen.motion=[0.0,-17.0]",
        "tools.platen.friction=stick", "discretization.rereference=0.5",
        "discretization.rereference_supports=spacing"])
    sim = build(scene)
    stepper = StepperState()
    result = newton_steps(sim.problem, sim.prescribed, steps=np.linspace(0, 1, 11)[1:3],
                          tol=scene["steps"]["tolerance"], stepper=stepper,
                          contributions=sim.contributions)
    assert result.completed
    old = sim.problem
    ev = old.evaluate(result.d, tangent=False)
    before = dict(sigma=old.cauchy_stress(ev), alpha=old.state.alpha.copy(),
                  volume=old.assembler.layout.dx.ravel() * np.linalg.det(ev.F),
                  force=sim.tools[0].state.force.copy())
    chain = Rereferencing(sim, 0.5, supports="spacing", transfer=transfer)
    d = chain.rebuild(result.d, stepper.t, "test", stepper)
    ev = sim.problem.evaluate(d, tangent=False)
    after = dict(sigma=sim.problem.cauchy_stress(ev), alpha=sim.problem.state.alpha,
                 volume=sim.problem.assembler.layout.dx.ravel(), residual=_residual_with(
                     sim, d, stepper.t))
    more = newton_steps(sim.problem, sim.prescribed, steps=np.linspace(0, 1, 11)[3:4],
                        tol=scene["steps"]["tolerance"], d0=d, stepper=stepper,
                        contributions=sim.contributions)
    return before, after, more, scene


def _residual_with(sim, d, t):
    """Newton's relative out-of-balance force with the contact forces."""
    ev = sim.problem.evaluate(d)
    f, ref = ev.f_int.copy(), np.linalg.norm(ev.f_int)
    for c in sim.contributions:
        f_c, _ = c.evaluate(d, t)
        f, ref = f + f_c, max(ref, np.linalg.norm(f_c))
    rows = ConstraintSet([p.constraint(sim.basis) for p in sim.prescribed],
                         sim.problem.N, [p.name for p in sim.prescribed])
    return np.linalg.norm(_Reactions(rows.C).out_of_balance(-f)) / ref


@pytest.mark.parametrize("transfer", ["points", "local"])
def test_a_rebuilt_ring_keeps_its_plastic_state(transfer):
    """A converged, non-uniform state (the stick ring at 17 %): copied
    point by point the stress and plastic strain are the same numbers; fitted,
    the plastic volume ∫ ε̄ᵖ dv is kept to the quadrature of the new cells
    (2 %) and no value leaves the old range.  The out-of-balance force of
    the rebuilt discretization is that of new functions on the same state,
    a few percent (measured on these 6 x 4 cells: 6 % copied, 10 % fitted; 3 %
    at the paper's 15 x 10 cells),
    and the next step converges."""
    before, after, more, scene = _ring(transfer)
    if transfer == "points":
        assert np.array_equal(after["alpha"], before["alpha"])
        assert np.abs(after["sigma"] - before["sigma"]).max() <= 1e-9 * np.abs(
            before["sigma"]).max()
    plastic = [np.sum(s["alpha"] * s["volume"]) for s in (before, after)]
    assert plastic[1] == pytest.approx(plastic[0], rel=0.02)
    assert after["alpha"].max() <= before["alpha"].max() * (1 + 1e-9)
    assert after["alpha"].min() >= 0.0
    assert scene["steps"]["tolerance"] < after["residual"] < 0.15
    assert more.completed, more.message
