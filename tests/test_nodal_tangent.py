"""The nodal tangent summed over clusters of particles
(:mod:`skfem_rkpm.mechanics.nodal_tangent`) against the per-point assembly
and the sparse products ``Bᵀ D B`` and ``Bᵀ (w P)`` of the smoothed
gradients: the same sparsity pattern and the same entries to round-off, on
the ring (axisymmetric, box supports of 3 spacings, stabilized SCNI) and on a
3D block of tetrahedra, in a plastic state (consistent tangent per
particle); the 3D stabilized tangent against central differences."""

import numpy as np
import pytest
import scipy.sparse as sp

from skfem_rkpm import RKBasis
from skfem_rkpm.assembly import Assembler, Layout
from skfem_rkpm.mechanics.kinematics import deformation_gradient, from_entries
from skfem_rkpm.mechanics.materials import J2Material, perfect
from skfem_rkpm.mechanics.nodal_tangent import ClusteredTangent, point_clusters
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.meshes import box, rectangle

from _roundoff import sum_bound


def ring_problem():
    """The ring section of scenes/ring.toml with SCNI (α = 1e-3)."""
    mesh = rectangle(30.0, 20.0, 15, 10, origin=(30.0, 0.0))
    basis = RKBasis(mesh, vector=True, radius=6.0, support_shape="box",
                    axisymmetric=True, integration="scni", stabilization=1e-3)
    return SolidProblem(basis, J2Material(288e3, 0.3, perfect(100.0)), "axisymmetric")


def block_problem():
    """A unit cube of 4 x 4 x 4 x 6 tetrahedra, SCNI, radial support 2."""
    basis = RKBasis(box(1.0, 1.0, 1.0, 4, 4, 4, kind="tet"), vector=True, support=2.0,
                    integration="scni")
    return SolidProblem(basis, J2Material(288e3, 0.3, perfect(100.0)), "3d")


def plastic_tangent(problem, seed=0, stress=False):
    """The per-point consistent tangent ``A_ext`` after a 30 % compression
    with a random perturbation (every particle plastic); with ``stress``
    also ``P_ext``."""
    X = problem.basis.nodes
    u = np.vstack([(1 / np.sqrt(0.7) - 1) * X[:-1], -0.3 * X[-1:]])
    u += 1e-3 * np.ptp(X) * np.random.default_rng(seed).uniform(-1, 1, u.shape)
    d = u.T.ravel()
    F = deformation_gradient(problem.assembler.gradient(d), problem.model)
    P, _, state, A = problem.material.update(F, problem.state, entries=problem.entries)
    assert np.all(state.alpha > 0)
    P_ext, A_ext = from_entries(problem._at_entries(P), A, problem.model, problem.shape)
    return (d, A_ext, P_ext) if stress else (d, A_ext)


def smoothed_gradient_matrix(layout):
    """``B``: the (smoothed) gradients of every point as one sparse matrix,
    row ``(point c + comp) dim + l``, column dof ``c I + comp``."""
    c, dim = layout.ncomp, layout.dim
    nloc, npoints = layout.element_nodes.shape
    G = layout.trial_grads[..., 0]  # (dim, nloc, npoints)
    shape = (dim, nloc, npoints, c)
    rows = ((np.arange(npoints)[None, None, :, None] * c + np.arange(c)) * dim
            + np.arange(dim)[:, None, None, None])
    cols = c * layout.element_nodes[None, :, :, None] + np.arange(c)
    return sp.csr_matrix((np.broadcast_to(G[..., None], shape).ravel(),
                          (np.broadcast_to(rows, shape).ravel(),
                           np.broadcast_to(cols, shape).ravel())),
                         shape=(npoints * c * dim, c * layout.nscalar))


