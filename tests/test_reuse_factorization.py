"""The last factorization reused as the preconditioner of GMRES
(:mod:`skfem_rkpm.solvers.reuse`): the solves equal the direct ones to the
bound the GMRES tolerance and the conditioning give, a stalled GMRES falls
back to a factorization (counted), and a 3D scene converges as with direct
solves."""

import csv

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementHex1, ElementVector, MeshHex, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from _roundoff import EPS, inf_norm, inverse_norm, solve_bound
from skfem_rkpm.solvers.constrained import solve_saddle_point
from skfem_rkpm.solvers.linear import Auto, SuperLU, make_solver
from skfem_rkpm.solvers.reuse import NEWTON_FRACTION, Reusing


def _tangents(seed=0):
    """The clamped Hex1 elasticity tangent of a 6 x 4 x 4 box (525 unknowns
    free), and the next "iteration": 2 % more on the diagonal and a
    non-symmetric coupling of 1 % (friction), both known exactly."""
    mesh = MeshHex.init_tensor(np.linspace(0, 3, 7), np.linspace(0, 2, 5),
                               np.linspace(0, 2, 5))
    basis = Basis(mesh, ElementVector(ElementHex1()))
    K = asm(linear_elasticity(*lame_parameters(200e3, 0.3)), basis)
    free = basis.complement_dofs(basis.get_dofs(lambda x: x[0] < 1e-9))
    K0 = sp.csr_matrix(K[free][:, free])
    rng = np.random.default_rng(seed)
    skew = sp.random(len(free), len(free), density=0.01, random_state=rng)
    scale = abs(K0).max()
    K1 = sp.csr_matrix(K0 + 0.02 * sp.diags(K0.diagonal()) + 0.01 * scale * (skew - skew.T))
    return K0, K1, rng.standard_normal(len(free))


def test_reused_solve_equals_the_direct_one():
    """GMRES stops at ``|b - A x| ≤ rtol |b|``, so ``|x - x_direct|∞ ≤
    ‖A⁻¹‖∞ rtol |b|₂`` plus the direct solve's own round-off; measured
    1e-3..1e-2 of that bound.  One factorization serves both matrices."""
    K0, K1, b = _tangents()
    solver = Reusing(SuperLU(), rtol=1e-10)
    solver.factor(K0)
    solver.factor(K1)
    x = solver.solve(b)
    direct = SuperLU().factor(K1).solve(b)
    assert solver.stats["factorizations"] == 1 and solver.stats["reused"] == 1
    assert solver.stats["fallbacks"] == 0 and 1 < solver.iterations[0] <= solver.maxiter
    assert np.linalg.norm(b - K1 @ x) <= 1e-10 * np.linalg.norm(b)
    bound = inverse_norm(K1) * 1e-10 * np.linalg.norm(b) + solve_bound(K1, direct, b)
    assert np.abs(x - direct).max() <= bound
    # a defect the bound catches: the old matrix's solution
    assert np.abs(SuperLU().factor(K0).solve(b) - direct).max() > 100 * bound


def test_newton_tolerance_sets_the_linear_one():
    solver = make_solver("auto", reuse_factorization="on")
    solver.follow_newton(1e-6)
    assert solver.backend("superlu").rtol == pytest.approx(NEWTON_FRACTION * 1e-6)
    assert make_solver("auto").backend("superlu").__class__ is SuperLU  # "off"
    with pytest.raises(ValueError, match="reuse_factorization must be one of"):
        make_solver("auto", reuse_factorization="yes")


