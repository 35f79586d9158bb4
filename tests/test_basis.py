"""RKBasis behind scikit-fem's face: asm with stock forms, mixing with FEM,
fields, dofs, facets, and the vectorized assembler against skfem.asm."""

import numpy as np
import pytest
from skfem import (Basis, ElementQuad1, ElementQuad2, ElementTriP1, ElementTriP2,
                   ElementVector, Functional, LinearForm, MeshQuad, MeshTri, asm)
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity
from skfem.models.poisson import laplace, mass, unit_load

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent

LAM, MU = lame_parameters(200.0, 0.3)


@pytest.fixture
def rect():
    """A 2 x 1 rectangle of 8 x 5 quads with named sides."""
    m = MeshQuad.init_tensor(np.linspace(0, 2, 9), np.linspace(0, 1, 6))
    return m.with_defaults()


def test_stock_forms_assemble(rect):
    b = RKBasis(rect)
    area = 2.0
    assert asm(mass, b).sum() == pytest.approx(area, rel=1e-13)
    assert asm(unit_load, b).sum() == pytest.approx(area, rel=1e-13)
    # constants are in the kernel of the Laplacian (Σ_I ∇Ψ_I = 0)
    K = asm(laplace, b.trial, b)
    assert np.abs(K @ np.ones(b.N)).max() < 1e-13
    # ∫ |∇x|² = area: coefficients of x are the particle x-coordinates
    x = b.nodes[0]
    assert x @ asm(laplace, b.trial, b) @ x == pytest.approx(area, rel=1e-12)
    assert Functional(lambda w: w.x[0] * w.x[1]).assemble(b) == pytest.approx(1.0)
    # elasticity: rigid translations and the infinitesimal rotation have zero energy
    bv = RKBasis(rect, vector=True)
    K = asm(linear_elasticity(LAM, MU), bv.trial, bv)
    rotation = np.stack([-bv.nodes[1], bv.nodes[0]], axis=1).ravel()
    for mode in (np.tile([1.0, 0.0], bv.nnodes), np.tile([0.0, 1.0], bv.nnodes), rotation):
        assert np.abs(K @ mode).max() < 1e-10 * abs(K).max()


@pytest.mark.parametrize("integration", ["vci", "gauss"])
@pytest.mark.parametrize("vector", [False, True])
def test_fast_assembler_matches_skfem_asm(rect, integration, vector):
    b = RKBasis(rect, vector=vector, support=2.5, integration=integration)
    A = Assembler(b)
    if vector:
        K_ref = asm(linear_elasticity(LAM, MU), b.trial, b)
        K = A.bilinear(isotropic_tangent(LAM, MU, 2))
    else:
        K_ref = asm(laplace, b.trial, b)
        K = A.bilinear(np.eye(2)[None, :, None, :])
    assert abs(K - K_ref).max() < 1e-12 * abs(K_ref).max()
    M = A.mass(3.0)
    M_ref = asm(mass, b) * 3.0 if not vector else None
    if M_ref is not None:
        assert abs(M - M_ref).max() < 1e-13


@pytest.mark.parametrize("mesh, element", [
    ("quad", ElementQuad1), ("quad", ElementQuad2),
    ("tri", ElementTriP1), ("tri", ElementTriP2),
])
def test_fast_assembler_matches_skfem_asm_for_fem(mesh, element):
    t = np.linspace(0, 1, 6)
    m = MeshQuad.init_tensor(t, t) if mesh == "quad" else MeshTri.init_tensor(t, t)
    fb = Basis(m, ElementVector(element()), intorder=4)
    K_ref = asm(linear_elasticity(LAM, MU), fb)
    K = Assembler(fb).bilinear(isotropic_tangent(LAM, MU, 2))
    assert abs(K - K_ref).max() < 1e-12 * abs(K_ref).max()
    # internal force of a field equals K u
    u = np.random.default_rng(0).normal(size=fb.N)
    A = Assembler(fb)
    G = A.gradient(u)
    eps = 0.5 * (G + G.transpose(1, 0, 2, 3))
    sigma = LAM * np.einsum("kk...->...", eps) * np.eye(2)[:, :, None, None] + 2 * MU * eps
    np.testing.assert_allclose(A.linear(sigma), K_ref @ u, atol=1e-9 * abs(K_ref @ u).max())


def test_mixed_rk_and_fem_bases(rect):
    """∫ Ψ_J φ_i summed over J is ∫ φ_i (partition of unity)."""
    rk = RKBasis(rect, intorder=4)
    fem = Basis(rect, ElementQuad1(), intorder=4)
    M = asm(mass, rk, fem)  # rows: FEM test functions, columns: RK trial
    assert M.shape == (fem.N, rk.N)
    np.testing.assert_allclose(M @ np.ones(rk.N), asm(unit_load, fem), atol=1e-14)
    # and the transpose pairing
    np.testing.assert_allclose(asm(mass, fem, rk) @ np.ones(fem.N),
                               asm(unit_load, rk), atol=1e-14)


