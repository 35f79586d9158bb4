"""Frozen contact statuses of grazing nodes (mechanics/contact_status.py):
exact stick (μ = ∞, augmented Lagrangian) where a side folds onto the
platen, and the rules of :class:`StatusFreeze` on their own."""

import numpy as np

from skfem_rkpm.mechanics.contact_status import CLOSED, StatusFreeze
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from test_contact import LAW, problem_on


def fold_over(enforcement="augmented", friction="stick", max_cutbacks=4):
    """Plane strain upsetting of an 8 × 8 Q1 block (upper half, F-bar) by a
    rough platen to 50 % in 20 steps; the free side folds onto the platen,
    where a corner node grazes it."""
    problem = problem_on("fem", rectangle(1.0, 1.0, 8, 8), law=LAW, locking="fbar")
    platen = RigidContact(problem, Platen((0, 1), (0, -1), motion=(0, -0.5), name="platen"),
                          ["top", "right"], friction=friction, enforcement=enforcement,
                          factor=10.0 if enforcement == "augmented" else 1e3)
    lines = []
    result = newton_steps(problem, [Prescribed("bottom", 1, 0.0), Prescribed("left", 0, 0.0)],
                          steps=20, contributions=[platen], tol=1e-8,
                          max_cutbacks=max_cutbacks, log=lines.append)
    return result, platen, lines


def test_exact_stick_fold_over_converges_only_with_frozen_statuses(monkeypatch):
    """Without the freeze the grazing corner node cycles between touching and
    apart (measured, also with the code before the freeze: the run stops at
    90 % of the stroke, residuals 1e-2 to 9e-2 after 4 cut-backs, 8 cut-backs
    do not help); with it every step converges without a
    cut-back, and the final state satisfies the contact law: pressed nodes
    penetrate less than the tolerance, no node pulls on the platen, sticking
    nodes have not slipped beyond the tolerance in any step (the
    augmentation ends only then), and the node released to slide carries
    no shear and no tension."""
    result, platen, lines = fold_over()
    assert result.completed, result.message
    assert sum(r.cutbacks for r in result.history) == 0
    assert any("frozen closed" in line for line in lines)  # the freeze acted
    state, h = platen.state, platen.points.spacing
    tolerance = platen.tolerance * h
    assert np.maximum(-state.node_gap, 0.0)[state.active].max() <= tolerance
    assert state.pressure.min() >= 0.0  # no tension at the end
    sliding = state.slip & state.active
    assert sliding.sum() <= 1  # measured: 1 of 17 pressed nodes
    assert np.all(state.shear[sliding] == 0.0)
    assert state.active.sum() >= 10
    # the measured nodes carry the platen force: stick holds it back outward
    fx, fy = result.history[-1].reactions["platen"]
    assert fy < 0 and fx < 0

    monkeypatch.setattr(StatusFreeze, "observe", lambda self, active: 0)
    unfrozen, _, _ = fold_over()
    assert not unfrozen.completed
    assert unfrozen.history[-1].t < 0.95


def test_the_penalty_law_never_freezes():
    """The penalty law (μ = 10 for "stick") keeps the freeze disabled: no
    node is frozen on the fold that needs it under exact stick.  (Its
    histories were compared with those of the code before the freeze:
    identical in every column but the seconds, docs/contact.md.)"""
    result, platen, lines = fold_over("penalty")
    assert result.completed and not platen._freeze.enabled
    assert platen._freeze.count == 0
    assert not any("frozen" in line for line in lines)


def test_a_node_that_flips_back_is_frozen_closed():
    freeze = StatusFreeze(3)
    for active in ([0, 0, 1], [1, 0, 1], [0, 0, 1]):
        newly = freeze.observe(np.array(active, bool))
    assert newly == 1 and freeze.closed.tolist() == [True, False, False]
    # the law's statuses are replaced for frozen nodes only
    assert freeze.apply(np.array([False, True, False])).tolist() == [True, True, False]


def test_a_node_predicted_in_contact_but_never_reached_is_frozen_closed():
    freeze = StatusFreeze(2, misses=3)
    for k in range(3):
        assert not freeze.closed.any()
        freeze.predict(np.array([True, k == 0]))
        freeze.observe(np.array([False, False]))
    assert freeze.closed.tolist() == [True, False]  # node 1 missed once only


def test_disabled_freeze_never_freezes():
    freeze = StatusFreeze(1, enabled=False)
    for active in ([0], [1], [0], [1]):
        assert freeze.observe(np.array(active, bool)) == 0
    assert freeze.count == 0


def test_review_opens_a_pulling_node_then_lets_it_slide_if_it_penetrates():
    """closed in tension -> open; open and penetrating -> sliding
    (frictionless, unilateral); a sliding node stays; within tolerance
    nothing changes."""
    freeze = StatusFreeze(2)
    freeze.status[:] = CLOSED  # both frozen closed
    changed = freeze.review(np.zeros(2), np.array([-2.0, -0.5]), 1e-6, 1.0)
    assert changed.tolist() == [True, False] and freeze.held.tolist() == [True, True]
    assert freeze.apply(np.array([True, False])).tolist() == [False, True]
    changed = freeze.review(np.array([-1e-3, 0.0]), np.zeros(2), 1e-6, 1.0)
    assert changed.tolist() == [True, False] and freeze.sliding.tolist() == [True, False]
    # sliding: the law decides open/closed, without shear
    assert freeze.apply(np.array([True, False])).tolist() == [True, True]
    assert freeze.apply(np.array([False, False])).tolist() == [False, True]
    shear, slip = freeze.release(np.array([3.0, 4.0]), np.array([False, False]))
    assert shear.tolist() == [0.0, 4.0] and slip.tolist() == [True, False]
    vectors, _ = freeze.release(np.ones((2, 3)), np.zeros(2, bool))
    assert vectors.tolist() == [[0.0] * 3, [1.0] * 3]
    assert not freeze.review(np.array([-1.0, 0.0]), np.array([-5.0, 0.0]), 1e-6, 1.0).any()
    freeze.reset()
    assert freeze.count == 0
