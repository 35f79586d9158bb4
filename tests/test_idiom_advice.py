"""Every suggestion in a BasisIdiomError or warning of an RK basis, run as written.

Each test triggers one refusal or warning, reads the call it suggests from
its message, and runs that call: it must give the right number (an exact
solution, FEM's value, or the value the refused idiom meant).
"""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import skfem
from skfem import (Basis, BilinearForm, ElementQuad0, ElementQuad1, ElementTriP1,
                   ElementVector, LinearForm, MeshQuad, MeshTri, condense, solve)
from skfem.helpers import dot, grad
from skfem.models.poisson import laplace, unit_load

import skfem_rkpm
from skfem_rkpm import (BasisIdiomError, RKBasis, RKInteriorFacetBasis, ZeroJumpWarning,
                        recovery_indicator)
from skfem_rkpm.forms import PairwiseLoopWarning

MESH = MeshQuad().refined(3).with_defaults()


def test_basis_of_rk_elem_names_with_elements_and_with_element():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    assert type(rk.elem).__name__ == "ElementQuad1" and rk.elem.maxdeg == 2
    left = np.flatnonzero(MESH.p[0, MESH.t].mean(axis=0) < 0.5)
    for build in (lambda: Basis(MESH, rk.elem, elements=left),
                  lambda: Basis(MESH, ElementVector(rk.elem))):
        with pytest.raises(BasisIdiomError, match=r"rk\.with_elements\(E\).*"
                           r"rk\.with_element\(rk\.elem\)"):
            build()
    # rk.with_elements(E): the RK functions on those cells, the left half's area
    assert skfem_rkpm.asm(unit_load, rk.with_elements(left)).sum() == pytest.approx(0.5)
    # rk.with_element(rk.elem): FEM Q1 on the same quadrature
    fem = rk.with_element(rk.elem)
    assert fem.N == MESH.nvertices and fem.X.shape == rk.X.shape
    assert type(RKBasis(MESH, vector=True).elem).__name__ == "ElementVector"


def test_facet_project_sets_boundary_values_and_its_refusal_runs():
    """scikit-fem's ``U = facet_basis.project(g)`` then ``condense(K, x=U, D=D)``:
    with g = 1 + x (harmonic) on the whole boundary the solution is 1 + x."""
    exact = lambda x: 1.0 + x[0]  # noqa: E731
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    K = skfem_rkpm.asm(laplace, rk)
    D = rk.get_dofs()
    U = rk.boundary().project(exact)
    np.testing.assert_array_equal(U[D], exact(rk.doflocs[:, D]))
    U = solve(*condense(K, x=U, D=D))
    np.testing.assert_allclose(U, exact(rk.doflocs), atol=2e-4)  # measured 1.1e-4, below
    left = rk.boundary("left").project(2.0)  # a number, one side only
    assert set(np.flatnonzero(left)) == set(rk.get_dofs("left")) and left.max() == 2.0
    with pytest.raises(BasisIdiomError, match="project.lambda x"):
        rk.boundary().project(np.ones(rk.boundary().X.shape[-1]))

    plain = RKBasis(MESH, ElementQuad1())
    with pytest.raises(BasisIdiomError, match=r"x = basis\.zeros\(\); D = basis\.get_dofs"
                       r"\(facets\); x\[D\] = value; .*skfem_rkpm\.condense\(K, f, x=x, "
                       r"D=D, basis=basis\)"):
        plain.boundary().project(exact)
    # the suggestion as written, on the standard basis
    basis = plain
    K = skfem_rkpm.asm(laplace, basis.trial, basis)
    f = np.zeros(basis.N)
    x = basis.zeros()
    D = basis.get_dofs(None)
    x[D] = exact(basis.doflocs[:, D])
    d = solve(*skfem_rkpm.condense(K, f, x=x, D=D, basis=basis))
    # nodal values prescribed on the whole boundary (the transformation method)
    # leave the test functions nonzero between the boundary particles: 2.9e-4
    # here (1.1e-4 interpolating), against Q1's round-off
    np.testing.assert_array_equal(x[D], exact(basis.doflocs[:, D]))
    np.testing.assert_allclose(basis.nodal_values(d), exact(basis.nodes), atol=5e-4)