def test_auto_reuses_below_the_order_limit_from_the_entries_limit():
    """``auto`` reuses the factorization of matrices of fewer than
    ``REUSE_LIMIT`` unknowns when they have at least ``REUSE_ENTRIES``
    stored entries (here the 525 x 525 Hex1 tangent, 30,000 entries, against
    a limit set just above and just below them); the reused solve meets the
    GMRES tolerance."""
    from skfem_rkpm.solvers import reuse
    K0, K1, b = _tangents()
    for limit, reused in ((K1.nnz + 1, 0), (K0.nnz, 1)):
        solver = reuse.reusing(SuperLU(), "auto", "superlu")
        assert K0.shape[0] < solver.min_size == reuse.REUSE_LIMIT
        solver.min_entries = limit
        solver.follow_newton(1e-4)
        solver.factor(K0)
        x = solver.factor(K1).solve(b)
        assert solver.stats["reused"] == reused
        assert solver.stats["factorizations"] == 2 - reused
        assert np.linalg.norm(b - K1 @ x) <= solver.rtol * np.linalg.norm(b)
    assert reuse.reusing(SuperLU(), "auto", "superlu").min_entries == reuse.REUSE_ENTRIES
    assert reuse.reusing(SuperLU(), "on", "superlu").min_size == 0


def test_stalled_gmres_refactors_and_counts_it():
    """A cap of 2 GMRES iterations on a matrix 2 % off the factored one:
    GMRES stalls, the matrix is factored after all (a fallback) and solved
    directly (round-off bound); that factorization is then the
    preconditioner: the same matrix again takes one GMRES iteration."""
    K0, K1, b = _tangents(1)
    solver = Reusing(SuperLU(), rtol=1e-10, maxiter=2)
    solver.factor(K0)
    solver.factor(K1)
    x = solver.solve(b)
    assert solver.stats["fallbacks"] == 1 and solver.stats["factorizations"] == 2
    assert solver.iterations == [2]
    direct = SuperLU().factor(K1).solve(b)
    assert np.abs(x - direct).max() <= 2 * solve_bound(K1, direct, b)
    solver.factor(K1)
    y = solver.solve(b)
    assert solver.iterations[-1] == 1 and solver.stats["factorizations"] == 2
    assert np.abs(y - direct).max() <= inverse_norm(K1) * 1e-10 * np.linalg.norm(b) \
        + solve_bound(K1, direct, b)


def test_slow_gmres_refreshes_the_preconditioner():
    """More than half the cap of iterations: the next matrix is factored."""
    K0, K1, b = _tangents(2)
    solver = Reusing(SuperLU(), rtol=1e-10, maxiter=24)  # 15 iterations needed
    solver.factor(K0)
    solver.factor(K1).solve(b)
    assert solver.iterations[0] > 12 and solver.stats["fallbacks"] == 0
    solver.factor(K1 + sp.identity(K1.shape[0]))
    assert solver.stats["factorizations"] == 2 and not solver.stale


def test_reused_saddle_point_equals_the_direct_one():
    """The augmented Lagrangian path (SuperLU, ``K + ρCᵀC``): one GMRES on
    the saddle-point system with the kept factorization of the earlier
    ``K_ρ``.  ``C d = g`` holds to round-off, and ``d`` is the direct one
    within ``‖A⁻¹‖∞`` times the residuals the two solutions leave in the
    saddle-point matrix ``A`` (GMRES: at most ``rtol |b - K d₀|``, ``C d₀ =
    g``), plus the
    round-off of forming them."""
    K0, K1, b = _tangents(3)
    n = K0.shape[0]
    rng = np.random.default_rng(4)
    rows = rng.choice(n, 30, replace=False)
    C = sp.csr_matrix((np.ones(60) * np.repeat([1.0, -0.5], 30),
                       (np.tile(np.arange(30), 2), np.concatenate([rows, (rows + 7) % n]))),
                      shape=(30, n))
    g = 1e-3 * rng.standard_normal(30)
    solver = make_solver("superlu", reuse_factorization="on")
    solver.rtol = 1e-10
    solve_saddle_point(solver, K0, b, C, g)
    d, lam = solve_saddle_point(solver, K1, b, C, g)
    assert solver.stats["factorizations"] == 1 and solver.stats["reused"] == 1
    assert 1 < solver.iterations[-1] <= solver.maxiter
    d_direct, lam_direct = solve_saddle_point(make_solver("superlu"), K1, b, C, g)
    assert np.abs(C @ d - g).max() <= 100 * EPS * np.abs(g).max()
    inverse = np.linalg.inv(sp.bmat([[K1, C.T], [C, None]]).toarray())[:n]
    to_forces, to_values = (np.abs(inverse[:, :n]).sum(1).max(),
                            np.abs(inverse[:, n:]).sum(1).max())

    def bound_of(d, lam):
        """``‖A⁻¹[d, f-rows]‖∞ |r_f|∞ + ‖A⁻¹[d, g-rows]‖∞ |r_g|∞``, the residuals
        with the round-off of forming them."""
        r_f = np.abs(b - K1 @ d + C.T @ lam).max() + 16 * EPS * (
            inf_norm(K1) * np.abs(d).max() + inf_norm(C.T) * np.abs(lam).max())
        r_g = np.abs(g - C @ d).max() + 16 * EPS * inf_norm(C) * np.abs(d).max()
        return to_forces * r_f, to_values * r_g

    d0 = C.T @ np.linalg.solve((C @ C.T).toarray(), g)  # the load of the homogeneous rows
    assert np.linalg.norm(b - K1 @ d + C.T @ lam) <= 1e-10 * np.linalg.norm(b - K1 @ d0)
    # both solve the saddle-point system up to their residuals
    bound = sum(bound_of(d, lam)) + sum(bound_of(d_direct, lam_direct))
    assert np.abs(d - d_direct).max() <= bound
    assert np.abs(d - solve_saddle_point(make_solver("superlu"), K0, b, C, g)[0]).max() \
        > 100 * bound


