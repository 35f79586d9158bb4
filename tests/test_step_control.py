"""Load-step control: cut on failure, remember the size, grow after easy steps."""

import numpy as np
import pytest

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.materials import J2Material, perfect
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from skfem_rkpm.solvers.step_control import StepControl


def test_steps_land_on_targets_in_equal_parts():
    control = StepControl(max_step=0.1, min_step=1e-6, size=0.04)
    assert control.next(0.0, 0.1) == pytest.approx(0.1 / 3)  # not 0.04 + 0.04 + 0.02
    assert control.next(0.2, 0.22) == pytest.approx(0.02)


def test_a_failure_halves_and_the_size_is_remembered():
    control = StepControl(max_step=0.1, min_step=0.01)
    assert control.failed(0.1) and control.size == 0.05
    control.converged(0.05, iterations=3, cut=True)   # needed a cut: no growth
    assert control.size == 0.05
    assert control.next(0.05, 0.1) == 0.05
    assert not control.failed(0.015)                   # 0.0075 < min_step: give up


@pytest.mark.parametrize("iterations, changes, size", [
    (6, 0, 0.02),            # at the target count: keep
    (2, 0, 0.02 * np.sqrt(3)),  # easy: sqrt(6 / 2)
    (1, 0, 0.04),            # at most by `growth`
    (12, 0, 0.02),           # hard steps do not shrink the next one
    (2, 3, 0.02),            # the contact status of 3 > 2 nodes changed: keep
])
def test_growth_follows_the_iterations(iterations, changes, size):
    control = StepControl(max_step=0.1, min_step=1e-3, size=0.02, patience=1)
    control.converged(0.02, iterations, changes)
    assert control.size == pytest.approx(size)


def test_growth_waits_for_steps_without_cut_backs():
    control = StepControl(max_step=0.1, min_step=1e-3, size=0.02, patience=3)
    control.converged(0.02, 1, cut=True)
    control.converged(0.02, 1)
    control.converged(0.02, 1)
    assert control.size == 0.02
    control.converged(0.02, 1)  # the third step in a row without a cut-back
    assert control.size == 0.04


def test_growth_stops_at_the_largest_step():
    control = StepControl(max_step=0.1, min_step=1e-3, size=0.08, patience=1)
    control.converged(0.08, 1)
    assert control.size == 0.1


def test_history_counts_every_attempt():
    """A perfectly plastic block pressed 30 % in one step with at most 4
    iterations cannot converge at once: the step is cut, and its record
    counts the failed attempts, their iterations and the cut-backs; later
    steps start from the remembered size instead of failing at full size."""
    mesh = rectangle(1.0, 1.0, 4, 4)
    problem = SolidProblem(RKBasis(mesh, vector=True), J2Material(200e3, 0.3, perfect(300.0)),
                           "plane_strain")
    conditions = [Prescribed("bottom", 1, 0.0), Prescribed("bottom", 0, 0.0),
                  Prescribed("top", 1, -0.3), Prescribed("top", 0, 0.0)]
    result = newton_steps(problem, conditions, steps=2, max_iterations=4, max_cutbacks=6)
    assert result.completed
    first = result.history[0]
    assert first.cutbacks >= 1
    # two starts (extrapolated, plain) exist only from the second step on
    assert first.attempts == first.cutbacks + 1
    assert first.spent_iterations == 4 * first.cutbacks + first.iterations
    # measured: cut twice to 0.125; then steps of that size without a
    # failure up to the target 0.5 (three in a row, the patience), after
    # which the size grows by sqrt(6 / 3) to 0.177: three equal steps of 1/6
    # to the target 1
    t = np.array([r.t for r in result.history])
    dt = np.diff(np.concatenate([[0.0], t]))
    assert first.t == 0.125 and np.allclose(dt[:4], 0.125)
    assert all(r.attempts == 1 for r in result.history[1:4])
    np.testing.assert_allclose(dt[4:], 1 / 6)
    assert t[-1] == 1.0
