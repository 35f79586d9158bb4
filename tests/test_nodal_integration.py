"""Nodal integration of RK bases: smoothing cells, SCNI patch tests (plane and
axisymmetric, finite-strain plasticity), the modified SCNI stabilization
against spurious low-energy modes, and the patch-test failure of DNI."""

import numpy as np
import pytest
import scipy.linalg as sl
from skfem import MeshTri, MeshWedge1

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.approximation.nodal_integration import (smoothing_cells,
                                                        stabilization_matrix)
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.stabilization import stabilization_moduli
from skfem_rkpm.meshes import gmsh_rectangle, rectangle
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from test_patch import assert_round_off, linear_field, rk_error
from test_plasticity import LAWS, E, NU, plane_strain_reference, uniaxial_exact

from _roundoff import sum_bound

C = isotropic_tangent(E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU)), 2)


def mesh_area(mesh):
    p, t = mesh.p, mesh.t
    n = t.shape[0]
    return abs(0.5 * sum(p[0, t[j]] * p[1, t[(j + 1) % n]] - p[0, t[(j + 1) % n]] * p[1, t[j]]
                         for j in range(n)))


def mesh_named(name, request):
    """A fixture mesh, or ``"graded_tris"``: a gmsh square graded 10:1 to a corner."""
    if name == "graded_tris":
        return gmsh_rectangle(1.0, 1.0, 0.1, kind="tri", h_corner=0.01)
    return request.getfixturevalue(name)


@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris", "graded_tris"])
def test_smoothing_cells_tile_the_domain_and_close(mesh, request):
    m = mesh_named(mesh, request)
    cells = smoothing_cells(m)
    assert cells.area.min() > 0
    # the pieces tile every mesh cell: areas add up cell by cell and in total
    np.testing.assert_allclose(cells.cell_area.sum(), 1.0, rtol=1e-13)
    piece_cell = np.tile(np.arange(m.nelements), m.t.shape[0])
    np.testing.assert_allclose(np.bincount(piece_cell, cells.area), mesh_area(m),
                               rtol=1e-12)
    assert_cells_close(cells)


def assert_cells_close(cells):
    """The divergence theorem per piece and per cell of 2D smoothing cells:
    ∮ n dΓ = 0 and ∮ x_k n_l dΓ = A δ_kl (the segment rule is exact for
    linear functions; the off-diagonal terms |x n dΓ| ≤ h cancel to
    round-off)."""
    ndg = cells.segment_normals()
    x = cells.segment_points
    for f, k in [(np.ones_like(x[0]), None), (x[0], 0), (x[1], 1)]:
        for d in range(2):
            flux = cells.incidence @ (ndg[d] * f).sum(axis=1)
            if d == k:  # small pieces (Voronoi slivers): an absolute floor too
                np.testing.assert_allclose(flux, cells.area, rtol=1e-12, atol=1e-15)
                np.testing.assert_allclose(cells.to_cells @ flux, cells.cell_area,
                                           rtol=1e-12, atol=1e-15)
            else:
                np.testing.assert_allclose(flux, 0.0, atol=1e-15)
                np.testing.assert_allclose(cells.to_cells @ flux, 0.0, atol=1e-15)


@pytest.mark.parametrize("smoothing", ["median_dual", "voronoi"])
@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
def test_smoothed_gradients_meet_the_integration_constraint(mesh, smoothing, request):
    """Σ_L A_L b_I(X_L) = ∮_Γ Ψ_I n dΓ, the right side from the facet basis
    (scikit-fem's facet quadrature, independent of the cells), and the
    smoothed gradients reproduce ∇x = I at every particle.  The boundary
    edges of these meshes are split at their midpoints by either kind of
    cells (their boundary vertices are not moved)."""
    m = request.getfixturevalue(mesh)
    basis = RKBasis(m, support=2.0, integration="scni", smoothing=smoothing)
    lhs, rhs, grads = integration_constraint(basis)
    # |b_I| A_L ~ 1: round-off of the sums of about 50 terms
    np.testing.assert_allclose(lhs, rhs, atol=1e-14)
    assert np.abs(rhs).max() > 0.1  # particles near the boundary feel it
    np.testing.assert_allclose(grads, np.broadcast_to(np.eye(2), grads.shape), atol=1e-12)


