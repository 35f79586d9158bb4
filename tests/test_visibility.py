"""Supports cut at material interfaces, RKBasis(..., interfaces=...).

The visibility criterion (skfem_rkpm/approximation/visibility.py): each
material's RK functions are built from its own particles, the interface
particles shared.  Checked: a field linear in each material and continuous
across a straight interface (a kink, as in a two-material solution) is
reproduced exactly by each material's functions, where smooth functions
miss it by 1e-2; a particle's function is zero in the other material; one
region gives the standard table; bad input is refused by name.
"""

import warnings

import numpy as np
import pytest
from skfem import (BilinearForm, ElementQuad0, ElementQuad1, ElementQuad2, ElementTriP1,
                   MeshQuad, MeshTri)
from skfem.helpers import dot, grad

import skfem_rkpm
from skfem_rkpm import MaterialInterfaceWarning, RKBasis


def halves(mesh):
    mid = mesh.p[0, mesh.t].mean(axis=0)
    return mesh.with_subdomains({"left": np.flatnonzero(mid < 0.5),
                                 "right": np.flatnonzero(mid > 0.5)})


MESH = halves(MeshQuad().refined(3))


def kinked(x):
    """Slope 3 for x < 1/2, slope 1 beyond, continuous; plus a linear y part."""
    return np.where(x[0] < 0.5, 3.0 * x[0], 1.5 + (x[0] - 0.5)) + 2.0 * x[1] - 1.0


def kinked_grad(x):
    return np.stack([np.where(x[0] < 0.5, 3.0, 1.0), np.full(x.shape[1:], 2.0)])


@pytest.mark.parametrize("element, interpolating", [
    (ElementQuad1(), True), (ElementQuad1(), False), (ElementQuad2(), False)])
def test_a_kinked_linear_field_is_reproduced_exactly(element, interpolating):
    """Each material reproduces the monomials of the basis order from its own
    particles (Eq. 3.16-3.19), and the field is linear in each: with the
    coefficients d_I = u(X_I) the values and gradients are exact at every
    quadrature point and at points off the quadrature, to round-off."""
    rk = RKBasis(MESH, element, interpolating=interpolating, interfaces=True)
    d = kinked(rk.nodes)
    field = rk.interpolate(d)
    x = np.asarray(rk.global_coordinates())
    np.testing.assert_allclose(np.asarray(field), kinked(x), atol=1e-12)
    # the exact gradients (rk.trial), not the VCI-corrected test gradients
    np.testing.assert_allclose(rk.trial.interpolate(d).grad, kinked_grad(x), atol=1e-10)
    rng = np.random.default_rng(0)
    y = rng.uniform(0.0, 1.0, (2, 200))
    y = y[:, np.abs(y[0] - 0.5) > 1e-6]
    np.testing.assert_allclose(rk.probes(y) @ d, kinked(y), atol=1e-12)
    # smooth functions cannot kink: 1e-2 off at the same points
    smooth = RKBasis(MESH, element, interpolating=interpolating)
    assert np.abs(np.asarray(smooth.interpolate(kinked(smooth.nodes))) - kinked(x)).max() > 3e-3


def test_a_particle_is_invisible_from_the_other_material():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True, interfaces=["left", "right"])
    A = rk.table.matrix().tocsc()
    right_points = np.repeat(np.isin(np.arange(MESH.nelements),
                                     MESH.subdomains["right"]), rk.X.shape[-1])
    left_only = np.flatnonzero(rk.nodes[0] < 0.5 - 1e-9)
    on_interface = np.flatnonzero(np.abs(rk.nodes[0] - 0.5) < 1e-9)
    assert abs(A[right_points][:, left_only]).max() == 0.0
    assert abs(A[right_points][:, on_interface]).max() > 0.1  # shared
    smooth = RKBasis(MESH, ElementQuad1(), interpolating=True).table.matrix().tocsc()
    assert abs(smooth[right_points][:, left_only]).max() > 0.01  # smooth ones reach over


def test_one_region_is_the_standard_basis():
    """interfaces= with all cells in one material cuts nothing: the same
    pairs, values and gradients as the basis without the option."""
    one = MeshQuad().refined(3).with_subdomains({"all": np.arange(64)})
    for opts in ({"interpolating": True}, {"integration": "vci"}, {"integration": "gauss"}):
        plain = RKBasis(one, ElementQuad1(), **opts)
        cut = RKBasis(one, ElementQuad1(), interfaces=True, **opts)
        np.testing.assert_array_equal(cut.table.indices, plain.table.indices)
        np.testing.assert_allclose(cut.table.values, plain.table.values, atol=1e-14)
        np.testing.assert_allclose(cut.table.grads, plain.table.grads, atol=1e-12)
        if plain.table.test_grads is not None:
            np.testing.assert_allclose(cut.table.test_grads, plain.table.test_grads,
                                       atol=1e-12)
        assert plain._regions is None