def magnitude(assembler, A_ext):
    """``Σ_L |B_L|ᵀ |D_L| |B_L|``: the sum of the absolute values of the
    terms of every tangent entry."""
    L = assembler.layout
    absolute = Layout(L.element_nodes, L.values, np.abs(L.trial_grads),
                      np.abs(L.test_grads), np.abs(L.dx), L.ncomp, L.nscalar)
    return Assembler(absolute).bilinear(np.abs(A_ext))


@pytest.mark.parametrize("make", [ring_problem, block_problem], ids=["ring", "block_3d"])
def test_clustered_tangent_equals_the_per_point_tangent(make):
    """Relative Frobenius difference at round-off, for every cluster size.

    Every entry of ``K`` is a sum of at most ``dim² · points`` products (the
    ``dim²`` terms of ``∂_l N_a C ∂_m N_b`` at each point whose gradient
    reaches both particles), summed in another order by the two paths; each
    errs by at most ``count ε Σ|terms|`` (``sum_bound``), so their
    difference by twice that, entry by entry and in the Frobenius norm.
    """
    problem = make()
    assembler = problem.assembler
    L = assembler.layout
    d, A_ext, P_ext = plastic_tangent(problem, stress=True)
    reference = assembler.matrix(assembler.local_bilinear(A_ext))
    bound = 2 * sum_bound(magnitude(assembler, A_ext).data, L.dim**2 * L.dx.shape[0])
    # the internal force is B_smoothᵀ (w P): the sparse product, sums of
    # (points x dim) terms, against the assembler's
    B = smoothed_gradient_matrix(L)
    wP = (P_ext[..., 0] * L.dx[:, 0]).transpose(2, 0, 1).ravel()
    f_bound = 2 * sum_bound(abs(B).T @ np.abs(wP), L.dim * L.dx.shape[0])
    assert np.all(np.abs(B.T @ wP - assembler.linear(P_ext)) <= f_bound)
    # and the tangent the sparse product Bᵀ D B
    D = sp.block_diag(list(A_ext[..., 0].transpose(4, 0, 1, 2, 3).reshape(
        L.dx.shape[0], L.ncomp * L.dim, -1) * L.dx[:, :, None]), format="csr")
    assert np.all(np.abs((B.T @ D @ B - reference).toarray()) <= 2 * bound.max())
    x = np.asarray(problem.basis.global_coordinates()).reshape(-1, L.dx.shape[0])
    for size in (4, 16):
        tangent = ClusteredTangent(assembler, x, size)
        K = tangent.matrix(A_ext)
        assert np.array_equal(K.indptr, reference.indptr)
        assert np.array_equal(K.indices, reference.indices)
        assert tangent.entries < L.dx.shape[0] * (L.element_nodes.shape[0] * L.ncomp) ** 2
        difference = np.linalg.norm(K.data - reference.data)
        assert difference <= np.linalg.norm(bound), (size, difference, np.linalg.norm(bound))
        assert np.all(np.abs(K.data - reference.data) <= bound)
    # the solid's own tangent (with the stabilization on the ring) uses the clusters
    assert problem._nodal_clusters() is not None
    K = problem.evaluate(d, tangent=True).K
    expected = reference if problem.stabilization is None else \
        problem.stabilization.add_to(reference.copy())
    assert np.linalg.norm((K - expected).data) <= 2 * np.linalg.norm(bound)


def test_a_wrong_scatter_is_seen():
    """The comparison above fails for a cluster tangent that loses one
    point: its entries then differ by far more than the round-off bound."""
    problem = ring_problem()
    assembler = problem.assembler
    L = assembler.layout
    _, A_ext = plastic_tangent(problem)
    reference = assembler.matrix(assembler.local_bilinear(A_ext))
    bound = 2 * sum_bound(magnitude(assembler, A_ext).data, L.dim**2 * L.dx.shape[0])
    x = np.asarray(problem.basis.global_coordinates()).reshape(-1, L.dx.shape[0])
    tangent = ClusteredTangent(assembler, x, 8)
    tangent.groups[0].layout.dx[0, 0] = 0.0  # the weight of one point lost
    K = tangent.matrix(A_ext)
    assert np.linalg.norm(K.data - reference.data) > 1e6 * np.linalg.norm(bound)


