"""scikit-fem's own Dirichlet problems, with a FEM basis and with an RK basis.

Each problem is written once, as a scikit-fem user writes it, and run with
``Basis(m, ElementQuad1())`` and with ``RKBasis(m)``.  The RK run changes
three lines of the FEM script: the ``Basis`` line, ``condense`` imported
from ``skfem_rkpm`` instead of ``skfem`` with ``basis=basis`` added to its
call, and ``asm(laplace, basis.trial, basis)`` (the default VCI corrects
only test gradients; with ``integration="vci_symmetric"`` that line stays).
For a FEM basis ``skfem_rkpm.condense`` is ``skfem.condense``.

Every RK result is checked at the particles, through its nodal values
``Λᵀ d`` (Eq. 3.32), and against scikit-fem's ``condense`` used naively on
the RK basis, which constrains coefficients instead and misses the
boundary condition.
"""

import numpy as np
import pytest
import scipy.sparse as sp
import skfem
from skfem import Basis, ElementQuad1, Functional, MeshQuad, asm, solve
from skfem.helpers import dot, grad
from skfem.models.poisson import laplace, mass, unit_load

import skfem_rkpm
from skfem_rkpm import RKBasis, coefficients, condense, eigen, enforce, penalize

#: max of u for -Δu = 1 on the unit square, u = 0 on its boundary (series)
POISSON_MAX = 0.0736713532814
#: ∫|∇u|² of u = x² - y² on the unit square
ENERGY = 8.0 / 3.0


def square(n):
    return MeshQuad.init_tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))


def nodal(basis, d):
    """Field values at the particles/nodes: Λᵀ d on RK bases, d on FEM bases."""
    return basis.nodal_values(d) if isinstance(basis, RKBasis) else d


def stiffness(basis):
    return asm(laplace, getattr(basis, "trial", basis), basis)


def poisson(basis):
    """scikit-fem's first example: -Δu = 1, u = 0 on the boundary."""
    K, f = stiffness(basis), asm(unit_load, basis)
    return solve(*condense(K, f, D=basis.get_dofs(), basis=basis)), K, f


def centre(mesh):
    return np.flatnonzero(np.all(np.isclose(mesh.p, 0.5), axis=0))[0]


@pytest.fixture(scope="module")
def rk_bases():
    return {n: RKBasis(square(n)) for n in (16, 32)}


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_poisson_unit_square_max(kind, rk_bases):
    """Both bases converge to max u = 0.07367 at the centre as O(h²).

    Bilinear FEM has a nodal error at the centre of about 0.06 h²
    (2.3e-4 at h = 1/16, 5.7e-5 at 1/32); linear-reproducing RK is bounded
    by the same order.  Tolerance: 0.1 h² at each level, and the error must
    fall by at least 3.5 from h = 1/16 to 1/32 (4 for O(h²)).
    """
    errors = []
    for n in (16, 32):
        m = square(n)
        basis = Basis(m, ElementQuad1()) if kind == "fem" else rk_bases[n]
        d, _, _ = poisson(basis)
        u = nodal(basis, d)
        errors.append(abs(u[centre(m)] - POISSON_MAX))
        assert errors[-1] < 0.1 / n**2
        assert np.abs(u[basis.get_dofs()]).max() < 1e-14   # u = 0 at boundary nodes
        assert u.max() == pytest.approx(u[centre(m)], abs=1e-12)
    assert errors[0] / errors[1] > 3.5


def test_poisson_matches_saddle_point_and_enforce_and_naive_condense_does_not(rk_bases):
    basis = rk_bases[16]
    D = basis.get_dofs()
    d, K, f = poisson(basis)
    # the transformation method's saddle-point solve gives the same vector
    reference = skfem_rkpm.solve(K, f, basis, D=D)
    assert np.abs(d - reference).max() < 1e-12 * np.abs(reference).max()
    assert np.abs(solve(*enforce(K, f, D=D, basis=basis)) - reference).max() < \
        1e-12 * np.abs(reference).max()
    # the penalty (1/ε = 1e10 max diag K) misses it by O(ε): measured 6e-10
    penalized = solve(*penalize(K, f, D=D, basis=basis))
    assert np.abs(penalized - reference).max() < 1e-8 * np.abs(reference).max()
    # the same with I= instead of D=
    kept = np.setdiff1d(np.arange(basis.N), D)
    assert np.abs(solve(*condense(K, f, I=kept, basis=basis)) - reference).max() < \
        1e-12 * np.abs(reference).max()
    # scikit-fem's condense fixes the coefficients d_D = 0: the boundary
    # nodal values are then up to 2.6e-4 (0.3 % of max u), not 0
    naive = solve(*skfem.condense(K, f, D=D))
    assert np.abs(basis.nodal_values(naive)[D]).max() > 1e-4
    assert np.abs(basis.nodal_values(d)[D]).max() < 1e-15


