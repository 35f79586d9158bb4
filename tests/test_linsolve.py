"""Linear solver backends (skfem_rkpm.solvers.linear): every installed backend
against dense numpy solutions on RK and FEM elasticity systems, the choices
of ``auto``, the message for a missing backend, analysis reuse, and the
Newton history of a plastic problem with each backend."""

import importlib

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementQuad1, ElementVector
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.approximation.constraints import nodal_constraint
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.solvers import backend as backend_registry
from skfem_rkpm.solvers import linear as linsolve
from skfem_rkpm.solvers.constrained import _penalty, solve_constrained
from skfem_rkpm.solvers.linear import (BackendUnavailable, NotPositiveDefinite, available,
                                       is_symmetric, make_solver)

OPTIONAL = ["pardiso", "cholmod", "umfpack", "amg"]
ALL = ["dense", "superlu", *OPTIONAL]
EPS = np.finfo(float).eps


def backend(name):
    """A solver, or skip when its optional package is not installed."""
    module = linsolve.BACKENDS[name][0]
    if module is not None:
        pytest.importorskip(module)
    return make_solver(name)


def system(kind):
    """(K, C, g, f) of plane elasticity on a 10 x 5 mesh, left side clamped
    (both components, the y component moved by 0.01)."""
    mesh = rectangle(2.0, 1.0, 10, 5)
    if kind == "fem":
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    else:
        basis = RKBasis(mesh, vector=True, support=2.0,
                        integration="gauss" if kind == "rk-gauss" else "vci")
    lam, mu = lame_parameters(200e3, 0.3)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2)).tocsr()
    groups = [nodal_constraint(basis, "left", i) for i in range(2)]
    C = sp.vstack([c.C for c in groups]).tocsr()
    g = np.concatenate([np.zeros(len(groups[0])), np.full(len(groups[1]), 0.01)])
    f = np.random.default_rng(3).normal(size=K.shape[0]) * 100.0
    return K, C, g, f


def tolerance(A, name):
    """Forward error bound: cond(A) × (unit round-off × 1e3, or AMG's rtol × 10)."""
    cond = np.linalg.cond(A.toarray() if sp.issparse(A) else A)
    return cond * (1e-11 if name == "amg" else 1e3 * EPS)


def rel(x, y):
    return np.linalg.norm(x - y) / np.linalg.norm(y)


def test_rk_vci_tangent_is_not_symmetric_gauss_and_fem_are():
    # the reason SPD-only backends cannot take RK tangents with VCI
    assert not is_symmetric(system("rk")[0])
    assert is_symmetric(system("rk-gauss")[0]) and is_symmetric(system("fem")[0])


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("kind", ["fem", "rk-gauss", "rk"])
def test_backend_solves_the_augmented_matrix(name, kind):
    """K + ρCᵀC: SPD for FEM and RK-Gauss, non-symmetric for RK with VCI."""
    solver = backend(name)
    K, C, _, f = system(kind)
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    ref = np.linalg.solve(A.toarray(), f)
    if name == "cholmod" and kind == "rk":
        with pytest.raises(NotPositiveDefinite, match="symmetric"):
            solver.factor(A)
        return
    x = solver.factor(A).solve(f)
    assert rel(x, ref) < tolerance(A, name)
    # 2-D right-hand sides
    X = solver.solve(np.column_stack([f, 2 * f]))
    assert X.shape == (len(f), 2) and rel(X[:, 1], 2 * ref) < tolerance(A, name)


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("kind", ["fem", "rk-gauss", "rk"])
def test_backend_solves_the_constrained_system(name, kind):
    """The symmetric indefinite KKT system of solve_constrained: factored
    directly, or through the augmented Lagrangian by SPD-only backends."""
    solver = backend(name)
    K, C, g, f = system(kind)
    N, m = K.shape[0], C.shape[0]
    kkt = sp.bmat([[K, C.T], [C, None]]).toarray()
    ref = np.linalg.solve(kkt, np.concatenate([f, g]))
    if name == "cholmod" and kind == "rk":
        with pytest.raises(NotPositiveDefinite, match="symmetric"):
            solve_constrained(K, f, C, g, solver=solver)
        return
    d, lam = solve_constrained(K, f, C, g, solver=solver)
    tol = tolerance(kkt, name)
    assert rel(d, ref[:N]) < tol and rel(lam, -ref[N:]) < tol
    assert np.abs(C @ d - g).max() < 1e-9 * np.abs(g).max()


