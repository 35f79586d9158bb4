"""The augmented Lagrangian solve of the saddle-point system
(:func:`skfem_rkpm.solvers.constrained.solve_saddle_point` with SuperLU:
``K + ρCᵀC`` factored, GMRES on the Schur complement of the multipliers)
against the saddle-point matrix ``[[K, Cᵀ], [C, 0]]`` factored as it is by
dense LU: RK and FEM bases in 2D and 3D, weak and nodal conditions, skew
directions, several right-hand sides, a stiffness that is singular until the
conditions remove its rigid motions, and a 3D Newton run."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, ElementHex1, ElementQuad1, ElementVector
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.approximation.constraints import (ConstraintSet, nodal_constraint,
                                                  weak_constraint)
from skfem_rkpm.meshes import box, rectangle
from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.runner import run
from skfem_rkpm.runs.scene import builtin_scenes, load_scene
from skfem_rkpm.solvers.constrained import solve_saddle_point
from skfem_rkpm.solvers.linear import make_solver

# results exact but for round-off of dense and sparse solves
pytestmark = pytest.mark.roundoff

SKEW = np.array([0.8, 0.0, 0.6])  # a unit direction not along an axis


def elasticity(basis, dim):
    lam, mu = lame_parameters(200e3, 0.3)
    return Assembler(basis).bilinear(isotropic_tangent(lam, mu, dim)).tocsr()


def rk_2d_weak():
    """2D RK (VCI: K not symmetric), weak conditions on both components of
    the left side (g = 0.01 in the second right-hand side)."""
    basis = RKBasis(rectangle(2.0, 1.0, 12, 6), vector=True, support=2.0)
    rows = ConstraintSet([weak_constraint(basis, "left", 0), weak_constraint(basis, "left", 1)],
                         basis.N)
    return elasticity(basis, 2), rows.C, 0.01


def rk_3d_skew():
    """3D RK on a 3 x 3 x 3 box: weak n·u = 0 on xmin with n skew, nodal
    n·u = 0 (rows Σ n_c Λᵀ[c]) on ymin with another skew n, weak z on zmin:
    together they remove the rigid motions."""
    basis = RKBasis(box(1.0, 1.0, 1.0, 3, 3, 3), vector=True, support=2.0)
    rows = ConstraintSet([weak_constraint(basis, "xmin", tuple(SKEW)),
                          nodal_constraint(basis, "ymin", tuple(SKEW[[1, 0, 2]])),
                          weak_constraint(basis, "zmin", 2)], basis.N)
    return elasticity(basis, 3), rows.C, 0.0


def fem_3d_skew():
    """FEM Hex1 (Λ the identity): nodal skew condition on xmin, z on zmin, y on ymin."""
    basis = Basis(box(1.0, 1.0, 1.0, 4, 4, 4), ElementVector(ElementHex1()), intorder=2)
    rows = ConstraintSet([nodal_constraint(basis, "xmin", tuple(SKEW)),
                          nodal_constraint(basis, "ymin", 1),
                          nodal_constraint(basis, "zmin", 2)], basis.N)
    return elasticity(basis, 3), rows.C, 0.0


def fem_2d_clamped():
    """FEM Quad1 with the left side clamped (nodal rows of the identity)."""
    basis = Basis(rectangle(2.0, 1.0, 16, 8), ElementVector(ElementQuad1()), intorder=2)
    rows = ConstraintSet([nodal_constraint(basis, "left", 0),
                          nodal_constraint(basis, "left", 1)], basis.N)
    return elasticity(basis, 2), rows.C, 0.01


CASES = {"rk 2d weak": rk_2d_weak, "rk 3d skew": rk_3d_skew,
         "fem 3d skew": fem_3d_skew, "fem 2d clamped": fem_2d_clamped}


def saddle_point_reference(K, C, f, g):
    """``d, λ`` from dense LU of ``[[K, Cᵀ], [C, 0]]``, and how far another
    direct solve of it (SuperLU, COLAMD, partial pivoting) lies from that in
    ``d`` and in ``λ``: the round-off of a direct solve of this system."""
    A = sp.bmat([[K, C.T], [C, None]]).tocsc()
    b = np.concatenate([f, g])
    x = np.linalg.solve(A.toarray(), b)
    y = splu(A, permc_spec="COLAMD").solve(b)
    N = K.shape[0]
    return x[:N], -x[N:], (rel(y[:N], x[:N]), rel(y[N:], x[N:]))


def tolerance(spread):
    """Ten times the spread of two direct solves, at least 1e-12: the
    augmented Lagrangian solve is backward stable to 1e-12 (it refines to
    that), so it lies as close to a direct solve as two direct solves lie to
    each other.  Measured: 1e-14 to 1e-13 from dense LU where the spread is
    5e-12 to 7e-11 in ``d``; in the 3D RK case dense LU lies 1e-10 to 3e-10
    from both the augmented and the COLAMD solve (the spread)."""
    return max(10.0 * spread, 1e-12)


def rel(x, y):
    return np.linalg.norm(x - y) / np.linalg.norm(y)


@pytest.mark.parametrize("case", list(CASES))
def test_augmented_solve_equals_the_saddle_point_solve(case):
    """One and three right-hand sides, against dense LU of the saddle-point
    matrix (:func:`tolerance`)."""
    K, C, value = CASES[case]()
    N, m = K.shape[0], C.shape[0]
    rng = np.random.default_rng(7)
    F = rng.normal(size=(N, 3)) * 100.0
    G = np.zeros((m, 3))
    G[:, 1] = value
    G[:, 2] = rng.normal(size=m) * 0.01
    solver = make_solver("superlu")
    D, L = solve_saddle_point(solver, K, F, C, G)
    assert solver.A.shape == (N, N)  # K + ρCᵀC was factored, not the saddle point
    assert solver.system.startswith("K + ρCᵀC")  # and the Newton log says so
    assert D.shape == (N, 3) and L.shape == (m, 3)
    for j in range(3):
        d_ref, lam_ref, (spread_d, spread_lam) = saddle_point_reference(K, C, F[:, j],
                                                                        G[:, j])
        assert rel(D[:, j], d_ref) < tolerance(spread_d)
        assert rel(L[:, j], lam_ref) < tolerance(spread_lam)
        d, lam = solve_saddle_point(solver, K, F[:, j], C, G[:, j])  # one column
        assert rel(d, d_ref) < tolerance(spread_d)
        # the conditions hold to the backward error the solve refines to
        # (1e-12 of |C| |d| + |g|, max norms)
        scale = abs(C).sum(axis=1).max() * np.abs(d).max() + np.abs(G[:, j]).max()
        assert np.abs(C @ d - G[:, j]).max() <= 1e-12 * scale


def test_singular_stiffness_whose_rigid_motions_the_conditions_remove():
    """Plane RK elasticity with no support but weak conditions: K alone is
    singular (the three rigid motions are in its null space), K + ρCᵀC is
    not, and the solve equals the saddle-point solve."""
    basis = RKBasis(rectangle(1.0, 1.0, 8, 8), vector=True, support=2.0)
    K = elasticity(basis, 2)
    x, y = basis.doflocs[0, 0::2], basis.doflocs[1, 0::2]  # particle positions
    rotation = np.zeros(basis.N)
    rotation[0::2], rotation[1::2] = -y, x
    from skfem_rkpm.solvers.idioms import coefficients
    d_rot = coefficients(basis, rotation)  # RK coefficients of the rigid rotation
    assert np.linalg.norm(K @ d_rot) < 1e-8 * abs(K).max() * np.linalg.norm(d_rot)
    rows = ConstraintSet([weak_constraint(basis, "left", 0),
                          weak_constraint(basis, "bottom", 1)], basis.N)
    C = rows.C
    f = np.random.default_rng(1).normal(size=basis.N)
    f -= (f @ d_rot) / (d_rot @ d_rot) * d_rot  # a load of any resultant is fine too
    g = np.full(C.shape[0], 0.002)
    solver = make_solver("superlu")
    d, lam = solve_saddle_point(solver, K, f, C, g)
    assert solver.A.shape == K.shape
    d_ref, lam_ref, (spread_d, spread_lam) = saddle_point_reference(K, C, f, g)
    assert rel(d, d_ref) < tolerance(spread_d) and rel(lam, lam_ref) < tolerance(spread_lam)


def test_singular_augmented_matrix_falls_back_to_the_saddle_point():
    """``K = [[1, 1], [1, 1/11]]`` with ``C = [1, 0]``: ``ρ = 10`` and
    ``K + ρCᵀC`` is singular, the saddle-point matrix is not (determinant
    -1/11); SuperLU then factors the saddle-point matrix, and the answer is
    exact."""
    K = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0 / 11.0]]))
    C = sp.csr_matrix(np.array([[1.0, 0.0]]))
    f, g = np.array([1.0, 2.0]), np.array([0.5])
    solver = make_solver("superlu")
    d, lam = solve_saddle_point(solver, K, f, C, g)
    # C d = g: d0 = 0.5; row 2: d0 + d1/11 = 2 -> d1 = 16.5; row 1: d0 + d1 - λ = 1
    np.testing.assert_allclose(d, [0.5, 16.5], rtol=1e-12)
    np.testing.assert_allclose(lam, [16.0], rtol=1e-12)
    assert solver.A.shape == (3, 3)  # the saddle-point matrix
    assert "saddle-point" in solver.system


def test_block_3d_newton_run_is_the_same_as_with_the_saddle_point():
    """block_3d, 3 x 3 x 3 cells, 5 steps into the plastic range: SuperLU
    (augmented Lagrangian) against dense LU of the saddle-point matrix; the
    forces and the corner's path agree to 1e-10 (each run's Newton residual
    is below 1e-12; the exact solution is met to 1e-10 by both,
    tests/test_scenes_3d.py)."""
    settings = ["geometry.divisions=[3, 3, 3]", "steps.count=5", "steps.tolerance=1e-12",
                "output.figures=false", "output.fields=false"]
    results = {}
    for name in ("dense", "superlu"):
        sim = build(load_scene(builtin_scenes()["block_3d"],
                               settings + [f'steps.solver="{name}"']), "rkpm")
        result = run(sim, progress=False)
        assert result.completed, result.message
        results[name] = result
    a, b = results["dense"], results["superlu"]
    assert len(a.history) == len(b.history) == 5
    for ra, rb in zip(a.history, b.history):
        for key, force in ra.reactions.items():
            assert rb.reactions[key] == pytest.approx(force, rel=1e-10, abs=1e-10 * max(
                abs(v) for v in ra.reactions.values()))
    assert rel(b.d, a.d) < 1e-10


def fem_3d_weak():
    """FEM Hex1 with the weak symmetry rows of billet_3d on xmin, ymin,
    zmin: for linear elements they touch only the constrained dofs, so the
    null-space basis is a selection of the other unknowns."""
    basis = Basis(box(2.0, 1.0, 1.5, 4, 2, 3), ElementVector(ElementHex1()), intorder=2)
    rows = ConstraintSet([weak_constraint(basis, "xmin", 0), weak_constraint(basis, "ymin", 1),
                          weak_constraint(basis, "zmin", 2)], basis.N)
    return elasticity(basis, 3), rows.C, 0.01


@pytest.mark.parametrize("case", list(CASES) + ["fem 3d weak"])
def test_null_space_solve_equals_the_saddle_point_solve(case):
    """``auto`` eliminates the conditions by a null-space basis
    (:mod:`skfem_rkpm.solvers.nullspace`): one and three right-hand sides
    against dense LU of the saddle-point matrix and against the augmented
    Lagrangian solve (:func:`tolerance`)."""
    K, C, value = (CASES.get(case) or fem_3d_weak)()
    N, m = K.shape[0], C.shape[0]
    rng = np.random.default_rng(11)
    F = rng.normal(size=(N, 3)) * 100.0
    G = np.zeros((m, 3))
    G[:, 1] = value
    G[:, 2] = rng.normal(size=m) * 0.01
    solver = make_solver("auto")
    D, L = solve_saddle_point(solver, K, F, C, G)
    assert solver.system.startswith("Zᵀ K Z")
    # Z a selection for FEM rows of one component; skew rows couple components
    assert solver.null_space.selection == (case.startswith("fem") and "skew" not in case)
    augmented = make_solver("superlu")
    for j in range(3):
        d_ref, lam_ref, (spread_d, spread_lam) = saddle_point_reference(K, C, F[:, j],
                                                                        G[:, j])
        assert rel(D[:, j], d_ref) < tolerance(spread_d)
        assert rel(L[:, j], lam_ref) < tolerance(spread_lam)
        d, lam = solve_saddle_point(solver, K, F[:, j], C, G[:, j])  # one column, kept basis
        d_aug, lam_aug = solve_saddle_point(augmented, K, F[:, j], C, G[:, j])
        assert rel(d, d_aug) < tolerance(spread_d) and rel(lam, lam_aug) < tolerance(spread_lam)
        scale = abs(C).sum(axis=1).max() * np.abs(d).max() + np.abs(G[:, j]).max()
        assert np.abs(C @ d - G[:, j]).max() <= 1e-12 * scale


def test_null_space_of_dependent_rows_keeps_the_saddle_point():
    """Rows that are nearly dependent (the pivoted QR finds it) are not
    eliminated: ``auto`` solves the saddle point, as before."""
    K, C, _ = rk_2d_weak()
    C = sp.vstack([C, C[:1] * (1 + 1e-14)]).tocsr()
    from skfem_rkpm.solvers.nullspace import null_space
    assert null_space(C) is None


#: the coarse billet pressed by 1.5 mm (10 %) in 4 steps: friction, contact
#: (at the scene's tolerance 1e-6; at 1e-12 the RK run needs 800 sub-steps)
BILLET = ["geometry.divisions=[4, 2, 3]", "steps.count=4",
          "tools.platen.motion=[0.0, 0.0, -1.5]"]
BLOCK = ["geometry.divisions=[3, 3, 3]", "steps.count=5", "steps.tolerance=1e-12"]


def test_null_space_is_built_once_per_set_of_rows():
    """The same rows give the kept basis (also to a new solver); rows
    changed in place or gone are not served from the cache."""
    import gc
    import weakref

    from skfem_rkpm.solvers import nullspace
    _, C, _ = rk_2d_weak()
    first = nullspace.for_rows(C)
    assert nullspace.for_rows(C) is first
    C.data *= 2.0
    second = nullspace.for_rows(C)
    assert second is not first
    np.testing.assert_allclose(second.W, first.W, rtol=1e-12, atol=1e-12)  # C_D⁻¹ C_I
    gone = weakref.ref(C)
    del C
    gc.collect()
    assert gone() is None  # the kept basis does not hold the rows alive
    other = rk_2d_weak()[1]
    nullspace.for_rows(other)  # and the entry of the rows gone is dropped
    assert all(entry[0]() is not None for entry in nullspace._KEPT)


@pytest.mark.parametrize("scene, method, settings", [
    ("block_3d", "rkpm", BLOCK), ("block_3d", "fem", BLOCK),
    ("billet_3d", "rkpm", BILLET), ("billet_3d", "fem", BILLET),
])
def test_newton_run_with_the_null_space_is_the_same(scene, method, settings):
    """Newton runs with ``auto`` (conditions eliminated) and with SuperLU
    by name (augmented Lagrangian): the same steps and iterations, the
    reactions (tool forces too) and coefficients equal to 1e-9.  Each
    linear solve is backward stable to 1e-12, so both runs take the same
    decisions and end their steps within round-off of each other (measured
    on the billet: 1.5e-12 in d, 3e-12 in the forces)."""
    common = settings + ["output.figures=false", "output.fields=false"]
    results = {}
    for name in ("auto", "superlu"):
        sim = build(load_scene(builtin_scenes()[scene], common + [f'steps.solver="{name}"']),
                    method)
        result = run(sim, progress=False)
        assert result.completed, result.message
        results[name] = result
    a, b = results["auto"], results["superlu"]
    assert [r.iterations for r in a.history] == [r.iterations for r in b.history]
    for ra, rb in zip(a.history, b.history):
        largest = max(np.abs(v).max() for v in ra.reactions.values())
        for key, force in ra.reactions.items():
            assert np.abs(np.asarray(rb.reactions[key]) - force).max() <= 1e-9 * largest
    assert rel(a.d, b.d) < 1e-9


def test_gram_of_the_conditions_is_kept_while_they_are_unchanged():
    """``CᵀC`` of the augmented Lagrangian is formed once per set of rows:
    the kept matrix is the product itself (same entries, bit for bit), it is
    formed again when the rows change in place, and other rows get their
    own."""
    from skfem_rkpm.solvers.constrained import _gram
    rng = np.random.default_rng(2)
    C = sp.random(30, 200, density=0.05, format="csr", random_state=rng)
    first = _gram(C, sp.csr_matrix(C))
    expected = sp.csr_matrix(C.T @ C)
    assert (first != expected).nnz == 0
    assert _gram(C, sp.csr_matrix(C)) is first
    C.data[0] *= 2.0  # changed in place: formed again
    again = _gram(C, sp.csr_matrix(C))
    assert again is not first and (again != sp.csr_matrix(C.T @ C)).nnz == 0
    other = sp.random(30, 200, density=0.05, format="csr", random_state=rng)
    assert (_gram(other, other) != sp.csr_matrix(other.T @ other)).nnz == 0
