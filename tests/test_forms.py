"""skfem_rkpm.asm: any scikit-fem form on RK bases, checked against skfem.asm.

scikit-fem's own loop over pairs of local functions is the independent
reference: ``skfem_rkpm.asm`` reads the form's pointwise operator from unit
fields and assembles with batched products, so the two agree to round-off
(tolerance 1e-12 of the largest entry: sums of ~100 products of O(1) terms
in a different order).
"""

import warnings

import numpy as np
import pytest
import skfem
from skfem import (Basis, BilinearForm, ElementQuad0, ElementQuad1, ElementTetP1,
                   ElementTriP1, ElementVector, Functional, LinearForm,
                   MeshQuad, MeshTet, MeshTri)
from skfem.helpers import dot, grad
from skfem.models import laplace, linear_elasticity, mass, unit_load, vector_laplace
from skfem.models.general import curluv, divu, rot, vrot

import skfem_rkpm
import skfem_rkpm.assembly as assembly
from skfem_rkpm import Assembler, RKBasis
from skfem_rkpm.forms import (CorrectedTrialWarning, SlowAssemblyWarning, asm,
                              pointwise_operator)

RTOL = 1e-12

# the comparisons with skfem.asm assemble (basis, basis) pairs of VCI bases on
# purpose; test_vci_basis_as_trial_basis_is_loud checks the warning itself
pytestmark = pytest.mark.filterwarnings("ignore::skfem_rkpm.forms.CorrectedTrialWarning")


def dense(A):
    return A.toarray() if hasattr(A, "toarray") else np.asarray(A, dtype=float)


def assert_same(A, B, rtol=RTOL):
    A, B = dense(A), dense(B)
    assert A.shape == B.shape
    scale = np.abs(B).max()
    assert scale > 0
    assert np.abs(A - B).max() <= rtol * scale


