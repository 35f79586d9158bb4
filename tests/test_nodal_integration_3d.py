"""Nodal integration on 3D meshes: the median dual cells of tetrahedra and
hexahedra (tiling, divergence theorem per piece and per cell), SCNI's
integration constraint and linear patch tests, DNI's failure of the patch
test, the stabilization, the zero-energy modes of a free block, and a
finite-strain plastic compression with the material state at the particles."""

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp
from skfem import LinearForm, MeshHex, MeshTet, asm
from skfem.helpers import dot

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent, solve
from skfem_rkpm.approximation.constraints import weak_constraint
from skfem_rkpm.approximation.nodal_integration import (smoothing_cells,
                                                        stabilization_matrix)
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.meshes import box, rectangle
from skfem_rkpm.solvers.constrained import solve_constrained
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from skfem_rkpm.verification.exact import uniaxial_compression
from skfem_rkpm.verification.studies import cube_corner_dofs
from test_basis_3d import perturbed_cube
from test_nodal_integration import integration_constraint, integration_constraint_bounds
from test_plasticity import LAWS, E, NU

from _roundoff import (EPS, assert_errors_within, assert_within, constrained_solve_bound,
                       field_bounds, sum_bound)

LAM, MU = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
C = isotropic_tangent(LAM, MU, 3)
GRADIENT = np.array([[0.1, 0.2, -0.1], [0.05, -0.1, 0.3], [0.2, -0.15, 0.05]])
SHIFT = np.array([0.1, -0.2, 0.05])

