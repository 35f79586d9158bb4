"""Contact by the augmented Lagrangian (Uzawa updates around the penalty
Newton solves): penetration and stick slip to the tolerance, independent of
the penalty; μ = ∞ stick."""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.materials import J2Material, linear
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from skfem_rkpm.verification.exact import uniaxial_compression

E, NU = 200e3, 0.3
LAW = linear(300.0, 2000.0)


def problem_on(kind, mesh, model="plane_strain", law=LAW):
    if kind == "rk":
        basis = RKBasis(mesh, vector=True, support=2.0, axisymmetric=model == "axisymmetric")
    else:
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    return SolidProblem(basis, J2Material(E, NU, law), model)


def compress(kind, travel, steps, factor, enforcement, collocation="nodal", tolerance=1e-6):
    mesh = rectangle(1.0, 1.0, 4, 4)
    problem = problem_on(kind, mesh, "axisymmetric")
    kw = dict(collocation=collocation, factor=factor, enforcement=enforcement,
              tolerance=tolerance)
    bottom = RigidContact(problem, Platen((0, 0), (0, 1), name="bottom"), "bottom", **kw)
    top = RigidContact(problem, Platen((0, 1), (0, -1), motion=(0, -travel), name="top"),
                       "top", **kw)
    result = newton_steps(problem, [Prescribed("left", 0, 0.0)], steps=steps, tol=1e-10,
                          contributions=[bottom, top])
    assert result.completed, result.message
    return problem, result, top, bottom


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "quadrature")])
def test_frictionless_compression_penetrates_to_the_tolerance_only(kind, collocation):
    """Axisymmetric cylinder pressed 5 % by two platens: with the augmented
    Lagrangian the penetration falls below 1e-9 of the spacing whatever the
    penalty (the penalty law alone penetrates p h / (factor E)), and the
    force is the closed form of the travel itself."""
    for factor in (1e1, 1e3):
        problem, result, top, bottom = compress(kind, 0.05, 2, factor, "augmented",
                                                collocation, tolerance=1e-9)
        h = top.points.spacing
        assert top.penetration() <= 1e-9 * h and bottom.penetration() <= 1e-9 * h
        # uniaxial stress, height change = travel (up to the penetrations)
        force = np.pi * uniaxial_compression(0.05, E, NU, LAW).nominal  # unit radius
        assert result.history[-1].reactions["top"][1] == pytest.approx(force, rel=1e-9)
    _, _, top_penalty, _ = compress(kind, 0.05, 2, 1e1, "penalty", collocation)
    assert top_penalty.penetration() > 1e-4 * h  # what the augmentations removed