def test_fields_probes_projection_nodal_values(rect):
    b = RKBasis(rect, vector=True)

    def f(x):
        return np.array([1.0 + 2.0 * x[0] - x[1], 0.5 * x[0] + 3.0 * x[1]])

    # a linear field is reproduced: its coefficients are its nodal values
    d = f(b.nodes).T.ravel()
    u = b.interpolate(d)
    x = np.asarray(b.global_coordinates())
    np.testing.assert_allclose(np.asarray(u), f(x), atol=1e-13)
    np.testing.assert_allclose(u.grad[0, 0], 2.0, atol=1e-12)
    np.testing.assert_allclose(u.grad[1, 1], 3.0, atol=1e-12)
    np.testing.assert_allclose(b.nodal_values(d), d, atol=1e-13)
    pts = np.random.default_rng(2).uniform([[0], [0]], [[2], [1]], (2, 7))
    np.testing.assert_allclose(b.interpolator(d)(pts), f(pts), atol=1e-13)
    P = b.probes(pts)
    np.testing.assert_allclose(P @ d, f(pts).ravel(), atol=1e-13)
    # L2 projection of a linear field is exact
    np.testing.assert_allclose(b.project(lambda x: f(np.asarray(x))), d, atol=1e-10)
    # coefficients of a non-polynomial field differ from its nodal values
    s = RKBasis(rect)
    c = s.project(lambda x: np.sin(3 * np.asarray(x)[0]))
    assert np.abs(s.nodal_values(c) - np.sin(3 * s.nodes[0])).max() < 2e-2
    assert np.abs(c - np.sin(3 * s.nodes[0])).max() > 1e-3