def test_trace_split_and_nodal_dofs_suggestions_run():
    rk = RKBasis(MESH, ElementVector(ElementQuad1()))
    field = lambda x: np.array([x[0] + 2.0 * x[1], 2.0 - x[1]])  # noqa: E731 (linear)
    d = skfem_rkpm.coefficients(rk, field(rk.nodes).T.ravel())
    fb = rk.boundary()
    with pytest.raises(BasisIdiomError, match=r"facet_basis\.interpolate\(x\).*"
                       r"facet_basis\.probes\(points\) @ x"):
        fb.trace(d)
    xq = fb.global_coordinates()
    np.testing.assert_allclose(np.asarray(fb.interpolate(d)), field(xq), atol=1e-10)
    points = np.array([[0.0, 0.5], [0.25, 0.0]])
    np.testing.assert_allclose((fb.probes(points) @ d).reshape(2, -1), field(points),
                               atol=1e-10)
    with pytest.raises(BasisIdiomError, match=r"basis\.split\(x\)"):
        fb.split(d)
    (u0, b0), (u1, b1) = rk.split(d)
    np.testing.assert_allclose(u1, 2.0 - MESH.p[1], atol=1e-10)
    with pytest.raises(BasisIdiomError, match=r"basis\.nodal_values\(x\)\[c::2\]"):
        rk.nodal_dofs
    np.testing.assert_allclose(rk.nodal_values(d)[0::2], MESH.p[0] + 2.0 * MESH.p[1],
                               atol=1e-10)


def test_nodal_scheme_refusal_suggests_a_cell_scheme_that_works():
    with pytest.raises(BasisIdiomError, match="integration='vci', 'vci_symmetric'"):
        RKBasis(MESH, integration="scni").with_element(ElementQuad0())
    rk = RKBasis(MESH, integration="vci")
    p0 = rk.with_element(ElementQuad0())
    assert p0.N == MESH.nelements
    with pytest.raises(BasisIdiomError, match=r"skfem\.Basis\(mesh, elem\)"):
        RKBasis(MESH, integration="scni").with_elements([0])
    assert Basis(MESH, ElementQuad0()).N == MESH.nelements


def test_composite_refusal_suggestions_run():
    fem = ElementQuad0()
    rk = RKBasis(MESH, integration="vci")
    with pytest.raises(BasisIdiomError, match="integration='vci_symmetric'.*bmat"):
        rk * rk.with_element(fem)

    @BilinearForm
    def block(u, p, v, q, w):
        return dot(grad(u), grad(v)) + u * q + p * v

    symmetric = RKBasis(MESH, integration="vci_symmetric")
    p0 = symmetric.with_element(fem)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PairwiseLoopWarning)
        A = skfem.asm(block, symmetric * p0)  # the first suggestion (scikit-fem's loop)
    # the second: the blocks with skfem_rkpm.asm, joined with scipy.sparse.bmat
    a = skfem_rkpm.asm(laplace, symmetric)
    b = skfem_rkpm.asm(BilinearForm(lambda u, q, w: u * q), symmetric, p0)
    K = sp.bmat([[a, b.T], [b, None]]).tocsr()
    np.testing.assert_allclose((A - K).toarray(), 0.0, atol=1e-12)
    assert abs(K).sum() > 0 and K.shape == (rk.N + MESH.nelements,) * 2


def test_pairwise_loop_warnings_name_the_call_that_replaces_them():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    with pytest.warns(PairwiseLoopWarning, match=r"^form\.assemble runs.*"
                      r"skfem_rkpm\.asm\(form, basis, \*\*kwargs\)") as record:
        A = laplace.assemble(rk)
    assert record[0].filename == __file__  # at the line that called it
    np.testing.assert_allclose((skfem_rkpm.asm(laplace, rk) - A).toarray(), 0, atol=1e-12)
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    with pytest.warns(PairwiseLoopWarning, match=r"^skfem\.asm runs.*"
                      r"from skfem_rkpm import asm") as record:
        b = skfem.asm(unit_load, rk)
    assert record[0].filename == __file__
    from skfem_rkpm import asm
    np.testing.assert_allclose(asm(unit_load, rk), b, atol=1e-14)


def test_interior_facet_basis_refuses_boundary_with_a_call_that_works():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    inner = RKInteriorFacetBasis(rk)
    with pytest.raises(BasisIdiomError, match=r"basis\.boundary\(facets\)"):
        inner.boundary()
    assert rk.boundary(MESH.boundary_facets()).find.size == 32


# ---------------------------------------------------------------------------
# error indicators: the jump idiom (scikit-fem's ex22) and the recovery indicator

@LinearForm
def unit(v, w):
    return 1.0 * v


def poisson(mesh, load, D=None):
    rk = RKBasis(mesh, ElementTriP1(), interpolating=True)
    u = solve(*condense(skfem_rkpm.asm(laplace, rk), skfem_rkpm.asm(load, rk),
                        D=rk.get_dofs() if D is None else D))
    return rk, u