def test_fem_basis_gives_scikit_fem_results_exactly():
    basis = Basis(square(6), ElementQuad1())
    K, f, M = asm(laplace, basis), asm(unit_load, basis), asm(mass, basis)
    D = basis.get_dofs()
    x = basis.doflocs[0] ** 2
    for ours, theirs in [(condense(K, f, x=x, D=D, basis=basis), skfem.condense(K, f, x=x, D=D)),
                         (condense(K, M, D=D), skfem.condense(K, M, D=D)),
                         (condense(K, f, D=D, expand=False, basis=basis),
                          skfem.condense(K, f, D=D, expand=False)),
                         (enforce(K, f, x=x, D=D, basis=basis), skfem.enforce(K, f, x=x, D=D)),
                         (penalize(K, f, x=x, D=D, basis=basis),
                          skfem.penalize(K, f, x=x, D=D))]:
        assert len(ours) == len(theirs)
        for a, b in zip(ours, theirs):
            a, b = (a.toarray(), b.toarray()) if sp.issparse(a) else (a, b)
            np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(coefficients(basis, x), x)


energy = Functional(lambda w: dot(grad(w["u"]), grad(w["u"])))


def harmonic(x):
    return x[0] ** 2 - x[1] ** 2


def laplace_inhomogeneous(basis):
    """scikit-fem's inhomogeneous Dirichlet example: Δu = 0, u = x² - y² on ∂Ω."""
    K = stiffness(basis)
    x = harmonic(basis.doflocs)
    return solve(*condense(K, x=x, D=basis.get_dofs(), basis=basis)), K


def test_inhomogeneous_dirichlet_energy(rk_bases):
    """∫|∇u_h|² → 8/3.

    Bilinear FEM reproduces u at the nodes, and the energy of the bilinear
    interpolant of x² - y² on a uniform mesh is 8/3 - 2h²/3 exactly (per
    direction ∫(2x)² - (2x_mid)² = h²/3).  RK must do at least as well:
    |E_h - 8/3| ≤ 2h²/3 on each mesh and a reduction by at least 4 (O(h²))
    from h = 1/16 to 1/32 (measured 1.4e-4 and 2.1e-5, rate 2.8).  The
    nodal values on the boundary are the data to round-off; inside they
    converge (measured max 2.9e-4 and 1.4e-4).
    """
    rk = []
    for n in (16, 32):
        m = square(n)
        fem = Basis(m, ElementQuad1())
        u, _ = laplace_inhomogeneous(fem)
        assert energy.assemble(fem, u=fem.interpolate(u)) == pytest.approx(
            ENERGY - 2 / (3 * n**2), rel=1e-12)
        np.testing.assert_allclose(u, harmonic(fem.doflocs), atol=1e-12)

        basis = rk_bases[n]
        d, K = laplace_inhomogeneous(basis)
        rk.append(abs(energy.assemble(basis, u=basis.interpolate(d)) - ENERGY))
        assert rk[-1] <= 2 / (3 * n**2)
        u, exact, D = basis.nodal_values(d), harmonic(basis.nodes), basis.get_dofs()
        assert np.abs(u[D] - exact[D]).max() < 1e-14
        assert np.abs(u - exact).max() < 5e-3 / n
        # naive skfem.condense prescribes coefficients: wrong boundary values
        # (1.3e-3 and 3.3e-4) and an energy error at least 50 times larger
        naive = solve(*skfem.condense(K, x=harmonic(basis.nodes), D=D))
        assert np.abs(basis.nodal_values(naive)[D] - exact[D]).max() > 5 / n**3
        assert abs(energy.assemble(basis, u=basis.interpolate(naive)) - ENERGY) > 50 * rk[-1]
    assert rk[0] / rk[1] > 4


