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
from test_nodal_integration import integration_constraint
from test_plasticity import LAWS, E, NU

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


def tet_volumes(mesh):
    p, t = mesh.p, mesh.t
    J = np.stack([p[:, t[k]] - p[:, t[0]] for k in (1, 2, 3)], axis=1)
    return np.abs(np.linalg.det(np.moveaxis(J, -1, 0))) / 6


def linear_field(x):
    return np.einsum("ij,j...->i...", GRADIENT, x) + SHIFT.reshape(3, *[1] * (x.ndim - 1))


STRESS = LAM * np.trace(GRADIENT) * np.eye(3) + MU * (GRADIENT + GRADIENT.T)


@pytest.mark.parametrize("name", ["uniform_tets", "distorted_tets", "gmsh_tets",
                                  "distorted_hexes"])
def test_smoothing_cells_tile_the_domain_and_close(name, request):
    m = mesh_3d(name, request)
    cells = smoothing_cells(m)
    assert cells.area.min() > 0
    # the cells tile the unit cube (planar boundary faces)
    np.testing.assert_allclose(cells.cell_area.sum(), 1.0, rtol=1e-12)
    if m.t.shape[0] == 4:  # the pieces tile every tetrahedron
        piece_cell = np.tile(np.arange(m.nelements), 4)
        np.testing.assert_allclose(np.bincount(piece_cell, cells.area), tet_volumes(m),
                                   rtol=1e-12)
    # divergence theorem per piece and per cell: ∮ n dΓ = 0, ∮ x_k n_l dΓ = V δ_kl
    # (terms |x n dΓ| ≤ h²/4 ~ 1e-2: round-off of their sums ~1e-17)
    ndg = cells.segment_normals()
    x = cells.segment_points
    for f, k in [(np.ones_like(x[0]), None), (x[0], 0), (x[1], 1), (x[2], 2)]:
        flux = np.stack([cells.incidence @ (ndg[d] * f).sum(axis=1) for d in range(3)])
        cell_flux = np.stack([cells.to_cells @ flux[d] for d in range(3)])
        for d in range(3):
            if d == k:
                np.testing.assert_allclose(flux[d], cells.area, rtol=1e-11)
                np.testing.assert_allclose(cell_flux[d], cells.cell_area, rtol=1e-12)
            else:
                np.testing.assert_allclose(flux[d], 0.0, atol=1e-15)
                np.testing.assert_allclose(cell_flux[d], 0.0, atol=1e-15)
    # merged into whole cells: the triangles inside a cell cancel and are
    # dropped, the rest bounds the same volume
    whole = cells.merged()
    assert whole.segment_points.shape[1] < 0.7 * x.shape[1]
    ndg = whole.segment_normals()
    for k in range(3):
        np.testing.assert_allclose(whole.incidence @ (ndg[k] * whole.segment_points[k]).sum(
            axis=1), cells.cell_area, rtol=1e-12)


@pytest.mark.parametrize("name", ["distorted_tets", "gmsh_tets", "distorted_hexes"])
def test_smoothed_gradients_meet_the_integration_constraint(name, request):
    """Σ_L V_L b_I(X_L) = ∮_Γ Ψ_I n dΓ, the right side from the facet basis
    (scikit-fem's facet map of the composite rule, not the cells' triangles),
    and the smoothed gradients reproduce ∇x = I at every particle."""
    m = mesh_3d(name, request)
    basis = RKBasis(m, support=2.0, integration="scni")
    lhs, rhs, grads = integration_constraint(basis)
    # |b_I| V_L ~ h²: round-off of the sums of ~100 terms
    np.testing.assert_allclose(lhs, rhs, atol=1e-15)
    assert np.abs(rhs).max() > 1e-3  # particles near the boundary feel it
    np.testing.assert_allclose(grads, np.broadcast_to(np.eye(3), grads.shape), atol=1e-12)
    # the piece gradients (kept for the stabilization) change nothing
    stabilized = RKBasis(m, support=2.0, integration="scni", stabilization=1.0)
    np.testing.assert_allclose(stabilized.table.grads, basis.table.grads, atol=1e-12)