def test_jump_indicator_warns_and_the_recovery_indicator_finds_the_corner():
    """ex22's L-shaped domain, -Δu = 1: the gradient jumps read exactly zero
    (and warn); the recovery indicator is largest at the re-entrant corner
    and marks a few cells, not all."""
    m = MeshTri.init_lshaped().refined(3)
    rk, u = poisson(m, unit)
    sides = [RKInteriorFacetBasis(rk, side=i) for i in (0, 1)]
    with pytest.warns(ZeroJumpWarning, match=r"skfem_rkpm\.recovery_indicator\(basis, u\)"):
        w = [s.interpolate(u) for s in sides]
    assert np.abs(w[0].grad - w[1].grad).max() == 0.0
    eta = recovery_indicator(rk, u)
    corner = (np.abs(m.p[:, m.t]).max(axis=0) < 1e-12).any(axis=0)
    assert corner[np.argmax(eta)]
    marked = skfem.adaptive_theta(eta)
    assert 0 < marked.size < 0.1 * m.nelements and corner[marked].any()


def test_recovery_indicator_matches_the_gradient_error_of_a_smooth_solution():
    """u = sin πx sin πy: the indicator's total against the exact H¹-seminorm
    error (measured effectivity 1.00-1.01 on 8²-32² triangles)."""
    @LinearForm
    def load(v, w):
        return 2 * np.pi ** 2 * np.sin(np.pi * w.x[0]) * np.sin(np.pi * w.x[1]) * v

    ratios, totals = [], []
    for n in (3, 4):
        rk, u = poisson(MeshTri().refined(n), load)
        x = rk.global_coordinates()
        exact = np.pi * np.array([np.cos(np.pi * x[0]) * np.sin(np.pi * x[1]),
                                  np.sin(np.pi * x[0]) * np.cos(np.pi * x[1])])
        error = np.sqrt(np.sum(((rk.interpolate(u).grad - exact) ** 2).sum(0) * rk.dx))
        totals.append(np.sqrt(recovery_indicator(rk, u).sum()))
        ratios.append(totals[-1] / error)
    assert all(0.8 < r < 1.25 for r in ratios), ratios
    assert totals[1] < 0.6 * totals[0]  # it falls with h (measured 0.49)
    with pytest.raises(ValueError, match="scalar basis"):
        recovery_indicator(RKBasis(MESH, vector=True), np.zeros(2 * MESH.nvertices))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(TypeError, match="RK cell basis"):
            recovery_indicator(Basis(MESH, ElementQuad1()), np.zeros(MESH.nvertices))


def test_dofs_of_an_interpolating_basis_names_get_dofs():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True)
    with pytest.raises(BasisIdiomError, match=r"x\[basis\.get_dofs\(facets\)\] = g"):
        rk.dofs
    assert not hasattr(rk, "dofs")
    x = rk.zeros()
    x[rk.get_dofs("left")] = 3.0
    np.testing.assert_allclose(rk.probes(np.array([[0.0], [0.25]])) @ x, 3.0, atol=1e-12)
    np.testing.assert_array_equal(rk.nodal_dofs[0], np.arange(rk.N))


# material interfaces: the warning names supports cut at the subdomains

def test_material_interface_warning_suggestion_runs():
    """A P0 coefficient jumping at x = 1/2 on a mesh with subdomains: the
    warning names ``RKBasis(mesh, element, interpolating=True,
    interfaces=True)``; built as written, the form is quiet and the field
    of the two-material problem, linear in each half with a kink at the
    interface, is in the basis (reproduced to round-off)."""
    mid = MESH.p[0, MESH.t].mean(axis=0)
    mesh = MeshQuad().refined(3).with_subdomains({"a": np.flatnonzero(mid < 0.5),
                                                  "b": np.flatnonzero(mid > 0.5)})
    element = ElementQuad1()

    @BilinearForm
    def conduction(u, v, w):
        return w["k"] * dot(grad(u), grad(v))

    def k_of(basis):
        b0 = basis.with_element(ElementQuad0())
        k = b0.zeros() + 1.0
        k[b0.get_dofs(elements="b")] = 4.0
        return b0.interpolate(k)

    rk = RKBasis(mesh, element, interpolating=True)
    with pytest.warns(skfem_rkpm.MaterialInterfaceWarning,
                      match=r"RKBasis\(mesh, element, interpolating=True, interfaces=True\)"):
        skfem_rkpm.asm(conduction, rk, k=k_of(rk))
    basis = RKBasis(mesh, element, interpolating=True, interfaces=True)  # as written
    with warnings.catch_warnings():
        warnings.simplefilter("error", skfem_rkpm.MaterialInterfaceWarning)
        skfem_rkpm.asm(conduction, basis, k=k_of(basis))
    u = lambda x: np.where(x[0] < 0.5, 4 * x[0], 2.0 + (x[0] - 0.5))  # noqa: E731
    np.testing.assert_allclose(np.asarray(basis.interpolate(u(basis.nodes))),
                               u(np.asarray(basis.global_coordinates())), atol=1e-12)