def _billet(tmp_path, monkeypatch, method, reuse, solver, divisions, steps):
    """History rows and the linear solver of the run: ``steps`` steps of
    0.3 mm (the scene's)."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()["billet_3d"], [
        f"steps.count={steps}", f"tools.platen.motion=[0, 0, {-0.3 * steps}]",
        f"geometry.divisions={divisions}", f"steps.solver={solver}",
        f"steps.reuse_factorization={reuse}", "output.fields=false", "output.figures=false"])
    made, inner = [], runner._linear_solver
    monkeypatch.setattr(runner, "_linear_solver", lambda sim: made.append(inner(sim)) or made[-1])
    out = tmp_path / f"{method}-{reuse}"
    assert runner.run(runner.build(scene, method), out, progress=False).completed
    with open(out / "history.csv", newline="") as handle:
        return list(csv.DictReader(handle)), made[0]


@pytest.mark.parametrize("method, solver, divisions, steps",
                         [("fem", "auto", [8, 4, 6], 3), ("rkpm", "superlu", [4, 2, 3], 4)])
def test_billet_converges_as_with_direct_solves(tmp_path, monkeypatch, method, solver,
                                                divisions, steps):
    """The billet's first steps (FEM at the scene's 945 unknowns: the
    symmetry rows eliminated, ``auto`` picks SuperLU for ``K_II``; RKPM at
    180: SuperLU on ``K + ρCᵀC``, the multipliers in the GMRES).  A linear residual of ``NEWTON_FRACTION · tol`` moves
    Newton's relative residual by at most 0.2 % of ``tol``: every step takes
    the same iterations, and the converged reactions and points, each a
    solution of the same equations to the relative residual ``tol``, agree
    to ``tol`` relative (measured 1e-11..1e-9)."""
    tol = 1e-6
    direct, _ = _billet(tmp_path, monkeypatch, method, "off", solver, divisions, steps)
    reused, linear = _billet(tmp_path, monkeypatch, method, "on", solver, divisions, steps)
    backend = linear.current if isinstance(linear, Auto) else linear
    assert isinstance(backend, Reusing) and backend.stats["reused"] > 0
    assert backend.stats["factorizations"] < backend.stats["reused"]
    assert [r["iterations"] for r in reused] == [r["iterations"] for r in direct]
    columns = [k for k in direct[0] if k.startswith(("reaction", "corner", "top_corner"))]
    for a, b in zip(reused, direct):
        values = np.array([[float(a[k]), float(b[k])] for k in columns])
        scale = np.abs(values[:, 1]).max()
        assert np.abs(values[:, 0] - values[:, 1]).max() <= tol * scale