def integration_constraint(basis):
    """Both sides of the integration constraint of a nodal basis,
    ``Σ_L A_L b_I(X_L)`` and ``∮_Γ Ψ_I n dΓ`` (the right side from the facet
    basis: scikit-fem's facet quadrature, independent of the cells), shape
    (dim, nnodes), and the smoothed gradients of ``x`` at the particles,
    (nnodes, dim, dim)."""
    dim = basis.mesh.dim()
    A = basis.dx[:, 0]
    lhs = np.stack([np.bincount(basis.table.indices, basis.table.grads[k]
                                * A[basis.table.rows], minlength=basis.nnodes)
                    for k in range(dim)])
    fb = basis.boundary()
    w = (fb.dx[None] * fb.geometry.normals).reshape(dim, -1)
    rhs = np.stack([fb.table.matrix().T @ w[k] for k in range(dim)])
    grads = np.stack([basis.table.gradient_matrix(k) @ basis.mesh.p.T for k in range(dim)],
                     axis=1)
    return lhs, rhs, grads


def integration_constraint_bounds(basis):
    """Round-off bounds (tests/_roundoff.py) of :func:`integration_constraint`:
    of ``lhs - rhs``, the sums of the terms ``|b_I(X_L)| A_L`` and ``|Ψ_I n
    dΓ|``, and of the gradients of ``x``, the sums of ``|∇̃Ψ_I| |x_I|`` (each
    with as many ε as it has terms)."""
    dim = basis.mesh.dim()
    A = basis.dx[:, 0]
    table = basis.table
    lhs = np.stack([np.bincount(table.indices, np.abs(table.grads[k] * A[table.rows]),
                                minlength=basis.nnodes) for k in range(dim)])
    fb = basis.boundary()
    w = np.abs(fb.dx[None] * fb.geometry.normals).reshape(dim, -1)
    values = abs(fb.table.matrix()).tocsc()
    rhs = np.stack([values.T @ w[k] for k in range(dim)])
    constraint = (sum_bound(lhs, np.bincount(table.indices).max())
                  + sum_bound(rhs, np.diff(values.indptr).max()))
    gradients = [abs(table.gradient_matrix(k)).tocsr() for k in range(dim)]
    grads = np.stack([sum_bound(g @ np.abs(basis.mesh.p.T), np.diff(g.indptr).max())
                      for g in gradients], axis=1)
    return constraint, grads


@pytest.mark.roundoff
@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
@pytest.mark.parametrize("support", [1.5, 2.0, 3.0])
def test_linear_patch_scni_round_off(mesh, support, request):
    assert_round_off(*rk_error(request.getfixturevalue(mesh), linear_field, 1, support,
                               "scni", 2, bound=True))


@pytest.mark.roundoff
@pytest.mark.parametrize("kind", ["tri", "quad"])
def test_linear_patch_scni_on_graded_gmsh_meshes(kind):
    m = gmsh_rectangle(1.0, 1.0, 0.1, kind=kind, h_corner=0.01)
    assert_round_off(*rk_error(m, linear_field, 1, 2.0, "scni", 2, bound=True))


@pytest.mark.parametrize("mesh", ["distorted_quads", "distorted_tris"])
def test_linear_patch_dni_fails(mesh, request):
    """DNI: exact gradients at the particles, weights the cell areas; it
    misses the integration constraint, so the patch test fails by far more
    than round-off (measured: 3-4e-1 in the gradient)."""
    err, gerr = rk_error(request.getfixturevalue(mesh), linear_field, 1, 2.0, "dni", 2)
    assert gerr > 1e-2 and err > 1e-3


@pytest.mark.parametrize("moduli", ["elastic", "shear"])
def test_stabilized_patch_test_is_unchanged(moduli, distorted_tris):
    """The stabilization vanishes on linear fields: K_stab d = 0 for them."""
    basis = RKBasis(distorted_tris, vector=True, support=2.0, integration="scni",
                    stabilization=1.0)
    K = stabilization_matrix(basis.nodal_quadrature,
                             stabilization_moduli(J2Material(E, NU), moduli, 2), 2)
    d = linear_field(distorted_tris.p).T.ravel()  # linear: coefficients = values
    assert np.abs(K @ d).max() < 1e-9 * abs(K).max() * np.abs(d).max()
    assert abs(K @ np.random.default_rng(0).normal(size=basis.N)).max() > 1e-2 * abs(K).max()


