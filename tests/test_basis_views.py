"""scikit-fem's basis idioms on RK bases, checked against FEM and exact answers.

``with_element`` (mixed RK x FEM forms), quadrature checks, ``split``,
``refinterp``, ``plot``, ``probes`` on facet bases, quadratic meshes and
``with_elements`` (subdomains).

Tolerances: the RK functions reproduce linear fields (order 1) and
quadratic fields (order 2) to round-off, so a linear field has its values at
the particles as coefficients and every integral of it below is exact up to
sums of O(100) products of O(1) numbers: 1e-12 (1e-10 where a moment matrix
of order 2, condition ~1e4, is inverted at every point).
"""

import matplotlib
import numpy as np
import pytest
import skfem
from skfem import (Basis, BilinearForm, ElementQuad0, ElementQuad1, ElementTriP1,
                   ElementTriP2,
                   ElementVector, FacetBasis, Functional, LinearForm, MeshQuad1,
                   MeshQuad2, MeshTri1, MeshTri2, asm)
from skfem.helpers import div, dot
from skfem.models.poisson import laplace, mass

import skfem_rkpm
from skfem_rkpm import RKBasis
from skfem_rkpm.approximation.basis_views import BasisIdiomError
from skfem_rkpm.meshes import rectangle

matplotlib.use("Agg")

U = lambda x: np.array([2.0 * x[0] + x[1], x[0] - 3.0 * x[1]])  # div U = -1
DIV_U = -1.0


@pytest.fixture(scope="module")
def quads():
    return rectangle(2.0, 1.0, 8, 5, perturb=0.2)


def linear_coefficients(basis, field):
    """Coefficients of a field the basis reproduces: its particle values,
    interleaved per component."""
    values = np.atleast_2d(field(basis.nodes))
    return values.T.ravel()


@BilinearForm
def divergence(u, v, w):
    return div(u) * v


def test_with_element_p0_pressure_against_rk_velocity(quads):
    """A P0 pressure next to RK velocities: ∫_cell q div u = -|cell| for the
    linear U, the same as with Q1 velocities on the same quadrature."""
    rk = RKBasis(quads, vector=True)
    p0 = rk.with_element(ElementQuad0())
    assert isinstance(p0, skfem.CellBasis) and p0.N == quads.nelements
    assert np.array_equal(p0.X, rk.X) and np.array_equal(p0.dx, rk.dx)
    np.testing.assert_array_equal(p0.global_coordinates(),
                                  rk.global_coordinates())
    d = linear_coefficients(rk, U)
    B = asm(divergence, rk.trial, p0)
    area = p0.dx.sum(axis=1)
    np.testing.assert_allclose(B @ d, DIV_U * area, rtol=0, atol=1e-12)
    q1 = rk.with_element(ElementVector(ElementQuad1()))
    B_fem = asm(divergence, q1, p0)
    np.testing.assert_allclose(B @ d, B_fem @ U(q1.doflocs[:, ::2]).T.ravel(),
                               rtol=0, atol=1e-12)
    # the fast path reads the same mixed form
    assert abs(skfem_rkpm.asm(divergence, rk.trial, p0) - B).max() < 1e-13


def test_with_element_on_a_facet_basis(quads):
    """Outflow ∫_Γ U·n q per boundary facet, RK against Q1 on the same points."""
    rk = RKBasis(quads, vector=True)
    fb = rk.boundary()
    fem = fb.with_element(ElementVector(ElementQuad1()))
    assert isinstance(fem, FacetBasis)
    np.testing.assert_array_equal(np.asarray(fem.normals), np.asarray(fb.geometry.normals))
    assert np.array_equal(fb.find, fem.find)
    test = fb.with_element(ElementQuad1())
    flux = BilinearForm(lambda u, v, w: dot(u, w.n) * v)
    rk_flux = asm(flux, fb, test) @ linear_coefficients(rk, U)
    fem_flux = asm(flux, fem, test) @ U(fem.doflocs[:, ::2]).T.ravel()
    np.testing.assert_allclose(rk_flux, fem_flux, rtol=0, atol=1e-12)
    # divergence theorem: total outflow = ∫ div U = -area
    assert rk_flux.sum() == pytest.approx(DIV_U * 2.0, abs=1e-12)


