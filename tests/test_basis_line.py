"""scikit-fem scripts that change only their ``Basis`` line (and ``asm``'s import).

Eight problems of scikit-fem's documentation (docs/examples: ex01, ex09,
ex03, ex14, ex11, ex10, ex19, ex43) and a cantilever beam on hexahedra,
each written once below as a scikit-fem user writes it, as a function of
the two names a user changes:

- the basis line, ``Basis(mesh, element, ...)`` →
  ``RKBasis(mesh, element, interpolating=True)``;
- the import of ``asm``, ``from skfem import asm`` →
  ``from skfem_rkpm import asm`` (same signature; scikit-fem's own ``asm``
  gives the same matrices on these bases, see
  :func:`test_scikit_fem_asm_gives_the_same_matrix`, but by its loop over
  local functions: 100-1000 times slower).

Nothing else changes: scikit-fem's ``condense`` (``D=``, ``I=``, ``x=``,
``expand=False``), ``penalize``, ``solve`` with its CG and eigenvalue
solvers, ``x[D] = g(...)``, ``u[basis.nodal_dofs]``, ``dofs.nodal['u^1']``,
``basis.doflocs`` and ``probes`` act on the coefficients, which on an
interpolating basis are the nodal values (Ψ_I(X_J) = δ_IJ, Chen, Han, You &
Meng 2003), and its matrices are symmetric (``integration="vci_symmetric"``,
the default of an interpolating basis).

tests/test_skfem_examples.py runs five of these examples on the standard
(non-interpolating) RK basis, which is more accurate but needs 3-9 more
changed lines per example (marked there); both are kept, because each basis
is a choice a user makes.

Every RK answer is checked against an exact or converged reference and
against the FEM run of the same script on the same mesh: the RK error must
not exceed ``FEM_FACTOR`` times FEM's.  The interpolating basis is about as
accurate as linear FEM (docs/rk_basis.md: 64² Poisson L² 1.02e-4 against
Q1's 1.05e-4); the ratios measured here are in docs/rk_basis.md, and the idioms they
guard against, coefficients read as values, miss by 10-100 times more
(ex10: 5.9e-3 against 1.3e-4).  The RK runs turn ``SlowAssemblyWarning``
into an error: every form takes the fast path.
"""

import warnings

import numpy as np
import pytest
import scipy.sparse.linalg as spl
import skfem
from skfem import (Basis, BilinearForm, ElementHex1, ElementHex2, ElementQuad1, ElementQuad2,
                   ElementTetP1, LinearForm,
                   ElementTriP0, ElementTriP1, ElementTriRT0, ElementVector, MeshHex, MeshLine,
                   MeshQuad, MeshTet, MeshTri, build_pc_ilu, condense, penalize, solve,
                   solver_eigen_scipy_sym, solver_iter_pcg)
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity
from skfem.models.poisson import laplace, mass, unit_load

import skfem_rkpm
from skfem_rkpm import RKBasis, SlowAssemblyWarning
# references and forms of the same examples, written for their other tests
from test_skfem_examples import (BLOCK_ENERGY, CUBE_CENTRE, DIFFUSIVITY, DT, HALFWIDTH,
                                 SURFACE_AREA, SURFACE_CENTRE, THETA, TWIST_ENERGY,
                                 crank_nicolson_factor,
                                 neo_hooke_energy, neo_hooke_residual, neo_hooke_tangent,
                                 surface_area, surface_residual, surface_tangent, vertex)

#: largest ratio of the RK error to the FEM error of the same script and mesh
FEM_FACTOR = 2.5


def rk_basis(mesh, element, **fem_only):
    """The changed line: ``RKBasis(mesh, element, interpolating=True)``
    (keywords of the FEM line such as ``intorder=1`` are left out)."""
    return RKBasis(mesh, element, interpolating=True)


RUNS = {"fem": (Basis, skfem.asm), "rk": (rk_basis, skfem_rkpm.asm)}


def run(script, kind, *args):
    Basis_, asm = RUNS[kind]
    with warnings.catch_warnings():
        if kind == "rk":
            warnings.simplefilter("error", SlowAssemblyWarning)
        return script(Basis_, asm, *args)