def dirichlet_modes(basis, k=4):
    """-Δu = λu on the unit square, u = 0 on ∂Ω, through scikit-fem's solve."""
    K, M = stiffness(basis), asm(mass, basis)
    D = basis.get_dofs()
    w, d = solve(*condense(K, M, D=D, basis=basis),
                 solver=skfem.solver_eigen_scipy_sym(k=k, sigma=0.0))
    return w, d, K, M


MODES = np.array([[1, 1], [1, 2], [2, 1], [2, 2]])
EIGENVALUES = np.pi**2 * (MODES**2).sum(axis=1)
#: leading term of bilinear FEM's relative eigenvalue error on a uniform
#: mesh, divided by h²: π² (m⁴ + n⁴) / (12 (m² + n²))
FEM_ERROR = np.pi**2 * (MODES**4).sum(axis=1) / (12 * (MODES**2).sum(axis=1))


def test_constrained_eigenproblem_square():
    """λ = π²(m² + n²).  Bilinear FEM's errors follow their leading term
    π²h²(m⁴ + n⁴)/(12(m² + n²)) (1.3e-2 at h = 1/8 for the first) to 10 %
    (the next term is O(h⁴)); RK (vci_symmetric, eigsh) is asserted at least ten times
    closer on the same mesh (measured 80-100 times) and converging (error
    down by more than 3 from h = 1/8 to 1/16; measured 5)."""
    rk_errors = []
    for n in (8, 16):
        m = square(n)
        fem = Basis(m, ElementQuad1())
        wf, _, _, _ = dirichlet_modes(fem)
        fem_error = np.abs(wf / EIGENVALUES - 1)
        np.testing.assert_allclose(fem_error, FEM_ERROR / n**2, rtol=0.1)

        basis = RKBasis(m, integration="vci_symmetric")
        w, d, K, M = dirichlet_modes(basis)
        error = np.abs(w / EIGENVALUES - 1)
        assert np.all(error < fem_error / 10)
        rk_errors.append(error.max())
        # the same pairs from eigen() (it picks eigsh: the matrices are symmetric)
        w2, d2 = eigen(K, M, basis, D=basis.get_dofs(), k=4)
        np.testing.assert_allclose(w2, w, rtol=1e-10)
        # the modes vanish at the boundary particles and are K-orthogonal modes
        D = basis.get_dofs()
        u = basis.nodal_values(d)
        assert np.abs(u[D]).max() < 1e-12 * np.abs(u).max()
        residual = K @ d - M @ d * w
        C = basis.nodal_matrix[D]
        # the residual is a reaction: it lies in the span of the rows of C
        lam = sp.linalg.lsqr(C.T, residual[:, 0], atol=1e-14, btol=1e-14)[0]
        assert np.linalg.norm(C.T @ lam - residual[:, 0]) < 1e-8 * np.linalg.norm(K @ d[:, 0])
    assert rk_errors[0] / rk_errors[1] > 3


def test_naive_eigen_condense_does_not_hold_the_nodal_values():
    """skfem.condense on the RK basis gives eigenvalues as close (both are
    approximate boundary conditions), but its modes do not vanish at the
    boundary particles: measured 0.5-2 % of the mode's maximum at h = 1/8."""
    basis = RKBasis(square(8), integration="vci_symmetric")
    K, M, D = asm(laplace, basis), asm(mass, basis), basis.get_dofs()
    _, d = solve(*skfem.condense(K, M, D=D),
                 solver=skfem.solver_eigen_scipy_sym(k=4, sigma=0.0))
    u = basis.nodal_values(d)
    assert np.all(np.abs(u[D]).max(axis=0) > 1e-3 * np.abs(u).max(axis=0))


def test_iterative_solver_through_condense():
    """With symmetric matrices the reduced system is SPD: scikit-fem's CG
    solves it (to its tolerance 1e-12) and returns the constrained vector."""
    basis = RKBasis(square(12), integration="vci_symmetric")
    K, f = asm(laplace, basis), asm(unit_load, basis)
    D, x = basis.get_dofs(), harmonic(basis.nodes)
    A, b, x0, I = condense(K, f, x=x, D=D, basis=basis)
    assert abs(A - A.T).max() < 1e-13 * abs(A).max()
    d = solve(A, b, x0, I, solver=skfem.solver_iter_pcg(rtol=1e-12))
    reference = skfem_rkpm.solve(K, f, basis, D=D, x=x)
    assert np.abs(d - reference).max() < 1e-9 * np.abs(reference).max()
    # expand=False: the unknowns are the coefficients off D
    with pytest.warns(skfem_rkpm.PartialSolutionWarning, match="x0, I = condense"):
        A2, b2 = condense(K, f, x=x, D=D, basis=basis, expand=False)
    np.testing.assert_allclose(sp.linalg.spsolve(A2.tocsc(), b2),
                               reference[np.setdiff1d(np.arange(basis.N), D)],
                               atol=1e-12 * np.abs(reference).max())