def test_fem_partner_with_other_quadrature_is_refused_with_the_fix():
    """P1 takes 3 points per triangle by default, the RK basis 6: the message
    names with_element and the intorder to pass; with either, the mixed mass
    matrix applied to ones gives the FEM lumped masses (Σ_I Ψ_I = 1)."""
    mesh = MeshTri1().refined(3)
    rk = RKBasis(mesh)
    with pytest.raises(ValueError, match=r"with_element\(elem\).*intorder=4"):
        skfem_rkpm.asm(mass, Basis(mesh, ElementTriP1()), rk)
    X, W = rk.quadrature
    shifted = Basis(mesh, ElementTriP1(), quadrature=(X[::-1].copy(), W))
    with pytest.raises(ValueError, match="at other points"):
        skfem_rkpm.asm(mass, shifted, rk)
    for fem in (rk.with_element(ElementTriP1()),
                Basis(mesh, ElementTriP1(), intorder=rk.intorder)):
        M = skfem_rkpm.asm(mass, rk, fem)
        assert M.shape == (mesh.nvertices, rk.N)
        np.testing.assert_allclose(M @ np.ones(rk.N),
                                   asm(mass, fem) @ np.ones(fem.N), atol=1e-14)
    # an FEM field as a form argument: at the RK points, or a message
    x = mesh.p[0] ** 2
    load = LinearForm(lambda v, w: w.u * v)
    with pytest.raises(ValueError, match=r"'u' is given at 128 cells x 3 points.*"
                                         r"with_element\(elem\).interpolate"):
        skfem_rkpm.asm(load, rk, u=Basis(mesh, ElementTriP1()).interpolate(x))
    fem = rk.with_element(ElementTriP1())
    f = skfem_rkpm.asm(load, rk, u=fem.interpolate(x))
    assert f.sum() == pytest.approx(asm(load, fem, u=fem.interpolate(x)).sum(), rel=1e-13)


def test_nodal_schemes_refuse_fem_partners_loudly(quads):
    rk = RKBasis(rectangle(1.0, 1.0, 4, 4), integration="scni")
    with pytest.raises(BasisIdiomError, match="integration='scni'.*cell scheme"):
        rk.with_element(ElementQuad0())
    with pytest.raises(BasisIdiomError, match="integration='scni'"):
        rk.with_elements([0])


def test_split_returns_nodal_values_with_a_basis_that_reads_them(quads):
    rk = RKBasis(quads, vector=True)
    d = rk.project(lambda x: np.array([np.sin(2.0 * x[0]), x[0] * x[1] ** 2]))
    pairs = rk.split(d)
    assert len(pairs) == 2
    at_vertices = (rk.probes(quads.p) @ d).reshape(2, -1)
    for c, (values, basis) in enumerate(pairs):
        assert isinstance(basis, skfem.CellBasis) and basis.N == quads.nvertices
        np.testing.assert_allclose(values, at_vertices[c], rtol=0, atol=1e-13)
        # the values are not the coefficients (the test would see it)
        assert np.abs(values - d[c::2]).max() > 1e-4
    # for a reproduced (linear) field the pair's basis gives the RK field back
    d = linear_coefficients(rk, U)
    rk_field = np.asarray(rk.interpolate(d))
    for c, (values, basis) in enumerate(rk.split(d)):
        np.testing.assert_allclose(np.asarray(basis.interpolate(values)), rk_field[c],
                                   rtol=0, atol=1e-12)
    scalar = RKBasis(quads)
    (values, basis), = scalar.split(d[::2])
    np.testing.assert_allclose(values, scalar.nodal_values(d[::2]), atol=0)


def test_split_with_custom_particles_says_what_to_use():
    mesh = MeshQuad1().refined(2)
    nodes = mesh.p[:, :-1] * 0.999 + 0.0005
    rk = RKBasis(mesh, nodes=nodes, radius=0.6)
    with pytest.raises(BasisIdiomError, match="nodal_values"):
        rk.split(np.zeros(rk.N))