@pytest.mark.parametrize("name", ["dense", "superlu", "pardiso", "umfpack", "amg"])
def test_backend_solves_a_non_symmetric_system(name):
    """A friction-like non-symmetric tangent: K plus a skew part of 10 % of |K|."""
    solver = backend(name)
    K, C, _, f = system("fem")
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    rng = np.random.default_rng(0)
    S = sp.random(A.shape[0], A.shape[0], density=0.01, random_state=rng).tocsr()
    A = (A + 0.1 * abs(K).max() * (S - S.T) / abs(S).max()).tocsr()
    assert not is_symmetric(A)
    ref = np.linalg.solve(A.toarray(), f)
    x = solver.factor(A).solve(f)
    assert rel(x, ref) < tolerance(A, name)


@pytest.mark.parametrize("name", ["pardiso", "cholmod", "umfpack"])
def test_analysis_is_reused_while_the_pattern_stays(name):
    solver = backend(name)
    K, C, _, f = system("fem")
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    solver.factor(A)
    A2 = (A + sp.diags(0.3 * A.diagonal())).tocsr()  # same pattern, other values
    x = solver.factor(A2).solve(f)
    assert solver.stats["analyses"] == 1 and solver.stats["factorizations"] == 2
    assert rel(x, np.linalg.solve(A2.toarray(), f)) < tolerance(A2, name)
    A3 = (A2 + sp.eye(A.shape[0], k=7) + sp.eye(A.shape[0], k=-7)).tocsr()  # new pattern
    x = solver.factor(A3).solve(f)
    assert solver.stats["analyses"] == 2
    assert rel(x, np.linalg.solve(A3.toarray(), f)) < tolerance(A3, name)


def big(n, symmetric):
    """A well-conditioned n x n sparse matrix (diagonally dominant)."""
    R = sp.random(n, n, density=5.0 / n, random_state=np.random.default_rng(1))
    R = R + R.T if symmetric else R
    return (R + sp.diags(np.asarray(abs(R).sum(axis=1)).ravel() + 1.0)).tocsr()


@pytest.mark.parametrize("installed, spd, symmetric, expected", [
    (["dense", "superlu"], False, True, "superlu"),
    (["dense", "superlu", "cholmod"], True, True, "cholmod"),
    (["dense", "superlu", "cholmod"], True, False, "superlu"),   # friction: never SPD-only
    (["dense", "superlu", "cholmod"], False, True, "superlu"),   # KKT: indefinite
    (["dense", "superlu", "cholmod", "amg"], True, False, "superlu"),
    (["dense", "superlu", "pardiso"], False, False, "superlu"),  # below PARDISO_LIMIT
])
def test_auto_choice_for_large_systems(installed, spd, symmetric, expected):
    auto = make_solver("auto")
    auto.installed = installed
    n = linsolve.DENSE_LIMIT + 100
    assert auto.choose(big(n, symmetric), spd=spd) == expected
    assert auto.choose(big(linsolve.DENSE_LIMIT, symmetric), spd=spd) == "dense"


@pytest.mark.parametrize("spd, symmetric", [(True, True), (False, False)])
def test_auto_takes_pardiso_for_the_largest_systems(spd, symmetric):
    auto = make_solver("auto")
    auto.installed = ["dense", "superlu", "pardiso", "cholmod"]
    assert auto.choose(big(linsolve.PARDISO_LIMIT + 100, symmetric), spd=spd) == "pardiso"
    assert auto.choose(big(linsolve.PARDISO_LIMIT, symmetric), spd=spd) != "pardiso"


@pytest.mark.parametrize("spd, symmetric", [(True, True), (False, False)])
def test_auto_never_takes_umfpack(spd, symmetric):
    """UMFPACK only by name: measured slower than SuperLU with nested
    dissection on large RK tangents (docs/benchmarks/linear_solvers.md)."""
    auto = make_solver("auto")
    auto.installed = ["dense", "superlu", "umfpack"]
    assert auto.choose(big(linsolve.PARDISO_LIMIT + 100, symmetric), spd=spd) == "superlu"


