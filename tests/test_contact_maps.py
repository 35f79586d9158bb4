"""The prebuilt maps of the contact tangent and prediction against the sparse
products they replace.

``_PointCoupling.tangent`` sums ``Gᵀ X G`` through a linear map from the
blocks of ``X`` built once; the sparse products sum the same terms in
another order, so the two differ by round-off: at most ``k ε`` times the
sum of the magnitudes of the terms of an entry, ``k`` the number of terms
(``|G|ᵀ |X| |G|``, the standard bound for a computed sum).  The touching
prediction computes ``Ĝ δ`` from ``G δ`` instead of from the sparse rows
``Ĝ``; the same bound holds with ``|Ĝ| |δ|``."""

import numpy as np
import pytest
import scipy.sparse as sp

from skfem_rkpm.mechanics import rigid_contact
from skfem_rkpm.mechanics.rigid_contact import _directional
from skfem_rkpm.mechanics.surface_contact import SurfaceContact

from test_surface_contact import SLAVES, TOOLS, cube, problem_on

EPS = np.finfo(float).eps


def _contact(tool, friction, kind, collocation):
    problem = problem_on(kind, cube())
    contact = SurfaceContact(problem, TOOLS[tool](), SLAVES[tool], friction, collocation,
                             penalty=1e5, tangential_penalty=2e4)
    rng = np.random.default_rng(4)
    d0 = 0.01 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    return contact, d0 + 0.01 * rng.normal(size=problem.N)


@pytest.mark.parametrize("tool", list(TOOLS))
@pytest.mark.parametrize("friction", [0.0, 0.3])
@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
def test_tangent_map_equals_sparse_products(tool, friction, kind, collocation, monkeypatch):
    contact, d = _contact(tool, friction, kind, collocation)
    coupling = contact._coupling
    f, K = contact.evaluate(d, 0.6)
    assert coupling._product[3] is not None  # the small cube takes the map
    blocks = []
    original = coupling.tangent
    monkeypatch.setattr(coupling, "tangent", lambda b: blocks.append(b) or original(b))
    contact.evaluate(d, 0.6)
    X = sp.bsr_matrix((blocks[0], coupling.indices, coupling.indptr),
                      shape=(3 * coupling.n,) * 2).tocsr()
    products = coupling.GT @ (X @ coupling.G)
    terms = abs(coupling.GT) @ (abs(X) @ abs(coupling.G))
    k = np.diff(coupling.G.indptr).max() ** 2 * np.diff(X.indptr).max()
    difference = abs(K - products).toarray()
    assert np.abs(K.toarray()).max() > 0
    assert np.all(difference <= k * EPS * terms.toarray())
    # the map's pattern holds every structural entry of the products
    present = (abs(products) > 0).astype(float)
    pattern = sp.csr_matrix((np.ones(K.nnz), K.indices, K.indptr), shape=K.shape)
    outside = present - present.multiply(pattern)
    outside.eliminate_zeros()
    assert outside.nnz == 0
    # and without the map (a limit of 0 terms) the products are used
    monkeypatch.setattr(rigid_contact, "PRODUCT_MAP_ENTRIES", 0)
    monkeypatch.setattr(coupling, "tangent", original)
    coupling._product.clear()
    _, K_products = contact.evaluate(d, 0.6)
    assert coupling._product[3] is None
    assert np.all(abs(K - K_products).toarray() <= k * EPS * terms.toarray())


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal")])
def test_touching_prediction_equals_sparse_rows(kind, collocation):
    """The linearized gaps of the nodes apart, ``ĝ + Ĝ δ``, computed from
    ``G δ``, against the rows ``Ĝ = W⁻¹ M B_n`` of the force."""
    contact, d = _contact("ball", 0.3, kind, collocation)
    contact.evaluate(d, 0.6)
    pts = contact.points
    rows = sp.csr_matrix((pts.weighted_hats @ _directional(pts.G, contact._normals))
                         / pts.node_weights[:, None])
    rng = np.random.default_rng(5)
    for scale in (1e-3, 1e-2, 1e-1):
        delta = scale * rng.normal(size=len(d))
        moved = np.einsum("in,in->n", contact._normals, pts.displacements(delta))
        bound = 4 * np.diff(rows.indptr).max() * EPS * (abs(rows) @ np.abs(delta))
        assert np.all(np.abs(pts.average(moved) - rows @ delta) <= bound)
    # a large update pushes apart nodes into the ball: the prediction names them
    apart = ~contact.trial.active
    assert apart.any()
    found = contact.touching(0.5 * np.tile([0.0, 0.0, 1.0], len(d) // 3))
    assert found is not None and found[0].any() and not (found[0] & ~apart).any()