def test_refinterp_evaluates_the_rk_field_on_the_fem_refined_mesh(quads):
    """Order 2 reproduces quadratics: the refined values are exact, the Q1
    refinement of the same nodal values is not; the refined mesh is the one
    scikit-fem's refinterp builds."""
    u = lambda x: 1.0 + x[0] - 2.0 * x[1] + x[0] ** 2 - x[0] * x[1] + 0.5 * x[1] ** 2
    rk = RKBasis(quads, order=2, support=3.0, intorder=6)
    d = u(rk.nodes)
    M, values = rk.refinterp(d, nrefs=2)
    fem = Basis(quads, ElementQuad1())
    M_fem, fem_values = fem.refinterp(u(quads.p), nrefs=2)
    assert type(M) is type(M_fem)
    np.testing.assert_array_equal(M.t, M_fem.t)
    np.testing.assert_allclose(M.p, M_fem.p, atol=1e-15)
    np.testing.assert_allclose(values, u(M.p), rtol=0, atol=1e-10)
    assert np.abs(fem_values - u(M.p)).max() > 1e-3
    # nrefs=0: the values are the nodal values at the cell vertices
    with pytest.raises(ValueError, match="coefficient vector has length"):
        rk.refinterp(d[:-1])
    M0, at_vertices = rk.refinterp(d, 0)
    np.testing.assert_allclose(at_vertices, rk.nodal_values(d)[quads.t.T.ravel()],
                               atol=1e-12)


def test_plot_draws_field_values_not_coefficients():
    mesh = MeshTri1().refined(3)
    rk = RKBasis(mesh)
    d = rk.project(lambda x: np.sin(3.0 * x[0]) * x[1])
    ax = rk.plot(d, nrefs=0, shading="gouraud")
    drawn = np.asarray(ax.collections[0].get_array())
    expected = rk.nodal_values(d)[mesh.t.T.ravel()]
    np.testing.assert_allclose(drawn, expected, atol=1e-14)
    assert np.abs(d[mesh.t.T.ravel()] - expected).max() > 1e-3
    vector = RKBasis(mesh, vector=True)
    rotation = np.stack([vector.nodes[1], -vector.nodes[0]], axis=1).ravel()
    arrows = vector.plot(rotation, nrefs=1).collections[0]
    M, _ = vector.refinterp(rotation, nrefs=1)
    np.testing.assert_allclose(arrows.U, M.p[1], atol=1e-13)
    np.testing.assert_allclose(arrows.V, -M.p[0], atol=1e-13)
    rk.draw()
    rk.plot3(d)
    matplotlib.pyplot.close("all")


def test_facet_basis_probes_and_interpolator(quads):
    rk = RKBasis(quads, vector=True)
    fb = rk.boundary("right")
    d = rk.project(lambda x: np.array([np.cos(x[1]), x[0] * x[1]]))
    x = np.asarray(fb.global_coordinates()).reshape(2, -1)
    at_points = (fb.probes(x) @ d).reshape(2, -1)
    np.testing.assert_allclose(at_points, np.asarray(fb.interpolate(d)).reshape(2, -1),
                               rtol=0, atol=1e-13)
    np.testing.assert_allclose(fb.interpolator(d)(x), at_points, atol=0)
    np.testing.assert_array_equal(fb.nodal_values(d), rk.nodal_values(d))


