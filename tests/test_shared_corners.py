"""Conditions that meet at a shared corner: dependent constraint rows.

Two boundaries fixing the same component at their common corner give the
corner's row twice (nodal), or rows whose span meets (weak, FEM): the
stacked ``C`` is rank deficient.  :class:`ConstraintSet` removes the
dependent rows; the solutions here are checked against the energy minimum
on the null space of the full, rank-deficient rows (unique because the
constraints are consistent), against the exact rigid translation, and the
reactions against equilibrium.
"""

import itertools

import numpy as np
import pytest
from scipy.linalg import null_space
from skfem import Basis, ElementQuad1, ElementVector, LinearForm, asm
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

from skfem_rkpm.approximation.basis import RKBasis
from skfem_rkpm.approximation.constraints import (ConstraintSet, nodal_constraint,
                                                  weak_constraint)
from skfem_rkpm.assembly import Assembler, facet_basis, isotropic_tangent
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers.constrained import solve_constrained
from skfem_rkpm.solvers.newton import Prescribed, newton_steps

E, NU = 1000.0, 0.3
LAM, MU = lame_parameters(E, NU)
SETS = {"x": [0], "y": [1], "xy": [0, 1]}
# left and bottom fixes that hold the rigid motions: x and y somewhere, and
# not only the tangential components (left y and bottom x allow the
# rotation about the corner)
COMBINATIONS = [(a, b) for a, b in itertools.product(SETS, SETS)
                if {0, 1} <= set(SETS[a]) | set(SETS[b]) and (a, b) != ("y", "x")]
# every combination with a shared component at the corner is in the list
SHARED = [(a, b) for a, b in COMBINATIONS if set(SETS[a]) & set(SETS[b])]
assert len(SHARED) == 5


def make_basis(method):
    mesh = rectangle(2.0, 2.0, 4, 4)
    if method == "rkpm":
        return RKBasis(mesh, vector=True, support=2.0)
    return Basis(mesh, ElementVector(ElementQuad1()))


def stiffness(basis):
    if isinstance(basis, RKBasis):
        return Assembler(basis).bilinear(isotropic_tangent(LAM, MU, 2))
    return asm(linear_elasticity(LAM, MU), basis)


def conditions(basis, left, bottom, how):
    build = nodal_constraint if how == "nodal" else weak_constraint
    out = [(f"left[{c}]", build(basis, "left", c)) for c in SETS[left]]
    out += [(f"bottom[{c}]", build(basis, "bottom", c)) for c in SETS[bottom]]
    return [n for n, _ in out], [c for _, c in out]


def top_pressure(basis, p=1.0):
    @LinearForm
    def load(v, w):
        return -p * dot(w.n, v)

    return asm(load, facet_basis(basis, "top"))


@pytest.mark.parametrize("method", ["rkpm", "fem"])
@pytest.mark.parametrize("how", ["nodal", "weak"])
@pytest.mark.parametrize("left,bottom", SHARED)
def test_dependent_rows_removed_and_solution_unchanged(method, how, left, bottom):
    basis = make_basis(method)
    names, groups = conditions(basis, left, bottom, how)
    rows = ConstraintSet(groups, basis.N, names)
    full = np.vstack([c.C.toarray() for c in groups])
    rank = np.linalg.matrix_rank(full)
    # what is removed is exactly the rank deficiency, and nothing else
    assert len(rows) == rank
    if how == "nodal" or method == "fem":
        # the shared corner: one row per shared component, found exactly
        assert len(full) - rank == len(set(SETS[left]) & set(SETS[bottom]))
    np.testing.assert_allclose(rows.combination @ rows.C.toarray(), full[rows.removed],
                               atol=1e-12 * np.abs(full).max())
    K, f = stiffness(basis), top_pressure(basis)
    g = np.zeros(len(full))
    d, lam = solve_constrained(K, f, rows.C, rows.values(g))
    # reference: the energy minimum on the null space of the full,
    # rank-deficient C (singular values of dependent rows ~1e-16, of the
    # nearly dependent RK weak rows at a corner ~3e-4: cut at 1e-10)
    Z = null_space(full, rcond=1e-10)
    ref = Z @ np.linalg.solve(Z.T @ K.toarray() @ Z, Z.T @ f)
    np.testing.assert_allclose(d, ref, atol=1e-9 * np.abs(ref).max())
    # reactions of all conditions balance the load: Σ λ_all C_all = -(f - K d)
    lam_all = rows.expand(lam)
    np.testing.assert_allclose(full.T @ lam_all, K @ d - f, atol=1e-9 * np.abs(f).max())