def test_umfpack_matches_dense_lu_on_several_right_hand_sides():
    """Non-symmetric RK tangent (VCI) plus a friction-like coupling of the
    x rows to the y columns: UMFPACK against LAPACK on four right-hand
    sides, 1-D and 2-D."""
    solver = backend("umfpack")
    K, C, _, f = system("rk")
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    A = (A + 0.3 * abs(K).max() * sp.eye(A.shape[0], k=1)).tocsr()  # x_i depends on y_i
    assert not is_symmetric(A)
    F = np.random.default_rng(5).normal(size=(A.shape[0], 4)) * 100.0
    ref = np.linalg.solve(A.toarray(), F)
    solver.factor(A)
    X = solver.solve(F)
    assert X.shape == F.shape
    for j in range(4):
        assert rel(X[:, j], ref[:, j]) < tolerance(A, "umfpack")
        assert rel(solver.solve(F[:, j]), ref[:, j]) < tolerance(A, "umfpack")


def test_umfpack_reports_a_singular_matrix():
    solver = backend("umfpack")
    K = system("fem")[0]  # no supports: rigid-body modes, singular
    A = K.tolil()
    A[0, :] = 0.0
    A[:, 0] = 0.0
    with pytest.raises(RuntimeError, match="singular"):
        solver.factor(A.tocsr())


@pytest.mark.parametrize("kind", ["fem", "rk-gauss", "rk"])
def test_superlu_with_nested_dissection_matches_dense_lu(kind, monkeypatch):
    """SuperLU on the METIS ordering (the path of large systems, forced here
    on a small one): symmetric (FEM, RK Gauss) and non-symmetric (RK VCI plus
    a friction-like coupling) against LAPACK, three right-hand sides, and
    again after a refactorization with the same pattern (ordering reused)."""
    pytest.importorskip("pymetis")
    monkeypatch.setattr(linsolve, "ND_LIMIT", 0)
    K, C, _, f = system(kind)
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    if kind == "rk":
        A = (A + 0.3 * abs(K).max() * sp.eye(A.shape[0], k=1)).tocsr()
    F = np.column_stack([f, -2 * f, np.random.default_rng(7).normal(size=len(f))])
    solver = make_solver("superlu")
    for M in (A, (A + sp.diags(0.5 * A.diagonal())).tocsr()):
        ref = np.linalg.solve(M.toarray(), F)
        X = solver.factor(M).solve(F)
        assert "nested dissection" in solver.describe()
        for j in range(F.shape[1]):
            assert rel(X[:, j], ref[:, j]) < tolerance(M, "superlu")
        assert rel(solver.solve(F[:, 2]), ref[:, 2]) < tolerance(M, "superlu")
    assert solver.stats["analyses"] == 1 and solver.stats["factorizations"] == 2


def test_nested_dissection_keeps_the_components_of_a_particle_together():
    pytest.importorskip("pymetis")
    A = (system("rk")[0] + sp.identity(2 * 66)).tocsr()  # 66 particles, 2 components
    perm = linsolve.nested_dissection(A)
    assert np.array_equal(np.sort(perm), np.arange(A.shape[0]))
    assert np.array_equal(perm[1::2], perm[0::2] + 1) and np.all(perm[0::2] % 2 == 0)


def test_superlu_orders_by_mmd_without_pymetis(monkeypatch):
    monkeypatch.setattr("builtins.__import__", _blocking_import("pymetis"))
    monkeypatch.setattr(linsolve, "ND_LIMIT", 0)
    K, C, _, f = system("rk")
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    assert linsolve.nested_dissection(A) is None
    solver = make_solver("superlu")
    x = solver.factor(A).solve(f)
    assert "MMD" in solver.describe()
    assert rel(x, np.linalg.solve(A.toarray(), f)) < tolerance(A, "superlu")


def _blocking_import(blocked):
    import builtins
    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == blocked:
            raise ImportError(f"No module named {blocked!r}")
        return real(name, *args, **kwargs)
    return fake