@pytest.mark.parametrize("quadratic, linear", [(MeshTri2, MeshTri1), (MeshQuad2, MeshQuad1)])
def test_straight_quadratic_mesh_uses_its_vertices_as_particles(quadratic, linear):
    """Mid-edge nodes are left out: on straight cells the basis is that of the
    linear mesh of the vertices, matrix for matrix."""
    m = quadratic().refined(3)
    rk = RKBasis(m)
    same = RKBasis(linear(m.p[:, :m.nvertices], m.t))
    assert rk.nnodes == m.nvertices < m.p.shape[1]
    assert rk.particles_are_vertices
    np.testing.assert_array_equal(rk.get_dofs(), same.get_dofs())
    K, K_lin = asm(laplace, rk.trial, rk), asm(laplace, same.trial, same)
    assert abs(K - K_lin).max() < 1e-13 * abs(K_lin).max()
    (values, partner), = rk.split(np.ones(rk.N))
    assert partner.N == m.nvertices and np.allclose(values, 1.0, atol=1e-14)
    named = quadratic().refined(2).with_defaults()
    left = RKBasis(named).get_dofs("left")
    np.testing.assert_array_equal(left, np.flatnonzero(named.p[0, :named.nvertices] == 0))
    # all nodes as particles, on request: not the vertices any more
    every = RKBasis(named, nodes=named.p, radius=0.3)
    assert every.nnodes == named.p.shape[1] and not every.particles_are_vertices
    with pytest.raises(BasisIdiomError, match="not the mesh vertices"):
        every.split(np.zeros(every.N))
    with pytest.raises(ValueError, match="not the mesh vertices"):
        every.get_dofs("left")


@pytest.mark.parametrize("integration", ["vci", "vci_symmetric"])
def test_curved_quadratic_mesh_passes_the_patch_test(integration):
    """The disc as MeshTri2 (curved boundary cells): the area is π to 1e-5
    (the polygon of the vertices misses it by 2e-2) and the linear Laplace
    patch test passes to round-off with VCI on the curved cells."""
    m = MeshTri2.init_circle(3)
    rk = RKBasis(m, integration=integration)
    polygon = RKBasis(MeshTri1(m.p[:, :m.nvertices], m.t))
    area = lambda b: Functional(lambda w: 1.0 + 0.0 * w.x[0]).assemble(b)
    assert abs(area(rk) - np.pi) < 2e-5 and abs(area(polygon) - np.pi) > 1e-2
    u = lambda x: 1.0 + 2.0 * x[0] - 3.0 * x[1]
    flux = LinearForm(lambda v, w: (2.0 * w.n[0] - 3.0 * w.n[1]) * v)
    D = rk.get_dofs()
    d = skfem_rkpm.solve(asm(laplace, rk.trial, rk), asm(flux, rk.boundary()), rk,
                         D=D, x=u(rk.nodes))
    grad = rk.interpolate(d).grad
    assert np.abs(grad - np.array([2.0, -3.0])[:, None, None]).max() < 1e-11
    # refinterp follows the curved cells, as scikit-fem's P2 refinterp does
    M, values = rk.refinterp(d, nrefs=2)
    M_fem, _ = Basis(m, ElementTriP2()).refinterp(np.zeros(m.p.shape[1]), nrefs=2)
    np.testing.assert_allclose(M.p, M_fem.p, atol=1e-14)
    np.testing.assert_allclose(values, u(M.p), atol=1e-11)


def test_nodal_integration_refuses_quadratic_meshes_with_the_fix():
    with pytest.raises(ValueError, match=r"MeshQuad1\(mesh.p\[:, :mesh.nvertices\]"):
        RKBasis(MeshQuad2().refined(2), integration="scni")


@pytest.mark.parametrize("integration", ["vci", "gauss"])
def test_subdomain_matrices_add_up_to_the_whole(quads, integration):
    rk = RKBasis(quads, integration=integration)
    left = rk.with_elements(lambda x: x[0] < 1.0)
    right = left.with_elements(lambda x: x[0] >= 1.0)
    assert left.nelems + right.nelems == quads.nelements and left.N == rk.N
    assert right.with_elements() is rk
    K = asm(laplace, rk.trial, rk)
    parts = [asm(laplace, b.trial, b) for b in (left, right)]
    assert abs(K - parts[0] - parts[1]).max() < 1e-13 * abs(K).max()
    fast = skfem_rkpm.asm(laplace, left.trial, left)
    assert abs(fast - parts[0]).max() < 1e-13 * abs(K).max()
    areas = [Functional(lambda w: 1.0 + 0.0 * w.x[0]).assemble(b) for b in (left, right)]
    fem = Basis(quads, ElementQuad1(), elements=left.tind, intorder=rk.intorder)
    assert areas[0] == pytest.approx(fem.dx.sum(), rel=1e-14)
    assert sum(areas) == pytest.approx(2.0, rel=1e-13)
    p0 = left.with_element(ElementQuad0())
    assert np.array_equal(p0.tind, left.tind)
    d = linear_coefficients(rk, lambda x: 3.0 * x[0])
    moments = asm(mass, left, p0) @ d  # ∫_cell 3x, on the subdomain's cells only
    np.testing.assert_allclose(moments[left.tind],
                               Functional(lambda w: 3.0 * w.x[0]).elemental(p0),
                               rtol=0, atol=1e-13)
    assert not moments[np.setdiff1d(np.arange(quads.nelements), left.tind)].any()
    with pytest.raises(ValueError, match="elements must select cells"):
        rk.with_elements(np.array([quads.nelements]))


