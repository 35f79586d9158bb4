"""RKBasis(mesh, element) honours the element as Basis(mesh, element) does:
its degree is the RK order, a quadratic element's dof locations are the
particles, numbered as its dofs; the answer of a P2/Q2 problem is as
accurate as FEM's."""

import numpy as np
import pytest
from skfem import (Basis, ElementQuad2, ElementTetP2, ElementTriP1, ElementTriP2,
                   ElementTriP3, ElementVector, Functional, LinearForm, MeshQuad, MeshTet,
                   MeshTri, asm, condense, solve)
from skfem.models.poisson import laplace

import skfem_rkpm
from skfem_rkpm import RKBasis
from skfem_rkpm.verification.exact import sine_poisson
from skfem_rkpm.approximation.element_particles import element_degree

CASES = [(lambda: MeshTri().refined(2), ElementTriP2),
         (lambda: MeshQuad().refined(2), ElementQuad2),
         (lambda: MeshQuad().refined(2), lambda: ElementVector(ElementQuad2())),
         (lambda: MeshTet().refined(1), ElementTetP2)]


@pytest.mark.parametrize("mesh, element", CASES)
def test_quadratic_element_dofs_line_up_with_fem(mesh, element):
    m, e = mesh().with_defaults(), element()
    fem = Basis(m, e)
    with pytest.warns(UserWarning, match="converge more slowly"):
        rk = RKBasis(m, e, interpolating=True)
    assert rk.order == 2 and rk.N == fem.N
    np.testing.assert_array_equal(rk.doflocs, fem.doflocs)
    for facets in (None, "left"):
        np.testing.assert_array_equal(np.sort(rk.get_dofs(facets).flatten()),
                                      np.sort(fem.get_dofs(facets).flatten()))
    names = ["nodal_dofs", "facet_dofs", "interior_dofs"] + (["edge_dofs"] if m.dim() == 3
                                                             else [])
    for name in names:
        np.testing.assert_array_equal(getattr(rk, name), getattr(fem, name), err_msg=name)
    x = np.zeros(rk.N)
    x[rk.get_dofs("left")] = 1.0  # scikit-fem's x[D] = g reads nodal values here
    np.testing.assert_allclose(rk.nodal_values(x), x, atol=1e-12)


def test_linear_elements_keep_the_vertices_and_order_one():
    m = MeshTri().refined(2)
    rk = RKBasis(m, ElementTriP1())
    assert rk.order == 1 and rk.N == m.nvertices
    # an explicit order wins over the element's degree; the particles stay
    assert RKBasis(m, ElementTriP2(), order=1).order == 1
    assert RKBasis(m, ElementTriP2(), order=1).N == Basis(m, ElementTriP2()).N


def test_elements_above_degree_two_are_refused_by_name():
    with pytest.raises(ValueError, match="ElementTriP3 has degree 3"):
        RKBasis(MeshTri(), ElementTriP3())
    assert element_degree(ElementTriP1()) == 1 and element_degree(ElementQuad2()) == 2


load = LinearForm(lambda v, w: sine_poisson(w.x)[1] * v)
l2_error = Functional(lambda w: (w["uh"] - sine_poisson(w.x)[0]) ** 2)


@pytest.mark.parametrize("mesh, element, bound", [
    (MeshTri().refined(3), ElementTriP2, 0.6),   # measured 0.41 x FEM's error
    (MeshQuad().refined(3), ElementQuad2, 1.2),  # measured 0.80
])
def test_quadratic_swap_is_as_accurate_as_fem(mesh, element, bound):
    """-Δu = 2π² sin πx sin πy, u = 0 on the unit square: the L² error of
    RKBasis(mesh, element) (order 2 on the element's dofs, support 2.5) is
    below FEM's (a bound of 1.5x the measured ratio; the target is 2.5x)."""
    fem = Basis(mesh, element(), intorder=6)
    u = solve(*condense(asm(laplace, fem), asm(load, fem), D=fem.get_dofs()))
    error = np.sqrt(l2_error.assemble(fem, uh=fem.interpolate(u)))
    rk = RKBasis(mesh, element())
    K = skfem_rkpm.asm(laplace, rk.trial, rk)
    f = skfem_rkpm.asm(load, rk)
    d = solve(*skfem_rkpm.condense(K, f, D=rk.get_dofs(), basis=rk))
    assert np.sqrt(l2_error.assemble(rk, uh=rk.interpolate(d))) < bound * error


def test_interpolating_quadratic_swap_warns_with_the_way_out():
    with pytest.warns(UserWarning, match="drop it and prescribe nodal values"):
        RKBasis(MeshTri().refined(1), ElementTriP2(), interpolating=True)