def test_auto_says_what_it_picked_and_solves():
    auto = make_solver("auto")
    assert "nothing factored" in auto.describe()
    A = big(200, False)
    f = np.arange(200.0)
    x = auto.factor(A).solve(f)
    assert auto.describe().startswith("auto: dense LU")
    assert rel(x, np.linalg.solve(A.toarray(), f)) < 1e-12
    A = big(linsolve.DENSE_LIMIT + 50, False)
    f = np.arange(A.shape[0], dtype=float)
    x = auto.factor(A).solve(f)
    assert auto.current.name == "superlu" and auto.describe() == "auto: " + auto.current.describe()
    assert rel(x, np.linalg.solve(A.toarray(), f)) < 1e-12


def test_auto_falls_back_when_cholmod_meets_an_indefinite_matrix():
    pytest.importorskip("sksparse.cholmod")
    auto = make_solver("auto")
    auto.installed = ["dense", "superlu", "cholmod"]
    A = big(linsolve.DENSE_LIMIT + 100, True)
    A = (A - sp.diags(np.r_[2 * A.diagonal()[:1], np.zeros(A.shape[0] - 1)])).tocsr()
    f = np.ones(A.shape[0])
    x = auto.factor(A, spd=True).solve(f)
    assert auto.current.name == "superlu"
    assert rel(x, np.linalg.solve(A.toarray(), f)) < 1e-10


@pytest.mark.parametrize("name", OPTIONAL)
def test_missing_backend_names_the_extra(name, monkeypatch):
    real = importlib.import_module
    module = linsolve.BACKENDS[name][0]

    def fake(mod, *args, **kwargs):
        if mod == module:
            raise ImportError(f"No module named {mod!r}")
        return real(mod, *args, **kwargs)

    monkeypatch.setattr(backend_registry.importlib, "import_module", fake)
    with pytest.raises(BackendUnavailable, match=rf"pip install skfem-rkpm\[{name}\]"):
        make_solver(name)
    assert name not in available()
    with pytest.raises(ValueError, match="unknown linear solver 'mumps'"):
        make_solver("mumps")


def test_spd_only_backend_refused_for_declared_non_symmetric():
    with pytest.raises(ValueError, match="symmetric positive definite"):
        make_solver("cholmod", symmetric=False)


def plastic_history(kind, name):
    from skfem_rkpm.mechanics.materials import J2Material, swift
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.solvers.newton import Prescribed, newton_steps

    mesh = rectangle(1.0, 1.0, 6, 6)
    basis = (RKBasis(mesh, vector=True, support=2.0) if kind == "rk"
             else Basis(mesh, ElementVector(ElementQuad1()), intorder=2))
    problem = SolidProblem(basis, J2Material(200e3, 0.3, swift(589.0, 1e-4, 0.216)),
                           "plane_strain")
    conditions = [Prescribed("bottom", 1, 0.0), Prescribed("bottom", 0, 0.0),
                  Prescribed("top", 1, -0.05), Prescribed("top", 0, 0.0)]
    lines = []
    result = newton_steps(problem, conditions, steps=3, tol=1e-10, log=lines.append,
                          linear_solver=name)
    assert result.completed, result.message
    assert any(line.startswith("linear solver: ") for line in lines)
    return [r.residuals for r in result.history], problem.state.alpha.max()


@pytest.mark.parametrize("name", ["superlu", *OPTIONAL])
@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_newton_history_is_the_same_with_every_backend(kind, name):
    """Residuals per iteration of a plastic compression with rough platens,
    against dense LU, to 1e-10 (the residuals are relative)."""
    backend(name)
    if name == "cholmod" and kind == "rk":
        pytest.skip("the RK tangent with VCI is not symmetric: CHOLMOD does not apply")
    reference, alpha = plastic_history(kind, "dense")
    history, _ = plastic_history(kind, name)
    assert alpha > 0.01  # plastic flow
    assert [len(r) for r in history] == [len(r) for r in reference]
    for res, ref in zip(history, reference):
        np.testing.assert_allclose(res, ref, rtol=0, atol=1e-10)