@BilinearForm
def conduction(u, v, w):
    return w["k"] * dot(grad(u), grad(v))


@pytest.mark.parametrize("options", [{"interpolating": True}, {"integration": "vci"}])
def test_two_material_patch_away_from_the_boundary(options):
    """-div(k grad u) = 0 with k = 1 | 3 and u kinked (flux continuous): the
    cut functions contain u, and the discrete equations of every particle
    whose support misses the outer boundary hold for it to round-off with
    VCI (plain Gauss: 1.5e-3 of the largest entry 7.7).  Smooth functions do
    not contain u.  (At the outer boundary RK test functions do not vanish
    between the boundary particles, with one material as with two.)"""
    rk = RKBasis(MESH, ElementQuad1(), interfaces=True, **options)
    b0 = rk.with_element(ElementQuad0())
    k = b0.zeros()
    k[b0.get_dofs(elements="left")], k[b0.get_dofs(elements="right")] = 1.0, 3.0
    exact = lambda x: np.where(x[0] < 0.5, 3 * x[0], 1.5 + (x[0] - 0.5))  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("error", MaterialInterfaceWarning)
        A = skfem_rkpm.asm(conduction, rk.trial, rk, k=b0.interpolate(k))
    x = rk.nodes
    far = np.flatnonzero(np.min([x[0], 1 - x[0], x[1], 1 - x[1]], axis=0) > rk.radius)
    assert far.size >= 9
    assert np.abs(A @ exact(x))[far].max() < 1e-12 * abs(A).max()
    gauss = RKBasis(MESH, ElementQuad1(), interfaces=True, integration="gauss",
                    interpolating=options.get("interpolating", False))
    A = skfem_rkpm.asm(conduction, gauss, k=gauss.with_element(ElementQuad0()).interpolate(k))
    assert np.abs(A @ exact(x))[far].max() > 1e-5 * abs(A).max()  # why VCI


def test_a_jump_inside_a_material_still_warns():
    rk = RKBasis(MESH, ElementQuad1(), interpolating=True, interfaces=True)
    b0 = rk.with_element(ElementQuad0())
    k = b0.zeros() + 1.0
    k[b0.get_dofs(elements=np.flatnonzero(MESH.p[1, MESH.t].mean(axis=0) < 0.5))] = 5.0
    with pytest.warns(MaterialInterfaceWarning, match="jumps between cells"):
        skfem_rkpm.asm(conduction, rk, k=b0.interpolate(k))
    # a part that is a whole material: quiet
    with warnings.catch_warnings():
        warnings.simplefilter("error", MaterialInterfaceWarning)
        skfem_rkpm.asm(conduction, rk.with_elements("left"), k=1.0)


def test_the_mesh_without_subdomains_gets_advice_with_cell_sets():
    mesh = MeshTri().refined(3)
    rk = RKBasis(mesh, ElementTriP1(), interpolating=True)
    left = np.flatnonzero(mesh.p[0, mesh.t].mean(axis=0) < 0.5)
    with pytest.warns(MaterialInterfaceWarning, match=r"interfaces=\[E1, E2, \.\.\.\]"):
        skfem_rkpm.asm(conduction, rk.with_elements(left), k=1.0)
    # that suggestion, with the cells of the two materials
    right = np.setdiff1d(np.arange(mesh.nelements), left)
    cut = RKBasis(mesh, ElementTriP1(), interpolating=True, interfaces=[left, right])
    with warnings.catch_warnings():
        warnings.simplefilter("error", MaterialInterfaceWarning)
        skfem_rkpm.asm(conduction, cut.with_elements(left), k=1.0)
    x = np.asarray(cut.global_coordinates())
    u = lambda x: np.where(x[0] < 0.5, x[0], 0.5 + 4 * (x[0] - 0.5))  # noqa: E731
    np.testing.assert_allclose(np.asarray(cut.interpolate(u(cut.nodes))), u(x), atol=1e-12)


def test_bad_interfaces_are_refused_by_name():
    with pytest.raises(ValueError, match="no subdomain named 'core'.*'left', 'right'"):
        RKBasis(MESH, ElementQuad1(), interfaces=["core"])
    with pytest.raises(ValueError, match="has none; give the cells"):
        RKBasis(MeshQuad().refined(2), ElementQuad1(), interfaces=True)
    with pytest.raises(ValueError, match="must not overlap"):
        RKBasis(MESH, ElementQuad1(), interfaces=[np.arange(10), np.arange(5, 20)])
    with pytest.raises(ValueError, match="integration='vci' or 'gauss'"):
        RKBasis(MESH, ElementQuad1(), interfaces=True, integration="scni")
    with pytest.raises(ValueError, match="leave nodes=None"):
        RKBasis(MESH, nodes=MESH.p + 0.01, radius=0.3, interfaces=True)
    with pytest.raises(ValueError, match="interfaces= takes True"):
        RKBasis(MESH, ElementQuad1(), interfaces=3)
