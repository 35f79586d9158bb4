"""The stick prediction of 3D contact (SurfaceContact.sticking): a
slipping node that the Newton update would carry back through the stick
cone takes its stick branch in the linear model.  Its linear model of the
law against the law itself, and the converged answer unchanged."""

import numpy as np
import pytest

from skfem_rkpm.mechanics import surface_contact
from test_contact_symmetry import upset
from test_surface_contact import TOOLS, cube, problem_on


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
def test_linearized_law_is_the_first_order_change_of_the_law(kind, collocation):
    """``linearized_law(ε δ)`` against the trial traction and pressure
    evaluated at ``d + ε δ`` under a ball (curved: the law is not linear
    in ``d``): relative to the change, the difference falls as ε (second
    order: a factor ~10 from ε = 1e-2 to 1e-3; asserted 5)."""
    problem = problem_on(kind, cube())
    contact = surface_contact.SurfaceContact(problem, TOOLS["ball"](), "top", 0.3,
                                             collocation, penalty=1e5,
                                             tangential_penalty=2e4)
    rng = np.random.default_rng(4)
    d0 = 0.01 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d = d0 + 0.01 * rng.normal(size=problem.N)
    delta = 0.01 * rng.normal(size=problem.N)
    contact.evaluate(d, 0.6)
    law = contact._linear[4]
    active = law[3]
    assert active.sum() >= 3
    errors = []
    for eps in (1e-2, 1e-3):
        contact.evaluate(d, 0.6)
        trial, pressure = contact.linearized_law(eps * delta)
        moved = contact.evaluate(d + eps * delta, 0.6)
        law_eps = contact._linear[4]
        both = active & law_eps[3]
        change = np.abs(law_eps[4][both] - law[4][both]).max()
        errors.append((np.abs(trial[both] - law_eps[4][both]).max()
                       + np.abs(pressure[both] - law_eps[0][both]).max()) / change)
        assert moved[0].shape == (problem.N,)
    assert errors[1] < errors[0] / 5 and errors[1] < 1e-2


def test_stick_prediction_keeps_the_converged_answer(monkeypatch):
    """The upset cube of test_contact_symmetry (μ = 0.3, augmented, edge
    nodes that turn from slip to stick): with the prediction (it holds
    nodes in stick in some updates) the converged steps agree with the
    run without it far below the Newton tolerance 1e-8 (measured 4e-14 of
    the platen force) in no more iterations (measured 45 against 46)."""
    held = {"count": 0}
    sticking = surface_contact.SurfaceContact.sticking

    def counted(self, delta):
        out = sticking(self, delta)
        held["count"] += out is not None
        return out

    monkeypatch.setattr(surface_contact.SurfaceContact, "sticking", counted)
    _, _, predicted = upset(True, steps=5, max_augmentations=30)
    assert predicted.completed and held["count"] > 0
    monkeypatch.setattr(surface_contact.SurfaceContact, "sticking", lambda self, delta: None)
    _, _, plain = upset(True, steps=5, max_augmentations=30)
    forces = np.array([r.reactions["top"] for r in predicted.history])
    reference = np.array([r.reactions["top"] for r in plain.history])
    np.testing.assert_allclose(forces, reference, atol=1e-7 * np.abs(reference[:, 2]).max())
    assert (sum(r.spent_iterations for r in predicted.history)
            <= sum(r.spent_iterations for r in plain.history))