def test_dofs_by_name_callable_and_component(rect):
    b = RKBasis(rect, vector=True)
    left = b.get_dofs("left")
    on_left = np.flatnonzero(np.isclose(b.nodes[0], 0.0))
    np.testing.assert_array_equal(left, np.sort(np.r_[2 * on_left, 2 * on_left + 1]))
    np.testing.assert_array_equal(b.get_dofs("left", component=1), 2 * on_left + 1)
    np.testing.assert_array_equal(b.get_dofs(lambda x: np.isclose(x[0], 0.0)), left)
    assert len(b.get_dofs({"left", "right"})) == 4 * len(on_left)
    assert len(b.get_dofs()) == 2 * len(rect.boundary_nodes())
    np.testing.assert_array_equal(b.doflocs[:, left], b.nodes[:, left // 2])
    with pytest.raises(ValueError, match="no boundary named 'lft'"):
        b.get_dofs("lft")
    with pytest.raises(ValueError, match="component 2 does not exist"):
        b.get_dofs("left", component=2)
    with pytest.raises(ValueError, match="length 3"):
        b.interpolate(np.zeros(3))


def test_facet_basis_pressure_load(rect):
    b = RKBasis(rect, vector=True)
    right = b.boundary("right")
    assert asm(Functional(lambda w: 1.0 + 0 * w.x[0]), right) == pytest.approx(1.0)

    @LinearForm
    def pressure(v, w):
        return -5.0 * dot(w.n, v)

    f = asm(pressure, right)
    # total force: Σ_I f_I = -5 n |Γ| = (-5, 0) by partition of unity
    np.testing.assert_allclose(f.reshape(-1, 2).sum(axis=0), [-5.0, 0.0], atol=1e-13)
    # moment about the origin of a uniform pressure on x = 2, y ∈ [0, 1]:
    # Σ_I X_I × f_I = ∫ x × t = -(2)(0) ... = ∫ (x t_y - y t_x) = 5 * 1/2
    F = f.reshape(-1, 2)
    moment = np.sum(b.nodes[0] * F[:, 1] - b.nodes[1] * F[:, 0])
    assert moment == pytest.approx(2.5, rel=1e-12)


def test_bad_arguments(rect):
    with pytest.raises(ValueError, match="integration must be one of"):
        RKBasis(rect, integration="nodal")
    with pytest.raises(ValueError, match="basis order must be 0, 1 or 2"):
        RKBasis(rect, order=3)
    with pytest.raises(ValueError, match="normalized support must be positive"):
        RKBasis(rect, support=-1.0)
    with pytest.raises(ValueError, match="smallest normalized support that works"):
        RKBasis(rect, support=0.6)


def test_gauss_degree_without_a_rule_names_the_degree_and_the_cells():
    """scikit-fem has triangle rules up to a finite degree only: the error
    says which degree and which cells instead of NotImplementedError."""
    from skfem_rkpm.meshes import rectangle

    with pytest.raises(ValueError, match="scikit-fem has no Gauss rule of degree 40 for "
                                         "MeshTri1 cells; use a lower intorder"):
        RKBasis(rectangle(1.0, 1.0, 2, 2, kind="tri"), intorder=40)


def test_per_cell_particle_lists_are_the_sorted_unique_particles_of_each_cell():
    """The per-cell layout (no global sort) equals the np.unique reference."""
    from skfem_rkpm.approximation.cell_layout import cell_particles
    from skfem_rkpm.meshes import rectangle

    mesh = rectangle(1.0, 0.7, 9, 6, kind="tri", perturb=0.2, seed=2)
    b = RKBasis(mesh, support=2.5, intorder=3, integration="gauss")
    nqp = b.X.shape[-1]
    indptr, indices, slot = cell_particles(b.table, b.nelems, nqp)
    cell = b.table.rows // nqp
    for e in range(b.nelems):
        pairs = cell == e
        expected = np.unique(b.table.indices[pairs])
        np.testing.assert_array_equal(indices[indptr[e]:indptr[e + 1]], expected)
        np.testing.assert_array_equal(expected[slot[pairs]], b.table.indices[pairs])


def test_the_pair_table_of_a_basis_is_the_shape_table_it_was_laid_out_from():
    """The basis keeps the per-cell layout only; ``basis.table`` gathers the
    pair layout back from it: the same pairs, in the same order, with the
    same bits as shape functions computed afresh at the quadrature points."""
    from skfem_rkpm.meshes import rectangle

    mesh = rectangle(1.0, 0.7, 9, 6, kind="tri", perturb=0.2, seed=2)
    for integration in ("gauss", "vci", "vci_symmetric"):
        b = RKBasis(mesh, vector=True, support=2.5, intorder=3, integration=integration)
        fresh = b._shape_table(b.global_coordinates().reshape(2, -1))
        table = b.table
        np.testing.assert_array_equal(table.indptr, fresh.indptr)
        np.testing.assert_array_equal(table.indices, fresh.indices)
        np.testing.assert_array_equal(table.values, fresh.values)
        np.testing.assert_array_equal(table.grads, fresh.grads)
        # the test gradients: the exact ones, or corrected by VCI
        corrected = np.abs(b.test_grads - fresh.grads).max() / np.abs(fresh.grads).max()
        assert (corrected > 1e-6) == (integration != "gauss")
        np.testing.assert_array_equal(b.trial.test_grads, fresh.grads
                                      if integration == "vci" else b.test_grads)


def test_a_basis_keeps_no_array_per_pair_but_its_slots():
    """Values and gradients are held once, in the padded per-cell arrays; the
    only array with one entry per pair is the slot of each pair in its cell
    (4 bytes per pair), and, with VCI, the exact gradients until the trial
    basis lays them out."""
    from skfem_rkpm.meshes import rectangle

    def per_pair(b):
        names = [name for name, value in vars(b).items()
                 if isinstance(value, np.ndarray) and b.npairs in value.shape]
        return names + [f"_cells[{k}]" for k, value in enumerate(b._cells)
                        if b.npairs in value.shape]

    mesh = rectangle(1.0, 1.0, 8, 8)
    b = RKBasis(mesh, vector=True, support=3.0, integration="gauss")
    assert per_pair(b) == ["_cells[2]"] and b._cells[2].itemsize == 4
    b = RKBasis(mesh, vector=True, support=3.0)
    assert per_pair(b) == ["_exact_grads", "_cells[2]"]
    exact = b.table.grads
    trial = b.trial
    assert per_pair(b) == per_pair(trial) == ["_cells[2]"]
    np.testing.assert_array_equal(b.table.grads, exact)
    np.testing.assert_array_equal(trial.table.grads, exact)
    np.testing.assert_array_equal(trial.test_grads, exact)


def test_the_tables_of_a_cell_selection_are_the_rows_of_the_whole_table():
    """``with_elements`` gathers the pairs of its cells only; they are the
    whole table's rows of those cells, before and after the trial basis lays
    out the exact gradients."""
    from skfem_rkpm.meshes import rectangle

    b = RKBasis(rectangle(1.0, 0.7, 9, 6, kind="tri", perturb=0.2, seed=2), vector=True,
                support=2.5, intorder=3)
    cells = np.array([3, 17, 40, 41, 100])
    nqp = b.X.shape[-1]
    rows = (cells[:, None] * nqp + np.arange(nqp)).ravel()
    whole = b.table
    pairs = np.concatenate([np.arange(whole.indptr[r], whole.indptr[r + 1]) for r in rows])
    test = b.test_grads[:, pairs]
    for _ in range(2):
        sub = b.with_elements(cells)
        np.testing.assert_array_equal(sub.table.indices, whole.indices[pairs])
        np.testing.assert_array_equal(sub.table.values, whole.values[pairs])
        np.testing.assert_array_equal(sub.table.grads, whole.grads[:, pairs])
        np.testing.assert_array_equal(sub.test_grads, test)
        b.trial  # the exact gradients laid out: the same numbers


def test_an_order_0_basis_has_nothing_to_correct():
    """Order 0 reproduces constants only: VCI has nothing to correct, and the
    trial basis is the basis itself."""
    from skfem_rkpm.meshes import rectangle

    b = RKBasis(rectangle(1.0, 1.0, 6, 6), order=0, support=2.5)
    assert b.trial is b and b._exact_grads is None