def test_vector_basis_one_side_and_several_loads():
    """A vector basis fixed on one side (both components), two loads at
    once: the same as one solve per load, and as the saddle-point solve."""
    m = square(6)
    basis = RKBasis(m, vector=True)
    K = asm(skfem.models.elasticity.linear_elasticity(1.0, 1.0), basis.trial, basis)
    D = basis.get_dofs(lambda x: np.isclose(x[0], 0.0))
    F = np.zeros((basis.N, 2))
    F[basis.get_dofs(lambda x: np.isclose(x[0], 1.0)).nodal["u^1"], 0] = 1.0
    F[basis.get_dofs(lambda x: np.isclose(x[0], 1.0)).nodal["u^2"], 1] = 1.0
    X = np.zeros((basis.N, 2))
    X[D, 1] = 0.01                                    # second load: also a shift
    both = skfem_rkpm.solve(K, F, basis, D=D, x=X)
    for j in range(2):
        one = skfem_rkpm.solve(K, F[:, j], basis, D=D, x=X[:, j])
        np.testing.assert_allclose(both[:, j], one, atol=1e-12 * np.abs(one).max())
        via_condense = solve(*condense(K, F[:, j], x=X[:, j], D=D, basis=basis))
        np.testing.assert_allclose(via_condense, one, atol=1e-10 * np.abs(one).max())
        np.testing.assert_allclose(basis.nodal_values(one)[D], X[D, j], atol=1e-14)


def test_coefficients_interpolate_given_nodal_values():
    basis = RKBasis(square(8))
    values = np.column_stack([harmonic(basis.nodes), np.sin(basis.nodes[0])])
    d = coefficients(basis, values)
    np.testing.assert_allclose(basis.nodal_values(d), values, atol=1e-14)
    # coefficients are not nodal values on the standard RK basis (6.6e-3 apart)
    assert np.abs(d - values).max() > 1e-3
    # a linear field is reproduced: its coefficients give it everywhere
    lin = coefficients(basis, 2 * basis.nodes[0] - basis.nodes[1])
    xq = np.asarray(basis.global_coordinates())
    np.testing.assert_allclose(basis.interpolate(lin), 2 * xq[0] - xq[1], atol=1e-12)


@pytest.mark.parametrize("call, message", [
    (lambda K, b: condense(K, np.ones(b.N), basis=b), "give either D"),
    (lambda K, b: condense(K, np.ones(b.N), D=[b.N], basis=b), "outside"),
    (lambda K, b: condense(K, np.ones(b.N), x=np.ones(3), D=[0], basis=b), "full vector"),
    (lambda K, b: coefficients(b, np.ones(3)), "one value per dof"),
    (lambda K, b: skfem_rkpm.solve(K, np.ones((b.N, 2)), b, D=[0, 1],
                                   x=np.ones((2, 3))), "columns"),
    (lambda K, b: eigen(K, K, b, D=np.arange(b.N - 3), k=2), "fewer than"),
])
def test_clear_errors(call, message):
    basis = RKBasis(square(4))
    K = stiffness(basis)
    with pytest.raises(ValueError, match=message):
        call(K, basis)


def test_enforce_eigenproblem_matches_eigen():
    """enforce on (K, M): rows D of M are zero, so the finite eigenpairs of
    the enforced pencil (scikit-fem's eigs about σ = 1) are the constrained
    ones: the same eigenvalues as eigen() to 1e-12, modes zero at D."""
    basis = RKBasis(square(8), integration="vci_symmetric")
    K, M, D = asm(laplace, basis), asm(mass, basis), basis.get_dofs()
    reference, _ = eigen(K, M, basis, D=D, k=4)
    w, d = solve(*enforce(K, M, D=D, basis=basis),
                 solver=skfem.solver_eigen_scipy(k=4, sigma=1.0))
    np.testing.assert_allclose(np.sort(w.real), reference, rtol=1e-12)
    u = basis.nodal_values(d.real)
    assert np.all(np.abs(u[D]).max(axis=0) < 1e-12 * np.abs(u).max(axis=0))