# a unit cube meshed by gmsh, graded 5:1 towards the corner at the origin
GRADED_GEO = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Mesh.MeshSizeMax = 0.3;
MeshSize{ PointsOf{ Volume{1}; } } = 0.3;
MeshSize{1} = 0.06;
Physical Volume("block") = {1};
"""


@pytest.fixture(scope="module")
def gmsh_tets(tmp_path_factory):
    from skfem_rkpm.meshes.gmsh import load

    path = tmp_path_factory.mktemp("gmsh") / "graded.geo"
    path.write_text(GRADED_GEO)
    mesh = load(path)
    assert isinstance(mesh, MeshTet)
    return mesh


def mesh_3d(name, request):
    if name == "gmsh_tets":
        return request.getfixturevalue("gmsh_tets")
    if name == "uniform_tets":
        return box(1.0, 1.0, 1.0, 4, 4, 4, kind="tet")
    return perturbed_cube(MeshTet if name == "distorted_tets" else MeshHex, n=4,
                          amplitude=0.3)


def tet_volumes(mesh, magnitude=False):
    """Volumes of the tetrahedra, or (``magnitude``) ``|x|_max h² / 6``
    (``h`` the longest edge): the size of the terms whose cancellation gives
    a volume from coordinates (not differences), to scale its round-off."""
    p, t = mesh.p, mesh.t
    J = np.stack([p[:, t[k]] - p[:, t[0]] for k in (1, 2, 3)], axis=1)
    if magnitude:
        edges = [p[:, t[a]] - p[:, t[b]] for a in range(4) for b in range(a)]
        h = np.max([np.linalg.norm(e, axis=0) for e in edges], axis=0)
        return np.abs(p[:, t]).max(axis=(0, 1)) * h ** 2 / 6
    return np.abs(np.linalg.det(np.moveaxis(J, -1, 0))) / 6


def linear_field(x):
    return np.einsum("ij,j...->i...", GRADIENT, x) + SHIFT.reshape(3, *[1] * (x.ndim - 1))


STRESS = LAM * np.trace(GRADIENT) * np.eye(3) + MU * (GRADIENT + GRADIENT.T)


@pytest.mark.roundoff
@pytest.mark.parametrize("name", ["uniform_tets", "distorted_tets", "gmsh_tets",
                                  "distorted_hexes"])
def test_smoothing_cells_tile_the_domain_and_close(name, request):
    m = mesh_3d(name, request)
    cells = smoothing_cells(m)
    assert cells.area.min() > 0
    # the cells tile the unit cube (planar boundary faces): sums of the
    # positive piece volumes, exact but for round-off (tests/_roundoff.py;
    # a missing or doubled piece is 1e-4 of the volume and more)
    assert abs(cells.cell_area.sum() - 1.0) <= sum_bound(1.0, cells.area.size)
    if m.t.shape[0] == 4:  # the pieces tile every tetrahedron
        piece_cell = np.tile(np.arange(m.nelements), 4)
        # four piece volumes and a determinant (six products of three
        # coordinate differences each), from coordinates of size |x|_max:
        # a coordinate's round-off ε |x| enters times an area ~ h²
        assert_within(np.bincount(piece_cell, cells.area), tet_volumes(m),
                      sum_bound(tet_volumes(m, magnitude=True), 4 + 6))
    # divergence theorem per piece and per cell: ∮ n dΓ = 0, ∮ x_k n_l dΓ = V δ_kl
    # to the round-off of the sums of the terms x n dΓ (|x n dΓ| ≤ h²/4 ~ 1e-2)
    ndg = cells.segment_normals()
    x = cells.segment_points
    incidence, to_cells = abs(cells.incidence), abs(cells.to_cells)
    count = np.diff(cells.incidence.tocsr().indptr).max() * x.shape[-1]
    cell_count = count * np.diff(cells.to_cells.tocsr().indptr).max()
    for f, k in [(np.ones_like(x[0]), None), (x[0], 0), (x[1], 1), (x[2], 2)]:
        flux = np.stack([cells.incidence @ (ndg[d] * f).sum(axis=1) for d in range(3)])
        cell_flux = np.stack([cells.to_cells @ flux[d] for d in range(3)])
        for d in range(3):
            magnitude = incidence @ np.abs(ndg[d] * f).sum(axis=1)
            piece_bound = sum_bound(magnitude + cells.area * (d == k), count)
            cell_bound = sum_bound(to_cells @ (magnitude + cells.area * (d == k)), cell_count)
            assert_within(flux[d], cells.area if d == k else 0.0, piece_bound)
            assert_within(cell_flux[d], cells.cell_area if d == k else 0.0, cell_bound)
    # merged into whole cells: the triangles inside a cell cancel and are
    # dropped, the rest bounds the same volume
    whole = cells.merged()
    assert whole.segment_points.shape[1] < 0.7 * x.shape[1]
    ndg = whole.segment_normals()
    count = np.diff(whole.incidence.tocsr().indptr).max() * whole.segment_points.shape[-1]
    for k in range(3):
        terms = ndg[k] * whole.segment_points[k]
        assert_within(whole.incidence @ terms.sum(axis=1), cells.cell_area,
                      sum_bound(abs(whole.incidence) @ np.abs(terms).sum(axis=1)
                                + cells.cell_area, count))


@pytest.mark.roundoff
@pytest.mark.parametrize("name", ["distorted_tets", "gmsh_tets", "distorted_hexes"])
def test_smoothed_gradients_meet_the_integration_constraint(name, request):
    """Σ_L V_L b_I(X_L) = ∮_Γ Ψ_I n dΓ, the right side from the facet basis
    (scikit-fem's facet map of the composite rule, not the cells' triangles),
    and the smoothed gradients reproduce ∇x = I at every particle."""
    m = mesh_3d(name, request)
    basis = RKBasis(m, support=2.0, integration="scni")
    lhs, rhs, grads = integration_constraint(basis)
    # both sides are sums of terms |b_I| V_L ~ h² and |Ψ_I n dΓ| (measured
    # up to 4 ε Σ|terms|, 8e-17: no BLAS in them); a side missing a piece of
    # the boundary is off by |∮ Ψ_I n dΓ| ~ 1e-3
    lhs_bound, grads_bound = integration_constraint_bounds(basis)
    assert_within(lhs, rhs, lhs_bound)
    assert np.abs(rhs).max() > 1e-3  # particles near the boundary feel it
    # ∇x = Σ_I ∇̃Ψ_I x_I: round-off of the sum and of each smoothed gradient
    # (measured up to 9 ε Σ|∇̃Ψ_I x_I|, 1e-14)
    assert_within(grads, np.broadcast_to(np.eye(3), grads.shape), grads_bound)
    # the piece gradients (kept for the stabilization) change nothing: the
    # same sums over a cell's boundary triangles in another order, terms up
    # to the cell's largest |b_I| (measured up to 8 ε that)
    stabilized = RKBasis(m, support=2.0, integration="scni", stabilization=1.0)
    table = basis.table
    largest = np.zeros(basis.table.rows.max() + 1)
    np.maximum.at(largest, table.rows, np.abs(table.grads).max(axis=0))
    cells = smoothing_cells(m)
    terms = np.diff((abs(cells.to_cells) @ abs(cells.incidence)).tocsr().indptr).max()
    assert_within(stabilized.table.grads, table.grads,
                  sum_bound(largest[table.rows], terms * cells.segment_points.shape[-1]))


def traction_patch(basis):
    """Linear elasticity with the traction of the linear field on the whole
    boundary, the 6 rigid motions fixed at three corners: errors of u and ∇u
    at the particles and their round-off bounds (:func:`patch_bounds`)."""
    @LinearForm
    def load(v, w):
        return dot(np.einsum("ij,j...->i...", STRESS, w.n), v)

    m = basis.mesh
    K = Assembler(basis).bilinear(C)
    f = asm(load, basis.boundary())
    D = cube_corner_dofs(m)
    values = linear_field(m.p).T.ravel()
    d = solve(K, f, basis, D=D, x=values)
    bound = constrained_solve_bound(K, f, basis.nodal_matrix.tocsr()[D], values[D])
    return patch_errors(basis, d), patch_bounds(basis, bound, d)


def patch_errors(basis, d):
    u = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    stress = LAM * np.einsum("ii...->...", u.grad) * np.eye(3)[:, :, None, None] + MU * (
        u.grad + np.swapaxes(u.grad, 0, 1))
    return (np.abs(np.asarray(u) - linear_field(x)).max(),
            np.abs(u.grad - GRADIENT[:, :, None, None]).max(),
            np.abs(stress - STRESS[:, :, None, None]).max() / np.abs(STRESS).max())


def patch_bounds(basis, coefficient_error, d):
    """Round-off bounds of :func:`patch_errors` from the bound on the
    coefficients (tests/_roundoff.py): u and ∇u through the shape functions,
    the relative stress through ``|δσ| ≤ (3λ + 2μ) |δ∇u|``."""
    ubound, gbound = field_bounds(basis, coefficient_error, d)
    return ubound, gbound, (3 * LAM + 2 * MU) * gbound / np.abs(STRESS).max()


def assert_patch_round_off(errors, bounds):
    assert_errors_within(errors, bounds, ("u", "grad u", "stress"))


@pytest.mark.roundoff
@pytest.mark.parametrize("name", ["distorted_tets", "gmsh_tets", "distorted_hexes"])
@pytest.mark.parametrize("support", [1.5, 2.5])
def test_linear_patch_scni_round_off(name, support, request):
    """Measured (distorted tetrahedra and hexahedra, graded gmsh tetrahedra
    with spacings 0.064 to 0.38): displacement errors 7e-15 to 2e-14,
    gradient 8e-15 to 6e-14, relative stress 4e-14 to 2e-13, under the
    SkylakeX, Haswell, Sandybridge and Nehalem kernels of OpenBLAS.  The
    round-off bounds (κ∞ of the saddle-point matrix 2e7 to 6e7 on the
    distorted meshes) are 1.7e-9 to 9e-9 in u, 1e-8 to 1.1e-7 in ∇u, 2.4e-7
    to 2.5e-6 in σ, 2e5 to 2e7 times the errors; DNI's failure of the same
    test is 4e-2 in u, 0.2 in ∇u, 1 in σ (test_linear_patch_dni_fails)."""
    m = mesh_3d(name, request)
    errors, bounds = traction_patch(RKBasis(m, vector=True, support=support,
                                            integration="scni"))
    assert_patch_round_off(errors, bounds)


@pytest.mark.roundoff
def test_linear_patch_scni_with_the_field_prescribed_on_the_boundary():
    """The linear field prescribed weakly on the three faces at the origin
    (boundary multipliers, piecewise linear on each face, integrated with the
    cells' boundary triangles), its traction on the other three: u and σ
    exact to round-off (measured 2.5e-13 to 2e-12 in u, 1e-11 to 9e-11
    relative in σ under the SkylakeX, Haswell, Sandybridge and Nehalem kernels
    of OpenBLAS; the round-off bound, from κ∞ = 2.6e8 of the saddle-point
    matrix, is 2.3e-9 in u, 100 to 1000 times that).  The
    multipliers carry the traction (constant on each face); one multiplier
    field over several faces cannot carry the jump of σn at the cube's edges
    (measured 5e-4 in u), and multipliers on all six faces over-constrain
    the 5 x 5 x 5 particles (singular saddle-point matrix)."""
    m = perturbed_cube(MeshTet, n=4, amplitude=0.3).with_boundaries(
        {f"{axis}{side}": (lambda x, a=a, at=at: np.abs(x[a] - at) < 1e-12)
         for a, axis in enumerate("xyz") for side, at in (("min", 0.0), ("max", 1.0))})
    basis = RKBasis(m, vector=True, support=2.0, integration="scni")
    constraints = [weak_constraint(basis, face, c) for face in ("xmin", "ymin", "zmin")
                   for c in range(3)]
    Cmat = sp.vstack([c.C for c in constraints]).tocsr()
    g = np.concatenate([c.R @ linear_field(c.coordinates)[c.component]
                        for c in constraints])

    @LinearForm
    def load(v, w):
        return dot(np.einsum("ij,j...->i...", STRESS, w.n), v)

    f = asm(load, basis.boundary(["xmax", "ymax", "zmax"]))
    # constraint rows scaled by E (same solution) to balance the blocks of
    # the saddle-point matrix: unscaled (|K| ~ E h, |C| ~ h²) its condition
    # is 1e19 instead of 2.6e8 and the round-off up to 10 times larger
    # (measured 2e-12 to 3.5e-12 in u, 9e-11 to 1.9e-10 in σ)
    K = Assembler(basis).bilinear(C)
    d, _ = solve_constrained(K, f, E * Cmat, E * g)
    bound = constrained_solve_bound(K, f, E * Cmat, E * g)
    # a real defect is far above the bound (2.3e-9 in u): one multiplier
    # field over the three faces misses the traction's jumps by 5e-4 in u
    assert_patch_round_off(patch_errors(basis, d), patch_bounds(basis, bound, d))


@pytest.mark.parametrize("name", ["distorted_tets", "distorted_hexes"])
def test_linear_patch_dni_fails(name, request):
    """DNI: exact gradients at the particles, weights the cell volumes; it
    misses the integration constraint (measured 1.8e-2 and 2.9e-2 on these
    meshes), and the patch test fails by far more than round-off (measured:
    displacement 4.4e-2 / 5.5e-2, gradient 0.23 / 0.20, tetrahedra /
    hexahedra)."""
    m = mesh_3d(name, request)
    (err, gerr, serr), bounds = traction_patch(RKBasis(m, vector=True, support=2.0,
                                                       integration="dni"))
    assert err > 1e-2 and gerr > 0.1 and serr > 0.1
    # the round-off bounds of the SCNI patch tests separate the two by far
    assert np.all(np.array([err, gerr, serr]) > 1e4 * np.array(bounds))


@pytest.mark.roundoff
def test_stabilization_vanishes_on_linear_fields():
    m = perturbed_cube(MeshTet, n=3, amplitude=0.3)
    basis = RKBasis(m, vector=True, support=2.0, integration="scni", stabilization=1.0)
    K = stabilization_matrix(basis.nodal_quadrature, C, 3)
    d = linear_field(m.p).T.ravel()  # linear: coefficients = values
    # K d = 0 but for the round-off of its row sums (measured 1.1e-12, 1.4 ε
    # Σ|K_IJ d_J|; the bound is 2e-10, a random d gives 1e-2 |K|, below)
    assert_within(K @ d, 0.0, sum_bound(abs(K) @ np.abs(d), np.diff(K.tocsr().indptr).max()))
    assert abs(K @ np.random.default_rng(0).normal(size=basis.N)).max() > 1e-2 * abs(K).max()
    unstabilized = RKBasis(m, vector=True, support=2.0, integration="scni")
    assert unstabilized.nodal_quadrature.jumps is None  # no piece gradients built


@pytest.mark.roundoff
@pytest.mark.parametrize("kind", ["tet", "hex"])
def test_free_block_has_six_zero_modes(kind):
    """A free block of 5 x 5 x 5 particles, support 1.5, linear elasticity:
    every scheme has exactly the 6 rigid motions as zero modes.  Low-energy
    modes: generalized eigenvalues λ of ``K v = λ K_ref v`` on the non-rigid
    motions (``K_ref``: Gauss degree 6 on the cells), the energy of each mode
    relative to its accurate energy.  Measured (tetrahedra / hexahedra):
    SCNI λ_min 0.128 / 0.142, α = 1 0.53 / 0.55, DNI 0.28 / 0.17 (and up to
    7.9 / 5.2: DNI is too stiff on other modes); SCNI never exceeds 1 but for
    the reference's quadrature error (1 + 3e-6)."""
    m = box(1.0, 1.0, 1.0, 4, 4, 4, kind=kind)
    ref = RKBasis(m, vector=True, support=1.5, integration="gauss", intorder=6)
    Kref = Assembler(ref).bilinear(C).toarray()
    _, V = np.linalg.eigh(Kref)
    Z = V[:, 6:]
    lam_min = {}
    for integration, alpha in [("dni", 0.0), ("scni", 0.0), ("scni", 1.0)]:
        basis = RKBasis(m, vector=True, support=1.5, integration=integration,
                        stabilization=alpha)
        K = Assembler(basis).bilinear(C)
        if alpha:
            K = K + alpha * stabilization_matrix(basis.nodal_quadrature, C, 3)
        K = K.toarray()
        ev = np.linalg.eigvalsh(K)
        # zero modes: a backward-stable eigensolver moves eigenvalues by
        # ≲ n ε ‖K‖₂ (8e-14 ‖K‖; measured up to 8e-16 ‖K‖); the seventh is
        # above 3e-3 ‖K‖
        assert np.sum(ev < len(ev) * EPS * ev.max()) == 6, (integration, alpha, ev[:8])
        lam = sl.eigh(Z.T @ K @ Z, Z.T @ Kref @ Z, eigvals_only=True)
        lam_min[integration, alpha] = lam.min()
        if integration == "scni":
            assert lam.max() < 1 + 1e-4
    assert 0.05 < lam_min["scni", 0.0] < 0.2
    assert lam_min["scni", 1.0] > 0.4


@pytest.mark.parametrize("alpha, moduli", [(0.0, "elastic"), (1.0, "elastic"),
                                           (1.0, "shear"), (1.0, "tangent")])
def test_scni_3d_compression_follows_the_exact_curve(alpha, moduli):
    """Homogeneous finite-strain compression of a unit cube of distorted
    tetrahedra between frictionless platens (weak conditions), to 30 %, Swift
    hardening: force, stress and ε̄ᵖ at every particle on the exact curve to
    1e-8 in every step, with one material point per particle (with every
    choice of stabilization moduli: the stabilization vanishes on it)."""
    m = perturbed_cube(MeshTet, n=3, amplitude=0.3)
    m = m.with_boundaries({"xmin": lambda x: x[0] < 1e-12, "ymin": lambda x: x[1] < 1e-12,
                           "zmin": lambda x: x[2] < 1e-12, "zmax": lambda x: x[2] > 1 - 1e-12})
    basis = RKBasis(m, vector=True, support=2.0, integration="scni", stabilization=alpha)
    law = LAWS["swift"]
    problem = SolidProblem(basis, J2Material(E, NU, law), "3d", stabilization_moduli=moduli)
    conditions = [Prescribed("zmin", 2, 0.0, "weak"), Prescribed("zmax", 2, -0.3, "weak"),
                  Prescribed("xmin", 0, 0.0, "weak"), Prescribed("ymin", 1, 0.0, "weak")]
    result = newton_steps(problem, conditions, steps=4, tol=1e-10)
    assert result.completed
    assert problem.npoints == m.nvertices
    for record in result.history:
        exact = uniaxial_compression(0.3 * record.t, E, NU, law)
        assert record.reactions["zmax[2]"] == pytest.approx(exact.nominal, rel=1e-8)
    exact = uniaxial_compression(0.3, E, NU, law)
    stress = problem.cauchy_stress(problem.evaluate(result.d, tangent=False))
    np.testing.assert_allclose(stress[:, 2, 2], exact.cauchy, rtol=1e-8)
    np.testing.assert_allclose(stress[:, 0, 0], 0.0, atol=1e-8 * abs(exact.cauchy))
    np.testing.assert_allclose(problem.state.alpha, exact.alpha, rtol=1e-8)


@pytest.mark.parametrize("cells", ["tet", "hex"])
def test_block_scene_with_scni_follows_the_exact_solution(tmp_path, cells):
    """The built-in scene ``block_3d`` with ``integration = "scni"`` (and the
    scene default stabilization): every step's platen force is the exact
    uniaxial one, as with Gauss+VCI (tests/test_scenes_3d.py), to the Newton
    tolerance."""
    from test_scenes_3d import COARSE, TETS, exact_block, run_block

    settings = COARSE + (TETS if cells == "tet" else []) + [
        'discretization.integration="scni"']
    _, rows, scene = run_block(tmp_path, "rkpm", settings)
    assert len(rows) == 5
    for row in rows:
        _, _, force = exact_block(scene, float(row["t"]))
        assert float(row["reaction zmax[2]"]) == pytest.approx(force, rel=1e-10)


def test_degenerate_cells_are_named():
    p = np.array([[0.0, 1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0, 1.0],
                  [0.0, 0.0, 0.0, 1.0, 0.0]])  # cell 1 lies in the plane z = 0
    mesh = MeshTet(p, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]).T)
    with pytest.raises(ValueError, match=r"mesh cell 1 \(vertices \[0, 1, 2, 4\]\) has zero "
                                         "volume"):
        smoothing_cells(mesh)