def test_elements_argument_is_with_elements(quads):
    left = lambda x: x[0] < 1.0
    built = RKBasis(quads, elements=left)
    restricted = RKBasis(quads).with_elements(left)
    np.testing.assert_array_equal(built.tind, restricted.tind)
    K = asm(laplace, built.trial, built)
    assert abs(K - asm(laplace, restricted.trial, restricted)).max() == 0.0
    assert built.with_elements().nelems == quads.nelements


def test_split_indices_and_bases_read_coefficients(quads):
    """skfem's split_indices/split_bases pair is coefficient level: component
    coefficients with the scalar RK basis give the component field."""
    rk = RKBasis(quads, vector=True)
    d = rk.project(lambda x: np.array([np.sin(2.0 * x[0]), x[0] * x[1] ** 2]))
    field = np.asarray(rk.interpolate(d))
    nodal = rk.nodal_values(d)
    for c, (ix, scalar) in enumerate(zip(rk.split_indices(), rk.split_bases())):
        np.testing.assert_array_equal(ix, np.arange(c, rk.N, 2))
        assert scalar.N == rk.nnodes and not scalar.vector
        np.testing.assert_allclose(np.asarray(scalar.interpolate(d[ix])), field[c],
                                   rtol=0, atol=1e-14)
        np.testing.assert_allclose(scalar.nodal_values(d[ix]), nodal[c::2], atol=1e-14)
    sub = rk.with_elements([0, 3]).scalar_basis()
    assert sub.nelems == 2 and sub.with_elements().nelems == quads.nelements


def test_point_source_is_the_test_functions_at_the_point(quads):
    rk = RKBasis(quads)
    x0 = np.array([0.7, 0.35])
    f = rk.point_source(x0)
    assert f.sum() == pytest.approx(1.0, abs=1e-14)  # partition of unity
    u = lambda x: 1.0 + 2.0 * x[0] - x[1]
    assert f @ u(rk.nodes) == pytest.approx(u(x0), abs=1e-13)  # linear reproduction


def test_dof_idioms_that_would_read_coefficients_are_loud(quads):
    rk = RKBasis(quads, vector=True)
    for basis in (rk, rk.boundary()):
        for name in ("nodal_dofs", "facet_dofs", "edge_dofs", "interior_dofs", "dofs"):
            with pytest.raises(skfem_rkpm.CoefficientsNotNodalError,
                               match=r"nodal_values\(x\)\[c::2\]"):
                getattr(basis, name)
            assert not hasattr(basis, name)
    fb = rk.boundary()
    for call in (lambda: fb.split(np.zeros(rk.N)), lambda: fb.project(lambda x: x[0]),
                 lambda: fb.trace(np.zeros(rk.N))):
        with pytest.raises(BasisIdiomError) as err:
            call()
        assert "basis." in str(err.value)