def test_augmented_agrees_with_the_penalty_law_as_the_penalty_grows():
    """The penalty solution tends to the augmented one like 1/ω."""
    _, aug, _, _ = compress("fem", 0.05, 2, 1e2, "augmented", tolerance=1e-10)
    f_aug = aug.history[-1].reactions["top"][1]
    gaps = []
    for factor in (1e2, 1e3, 1e4):
        _, pen, _, _ = compress("fem", 0.05, 2, factor, "penalty")
        gaps.append(abs(pen.history[-1].reactions["top"][1] / f_aug - 1))
    np.testing.assert_allclose(np.array(gaps[1:]) / gaps[:-1], 0.1, rtol=0.05)


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
@pytest.mark.parametrize("friction", [0.0, 0.3, "stick"])
def test_augmented_tangent_is_the_derivative_of_the_contact_force(kind, collocation,
                                                                  friction):
    """The tangent around non-zero multipliers (after an augmentation), in
    stick, slip and open states, against central differences."""
    from skfem_rkpm.mechanics.tools import Arc

    mesh = rectangle(1.0, 0.5, 4, 2)
    problem = problem_on(kind, mesh)
    contact = RigidContact(problem, Arc((0.5, 1.3), 0.85, (0, -180), motion=(0.3, -0.1)),
                           "top", friction, collocation, penalty=1e5,
                           tangential_penalty=2e4, enforcement="augmented")
    rng = np.random.default_rng(4)
    d0 = 0.003 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d1 = d0 + 0.002 * rng.normal(size=problem.N)
    contact.evaluate(d1, 0.55)
    assert contact.augment()  # multipliers = the tractions found at d1
    assert contact.multipliers[0].any()
    d = d1 + 0.002 * rng.normal(size=problem.N)
    _, K = contact.evaluate(d, 0.6)
    state = contact.trial
    assert state.active.any() and (~state.active).any()
    if friction == 0.3 and collocation == "nodal":
        assert state.slip.any() and (state.active & ~state.slip).any()
    h = 1e-7
    fd = np.column_stack([(contact.evaluate(d + h * e, 0.6)[0]
                           - contact.evaluate(d - h * e, 0.6)[0]) / (2 * h)
                          for e in np.eye(len(d))])
    K = K.toarray()
    assert np.abs(K - fd).max() < 1e-7 * np.abs(K).max()


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_rough_slider_sticks_exactly_until_the_coulomb_limit_then_slips(kind):
    """A strip held at its top is pressed by a platen from below, which then
    slides sideways.  With the augmented Lagrangian a pressed node moves with
    the platen (no slip, to 1e-9 of the spacing) while |t_t| ≤ μ t_n, and
    slips with |t_t| = μ t_n: no elastic slip of a tangential penalty."""
    mu, press, slide = 0.3, 1e-4, 1.2e-4
    mesh = rectangle(1.0, 0.25, 4, 1)
    problem = problem_on(kind, mesh, law=None)

    def motion(t):  # press up during t ≤ 1/2, then slide in +x
        return (slide * max(2 * t - 1, 0.0), press * min(2 * t, 1.0))

    platen = RigidContact(problem, Platen((0, 0), (0, 1), motion=motion, name="platen"),
                          "bottom", friction=mu, enforcement="augmented", tolerance=1e-9)
    conditions = [Prescribed("top", 0, 0.0), Prescribed("top", 1, 0.0)]
    states, x_bottom = [], []
    pts = platen.points
    result = newton_steps(problem, conditions, steps=np.r_[0.5, np.linspace(0.5, 1, 9)[1:]],
                          tol=1e-12, contributions=[platen],
                          on_step=lambda r, d, ev: (states.append(platen.state),
                                                    x_bottom.append(pts.displacements(d)[0])))
    assert result.completed, result.message
    h = pts.spacing
    sticking = []
    for k in range(1, len(states)):
        state = states[k]
        assert state.active.all()
        stick = ~state.slip
        ratio = np.abs(state.shear) / (mu * state.pressure)
        # stick: the node moved with the platen since the last step
        moved = x_bottom[k] - x_bottom[k - 1]
        platen_moved = motion(result.history[k].t)[0] - motion(result.history[k - 1].t)[0]
        np.testing.assert_allclose(moved[stick], platen_moved, atol=1e-9 * h)
        assert np.all(ratio[stick] <= 1 + 1e-12)
        # slip: on the Coulomb cone
        np.testing.assert_allclose(ratio[~stick], 1.0, rtol=1e-10)
        sticking.append(int(stick.sum()))
    # measured: slip spreads from the free ends inward as the drag grows,
    # sticking nodes per drag step 4, 3, 2, 1 (of 5)
    assert sticking[0] >= 3 and sticking[-1] <= 1
    assert all(a >= b for a, b in zip(sticking, sticking[1:]))


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_stick_is_exact_with_the_augmented_lagrangian(kind):
    """μ = ∞: the pressed top particles of a block follow a dragged platen
    to 1e-9 of the spacing, whatever the tangential penalty."""
    mesh = rectangle(1.0, 1.0, 4, 4)
    conditions = [Prescribed("bottom", 0, 0.0), Prescribed("bottom", 1, 0.0)]
    travel, drag = 2e-3, 4e-3

    def path(t):  # press during t ≤ 1/2, then drag in +x
        return (drag * max(2 * t - 1, 0.0), -travel * min(2 * t, 1.0))

    problem = problem_on(kind, mesh, law=LAW)
    platen = RigidContact(problem, Platen((0, 1), (0, -1), motion=path, name="platen"),
                          "top", friction="stick", enforcement="augmented", tolerance=1e-9)
    assert platen.mu == np.inf
    solutions = {}
    result = newton_steps(problem, conditions, steps=8, contributions=[platen],
                          on_step=lambda r, d, ev: solutions.update({r.t: d.copy()}))
    assert result.completed, result.message
    u = platen.points.displacements
    pressed = platen.state.active
    slip = u(result.d)[0] - u(solutions[0.5])[0] - drag
    assert pressed.sum() >= 3
    # each of the 4 drag steps may leave 1e-9 h of slip (the tolerance)
    assert np.abs(slip[pressed]).max() < 4 * 1e-9 * platen.points.spacing