def fast(form, *args, **kwargs):
    """skfem_rkpm.asm, failing if it fell back to scikit-fem's loop."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", SlowAssemblyWarning)
        return asm(form, *args, **kwargs)


@pytest.fixture(scope="module")
def quads():
    return MeshQuad().refined(2).with_defaults()


@pytest.fixture(scope="module")
def scalar(quads):
    return RKBasis(quads)


@pytest.fixture(scope="module")
def vector(quads):
    return RKBasis(quads, vector=True)


MODEL_FORMS = [
    ("laplace", laplace, False),
    ("mass", mass, False),
    ("vector_laplace", vector_laplace, True),
    ("vector mass", BilinearForm(lambda u, v, w: dot(u, v)), True),
    ("linear_elasticity", linear_elasticity(0.7, 1.3), True),
]


@pytest.mark.parametrize("name,form,is_vector", MODEL_FORMS, ids=[f[0] for f in MODEL_FORMS])
def test_model_bilinear_forms_equal_skfem_loop(name, form, is_vector, scalar, vector):
    basis = vector if is_vector else scalar
    for pair in [(basis.trial, basis), (basis,), (basis, basis.trial)]:
        assert_same(fast(form, *pair), skfem.asm(form, *pair))


def test_model_forms_between_vector_and_scalar_bases(scalar, vector, quads):
    # divu: vector trial, scalar test (RK and a P0 FEM pressure); curluv: 2D curl
    p0 = Basis(quads, ElementQuad0(), intorder=scalar.intorder)
    for test in (scalar, p0):
        assert_same(fast(divu, vector.trial, test), skfem.asm(divu, vector.trial, test))
    assert_same(fast(curluv, scalar, vector), skfem.asm(curluv, scalar, vector))


def test_model_linear_forms(scalar, vector):
    assert_same(fast(unit_load, scalar), skfem.asm(unit_load, scalar))
    # rot: curl of a scalar test function against a vector field; vrot: a
    # vector test function against the curl of a scalar field
    ws = scalar.interpolate(scalar.project(lambda x: np.sin(2 * x[0]) * x[1]))
    wv = vector.interpolate(vector.project(lambda x: np.array([x[1] ** 2, x[0] * x[1]])))
    assert_same(fast(rot, scalar, w=wv), skfem.asm(rot, scalar, w=wv))
    assert_same(fast(vrot, vector, w=ws), skfem.asm(vrot, vector, w=ws))


def test_forms_with_position_normals_and_fields(scalar):
    @BilinearForm
    def anisotropic(u, v, w):
        return (1 + w.x[0] ** 2) * u.grad[0] * v.grad[0] + w.x[1] * u * v.grad[1]

    @LinearForm
    def flux(v, w):
        return (2.0 * w.n[0] - 3.0 * w.n[1] + w.x[0]) * v

    @BilinearForm
    def robin(u, v, w):
        return (1 + w.n[0] ** 2) * u * v

    # the Newton tangent of the minimal surface problem: nonlinear in the
    # previous iterate (a coefficient vector interpolated by the basis)
    @BilinearForm
    def minimal_surface_tangent(u, v, w):
        g = grad(w["u_prev"])
        s = 1.0 / np.sqrt(1 + dot(g, g))
        return s * dot(grad(u), grad(v)) - s ** 3 * dot(g, grad(u)) * dot(g, grad(v))

    assert_same(fast(anisotropic, scalar.trial, scalar),
                skfem.asm(anisotropic, scalar.trial, scalar))
    facets = scalar.boundary()
    assert_same(fast(flux, facets), skfem.asm(flux, facets))
    assert_same(fast(robin, facets), skfem.asm(robin, facets))
    u_prev = scalar.project(lambda x: np.sin(np.pi * x[0]) * x[1] ** 2)
    K = fast(minimal_surface_tangent, scalar.trial, scalar, u_prev=u_prev)
    assert_same(K, skfem.asm(minimal_surface_tangent, scalar.trial, scalar, u_prev=u_prev))
    # the field changes the operator: not a constant-coefficient laplace
    assert np.abs(dense(K - fast(laplace, scalar.trial, scalar))).max() > 1e-3


def test_pointwise_operator_of_elasticity(vector):
    """D of linear elasticity is the isotropic tangent on the gradient channels."""
    lam, mu = 0.7, 1.3
    D = pointwise_operator(linear_elasticity(lam, mu), vector)
    C = skfem_rkpm.isotropic_tangent(lam, mu, 2)
    assert np.allclose(D[:, 1:, :, 1:], C[..., None, None], rtol=0, atol=1e-14)
    assert not D[:, :1].any() and not D[:, :, :, :1].any()


def test_mixed_rk_and_fem_bases(quads, scalar, vector):
    fem = Basis(quads, ElementQuad1(), intorder=scalar.intorder)
    femv = Basis(quads, ElementVector(ElementQuad1()), intorder=scalar.intorder)
    vector_mass = BilinearForm(lambda u, v, w: dot(u, v))
    cases = [((fem, scalar), (mass, laplace)), ((scalar, fem), (mass, laplace)),
             ((femv, vector.trial), (vector_mass, vector_laplace)),
             ((vector, femv), (vector_mass, vector_laplace))]
    for pair, forms in cases:
        for form in forms:
            A = fast(form, *pair)
            assert A.shape == (pair[1].N, pair[0].N)
            assert_same(A, skfem.asm(form, *pair))


def test_three_dimensional_elasticity():
    mesh = MeshTet().refined(1)
    basis = RKBasis(mesh, vector=True)
    form = linear_elasticity(1.0, 0.5)
    assert_same(fast(form, basis.trial, basis), skfem.asm(form, basis.trial, basis))
    fem = Basis(mesh, ElementVector(ElementTetP1()), intorder=basis.intorder)
    assert_same(fast(form, fem), skfem.asm(form, fem))  # FEM only: skfem.asm itself


def test_fem_only_is_skfem_asm(quads):
    fem = Basis(quads, ElementQuad1())
    assert_same(asm(laplace, fem), skfem.asm(laplace, fem), rtol=0)
    assert asm(Functional(lambda w: w.x[0]), fem) == pytest.approx(0.5, abs=1e-14)


def test_lists_of_bases_and_to(scalar, vector):
    summed = fast(mass, [scalar, scalar.trial], scalar)
    assert_same(summed, 2 * skfem.asm(mass, scalar))
    parts = asm(mass, [scalar, scalar.trial], scalar, to=list)
    assert len(parts) == 2
    assert_same(parts[0].tocsr(), skfem.asm(mass, scalar))
    assert fast(Functional(lambda w: w.x[0] * w.x[1]), scalar) == pytest.approx(0.25, abs=1e-13)


def test_plain_function_is_wrapped_like_skfem(scalar):
    assert_same(fast(lambda u, v, w: u * v, scalar), skfem.asm(mass, scalar))
    assert_same(fast(lambda v, w: v, scalar), skfem.asm(unit_load, scalar))


def test_forms_that_are_not_bilinear_fall_back_with_a_warning(scalar):
    @BilinearForm
    def affine(u, v, w):
        return u * v + 1.0

    @BilinearForm
    def quadratic(u, v, w):
        return u ** 2 * v

    @BilinearForm
    def summed_over_cells(u, v, w):
        return dot(u, v)  # dot of scalar fields sums over the cells

    with pytest.warns(SlowAssemblyWarning, match="not one number per quadrature point"):
        A = asm(summed_over_cells, scalar)
    assert_same(A, skfem.asm(summed_over_cells, scalar), rtol=0)

    for form in (affine, quadratic):
        with pytest.warns(SlowAssemblyWarning, match="not bilinear"):
            A = asm(form, scalar)
        assert_same(A, skfem.asm(form, scalar), rtol=0)

    @LinearForm
    def shifted(v, w):
        return v + 1.0

    with pytest.warns(SlowAssemblyWarning, match="not linear"):
        f = asm(shifted, scalar)
    assert_same(f, skfem.asm(shifted, scalar), rtol=0)

    complex_mass = BilinearForm(lambda u, v, w: 1j * u * v, dtype=np.complex128)
    with pytest.warns(SlowAssemblyWarning, match="complex"):
        asm(complex_mass, scalar)


def test_quadrature_mismatch_names_the_fix():
    mesh = MeshTri().refined(2)
    rk = RKBasis(mesh)
    fem = Basis(mesh, ElementTriP1())  # default quadrature: 3 points, RK: 6
    with pytest.raises(ValueError, match="intorder"):
        asm(mass, fem, rk)


def test_zero_form_gives_an_empty_matrix(scalar):
    A = fast(BilinearForm(lambda u, v, w: 0.0 * u * v), scalar)
    assert A.shape == (scalar.N, scalar.N) and abs(A).max() == 0


def test_assembler_places_by_table_and_by_search_agree(monkeypatch, vector, quads):
    """The dense position table and the stored scatter map give one matrix,
    square and rectangular (vector trial, scalar test)."""
    C = skfem_rkpm.isotropic_tangent(0.7, 1.3, 2)
    fem = Basis(quads, ElementQuad1(), intorder=vector.intorder)
    B = np.random.default_rng(1).normal(size=(1, 2, 2, 2))
    by_table = Assembler(vector).bilinear(C), Assembler(vector, test=fem).bilinear(B)
    monkeypatch.setattr(assembly, "DENSE_POSITIONS", 0)
    by_search = Assembler(vector).bilinear(C), Assembler(vector, test=fem).bilinear(B)
    for a, b in zip(by_table, by_search):
        assert_same(a, b, rtol=1e-15)
    # the rectangular matrix is the pairwise form
    form = BilinearForm(lambda u, v, w: sum(B[0, l, d, m] * u.grad[d, m] * v.grad[l]
                                            for l in range(2) for d in range(2)
                                            for m in range(2)))
    assert_same(by_table[1], skfem.asm(form, vector.trial, fem))


def test_rectangular_assembler_refuses_square_only_operations(vector, scalar):
    A = Assembler(vector, test=scalar)
    with pytest.raises(ValueError, match="one basis"):
        A.mass()


def test_cached_patterns_serve_each_pair_of_bases_its_own_gradients(quads):
    """Repeated calls on the pairs (trial, test), (test, test), (trial, trial)
    of one VCI basis reuse cached patterns but keep each basis's gradients."""
    basis = RKBasis(quads)
    pairs = [(basis.trial, basis), (basis, basis), (basis.trial, basis.trial),
             (basis, basis.trial)]
    expected = [skfem.asm(laplace, *p) for p in pairs]
    for _ in range(2):
        for pair, K in zip(pairs, expected):
            assert_same(fast(laplace, *pair), K)


def test_vci_basis_as_trial_basis_is_loud(scalar, vector):
    """asm(form, basis) on a VCI basis uses corrected gradients on both sides:
    a warning names the fix; mass-type forms and basis.trial stay quiet."""
    with pytest.warns(CorrectedTrialWarning, match=r"asm\(form, basis.trial, basis\)"):
        asm(laplace, scalar)
    with pytest.warns(CorrectedTrialWarning):
        asm(linear_elasticity(1.0, 1.0), vector, vector.trial)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        asm(mass, scalar)
        asm(laplace, scalar.trial, scalar)
        asm(laplace, RKBasis(scalar.mesh, integration="vci_symmetric"))
        asm(laplace, RKBasis(scalar.mesh, integration="gauss"))


def test_patterns_of_trial_bases_that_are_gone_are_freed(quads, scalar):
    import gc

    from skfem_rkpm.forms import _PATTERNS

    for _ in range(3):
        fem = Basis(quads, ElementQuad1(), intorder=scalar.intorder)
        fast(mass, fem, scalar)
        del fem
        gc.collect()
    fast(mass, scalar)
    assert all(entry[0]() is not None for entry in _PATTERNS[scalar].values())