@pytest.mark.parametrize("dim", [2, 3])
def test_shear_moduli_give_the_energy_of_the_deviator(dim):
    """``ε : C : ε`` with the "shear" moduli is ``2μ |dev ε|²`` of the 3D
    deviator (``ε_zz = 0`` in 2D), with the "elastic" ones ``λ (tr ε)² +
    2μ |ε|²``; in 3D the shear moduli do not see a volume change."""
    material = J2Material(E, NU)
    mu = E / (2 * (1 + NU))
    lam = E * NU / ((1 + NU) * (1 - 2 * NU))
    rng = np.random.default_rng(5)
    for _ in range(5):
        H = rng.normal(size=(dim, dim))  # a displacement gradient: C sees its symmetric part
        eps = np.zeros((3, 3))
        eps[:dim, :dim] = 0.5 * (H + H.T)
        dev = eps - np.trace(eps) / 3 * np.eye(3)
        shear = np.einsum("cl,cldm,dm", H, stabilization_moduli(material, "shear", dim), H)
        elastic = np.einsum("cl,cldm,dm", H, stabilization_moduli(material, "elastic", dim), H)
        assert shear == pytest.approx(2 * mu * np.sum(dev * dev), rel=1e-12)
        assert elastic == pytest.approx(lam * np.trace(eps) ** 2 + 2 * mu * np.sum(eps * eps),
                                        rel=1e-12)
    if dim == 3:
        volumetric = np.einsum("cldm,dm->cl", stabilization_moduli(material, "shear", 3),
                               np.eye(3))
        assert np.abs(volumetric).max() < 1e-12 * mu
    with pytest.raises(ValueError, match="'elastic' or 'shear', not 'bulk'"):
        stabilization_moduli(material, "bulk", dim)


def softest_modes(mesh, support, integration, alpha, moduli="elastic"):
    """Generalized eigenvalues ``K v = λ K_ref v`` on the non-rigid motions,
    with ``K_ref`` from Gauss points of degree 8 (accurately integrated).

    λ is the energy of a mode under nodal integration relative to its
    accurate energy; a spurious low-energy mode has λ ≪ 1.  Also returns the
    number of zero eigenvalues of ``K`` itself (below 1e-10 of the largest).
    """
    ref = RKBasis(mesh, vector=True, support=support, integration="gauss", intorder=8)
    Kref = Assembler(ref).bilinear(C).toarray()
    _, V = np.linalg.eigh(Kref)
    Z = V[:, 3:]
    basis = RKBasis(mesh, vector=True, support=support, integration=integration,
                    stabilization=alpha)
    K = Assembler(basis).bilinear(C)
    if alpha:
        K = K + alpha * stabilization_matrix(
            basis.nodal_quadrature, stabilization_moduli(J2Material(E, NU), moduli, 2), 2)
    K = K.toarray()
    ev = np.linalg.eigvalsh(K)
    zeros = int(np.sum(ev < 1e-10 * ev.max()))
    return zeros, sl.eigh(Z.T @ K @ Z, Z.T @ Kref @ Z, eigvals_only=True)


@pytest.mark.parametrize("kind", ["quad", "tri"])
def test_stabilization_removes_spurious_low_energy_modes(kind):
    """A free 12 x 12 patch, support 1.5.  Every scheme keeps exactly the 3
    rigid motions as zero modes; without stabilization SCNI and DNI have
    tens of modes whose energy is below 1/10 of their accurate energy
    (measured λ_min 0.02-0.03: the sawtooth patterns the nodal gradients
    miss), with α = 1 none is below 0.4 (measured 0.71-0.73)."""
    m = rectangle(1.0, 1.0, 12, 12, kind=kind)
    for integration, alpha in [("dni", 0.0), ("scni", 0.0)]:
        zeros, lam = softest_modes(m, 1.5, integration, alpha)
        assert zeros == 3
        assert lam.min() < 0.05 and np.sum(lam < 0.1) >= 10, (integration, lam[:5])
    zeros, lam = softest_modes(m, 1.5, "scni", 1.0)
    assert zeros == 3
    assert lam.min() > 0.4
    # SCNI smooths: never stiffer than exact integration (Jensen); the
    # reference's own quadrature error lets λ exceed 1 by 5e-7 (measured)
    assert lam.max() < 1 + 1e-5