def check_errors(name, fem_error, rk_error, limit=None):
    assert rk_error <= FEM_FACTOR * fem_error, (name, fem_error, rk_error)
    if limit is not None:
        assert rk_error < limit, (name, rk_error)


# ---------------------------------------------------------------------------
# ex01: Poisson, -Δu = 1 on the unit square, u = 0 on the boundary

def square_centre_series(terms=400):
    """u(½, ½) = Σ_{m,n odd} 16 (-1)^((m+n)/2-1) / (π⁴ m n (m² + n²))."""
    m = np.arange(1, 2 * terms, 2)
    M, N = np.meshgrid(m, m, indexing="ij")
    sign = (-1.0) ** ((M - 1) // 2 + (N - 1) // 2)
    return float(np.sum(16.0 * sign / (np.pi**4 * M * N * (M**2 + N**2))))


def ex01(Basis, asm):
    m = MeshTri().refined(5)
    e = ElementTriP1()
    basis = Basis(m, e)
    A = asm(laplace, basis)
    b = asm(unit_load, basis)
    x = solve(*condense(A, b, D=basis.get_dofs()))
    return x[vertex(m, (0.5, 0.5))], x.max()


def test_ex01_poisson():
    exact = square_centre_series()
    assert exact == pytest.approx(0.0736713, abs=1e-7)  # the value scikit-fem quotes: 0.07367
    (fem, _), (rk, rk_max) = run(ex01, "fem"), run(ex01, "rk")
    assert rk_max == rk  # the largest coefficient is the centre value
    check_errors("ex01", abs(fem - exact), abs(rk - exact), 1e-4)


# ---------------------------------------------------------------------------
# ex09: 3D Poisson on tetrahedra, preconditioned conjugate gradients

def ex09(Basis, asm, n=6):
    p = np.linspace(0, 1, n + 1)
    m = MeshTet.init_tensor(p, p, p)
    e = ElementTetP1()
    basis = Basis(m, e)
    A = asm(laplace, basis)
    b = asm(unit_load, basis)
    I = m.interior_nodes()
    x = basis.zeros()
    Aint, bint = condense(A, b, I=I, expand=False)
    x[I] = solve(Aint, bint, solver=solver_iter_pcg(M=build_pc_ilu(Aint, drop_tol=1e-3),
                                                     rtol=1e-10))
    residual = np.linalg.norm(Aint @ x[I] - bint) / np.linalg.norm(bint)
    return x[vertex(m, (0.5, 0.5, 0.5))], residual, abs(A - A.T).max() / abs(A).max()


def test_ex09_conjugate_gradients():
    (fem, _, _), (rk, residual, asymmetry) = run(ex09, "fem"), run(ex09, "rk")
    assert residual < 1e-8  # CG converged with ex09's own ILU preconditioner
    assert asymmetry < 1e-13
    check_errors("ex09", abs(fem - CUBE_CENTRE), abs(rk - CUBE_CENTRE), 3e-3)


# ---------------------------------------------------------------------------
# ex03: eigenvalues of an elastic beam clamped at one end

#: the three lowest eigenvalues of ex03's beam, [0, 5] x [0, 1], λ = μ = 1,
#: unit density, clamped at x = 0: biquadratic FEM (Q2) on 50 x 10, 100 x 20,
#: 200 x 40 cells gives λ₁ = 0.004154508, 0.004153720, 0.004153428 (the
#: differences fall by 2.7-2.8: the clamped corners), extrapolated with the
#: observed ratio (a correction of 4e-5 relative at most, uncertain by far
#: less than the 2-3 % error of the 26 x 6 particle runs).
BEAM_EIGENVALUES = np.array([0.00415326, 0.12065736, 0.26454541])


@BilinearForm
def unit_mass(u, v, w):
    return dot(u, v)


def ex03(Basis, asm, nx=25):
    m1 = MeshLine(np.linspace(0, 5, nx + 1))
    m2 = MeshLine(np.linspace(0, 1, nx // 5 + 1))
    m = (m1 * m2).with_defaults()
    e = ElementVector(ElementQuad1())
    gb = Basis(m, e)
    K = asm(linear_elasticity(1.0, 1.0), gb)
    M = asm(unit_mass, gb)
    D = gb.get_dofs("left")
    I = gb.complement_dofs(D)
    L, x = solve(*condense(K, M, I=I), solver=solver_eigen_scipy_sym(k=6, sigma=0.0))
    return L[:3]


def test_ex03_eigenvalues_with_constraints():
    fem, rk = run(ex03, "fem"), run(ex03, "rk")
    for k in range(3):
        check_errors(f"ex03 λ{k}", abs(fem[k] / BEAM_EIGENVALUES[k] - 1),
                     abs(rk[k] / BEAM_EIGENVALUES[k] - 1), 0.05)


@pytest.mark.slow
def test_beam_eigenvalue_reference():
    """BEAM_EIGENVALUES from ex03 itself with Q2 on 50 x 10 to 200 x 40 cells."""
    quadratic = lambda mesh, element: Basis(mesh, ElementVector(ElementQuad2()))  # noqa: E731
    runs = np.array([ex03(quadratic, skfem.asm, nx) for nx in (50, 100, 200)])
    steps = np.diff(runs, axis=0)
    ratio = steps[0] / steps[1]
    assert np.all((ratio > 2.0) & (ratio < 4.5))
    limit = runs[-1] + steps[-1] / (ratio - 1)
    assert limit == pytest.approx(BEAM_EIGENVALUES, rel=1e-6)


# ---------------------------------------------------------------------------
# ex14: inhomogeneous Dirichlet data, Laplace with u = x² - y²

def ex14(Basis, asm):
    m = MeshTri().refined(4)
    e = ElementTriP1()
    basis = Basis(m, e)
    A = asm(laplace, basis)

    def dirichlet(x):
        return x[0] ** 2 - x[1] ** 2

    u = basis.zeros()
    D = basis.get_dofs()
    u[D] = dirichlet(basis.doflocs[:, D])
    u = solve(*condense(A, np.zeros_like(u), u, D=D))
    return u @ A @ u


def test_ex14_inhomogeneous_dirichlet():
    """The energy ∫ |∇u|² of u = x² - y² is 8/3."""
    fem, rk = run(ex14, "fem"), run(ex14, "rk")
    check_errors("ex14", abs(fem - 8 / 3), abs(rk - 8 / 3), 1e-2)


# ---------------------------------------------------------------------------
# ex11: linear elasticity of a block on hexahedra

def ex11(Basis, asm):
    m = MeshHex().refined(2).with_defaults()
    e1 = ElementHex1()
    e = ElementVector(e1)
    ib = Basis(m, e, intorder=3)
    K = asm(linear_elasticity(*lame_parameters(1e3, 0.3)), ib)
    dofs = {"left": ib.get_dofs("left"), "right": ib.get_dofs("right")}
    u = ib.zeros()
    u[dofs["right"].nodal["u^1"]] = 0.3
    I = ib.complement_dofs(dofs)
    u = solve(*condense(K, x=u, I=I))
    displaced = m.translated(u[ib.nodal_dofs])
    return 0.5 * u @ K @ u, displaced.p[0].max()


def test_ex11_elastic_block():
    (fem, _), (rk, right) = run(ex11, "fem"), run(ex11, "rk")
    assert right == pytest.approx(1.3, abs=1e-12)  # the right face moved by 0.3
    check_errors("ex11", abs(fem - BLOCK_ENERGY), abs(rk - BLOCK_ENERGY), 2.0)


# ---------------------------------------------------------------------------
# a cantilever beam on hexahedra, end load

#: tip deflection of the beam below: triquadratic FEM (Hex2) on 10 x 2 x 2,
#: 20 x 4 x 4, 40 x 8 x 8 cells gives -0.506064, -0.507776, -0.508341
#: (differences falling by 3.0), extrapolated -0.50862, uncertain by about
#: 1e-4 (Euler-Bernoulli: F L³ / 3EI = -0.5, plus shear and the clamped end)
BEAM_TIP = -0.50862


@LinearForm
def end_load(v, w):
    return -1e-3 * v[2]


def cantilever(Basis, asm, nx=10, n=2, element=ElementVector(ElementHex1())):
    m = MeshHex.init_tensor(np.linspace(0, 5, nx + 1), np.linspace(0, 1, n + 1),
                            np.linspace(0, 1, n + 1)).with_defaults()
    ib = Basis(m, element)
    K = asm(linear_elasticity(*lame_parameters(1.0, 0.3)), ib)
    f = asm(end_load, ib.boundary("right"))
    u = solve(*condense(K, f, D=ib.get_dofs("left")))
    return (ib.probes(np.array([[5.0], [0.5], [0.5]])) @ u)[2]


def test_cantilever_beam_on_hexahedra():
    fem, rk = run(cantilever, "fem"), run(cantilever, "rk")
    check_errors("cantilever", abs(fem - BEAM_TIP), abs(rk - BEAM_TIP))


@pytest.mark.slow
def test_cantilever_reference():
    quadratic = ElementVector(ElementHex2())
    tips = np.array([cantilever(Basis, skfem.asm, nx, n, quadratic)
                     for nx, n in ((10, 2), (20, 4), (40, 8))])
    steps = np.diff(tips)
    ratio = steps[0] / steps[1]
    assert 2.5 < ratio < 4.5
    assert tips[-1] + steps[-1] / (ratio - 1) == pytest.approx(BEAM_TIP, abs=2e-5)


# ---------------------------------------------------------------------------
# ex10: the minimal surface, damped Newton

def ex10(Basis, asm):
    m = MeshTri().refined(5)
    basis = Basis(m, ElementTriP1())
    x = np.zeros(basis.N)
    I = m.interior_nodes()
    D = m.boundary_nodes()
    x[D] = np.sin(np.pi * m.p[0, D])
    for itr in range(100):
        w = basis.interpolate(x)
        J = asm(surface_tangent, basis, prev=w)
        F = asm(surface_residual, basis, prev=w)
        x_prev = x.copy()
        x += 0.7 * solve(*condense(J, -F, I=I))
        if np.linalg.norm(x - x_prev) < 1e-8:
            break
    return x[vertex(m, (0.5, 0.5))], surface_area.assemble(basis, u=basis.interpolate(x)), itr


def test_ex10_minimal_surface_newton():
    (fem, fem_area, fem_its), (rk, rk_area, rk_its) = run(ex10, "fem"), run(ex10, "rk")
    assert rk_its < 99 and fem_its < 99
    check_errors("ex10 centre", abs(fem - SURFACE_CENTRE), abs(rk - SURFACE_CENTRE))
    check_errors("ex10 area", abs(fem_area - SURFACE_AREA), abs(rk_area - SURFACE_AREA))


# ---------------------------------------------------------------------------
# ex19: the heat equation, Crank-Nicolson

def ex19(Basis, asm):
    mesh = MeshQuad.init_tensor(np.linspace(-1, 1, 16) * HALFWIDTH[0],
                                np.linspace(-1, 1, 16) * HALFWIDTH[1])
    basis = Basis(mesh, ElementQuad1())
    L = DIFFUSIVITY * asm(laplace, basis)
    M = asm(mass, basis)
    L0, M0 = penalize(L, M, D=basis.get_dofs())
    A = M0 + THETA * L0 * DT
    B = M0 - (1 - THETA) * L0 * DT
    backsolve = spl.splu(A.T).solve
    u = np.cos(np.pi * basis.doflocs / 2 / HALFWIDTH[:, None]).prod(0)
    probe = basis.probes(np.zeros((2, 1)))
    steps = 0
    while np.linalg.norm(u, np.inf) > 2**-3:
        u, steps = backsolve(B @ u), steps + 1
    return steps, (probe @ u)[0]


def test_ex19_heat_crank_nicolson():
    """Against the exact mode advanced by the same steps (only the spatial
    error remains; see tests/test_skfem_examples.py)."""
    r = crank_nicolson_factor()
    (fem_steps, fem), (rk_steps, rk) = run(ex19, "fem"), run(ex19, "rk")
    assert abs(rk_steps - fem_steps) <= 1
    check_errors("ex19", abs(fem / r**fem_steps - 1), abs(rk / r**rk_steps - 1), 0.05)


# ---------------------------------------------------------------------------
# ex43: Neo-Hookean hyperelasticity on hexahedra, Newton in every load step

def ex43(Basis, asm):
    mesh = MeshHex.init_tensor(np.linspace(0, 1, 10), np.linspace(-.1, .1, 3),
                               np.linspace(-.1, .1, 3)).with_boundaries({
        "left": lambda x: x[0] == 0.0, "right": lambda x: x[0] == 1.0})
    element = ElementVector(ElementHex1())
    basis = Basis(mesh, element, intorder=1)
    u = basis.zeros()
    uv = basis.interpolate(u)
    dofs = basis.get_dofs("right")
    dirichlet = basis.get_dofs({"right", "left"})
    f = asm(neo_hooke_residual, basis, displacement=uv)
    K = asm(neo_hooke_tangent, basis, displacement=uv)
    right, tol, nsteps = -0.1, 1e-10, 7
    iterations = []
    for step in range(nsteps):
        for iteration in range(10):
            c = (step + 1.0) / nsteps
            du_D = u.copy()
            x, y, z = basis.doflocs[:, dofs.nodal["u^1"]]
            du_D[dofs.nodal["u^1"]] = c * right - du_D[dofs.nodal["u^1"]]
            du_D[dofs.nodal["u^2"]] = (y * np.cos(c * np.pi) - z * np.sin(c * np.pi) - y
                                       - du_D[dofs.nodal["u^2"]])
            du_D[dofs.nodal["u^3"]] = (y * np.sin(c * np.pi) + z * np.cos(c * np.pi) - z
                                       - du_D[dofs.nodal["u^3"]])
            du = solve(*condense(K, -f, x=du_D, D=dirichlet))
            norm_du = np.linalg.norm(du)
            u += du
            uv = basis.interpolate(u)
            f = asm(neo_hooke_residual, basis, displacement=uv)
            K = asm(neo_hooke_tangent, basis, displacement=uv)
            if norm_du < tol:
                break
        iterations.append(iteration + 1 if norm_du < tol else None)
    return iterations, neo_hooke_energy.assemble(basis, displacement=uv)


def test_ex43_hyperelasticity_newton():
    """Newton converges in every load step (FEM: 7 iterations, RK: 8)."""
    (fem_its, fem), (rk_its, rk) = run(ex43, "fem"), run(ex43, "rk")
    assert None not in fem_its and None not in rk_its
    assert max(rk_its) <= max(fem_its) + 2
    check_errors("ex43", abs(fem - TWIST_ENERGY), abs(rk - TWIST_ENERGY))


# ---------------------------------------------------------------------------
# what the two changed lines rest on

def test_scikit_fem_asm_gives_the_same_matrix():
    """Without the import change: scikit-fem's loop builds the same matrix
    on an interpolating basis (its one set of gradients serves trial and
    test), slowly, and says so."""
    basis = rk_basis(MeshTri().refined(2), ElementTriP1())
    with pytest.warns(SlowAssemblyWarning, match="from skfem_rkpm import asm"):
        loop = skfem.asm(laplace, basis)
    fast = skfem_rkpm.asm(laplace, basis)
    assert abs(loop - fast).max() < 1e-12 * abs(fast).max()


def test_scikit_fem_loop_on_a_vci_basis_names_the_trial_basis():
    """On a standard (``vci``) basis scikit-fem's loop takes the corrected
    test gradients for trial gradients: the warning names the right call."""
    basis = RKBasis(MeshTri().refined(2), ElementTriP1())
    with pytest.warns(SlowAssemblyWarning, match=r"asm\(form, basis.trial, basis\)"):
        loop = laplace.assemble(basis)
    consistent = skfem_rkpm.asm(laplace, basis.trial, basis)
    assert abs(loop - consistent).max() > 1e-6 * abs(consistent).max()


def test_element_argument():
    mesh = MeshTri().refined(2)
    assert not RKBasis(mesh, ElementTriP1()).vector
    assert RKBasis(mesh, ElementVector(ElementTriP1())).vector
    for element in (ElementTriP0(), ElementTriRT0()):
        with pytest.raises(ValueError, match="with_element"):
            RKBasis(mesh, element)
    with pytest.raises(ValueError, match="vector=True/False or a scikit-fem element"):
        RKBasis(mesh, "vector")


def test_interpolating_default_is_symmetric():
    mesh = MeshTri().refined(3)
    assert RKBasis(mesh, interpolating=True).integration == "vci_symmetric"
    assert RKBasis(mesh).integration == "vci"
    assert RKBasis(mesh, interpolating=True, order=2, support=2.5).integration == "vci"
    assert RKBasis(mesh, interpolating=True, axisymmetric=True).integration == "vci"