def test_point_clusters_hold_every_point_once_and_are_compact():
    """Every point in exactly one cluster; all clusters but one full; on a
    grid of 16 x 11 points, clusters of 8 span at most 4 x 4 spacings."""
    x = np.stack(np.meshgrid(np.arange(16.0), np.arange(11.0), indexing="ij")).reshape(2, -1)
    members = point_clusters(x, 8)
    flat = members[members >= 0]
    assert np.array_equal(np.sort(flat), np.arange(x.shape[1]))
    assert np.sum(np.any(members < 0, axis=1)) <= 1
    for row in members:
        p = x[:, row[row >= 0]]
        assert np.all(np.ptp(p, axis=1) <= 4.0)
    with pytest.raises(ValueError, match="at least one point"):
        point_clusters(x, 0)


@pytest.mark.parametrize("kind", ["hex", "tet"])
def test_stabilized_3d_tangent_is_the_derivative_of_the_internal_force(kind):
    """3D SCNI with the stabilization (α = 0.3), a plastic state: central
    differences of ``f_int`` match the tangent summed over clusters (the
    2D cases are in test_nodal_integration.py)."""
    basis = RKBasis(box(1.0, 1.0, 1.0, 3, 2, 2, kind=kind), vector=True, support=2.0,
                    integration="scni", stabilization=0.3)
    problem = SolidProblem(basis, J2Material(288e3, 0.3, perfect(100.0)), "3d")
    d = 0.01 * np.random.default_rng(4).normal(size=basis.N)
    ev = problem.evaluate(d)
    assert ev.state.alpha.max() > 1e-3 and problem._nodal_clusters() is not None
    h = 1e-6
    fd = np.column_stack([
        (problem.evaluate(d + h * e, tangent=False).f_int
         - problem.evaluate(d - h * e, tangent=False).f_int) / (2 * h)
        for e in np.eye(basis.N)])
    K = ev.K.toarray()
    # central differences err by ~h² |f'''| + ε |f| / h: measured 2.5e-10 and
    # 3.7e-10 of max |K| at h = 1e-6 (10 times more at h = 1e-7: round-off)
    assert np.abs(K - fd).max() < 1e-8 * np.abs(K).max()


def test_ring_tangent_is_the_derivative_of_the_internal_force():
    """The ring of scenes/ring.toml with SCNI and α = 1e-3 (axisymmetric,
    box supports, the tangent summed over clusters) after a 30 %
    compression, every particle plastic: central differences of ``f_int``
    along 8 random directions ``v`` equal ``K v`` of the tangent that Newton
    uses.  The error of central differences is ``~h² |f'''| + ε |f| / h``:
    from h = 1e-5 to 1e-6 of the coordinates' span it falls ~100 times
    (second order: asserted 30) to below 1e-7 of ``|K v|`` (measured
    4.2e-7 and 4.2e-9), which a missing term of the tangent (the
    stabilization, the hoop row, a plastic correction) would not: without
    the stabilization's the error stays at 1.2e-4."""
    problem = ring_problem()
    d, _ = plastic_tangent(problem)
    ev = problem.evaluate(d)
    assert np.all(ev.state.alpha > 0) and problem._nodal_clusters() is not None
    V = np.random.default_rng(1).normal(size=(problem.N, 8))
    KV = ev.K @ V
    span = np.ptp(problem.basis.nodes)
    errors = []
    for h in (1e-5 * span, 1e-6 * span):
        fd = np.column_stack([
            (problem.evaluate(d + h * v, tangent=False).f_int
             - problem.evaluate(d - h * v, tangent=False).f_int) / (2 * h) for v in V.T])
        errors.append((np.linalg.norm(KV - fd, axis=0) / np.linalg.norm(KV, axis=0)).max())
    assert errors[1] < errors[0] / 30 and errors[1] < 1e-7, errors