@pytest.mark.parametrize("kind", ["quad", "tri"])
def test_shear_stabilization_leaves_no_spurious_modes(kind):
    """The same patch with the stabilization's shear (deviatoric) moduli
    only: still exactly the 3 rigid motions as zero modes (the 2D deviator of
    an in-plane dilatation keeps the energy ``μ/6 (tr ε)²``), and with α = 1 no mode
    below 0.3 of its accurate energy (measured 0.357 on quads and
    triangles); the shear moduli stiffen less than the elastic ones
    (measured λ_min 0.71-0.73 with those)."""
    m = rectangle(1.0, 1.0, 12, 12, kind=kind)
    zeros, lam = softest_modes(m, 1.5, "scni", 1.0, "shear")
    _, lam_elastic = softest_modes(m, 1.5, "scni", 1.0)
    assert zeros == 3
    assert 0.3 < lam.min() < lam_elastic.min()
    assert lam.max() < 1 + 1e-5


def compression(integration, model, law, steps, alpha=0.0, n=4, mesh=None, moduli="elastic"):
    mesh = mesh or rectangle(1.0, 1.0, n, n)
    basis = RKBasis(mesh, vector=True, support=2.0, integration=integration,
                    axisymmetric=model == "axisymmetric", stabilization=alpha)
    problem = SolidProblem(basis, J2Material(E, NU, LAWS[law]), model,
                           stabilization_moduli=moduli)
    conditions = [Prescribed("bottom", 1, 0.0, "weak"), Prescribed("top", 1, -0.3, "weak"),
                  Prescribed("left", 0, 0.0, "weak")]
    return problem, newton_steps(problem, conditions, steps=steps, tol=1e-10)


@pytest.mark.parametrize("law, alpha, moduli", [
    ("perfect", 0.0, "elastic"), ("swift", 0.0, "elastic"), ("perfect", 1.0, "elastic"),
    ("swift", 1.0, "elastic"), ("perfect", 1.0, "shear"), ("swift", 1.0, "tangent")])
def test_scni_axisymmetric_compression_follows_the_exact_curve(law, alpha, moduli,
                                                               distorted_quads):
    """Homogeneous finite-strain compression of a cylinder (axis included,
    distorted particles): the axisymmetric patch test at finite strain, to
    1e-8 in every step, with the material state at the particles."""
    problem, result = compression("scni", "axisymmetric", law, 6, alpha,
                                  mesh=distorted_quads, moduli=moduli)
    assert result.completed
    assert problem.npoints == distorted_quads.nvertices
    for record in result.history:
        _, force, _ = uniaxial_exact(0.3 * record.t, LAWS[law])
        assert record.reactions["top[1]"] == pytest.approx(force, rel=1e-8)
    sigma, _, alpha_exact = uniaxial_exact(0.3, LAWS[law])
    stress = problem.cauchy_stress(problem.evaluate(result.d, tangent=False))
    np.testing.assert_allclose(stress[:, 1, 1], sigma, rtol=1e-8)
    np.testing.assert_allclose(problem.state.alpha, alpha_exact, rtol=1e-8)


def test_scni_plane_strain_compression_force_is_2k():
    """Plane strain compression to 30 % between frictionless platens, perfect
    plasticity: the force per unit depth on the current width is 2k = 2σ_y/√3
    (the rate equations give the same), to the Newton tolerance."""
    problem, result = compression("scni", "plane_strain", "perfect", 4, 1.0, n=5)
    force, _ = plane_strain_reference(0.3, LAWS["perfect"])
    width = 1.0 / 0.7  # isochoric plastic flow, elastic volume change ~1e-3
    assert -force / width == pytest.approx(2 * 300.0 / np.sqrt(3), rel=2e-3)
    assert result.history[-1].reactions["top[1]"] == pytest.approx(force, rel=1e-8)
    stress = problem.cauchy_stress(problem.evaluate(result.d, tangent=False))
    np.testing.assert_allclose(stress[:, 1, 1], force / width, rtol=2e-3)
    # homogeneous to round-off: the plane strain patch test at finite strain
    assert np.ptp(stress[:, 1, 1]) < 1e-8 * abs(force)


