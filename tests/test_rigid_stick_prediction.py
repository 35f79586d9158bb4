"""The stick prediction of the 2D rigid-tool contact (RigidContact.sticking,
skfem_rkpm/mechanics/stick_prediction.py): a slipping node that the Newton
update would carry through the stick cone takes its stick branch in the
linear model of the update.  Its linear model of the law against the law
itself, and on the ring with SCNI the converged answer unchanged in fewer
iterations."""

import numpy as np
import pytest

from skfem_rkpm.mechanics import rigid_contact
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.stick_prediction import linearized_law
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.runs.runner import build
from skfem_rkpm.runs.scene import builtin_scenes, load_scene
from skfem_rkpm.solvers.newton import newton_steps
from test_contact import TOOLS, problem_on


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
def test_linearized_law_is_the_first_order_change_of_the_law(kind, collocation):
    """``linearized_law(ε δ)`` against the trial shear and the pressure
    evaluated at ``d + ε δ`` under an arc (curved: the law is not linear in
    ``d``), in slip: relative to the change, the difference falls as ε
    (second order: a factor ~10 from ε = 1e-2 to 1e-3; asserted 5).  A sign
    or a term missing in the linearization leaves an error of order 1."""
    problem = problem_on(kind, rectangle(1.0, 0.5, 4, 2))
    contact = RigidContact(problem, TOOLS["arc"](), "top", 0.02, collocation, penalty=1e5,
                           tangential_penalty=2e4)
    rng = np.random.default_rng(4)
    d0 = 0.003 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d = d0 + 0.003 * rng.normal(size=problem.N)
    delta = 0.003 * rng.normal(size=problem.N)
    contact.evaluate(d, 0.6)
    law = contact._linear[4]
    active = law[3]
    assert active.sum() >= 3 and law[2].any()  # nodes in contact, some slipping
    trial0, _, _ = linearized_law(contact, 0 * delta)
    errors = []
    for eps in (1e-2, 1e-3):
        contact.evaluate(d, 0.6)
        _, trial, pressure = linearized_law(contact, eps * delta)
        contact.evaluate(d + eps * delta, 0.6)
        law_eps = contact._linear[4]
        trial_eps, _, _ = linearized_law(contact, 0 * delta)
        both = active & law_eps[3]
        change = np.abs(trial_eps[both] - trial0[both]).max()
        errors.append((np.abs(trial[both] - trial_eps[both]).max()
                       + np.abs(pressure[both] - law_eps[0][both]).max()) / change)
    assert errors[1] < errors[0] / 5 and errors[1] < 1e-2


def ring_steps(predict):
    """The first three steps of scenes/ring.toml (μ = 0.15) with SCNI, with
    or without the stick prediction: ``(platen forces, d, iterations,
    predictions that held nodes in stick)``."""
    held = {"count": 0}
    sticking = rigid_contact.RigidContact.sticking

    def counted(self, delta):
        out = sticking(self, delta) if predict else None
        held["count"] += out is not None
        return out

    scene = load_scene(builtin_scenes()["ring"], ['discretization.integration="scni"',
                                                  "tools.platen.friction=0.15"])
    sim = build(scene, "rkpm")
    contact = sim.contributions[0]
    contact.sticking = counted.__get__(contact)
    result = newton_steps(sim.problem, sim.prescribed, load=sim.load,
                          steps=[0.01, 0.02, 0.03], tol=1e-6,
                          contributions=sim.contributions, max_iterations=30)
    assert result.completed and all(r.cutbacks == 0 for r in result.history)
    forces = np.array([r.reactions["platen"] for r in result.history])
    return (forces, result.solutions[-1], sum(r.spent_iterations for r in result.history),
            held["count"])


def test_stick_prediction_keeps_the_ring_answer_in_fewer_iterations():
    """The ring's first steps with SCNI, where the top nodes near the inner
    edge reverse their slip: with the prediction the platen force of every
    step agrees with the run without it to the Newton tolerance 1e-6
    (measured 1.8e-9 of the force), in fewer iterations (measured 16
    against 28)."""
    forces, d, iterations, held = ring_steps(True)
    plain_forces, plain_d, plain_iterations, plain_held = ring_steps(False)
    assert held > 0 and plain_held == 0
    np.testing.assert_allclose(forces, plain_forces, rtol=0,
                               atol=1e-6 * np.abs(plain_forces).max())
    assert iterations < plain_iterations