@pytest.mark.roundoff
@pytest.mark.parametrize("model", ["3d", "plane_strain", "axisymmetric"])
def test_tangent_moduli_of_the_virgin_state_are_the_elastic_ones(model):
    """At the undeformed state the material tangent is the elastic moduli
    (no stress), so the "tangent" stabilization committed there equals the
    "elastic" one to round-off: the tangent's entries reach the right
    ``C_{c l d m}`` (in 3D all nine, in 2D the in-plane four, never the hoop
    entry)."""
    mesh = (perturbed_cube(MeshTet, n=2, amplitude=0.3) if model == "3d"
            else rectangle(1.0, 1.0, 4, 4, kind="tri", perturb=0.2))
    basis = RKBasis(mesh, vector=True, support=2.0, integration="scni", stabilization=1.0,
                    axisymmetric=model == "axisymmetric")
    material = J2Material(E, NU, LAWS["linear"])
    tangent = SolidProblem(basis, material, model, stabilization_moduli="tangent")
    elastic = SolidProblem(basis, material, model).stabilization.matrix
    ev = tangent.evaluate(np.zeros(basis.N))
    tangent.commit(ev)
    S = tangent.stabilization.matrix
    # the same sums over the dim⁴ moduli, which agree to a few ε (measured
    # 5e-16 to 1e-15 of |S|; a moduli entry in the wrong place is O(1))
    dim = 3 if model == "3d" else 2
    assert abs(S - elastic).max() <= sum_bound(abs(elastic).max(), dim ** 4)