def traction_patch(basis):
    """Linear elasticity with the traction of the linear field on the whole
    boundary, the 6 rigid motions fixed at three corners: errors of u and ∇u
    at the particles."""
    @LinearForm
    def load(v, w):
        return dot(np.einsum("ij,j...->i...", STRESS, w.n), v)

    m = basis.mesh
    K = Assembler(basis).bilinear(C)
    f = asm(load, basis.boundary())
    d = solve(K, f, basis, D=cube_corner_dofs(m), x=linear_field(m.p).T.ravel())
    return patch_errors(basis, d)



def patch_errors(basis, d):
    u = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    stress = LAM * np.einsum("ii...->...", u.grad) * np.eye(3)[:, :, None, None] + MU * (
        u.grad + np.swapaxes(u.grad, 0, 1))
    return (np.abs(np.asarray(u) - linear_field(x)).max(),
            np.abs(u.grad - GRADIENT[:, :, None, None]).max(),
            np.abs(stress - STRESS[:, :, None, None]).max() / np.abs(STRESS).max())


@pytest.mark.parametrize("name", ["distorted_tets", "gmsh_tets", "distorted_hexes"])
@pytest.mark.parametrize("support", [1.5, 2.5])
def test_linear_patch_scni_round_off(name, support, request):
    """Measured (distorted tetrahedra and hexahedra, graded gmsh tetrahedra
    with spacings 0.064 to 0.38): displacement errors 7e-15 to 2e-14,
    gradient 8e-15 to 6e-14, relative stress 4e-14 to 2e-13."""
    m = mesh_3d(name, request)
    err, gerr, serr = traction_patch(RKBasis(m, vector=True, support=support,
                                             integration="scni"))
    assert err < 1e-12 and gerr < 1e-11 and serr < 1e-10


def test_linear_patch_scni_with_the_field_prescribed_on_the_boundary():
    """The linear field prescribed weakly on the three faces at the origin
    (boundary multipliers, piecewise linear on each face, integrated with the
    cells' boundary triangles), its traction on the other three: u and σ
    exact to round-off (measured 5e-14 in u, 2e-12 relative in σ).  The
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
    # the saddle-point matrix: unscaled (|K| ~ E h, |C| ~ h²) the round-off
    # is 100 times larger (measured 2.6e-12 in u, 9e-11 in σ)
    d, _ = solve_constrained(Assembler(basis).bilinear(C), f, E * Cmat, E * g)
    err, gerr, serr = patch_errors(basis, d)
    assert err < 1e-12 and gerr < 1e-11 and serr < 1e-10


@pytest.mark.parametrize("name", ["distorted_tets", "distorted_hexes"])
def test_linear_patch_dni_fails(name, request):
    """DNI: exact gradients at the particles, weights the cell volumes; it
    misses the integration constraint (measured 1.8e-2 and 2.9e-2 on these
    meshes), and the patch test fails by far more than round-off (measured:
    displacement 4.4e-2 / 5.5e-2, gradient 0.23 / 0.20, tetrahedra /
    hexahedra)."""
    m = mesh_3d(name, request)
    err, gerr, serr = traction_patch(RKBasis(m, vector=True, support=2.0,
                                             integration="dni"))
    assert err > 1e-2 and gerr > 0.1 and serr > 0.1


def test_stabilization_vanishes_on_linear_fields():
    m = perturbed_cube(MeshTet, n=3, amplitude=0.3)
    basis = RKBasis(m, vector=True, support=2.0, integration="scni", stabilization=1.0)
    K = stabilization_matrix(basis.nodal_quadrature, C, 3)
    d = linear_field(m.p).T.ravel()  # linear: coefficients = values
    assert np.abs(K @ d).max() < 1e-10 * abs(K).max() * np.abs(d).max()
    assert abs(K @ np.random.default_rng(0).normal(size=basis.N)).max() > 1e-2 * abs(K).max()
    unstabilized = RKBasis(m, vector=True, support=2.0, integration="scni")
    assert unstabilized.nodal_quadrature.jumps is None  # no piece gradients built


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
        assert np.sum(ev < 1e-10 * ev.max()) == 6, (integration, alpha, ev[:8])
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
    assert abs(S - elastic).max() < 1e-12 * abs(elastic).max()