def test_composite_basis_with_fem_is_the_block_matrix(quads):
    """``rk * p0`` (scikit-fem's CompositeBasis) assembles the block matrix of
    the four pairings; a VCI basis (two sets of gradients) is refused."""
    import scipy.sparse as sp

    rk = RKBasis(quads, integration="vci_symmetric")
    p0 = rk.with_element(ElementQuad0())
    form = BilinearForm(lambda u, p, v, q, w: dot(u.grad, v.grad) + u * q
                        + 2.0 * p * v + 3.0 * p * q)
    blocks = [[asm(BilinearForm(lambda u, v, w: dot(u.grad, v.grad)), rk),
               asm(BilinearForm(lambda p, v, w: 2.0 * p * v), p0, rk)],
              [asm(BilinearForm(lambda u, q, w: u * q), rk, p0),
               asm(BilinearForm(lambda p, q, w: 3.0 * p * q), p0)]]
    expected = sp.bmat(blocks)
    for assemble in (asm, skfem_rkpm.asm):
        A = assemble(form, rk * p0)
        assert A.shape == (rk.N + p0.N,) * 2
        assert abs(A - expected).max() < 1e-14 * abs(expected).max()
    with pytest.raises(BasisIdiomError, match="vci_symmetric"):
        RKBasis(quads) * p0
    with pytest.raises(ValueError, match="same cells and quadrature"):
        rk * Basis(quads, ElementQuad0(), intorder=2)


def test_interior_facet_basis_jump_terms_against_fem():
    """∫_F (u·n) [q] over the interior facets, q a DG P1 test function on
    either side: for the linear U the RK and P1 trial functions agree, so the
    jump terms agree to round-off; the facet lengths are scikit-fem's."""
    from skfem import ElementTriDG, InteriorFacetBasis

    m = MeshTri1().refined(3)
    rk = RKBasis(m, vector=True)
    sides = [skfem_rkpm.RKInteriorFacetBasis(rk, side=s) for s in (0, 1)]
    dg = [b.with_element(ElementTriDG(ElementTriP1())) for b in sides]
    p1 = [b.with_element(ElementVector(ElementTriP1())) for b in sides]
    assert all(isinstance(b, InteriorFacetBasis) for b in dg + p1)
    assert all(np.array_equal(b.X, sides[0].X) for b in dg + p1)
    flux = BilinearForm(lambda u, q, w: dot(u, w.n) * q)
    d = linear_coefficients(rk, U)
    nodal = U(p1[0].doflocs[:, ::2]).T.ravel()
    jump_rk = sum((-1) ** s * (asm(flux, sides[s], dg[s]) @ d) for s in (0, 1))
    jump_fem = sum((-1) ** s * (asm(flux, p1[s], dg[s]) @ nodal) for s in (0, 1))
    assert np.abs(jump_rk).max() > 0.1
    np.testing.assert_allclose(jump_rk, jump_fem, rtol=0, atol=1e-13)
    length = Functional(lambda w: 1.0 + 0.0 * w.x[0])
    fem = InteriorFacetBasis(m, ElementTriP1(), intorder=rk.intorder)
    assert length.assemble(sides[1]) == pytest.approx(length.assemble(fem), rel=1e-14)
    np.testing.assert_array_equal(np.asarray(sides[0].interpolate(d)),
                                  np.asarray(sides[1].interpolate(d)))
    with pytest.raises(ValueError, match="on the boundary"):
        skfem_rkpm.RKInteriorFacetBasis(rk, facets=m.boundary_facets(), side=0)
    with pytest.raises(ValueError, match="side must be 0 or 1"):
        skfem_rkpm.RKInteriorFacetBasis(rk, side=2)


def test_projection_on_a_subdomain_is_exact_for_linear_fields(quads):
    """Particles whose supports reach the subdomain carry the L² projection
    (exact for a linear field: it is in the space), the others 0."""
    sub = RKBasis(quads).with_elements(lambda x: x[0] < 0.6)
    u = lambda x: 1.0 + 2.0 * x[0] - x[1]
    d = sub.project(u)
    seen = np.unique(sub.element_nodes)
    np.testing.assert_allclose(d[seen], u(sub.nodes[:, seen]), rtol=0, atol=1e-12)
    assert len(seen) < sub.nnodes and not d[np.setdiff1d(np.arange(sub.nnodes), seen)].any()