def test_dni_axisymmetric_needs_particles_off_the_axis():
    with pytest.raises(ValueError, match="radius > 0"):
        compression("dni", "axisymmetric", "perfect", 1)


def test_nodal_integration_input_errors():
    m = rectangle(1.0, 1.0, 3, 3)
    with pytest.raises(ValueError, match="on tetrahedra and hexahedra, not on MeshWedge1"):
        RKBasis(MeshWedge1(), integration="scni")
    with pytest.raises(ValueError, match="leave nodes=None"):
        RKBasis(m, integration="scni", nodes=m.p + 0.01, radius=0.5)
    with pytest.raises(ValueError, match="needs integration='scni'"):
        RKBasis(m, integration="vci", stabilization=0.5)
    with pytest.raises(ValueError, match="stabilization must be"):
        RKBasis(m, integration="scni", stabilization=-1.0)
    with pytest.raises(ValueError, match="stabilization_moduli must be one of"):
        SolidProblem(RKBasis(m, vector=True, integration="scni", stabilization=0.5),
                     J2Material(E, NU), stabilization_moduli="secant")
    flat = np.array([[0.0, 1.0, 2.0, 0.0], [0.0, 0.0, 0.0, 1.0]])  # cell 0 on a line
    with pytest.raises(ValueError, match="mesh cell 0 .* zero area"):
        smoothing_cells(MeshTri(flat, np.array([[0, 1, 2], [0, 1, 3]]).T))


@pytest.mark.parametrize("model, moduli", [("plane_strain", "elastic"),
                                           ("axisymmetric", "elastic"),
                                           ("plane_strain", "shear"),
                                           ("axisymmetric", "shear")])
def test_stabilized_tangent_is_the_derivative_of_the_internal_force(model, moduli):
    """Plastic state, α = 0.3: central differences of f_int match K (the
    stabilization is added in the tangent's own pattern)."""
    mesh = rectangle(1.0, 1.0, 4, 4, kind="tri", perturb=0.2)
    basis = RKBasis(mesh, vector=True, support=2.0, integration="scni", stabilization=0.3,
                    axisymmetric=model == "axisymmetric")
    problem = SolidProblem(basis, J2Material(E, NU, LAWS["linear"]), model,
                           stabilization_moduli=moduli)
    d = 0.02 * np.random.default_rng(3).normal(size=basis.N)
    ev = problem.evaluate(d)
    assert ev.state.alpha.max() > 0.01 and problem.stabilization._slots is not False
    h = 1e-6
    fd = np.column_stack([
        (problem.evaluate(d + h * e, tangent=False).f_int
         - problem.evaluate(d - h * e, tangent=False).f_int) / (2 * h)
        for e in np.eye(basis.N)])
    K = ev.K.toarray()
    # central differences: truncation ~h² and round-off ~1e-16 |f| / h
    assert np.abs(K - fd).max() < 1e-7 * np.abs(K).max()


@pytest.mark.parametrize("model", ["plane_strain", "axisymmetric"])
def test_tangent_stabilization_force_and_stiffness_are_partners(model):
    """The "tangent" stabilization (the material tangent at each particle,
    from the last converged step): after a plastic step is committed, its
    stiffness has changed from the elastic one, the force at the committed
    coefficients is unchanged by the commit, and the tangent equals central
    differences of the internal force around a new state in the step."""
    mesh = rectangle(1.0, 1.0, 4, 4, kind="tri", perturb=0.2)
    basis = RKBasis(mesh, vector=True, support=2.0, integration="scni", stabilization=0.3,
                    axisymmetric=model == "axisymmetric")
    problem = SolidProblem(basis, J2Material(E, NU, LAWS["linear"]), model,
                           stabilization_moduli="tangent")
    rng = np.random.default_rng(3)
    elastic = problem.stabilization.matrix.copy()
    d1 = 0.02 * rng.normal(size=basis.N)
    ev = problem.evaluate(d1)
    assert ev.state.alpha.max() > 0.01
    problem.commit(ev)
    after = problem.evaluate(d1, tangent=False).f_int
    np.testing.assert_allclose(after, ev.f_int, atol=1e-10 * np.abs(ev.f_int).max())
    S = problem.stabilization.matrix
    assert abs(S - elastic).max() > 0.1 * abs(elastic).max()
    d = d1 + 0.01 * rng.normal(size=basis.N)
    K = problem.evaluate(d).K.toarray()
    assert problem.stabilization._slots is not False
    h = 1e-6
    fd = np.column_stack([
        (problem.evaluate(d + h * e, tangent=False).f_int
         - problem.evaluate(d - h * e, tangent=False).f_int) / (2 * h)
        for e in np.eye(basis.N)])
    assert np.abs(K - fd).max() < 1e-7 * np.abs(K).max()