def test_large_elimination_refused_with_the_alternative(monkeypatch):
    import skfem_rkpm.solvers.idioms as idioms

    basis = RKBasis(square(4))
    monkeypatch.setattr(idioms, "DENSE_LIMIT", 10)
    with pytest.raises(MemoryError, match=r"skfem_rkpm.solve\(K, f, basis, D=D"):
        condense(stiffness(basis), np.ones(basis.N), D=basis.get_dofs(), basis=basis)


def test_eigen_on_the_default_nonsymmetric_vci():
    """The default VCI stiffness is not symmetric (eigsh would be wrong);
    eigen() then uses eigs and is as close as the symmetric variant
    (measured 1.6e-4 to 7.1e-4 at h = 1/8, below FEM's error / 10)."""
    basis = RKBasis(square(8))
    K, M = stiffness(basis), asm(mass, basis)
    assert abs(K - K.T).max() > 1e-6 * abs(K).max()
    w, d = eigen(K, M, basis, D=basis.get_dofs(), k=4)
    assert np.all(np.abs(w / EIGENVALUES - 1) < FEM_ERROR / 8**2 / 10)
    assert np.abs(basis.nodal_values(d)[basis.get_dofs()]).max() < 1e-12 * np.abs(d).max()


def test_singular_constrained_block_is_reported():
    """Λᵀ[D][:, D] singular (two constrained particles with the same shape
    function values at both): a named error pointing to the saddle point."""
    class TwoAlike:
        N = 3
        nodal_matrix = sp.csr_matrix(np.array([[0.5, 0.5, 0.0],
                                               [0.5, 0.5, 0.0],
                                               [0.0, 0.2, 0.8]]))

    with pytest.raises(np.linalg.LinAlgError, match="singular.*skfem_rkpm.solve"):
        condense(sp.identity(3, format="csr"), np.ones(3), D=[0, 1], basis=TwoAlike())


@pytest.mark.parametrize("idiom", ["condense", "enforce", "penalize", "solve"])
def test_extra_multiplier_rows_with_prescribed_nodal_values(idiom):
    """A system bordered by a multiplier row (``∫ u = 1/10``, its multiplier
    a uniform source) with ``u = x`` at the particles of the left and right
    sides: scikit-fem's idioms with the bordered matrix give the solution of
    the saddle-point system with the conditions ``(Λᵀ d)_D = x_D`` written
    out in full (solved by sparse LU), the multiplier included."""
    m = square(6)
    basis = RKBasis(m)
    N = basis.N
    K = asm(laplace, basis.trial, basis)
    f = asm(unit_load, basis)
    b = f.copy()  # ∫ Ψ_I
    A = sp.bmat([[K, sp.csr_matrix(b).T], [sp.csr_matrix(b), None]]).tocsr()
    rhs = np.concatenate([f, [0.1]])
    D = basis.get_dofs(lambda X: (X[0] < 1e-12) | (X[0] > 1 - 1e-12)).all()
    x = np.concatenate([basis.nodes[0], [0.0]])  # nodal values u = x on D
    C = basis.nodal_matrix.tocsr()[D]  # Λᵀ, rows D
    C = sp.hstack([C, sp.csr_matrix((len(D), 1))])
    full = sp.bmat([[A, C.T], [C, None]]).tocsc()
    reference = sp.linalg.spsolve(full, np.concatenate([rhs, x[D]]))[:N + 1]
    if idiom == "condense":
        d = solve(*condense(A, rhs, x=x, D=D, basis=basis))
    elif idiom == "enforce":
        d = solve(*enforce(A, rhs, x=x, D=D, basis=basis))
    elif idiom == "penalize":
        d = solve(*penalize(A, rhs, x=x, D=D, basis=basis))
    else:
        d = skfem_rkpm.solve(A, rhs, basis, D=D, x=x)
    # penalize: nodal values off by O(ε |A|) = 1e-10 relative (its default ε)
    tol = 1e-7 if idiom == "penalize" else 1e-10
    np.testing.assert_allclose(d, reference, atol=tol * np.abs(reference).max())
    np.testing.assert_allclose(basis.nodal_values(d[:N])[D], x[D], atol=tol)
    assert abs(b @ d[:N] - 0.1) < 1e-9
