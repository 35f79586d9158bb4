"""Patch tests: RK with VCI reproduces linear (order 1) and quadratic (order 2)
elasticity solutions to round-off on distorted meshes; plain Gauss does not."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import (Basis, ElementQuad1, ElementTriP1, ElementVector, FacetBasis,
                   LinearForm, asm)
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent, solve

from _roundoff import assert_errors_within, constrained_solve_bound, field_bounds

LAM, MU = lame_parameters(1.0, 0.3)


def linear_field(x):
    return np.array([0.1 + 0.2 * x[0] - 0.3 * x[1], 0.05 - 0.2 * x[0] + 0.15 * x[1]])


def quadratic_field(x):
    return np.array([0.1 + 0.2 * x[0] - 0.3 * x[1] + 0.3 * x[0] ** 2 - 0.2 * x[0] * x[1],
                     -0.2 * x[0] + 0.1 * x[1] ** 2 + 0.25 * x[0] * x[1]])


def field_gradient(field, x, eps=0.5):
    """Central differences: exact (to round-off) for polynomials of degree ≤ 2."""
    x = np.asarray(x)
    g = []
    for k in range(2):
        dx = np.zeros_like(x)
        dx[k] = eps
        g.append((field(x + dx) - field(x - dx)) / (2 * eps))
    return np.stack(g, axis=1)  # (c, k, ...)


def stress(field, x):
    G = field_gradient(field, x)
    eps = 0.5 * (G + G.transpose(1, 0, *range(2, G.ndim)))
    tr = eps[0, 0] + eps[1, 1]
    return LAM * tr * np.eye(2).reshape(2, 2, *[1] * (G.ndim - 2)) + 2 * MU * eps


def body_force(field, x, eps=0.5):
    """b = -div σ, constant for quadratic fields."""
    x = np.asarray(x)
    div = 0.0
    for k in range(2):
        dx = np.zeros_like(x)
        dx[k] = eps
        div = div + (stress(field, x + dx)[:, k] - stress(field, x - dx)[:, k]) / (2 * eps)
    return -div


def solve_patch(basis, boundary, field, bound=False):
    """Coefficients of the patch test of ``field`` (traction on ``boundary``,
    body force, rigid motions fixed at two corners); with ``bound`` also
    the round-off bound of the coefficients (tests/_roundoff.py)."""
    @LinearForm
    def load(v, w):
        return dot(np.einsum("ij...,j...->i...", stress(field, w.x), w.n), v)

    @LinearForm
    def body(v, w):
        return dot(body_force(field, w.x), v)

    K = Assembler(basis).bilinear(isotropic_tangent(LAM, MU, 2))
    f = asm(load, boundary) + asm(body, basis)
    # remove rigid motions: both components at vertex 0 (0, 0), x at (0, 1)
    top_left = int(np.flatnonzero((basis.mesh.p[0] == 0) & (basis.mesh.p[1] == 1))[0])
    D = np.r_[0, 1, 2 * top_left]
    nodal = field(basis.mesh.p).T.ravel()
    d = solve(K, f, basis, D=D, x=nodal)
    if not bound:
        return d
    nodal_matrix = getattr(basis, "nodal_matrix", None)  # FEM: nodal values
    rows = (sp.identity(basis.N, format="csr") if nodal_matrix is None
            else nodal_matrix.tocsr())[D]
    return d, constrained_solve_bound(K, f, rows, nodal[D])


def rk_error(mesh, field, order, support, integration, intorder, bound=False):
    """Errors of u and ∇u of the RK patch test at the quadrature points;
    with ``bound`` also their round-off bounds: the bound on the
    coefficients from the condition of the constrained system, through the
    shape functions (tests/_roundoff.py).  Measured on the distorted and
    graded meshes of tests/test_patch.py and tests/test_nodal_integration.py
    the errors are 1e-7 to 4e-4 of the bounds (5e-12 to 3e-8 in u, 1.4e-10
    to 1.6e-7 in ∇u); plain Gauss integration misses the same tests by more
    than 1e-5 in ∇u (order 2) and 1e-4 (order 1), DNI by 0.3."""
    basis = RKBasis(mesh, vector=True, support=support, order=order,
                    integration=integration, intorder=intorder)
    d, coefficient_bound = solve_patch(basis, basis.boundary(), field, bound=True) \
        if bound else (solve_patch(basis, basis.boundary(), field), None)
    u = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    errors = (np.abs(np.asarray(u) - field(x)).max(),
              np.abs(u.grad - field_gradient(field, x)).max())
    if not bound:
        return errors
    return errors, field_bounds(basis, coefficient_bound, d)


def assert_round_off(errors, bounds):
    assert_errors_within(errors, bounds, ("u", "grad u"))


@pytest.mark.roundoff
@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
@pytest.mark.parametrize("support", [1.5, 2.0, 3.0])
def test_linear_patch_vci_round_off(mesh, support, request):
    m = request.getfixturevalue(mesh)
    assert_round_off(*rk_error(m, linear_field, 1, support, "vci", 2, bound=True))


@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
def test_linear_patch_gauss_fails_as_expected(mesh, request):
    """The paper's Gauss scheme misses the integration constraint."""
    m = request.getfixturevalue(mesh)
    err, gerr = rk_error(m, linear_field, 1, 2.0, "gauss", 2)
    assert gerr > 1e-4


@pytest.mark.roundoff
@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
def test_quadratic_patch_order2_vci_round_off(mesh, request):
    m = request.getfixturevalue(mesh)
    assert_round_off(*rk_error(m, quadratic_field, 2, 3.0, "vci", 4, bound=True))
    err_g, gerr_g = rk_error(m, quadratic_field, 2, 3.0, "gauss", 4)
    assert gerr_g > 1e-5


@pytest.mark.roundoff
@pytest.mark.parametrize("element", [ElementQuad1, ElementTriP1])
def test_linear_patch_fem(element, request):
    m = request.getfixturevalue("distorted_quads" if element is ElementQuad1
                                else "distorted_tris")
    e = ElementVector(element())
    basis = Basis(m, e, intorder=2)
    d, bound = solve_patch(basis, FacetBasis(m, e, intorder=2), linear_field, bound=True)
    # nodal values exact but for round-off (bounds 1.3e-11 and 2.2e-11 from
    # the constrained system, errors 8e-16 and 4e-15)
    assert_round_off([np.abs(d - linear_field(m.p).T.ravel()).max()], [bound])


@pytest.mark.roundoff
@pytest.mark.parametrize("kind", ["tri", "quad"])
def test_linear_patch_vci_on_graded_gmsh_meshes(kind):
    """Unstructured gmsh meshes graded 10:1 towards a corner."""
    from skfem_rkpm.meshes import gmsh_rectangle

    m = gmsh_rectangle(1.0, 1.0, 0.1, kind=kind, h_corner=0.01)
    assert_round_off(*rk_error(m, linear_field, 1, 2.0, "vci", 2, bound=True))
    err_g, gerr_g = rk_error(m, linear_field, 1, 2.0, "gauss", 2)
    assert gerr_g > 1e-4


@pytest.mark.roundoff
def test_linear_patch_vci_on_graded_tensor_mesh():
    from skfem_rkpm.meshes import graded_rectangle

    m = graded_rectangle(1.0, 1.0, 12, 12, ratio=20.0)
    assert_round_off(*rk_error(m, linear_field, 1, 2.0, "vci", 2, bound=True))