def test_scene_keys_choose_the_enforcement():
    from skfem_rkpm.runs.build import tool_from_scene

    problem = problem_on("fem", rectangle(1.0, 1.0, 2, 2))
    section = {"kind": "platen", "point": [0, 1], "normal": [0, -1], "friction": "stick",
               "slaves": ["top"], "enforcement": "augmented", "penalty_factor": 10.0,
               "tolerance": 1e-8}
    contact = tool_from_scene("platen", section, problem.basis, problem)
    assert contact.enforcement == "augmented" and contact.mu == np.inf
    assert contact.omega_n == pytest.approx(10.0 * E / contact.points.spacing)
    assert contact.tolerance == 1e-8
    penalty = tool_from_scene("platen", {**section, "enforcement": "penalty"},
                              problem.basis, problem)
    assert penalty.mu == 10.0  # the penalty law's stand-in for stick


@pytest.mark.parametrize("enforcement, factor, rtol", [("penalty", 1e3, 2e-5),
                                                       ("augmented", 10.0, 1e-6)])
def test_quadratic_elements_collocate_at_all_their_facet_nodes(enforcement, factor, rtol):
    """Q2: nodal collocation at the vertices and mid-side nodes of the
    facets, weighted by ∫N_K 2πR dR (1/6 and 2/3 of a facet, the axis node
    none): the consistent nodal forces of a uniform pressure, so the
    homogeneous compression is exact up to the penetration (penalty:
    p h / (1000 E) of the height; augmented: 1e-6 of the node spacing)."""
    from skfem import ElementQuad2

    mesh = rectangle(1.0, 1.0, 3, 3)
    basis = Basis(mesh, ElementVector(ElementQuad2()), intorder=4)
    problem = SolidProblem(basis, J2Material(E, NU, LAW), "axisymmetric")
    kw = dict(enforcement=enforcement, factor=factor)
    bottom = RigidContact(problem, Platen((0, 0), (0, 1), name="bottom"), "bottom", **kw)
    top = RigidContact(problem, Platen((0, 1), (0, -1), motion=(0, -0.3), name="top"),
                       "top", **kw)
    assert top.points.n == 6  # 7 facet nodes, the one on the axis has no area
    assert top.points.spacing == pytest.approx(1 / 6)
    np.testing.assert_allclose(top.points.weights.sum(), np.pi)  # ∫ 2πR dR over [0, 1]
    result = newton_steps(problem, [Prescribed("left", 0, 0.0)], steps=6, tol=1e-10,
                          contributions=[bottom, top])
    assert result.completed, result.message
    force = np.pi * uniaxial_compression(0.3, E, NU, LAW).nominal
    # measured: 1.0e-5 (penalty), 2.0e-7 (augmented)
    assert result.history[-1].reactions["top"][1] == pytest.approx(force, rel=rtol)


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_the_tangent_is_formed_once_per_newton_update(kind, monkeypatch):
    """Line-search trials and converged states need no tangent: the solid's
    tangent is formed exactly once per Newton iteration (every attempt
    counted), fewer times than the solid is evaluated, and the run is the
    one an eagerly formed tangent gives (the same matrices, so the same
    iterations and solution to the last bit)."""
    def run(lazy):
        problem = problem_on(kind, rectangle(1.0, 1.0, 4, 4))
        platen = RigidContact(problem, Platen((0, 1), (0, -1), motion=(0, -0.02),
                                              name="platen"), "top", friction=0.3)
        calls = {"evaluate": 0, "tangent": 0}
        evaluate, form = problem.evaluate, problem._tangent_matrix

        def counted_evaluate(d, *args, **kwargs):
            calls["evaluate"] += 1
            ev = evaluate(d, *args, **kwargs)
            if not lazy:
                ev.K  # noqa: B018 - formed at once
            return ev

        def counted_form(*args, **kwargs):
            calls["tangent"] += 1
            return form(*args, **kwargs)

        monkeypatch.setattr(problem, "evaluate", counted_evaluate)
        monkeypatch.setattr(problem, "_tangent_matrix", counted_form)
        result = newton_steps(problem, [Prescribed("bottom", 1, 0.0),
                                        Prescribed("left", 0, 0.0)],
                              steps=4, contributions=[platen])
        assert result.completed, result.message
        return result, calls

    lazy, calls = run(lazy=True)
    eager, eager_calls = run(lazy=False)
    iterations = sum(r.spent_iterations for r in lazy.history)
    assert calls["tangent"] == iterations
    assert eager_calls["tangent"] == eager_calls["evaluate"] > iterations
    assert [r.spent_iterations for r in lazy.history] == [
        r.spent_iterations for r in eager.history]
    np.testing.assert_array_equal(lazy.d, eager.d)