@pytest.mark.parametrize("method", ["rkpm", "fem"])
@pytest.mark.parametrize("how", ["nodal", "weak"])
@pytest.mark.parametrize("left,bottom", COMBINATIONS)
def test_prescribed_translation_is_exact(method, how, left, bottom):
    """A rigid translation prescribed on every condition is the solution:
    zero strain, zero reactions; removed rows carry values consistent with
    the kept ones (checked by ``values``).  Solved as the linear
    constrained problem: a stress-free state gives Newton no force scale
    to measure its residual against."""
    basis = make_basis(method)
    shift = (0.01, -0.02)
    names, groups = conditions(basis, left, bottom, how)
    rows = ConstraintSet(groups, basis.N, names)
    g = np.concatenate([c.R @ np.full(len(c.nodes), shift[c.component]) for c in groups])
    K = stiffness(basis)
    d, lam = solve_constrained(K, np.zeros(basis.N), rows.C, rows.values(g))
    nodal = basis.nodal_values(d) if isinstance(basis, RKBasis) else d
    u = nodal.reshape(-1, 2).T  # dofs 2 I + c (RK and Q1 alike)
    # round-off of the constrained solve of the 50-dof system
    np.testing.assert_allclose(u, np.array(shift)[:, None] + 0 * u, atol=1e-12)
    # no reactions: K d = 0 to round-off relative to |K| |d|; the nearly
    # dependent RK weak rows at a corner (cond(C Cᵀ) ≈ 1.5e7) amplify it
    # (measured 2.3e-9 of the scale)
    scale = abs(K).max() * np.abs(d).max()
    digits = 1e-7 if (method, how) == ("rkpm", "weak") else 1e-10
    assert np.abs(rows.expand(lam)).max() <= digits * scale


@pytest.mark.parametrize("method", ["rkpm", "fem"])
@pytest.mark.parametrize("how", ["nodal", "weak"])
@pytest.mark.parametrize("left,bottom", COMBINATIONS)
def test_newton_with_shared_corners_balances_the_load(method, how, left, bottom):
    """The reported crash (left x, bottom x and y) and every other
    combination run; the reactions add up to the applied pressure."""
    basis = make_basis(method)
    problem = SolidProblem(basis, J2Material(E, NU))
    prescribed = ([Prescribed("left", c, 0.0, how) for c in SETS[left]]
                  + [Prescribed("bottom", c, 0.0, how) for c in SETS[bottom]])
    f = top_pressure(basis, 1.0)
    result = newton_steps(problem, prescribed, load=lambda t: t * f, steps=1, tol=1e-9)
    assert result.completed, result.message
    reactions = result.history[-1].reactions
    total = [sum(v for k, v in reactions.items() if k.endswith(f"[{c}]")) for c in (0, 1)]
    # pressure 1 on the 2-wide top edge pushes down with 2; the supports push
    # back; 1e-7: the Newton tolerance 1e-9 relative to forces of order 1..100
    assert total[1] == pytest.approx(2.0, abs=1e-7)
    assert total[0] == pytest.approx(0.0, abs=1e-7)


def test_conflicting_values_at_a_shared_corner_are_reported():
    basis = make_basis("fem")
    problem = SolidProblem(basis, J2Material(E, NU))
    prescribed = [Prescribed("left", 0, 0.0), Prescribed("bottom", 0, 0.1),
                  Prescribed("bottom", 1, 0.0)]
    with pytest.raises(ValueError, match=r"bottom\[0\] and left\[0\] prescribe different "
                                         r"values of component 0 at the shared node "
                                         r"X = \(0, 0\)"):
        newton_steps(problem, prescribed, steps=1)


CORNER_SCENE = """
[geometry]
x = [0.0, 2.0]
y = [0.0, 2.0]
divisions = [4, 4]
[material]
E = 1000.0
nu = 0.3
[boundary.left]
fix = ["x"]
[boundary.bottom]
fix = ["x", "y"]
[boundary.top]
pressure = 1.0
[steps]
count = 2
"""


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_the_scene_of_the_issue_runs(method):
    """``[boundary.left] fix = ["x"]``, ``[boundary.bottom] fix = ["x", "y"]``
    ended in "Factor is exactly singular" before step 1."""
    from skfem_rkpm.runs.build import build
    from skfem_rkpm.runs.runner import run
    from skfem_rkpm.runs.scene import parse_scene

    result = run(build(parse_scene(CORNER_SCENE), method), progress=False)
    assert result.completed, result.message
    reactions = result.history[-1].reactions
    # the bottom carries the 2 of pressure; x reactions cancel (Newton tol 1e-6)
    assert reactions["bottom[1]"] == pytest.approx(2.0, rel=1e-6)
    assert reactions["left[0]"] + reactions["bottom[0]"] == pytest.approx(0.0, abs=1e-5)