def test_tangent_stabilization_vanishes_on_linear_fields(distorted_tris):
    """With moduli that differ from particle to particle (the plastic
    tangents of a random state) the stabilization still gives no force for
    a linear field: the piece gradients reproduce it."""
    basis = RKBasis(distorted_tris, vector=True, support=2.0, integration="scni",
                    stabilization=1.0)
    problem = SolidProblem(basis, J2Material(E, NU, LAWS["linear"]), "plane_strain",
                           stabilization_moduli="tangent")
    ev = problem.evaluate(0.02 * np.random.default_rng(4).normal(size=basis.N))
    assert np.ptp(ev.state.alpha) > 0.01  # the tangents differ between the particles
    problem.commit(ev)
    S = problem.stabilization.matrix
    d = linear_field(distorted_tris.p).T.ravel()
    assert np.abs(S @ d).max() < 1e-9 * abs(S).max() * np.abs(d).max()


def test_tangent_stabilization_scales_with_the_plastic_stiffness():
    """A free 12 x 12 patch in a homogeneous plastic state (plane strain,
    stretched 5 % and compressed 5 %, linear hardening), with that state's
    consistent tangent ``A`` at every point: the generalized eigenvalues
    ``K v = λ K_ref v`` on the non-rigid motions, ``K_ref`` integrated
    accurately with the same ``A``.  Plain SCNI has more than 100 modes below
    1/10 of their energy (measured λ_min 9e-4); stabilized with the tangent
    moduli (α = 1) none (measured 0.70), and no mode stiffer than accurate
    integration; with the elastic moduli the stabilization makes some mode 28
    times too stiff (measured 27.7).  The stiffness keeps exactly two zero
    modes (the translations) and one negative eigenvalue, the rotation
    against the initial stress (also without stabilization)."""
    from skfem_rkpm.mechanics.kinematics import entries
    from skfem_rkpm.mechanics.materials import MaterialState

    material = J2Material(E, NU, LAWS["linear"])
    F = np.diag([1.05, 0.95, 1.0])[None]
    _, _, state, A = material.update(F, MaterialState.virgin(1),
                                     entries=[e for _, e in entries("plane_strain")])
    assert state.alpha[0] > 0.05
    A = A[0].reshape(2, 2, 2, 2)
    mesh = rectangle(1.0, 1.0, 12, 12)
    ref = RKBasis(mesh, vector=True, support=1.5, integration="gauss", intorder=8)
    _, V = np.linalg.eigh(Assembler(ref).bilinear(C).toarray())
    Z = V[:, 3:]  # the non-rigid motions
    Kref = Z.T @ Assembler(ref).bilinear(A).toarray() @ Z
    basis = RKBasis(mesh, vector=True, support=1.5, integration="scni", stabilization=1.0)
    K0 = Assembler(basis).bilinear(A)
    per_particle = np.broadcast_to(A, (mesh.nvertices,) + A.shape)
    tangent = K0 + stabilization_matrix(basis.nodal_quadrature, per_particle, 2)
    elastic = K0 + stabilization_matrix(basis.nodal_quadrature, C, 2)

    def relative(K):
        return sl.eigh(Z.T @ K.toarray() @ Z, Kref, eigvals_only=True)

    plain, stabilized, stiff = relative(K0), relative(tangent), relative(elastic)
    assert plain.min() < 0.01 and np.sum(plain < 0.1) > 100
    assert stabilized.min() > 0.5 and stabilized.max() < 1 + 1e-5
    assert stiff.max() > 10
    ev = np.linalg.eigvalsh(tangent.toarray())
    small = 1e-10 * ev.max()
    assert np.sum(np.abs(ev) < small) == 2 and np.sum(ev < -small) == 1
