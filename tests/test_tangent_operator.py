"""The tangent applied without its matrix (:class:`TangentOperator`) against
the assembled tangent, and the stable-step estimate built on it against the
one of the assembled matrix.

The states are plastic (random gradients of about 2 %, ten times the yield
strain), so the consistent tangent is non-symmetric with F-bar and the VCI
test gradients differ from the trial ones: ``K v``, ``Kᵀ v`` and
``½ (K + Kᵀ) v`` are all exercised.  Both paths sum the same products in
other orders, so they agree to the round-off of sums of ``count`` terms
whose absolute values add up to ``|∇̃Ψ|ᵀ dΩ |A| |∇Ψ| |v|`` (plus the rank-one
and stabilization terms), formed here from the gradient matrices of unit
vectors; a wrong transposition or a missing term is of the size of ``K v``
itself, 1e10 and more units of that bound.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import (Basis, ElementHex1, ElementQuad1, ElementVector, MeshHex,
                   MeshQuad)

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.kinematics import entries
from skfem_rkpm.mechanics.mass import scaled_largest
from skfem_rkpm.mechanics.materials import J2Material, linear
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.solvers.explicit import CentralDifference

from _roundoff import assert_within, sum_bound

RHO = 7.85e-9

CASES = {  # name: (model, method, locking, basis options)
    "plane strain FEM": ("plane_strain", "fem", None, {}),
    "plane strain FEM F-bar": ("plane_strain", "fem", "fbar", {}),
    "plane strain RK": ("plane_strain", "rk", None, {}),
    "plane strain RK F-bar": ("plane_strain", "rk", "fbar", {}),
    "plane strain RK SCNI stabilized": ("plane_strain", "rk", None,
                                        {"integration": "scni", "stabilization": 0.3}),
    "axisymmetric RK F-bar": ("axisymmetric", "rk", "fbar", {"axisymmetric": True}),
    "3D FEM F-bar": ("3d", "fem", "fbar", {}),
    "3D RK": ("3d", "rk", None, {}),
    "3D RK F-bar": ("3d", "rk", "fbar", {}),
}


def problem_of(case):
    model, method, locking, options = CASES[case]
    if model == "3d":
        mesh = MeshHex.init_tensor(*[np.linspace(0, 1, 3)] * 3).with_defaults()
        element = ElementHex1()
    else:
        mesh = MeshQuad.init_tensor(np.linspace(0.5, 1.5, 4),
                                    np.linspace(0, 2, 5)).with_defaults()
        element = ElementQuad1()
    basis = (Basis(mesh, ElementVector(element), intorder=2) if method == "fem"
             else RKBasis(mesh, vector=True, support=2.0, **options))
    material = J2Material(200e3, 0.3, linear(250.0, 1e3))
    return SolidProblem(basis, material, model=model, locking=locking)


def plastic_state(problem, seed=3):
    """Coefficients of a random state about 2 % from the reference one."""
    return 0.01 * np.random.default_rng(seed).standard_normal(problem.N)


def gradient_matrix(problem, test):
    """``∇v`` at the model's entries of every point as a dense matrix
    (points * entries, N), from the gradients of unit vectors."""
    pairs = entries(problem.model)
    c, l = np.array([p[0][0] for p in pairs]), np.array([p[0][1] for p in pairs])
    columns = []
    for j in range(problem.N):
        e = np.zeros(problem.N)
        e[j] = 1.0
        H = problem.assembler.gradient(e, test=test)
        columns.append(H[c, l].reshape(len(c), -1).T.ravel())
    return np.array(columns).T


def magnitude(problem, evaluation, v, transpose=False):
    """Sum of the absolute values of the terms of ``K v`` (``Kᵀ v``), and the
    number of terms of its longest chain of sums."""
    A, rank_one = evaluation.tangent_parts()
    n, m = A.shape[:2]
    G, T = gradient_matrix(problem, False), gradient_matrix(problem, True)
    dx = np.asarray(problem.assembler.layout.dx).ravel()
    if transpose:
        G, T, A = T, G, A.transpose(0, 2, 1)
    inner = np.abs(A) @ (np.abs(G) @ np.abs(v)).reshape(n, m, 1)
    out = np.abs(T).T @ (dx[:, None] * inner[:, :, 0]).ravel()
    nloc = problem.assembler.layout.element_nodes.shape[0]
    count = problem.assembler.layout.ncomp * nloc + m + problem.shape[1] * m
    if rank_one is not None:
        u, w = rank_one if not transpose else rank_one[::-1]
        dofs = problem.assembler.element_dofs
        s = np.sum(np.abs(w) * np.abs(v)[dofs], axis=0)
        out += np.bincount(dofs.ravel(), weights=(np.abs(u) * s).ravel(),
                           minlength=problem.N)
    if problem.stabilization is not None:
        S = abs(problem.stabilization.matrix)
        out += (S.T if transpose else S) @ np.abs(v)
        count += S.getnnz(axis=1).max()
    return out, count


@pytest.mark.parametrize("case", list(CASES))
def test_products_equal_the_assembled_tangent(case):
    problem = problem_of(case)
    d = plastic_state(problem)
    evaluation = problem.evaluate(d)
    assert evaluation.state.alpha.max() > 0, "the state should be plastic"
    K = sp.csr_matrix(evaluation.K)
    operator = problem.tangent_operator(evaluation)
    v = np.random.default_rng(5).standard_normal(problem.N)
    forward, count = magnitude(problem, evaluation, v)
    backward, _ = magnitude(problem, evaluation, v, transpose=True)
    # the assembled path sums the same terms: both errors count
    assert_within(operator.matvec(v), K @ v, 2 * sum_bound(forward, count))
    assert_within(operator.rmatvec(v), K.T @ v, 2 * sum_bound(backward, count))
    assert_within(operator.symmetric(v), 0.5 * (K @ v + K.T @ v),
                  sum_bound(forward + backward, count))
    assert_within(operator.symmetric_operator() @ v, operator.symmetric(v), 0.0)


def test_the_tangent_is_exercised_unsymmetric():
    """The cases above are not trivially symmetric: with F-bar and VCI the
    tangent's antisymmetric part (5e-4 of its largest entry here, of the
    order of the stress over the modulus) is 1e9 times the round-off of the
    comparisons, so a product that transposed ``K`` would fail them."""
    problem = problem_of("3D RK F-bar")
    K = sp.csr_matrix(problem.evaluate(plastic_state(problem)).K)
    assert abs(K - K.T).max() > 1e-4 * abs(K).max()
    assert not problem.assembler.same_gradients


def test_an_evaluation_without_tangent_is_refused():
    problem = problem_of("plane strain FEM")
    with pytest.raises(ValueError, match="tangent=True"):
        problem.tangent_operator(problem.evaluate(np.zeros(problem.N), tangent=False))


@pytest.mark.parametrize("case", ["plane strain RK F-bar", "3D RK F-bar", "3D FEM F-bar",
                                  "plane strain RK F-bar, 722 rows"])
def test_stable_step_estimate_equals_the_assembled_one(case):
    """The estimate of :class:`CentralDifference` (on the products, by
    Lanczos at ``tol = 1e-6`` above 600 rows) against the largest eigenvalue
    of ``M⁻¹ K_sym`` of the assembled tangent, densely: within the Lanczos
    tolerance."""
    large = case.endswith("722 rows")
    if large:
        mesh = MeshQuad.init_tensor(np.linspace(0.5, 1.5, 19),
                                    np.linspace(0, 1, 19)).with_defaults()
        problem = SolidProblem(RKBasis(mesh, vector=True, support=2.0),
                               J2Material(200e3, 0.3, linear(250.0, 1e3)),
                               locking="fbar")
        assert problem.N == 722
    else:
        problem = problem_of(case)
    d = plastic_state(problem)
    scheme = CentralDifference(problem, RHO)
    K = sp.csr_matrix(problem.evaluate(d).K)
    scale = 1.0 / np.sqrt(scheme.mass)
    exact = np.linalg.eigvalsh(scale[:, None] * (0.5 * (K + K.T)).toarray() * scale)[-1]
    assert scheme.body_frequency2(d) == pytest.approx(exact, rel=1e-6)
