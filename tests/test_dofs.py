"""RK dof sets answer scikit-fem's DofsView calls like an FEM basis on the same mesh.

With the mesh vertices as particles, an RK basis numbers its dofs like
scikit-fem's Q1 / ElementVector(Q1) basis (``ncomp*I + c``), so scikit-fem's
own ``DofsView`` is the independent reference, call by call.
"""

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

import skfem_rkpm
from skfem_rkpm.approximation.dofs import RKDofs


@pytest.fixture(scope="module")
def mesh():
    return MeshQuad().refined(2).with_defaults()


@pytest.mark.parametrize("vector", [False, True])
def test_dofs_view_calls_match_scikit_fem(mesh, vector):
    rk = skfem_rkpm.RKBasis(mesh, vector=vector)
    element = ElementVector(ElementQuad1()) if vector else ElementQuad1()
    fem = Basis(mesh, element)
    for facets in (None, "left", {"left", "top"}):
        D, F = rk.get_dofs(facets), fem.get_dofs(facets)
        assert isinstance(D, RKDofs) and isinstance(D, np.ndarray)
        np.testing.assert_array_equal(D.all(), F.all())
        np.testing.assert_array_equal(np.asarray(D), F.flatten())
        assert sorted(D.nodal) == sorted(F.nodal)
        for name in F.nodal:
            np.testing.assert_array_equal(D.nodal[name], F.nodal[name])
            np.testing.assert_array_equal(D.all(name), F.all(name))
            np.testing.assert_array_equal(D.keep(name).all(), F.keep(name).all())
            np.testing.assert_array_equal(D.drop(name).all(), F.drop(name).all())
        assert D.facet == {} and D.interior == {}
        assert len(D) == len(F)


def test_dofs_remain_arrays(mesh):
    D = skfem_rkpm.RKBasis(mesh, vector=True).get_dofs("left")
    x = np.zeros(2 * mesh.nvertices)
    x[D] = 1.0
    assert x.sum() == len(D) == 10
    assert type(D + 1) is np.ndarray and type(D.all()) is np.ndarray
    assert not np.all(D)  # numpy's reduction: dof 0 is in the set
    np.testing.assert_array_equal(np.setdiff1d(D, D.keep("u^1")), D.nodal["u^2"])


def test_unknown_dof_name_lists_the_names(mesh):
    D = skfem_rkpm.RKBasis(mesh, vector=True).get_dofs()
    with pytest.raises(ValueError, match=r"has \['u\^1', 'u\^2'\]"):
        D.all("u")
