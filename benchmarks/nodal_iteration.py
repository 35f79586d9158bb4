"""Cost of one Newton iteration with nodal integration (SCNI, DNI) against
Gauss+VCI at equal particles, with the accuracy of each beside it.

Part 1, cost.  Two cases at several particle counts:

* ``ring``: the ring section of ``scenes/ring.toml`` (axisymmetric, r from 30
  to 60 mm, z from 0 to 20 mm, box supports of 3 spacings, 4 x 4 Gauss
  points per cell for Gauss+VCI);
* ``square``: a plane strain unit square with the RKBasis defaults (radial
  support 2 spacings, Gauss degree 4: 3 x 3 points per cell), as in
  ``benchmarks/newton_iteration.py``;

* ``block``: a unit cube of tetrahedra (``box(..., kind="tet")``, 6 per
  cube of the grid), 3D, radial support 2 spacings; Gauss+VCI with the
  default Gauss degree 4 (11 points per tetrahedron) and with degree 2 (4
  points); SCNI with the default triangle rule (3 points per triangle);

all J2 perfectly plastic (E = 288e3, σ_y = 100), compressed homogeneously
by 30 % (every point on the plastic branch, the costly path of the return
map) plus a small random perturbation.  Timed per scheme, median of ``--repeat``
(CPU time, ``time.process_time``, one BLAS thread):

* *material*: ``J2Material.update`` at every material point;
* *assembly*: internal force and tangent as ``SolidProblem`` assembles
  them (``assembler.linear``, ``SolidProblem._tangent_matrix``: per point,
  or for nodal integration by clusters of particles,
  :mod:`skfem_rkpm.mechanics.nodal_tangent`), plus the stabilization force
  and its sum into the tangent for stabilized SCNI;
* *evaluate*: ``SolidProblem.evaluate`` as a whole (kinematics, material,
  assembly, checks) with its tangent formed (``.K``: the tangent is formed
  on demand);
* *setup*: building the basis and the problem (shape functions, VCI or the
  smoothing cells, the stabilization matrix), done once per run.

Target: an SCNI iteration (material + assembly) at most 1/4 of the
Gauss+VCI one.

Part 2, accuracy.  Timoshenko's cantilever (linear elasticity, plane stress,
4n x n cells at level n, support 2): relative energy and L² errors of each
scheme (and of SCNI with α = 1, the elastic choice), measured with 4 x 4 Gauss points per cell (the same
particles and shape functions, so the error of the integration scheme is
not hidden by measuring it at its own points).

Part 3 (``--parts stabilization_update``): the cost of stabilized SCNI
by the moduli of its stabilization (elastic, shear, tangent), per iteration
and, for the tangent moduli, the update once per step.

Run:  python benchmarks/nodal_iteration.py [--sizes 16 32 64] [--repeat 5]
      python benchmarks/nodal_iteration.py --parts stabilization_update --repeat 7
      python benchmarks/nodal_iteration.py --cases block --parts cost [--block-sizes 6 10 14]
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

SCHEMES = {  # label: RKBasis keywords (Gauss rule: the case's)
    "Gauss+VCI": dict(integration="vci"),
    "Gauss+VCI 2x2": dict(integration="vci", intorder=3),
    "SCNI": dict(integration="scni"),
    "SCNI α=1e-3": dict(integration="scni", stabilization=1e-3),
    "DNI": dict(integration="dni"),
}
SCHEMES_3D = {  # the block's schemes (Gauss degree 4: 11 points per tetrahedron)
    "Gauss+VCI": dict(integration="vci"),
    "Gauss+VCI degree 2": dict(integration="vci", intorder=2),
    "SCNI": dict(integration="scni"),
    "SCNI α=1e-3": dict(integration="scni", stabilization=1e-3),
    "DNI": dict(integration="dni"),
}
BLOCK_ACCURACY_SCHEMES = {**SCHEMES_3D,
                          "SCNI α=1": dict(integration="scni", stabilization=1.0),
                          "SCNI 6-point triangles": dict(integration="scni", intorder=6)}
CASES = {  # name: (axisymmetric, support shape, support in spacings, Gauss degree)
    "ring": (True, "box", 3.0, 7),
    "square": (False, "radial", 2.0, 4),
    "block": (False, "radial", 2.0, 4),
}


def case_schemes(case):
    return SCHEMES_3D if case == "block" else SCHEMES
BEAM_SCHEMES = {**SCHEMES, "SCNI α=1": dict(integration="scni", stabilization=1.0)}
TARGET_RATIO = 0.25


def solid_problem(case, n, scheme, moduli="elastic"):
    """The case's solid problem with ``n`` cells across (radially);
    ``moduli``: those of the SCNI stabilization."""
    from skfem_rkpm import RKBasis
    from skfem_rkpm.mechanics.materials import J2Material, perfect
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import box, rectangle

    axisymmetric, shape, support, intorder = CASES[case]
    if case == "block":
        mesh, spacing = box(1.0, 1.0, 1.0, n, n, n, kind="tet"), 1.0 / n
    elif axisymmetric:
        mesh = rectangle(30.0, 20.0, n, max(2 * n // 3, 2), origin=(30.0, 0.0))
        spacing = 30.0 / n
    else:
        mesh, spacing = rectangle(1.0, 1.0, n, n), 1.0 / n
    keywords = {"intorder": intorder, **case_schemes(case)[scheme]}
    basis = RKBasis(mesh, vector=True, radius=support * spacing, support_shape=shape,
                    axisymmetric=axisymmetric, **keywords)
    model = "3d" if case == "block" else "axisymmetric" if axisymmetric else "plane_strain"
    return SolidProblem(basis, J2Material(288e3, 0.3, perfect(100.0)), model,
                        stabilization_moduli=moduli)


def time_stabilization_update(case, n, repeat):
    """Per Newton iteration and per step, CPU ms, of stabilized SCNI
    (α = 1e-3) with the elastic, shear and tangent moduli: *evaluate* with
    the tangent formed; *step update*: what the tangent moduli add once per
    converged step (``commit``: the material tangent at the particles, the
    stabilization matrix rebuilt, and the first tangent after it, which
    finds the matrix's slots in the tangent again)."""
    rows = {}
    for moduli in ("elastic", "shear", "tangent"):
        problem = solid_problem(case, n, "SCNI α=1e-3", moduli)
        d = compressed(problem)
        ev = problem.evaluate(d)
        evaluate = median_ms(lambda: problem.evaluate(d).K, repeat)

        def step():
            problem.commit(ev)
            return problem.evaluate(d).K

        rows[moduli] = dict(particles=problem.basis.nnodes, evaluate=evaluate,
                            update=median_ms(step, repeat) - evaluate
                            if moduli == "tangent" else 0.0)
    return rows


def compressed(problem, reduction=0.3, noise=1e-3, seed=0):
    """Coefficients of a homogeneous compression by ``reduction`` (isochoric
    radial growth) with a random perturbation of ``noise`` x the spacing;
    along the last axis."""
    X = problem.basis.nodes
    stretch = 1.0 - reduction
    lateral = (1 / np.sqrt(stretch) - 1) * X[:-1]
    u = np.vstack([lateral, (stretch - 1) * X[-1:]])
    h = np.ptp(X[0]) / (len(np.unique(X[0])) - 1)
    u += noise * h * np.random.default_rng(seed).uniform(-1, 1, u.shape)
    return u.T.ravel()  # linear fields: coefficients = nodal values (close enough)


def median_ms(fn, repeat):
    """Median CPU time of ``repeat`` calls after one warm-up call, in ms."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.process_time()
        fn()
        times.append(time.process_time() - start)
    return 1e3 * float(np.median(times))


def time_iteration(case, n, scheme, repeat):
    from skfem_rkpm.mechanics.kinematics import deformation_gradient, from_entries

    start = time.process_time()
    problem = solid_problem(case, n, scheme)
    if hasattr(problem, "_nodal_clusters"):  # the clusters of the nodal tangent
        problem._nodal_clusters()
    setup = time.process_time() - start
    d = compressed(problem)
    asm = problem.assembler
    F = deformation_gradient(asm.gradient(d), problem.model)
    P, _, _, A = problem.material.update(F, problem.state, entries=problem.entries)
    P_ext, A_ext = from_entries(problem._at_entries(P), A, problem.model, problem.shape)
    S = problem.stabilization

    def assembly():  # as SolidProblem.evaluate assembles them
        f = asm.linear(P_ext)
        K = problem._tangent_matrix(A_ext)
        if S is not None:
            f, K = f + S.force(d), S.add_to(K)
        return f, K

    ev = problem.evaluate(d)
    return dict(
        particles=problem.basis.nnodes, points=problem.npoints,
        plastic=100 * np.mean(ev.state.alpha > 0), setup=1e3 * setup,
        material=median_ms(lambda: problem.material.update(
            F, problem.state, entries=problem.entries), repeat),
        assembly=median_ms(assembly, repeat),
        evaluate=median_ms(lambda: problem.evaluate(d).K, repeat),
        pairs=int(np.prod(problem.assembler.layout.element_nodes.shape)),
    )


def elastic_errors(problem, level, scheme):
    """Energy and L² errors of a 2D elastic ``problem`` of
    :mod:`skfem_rkpm.verification` (exact tractions on the whole boundary,
    rigid motions fixed), measured on Gauss points of degree 7 on the cells."""
    from skfem import LinearForm
    from skfem.helpers import dot

    from skfem_rkpm import Assembler, RKBasis, asm, isotropic_tangent, solve
    from skfem_rkpm.approximation.nodal_integration import stabilization_matrix
    from skfem_rkpm.assembly import facet_basis
    from skfem_rkpm.verification.elasticity import (error_norms, lame,
                                                    stress_from_voigt)
    from skfem_rkpm.verification.studies import rigid_motion_dofs

    mesh = problem.mesh(level)
    basis = RKBasis(mesh, vector=True, support=2.0, **BEAM_SCHEMES[scheme])
    lam, mu = lame(problem.E, problem.nu, problem.plane)
    C = isotropic_tangent(lam, mu, 2)
    K = Assembler(basis).bilinear(C)
    if basis.stabilization:
        K = K + basis.stabilization * stabilization_matrix(basis.nodal_quadrature, C, 2)

    @LinearForm
    def traction(v, w):
        sig = stress_from_voigt(problem.stress(np.asarray(w.x)))
        return dot(np.einsum("ij...,j...->i...", sig, w.n), v)

    f = asm(traction, facet_basis(basis))
    nodes = basis.doflocs[:, ::2]
    D = rigid_motion_dofs(nodes)
    d = solve(K, f, basis, D=D, x=problem.displacement(nodes).T.ravel()[D])
    judge = RKBasis(mesh, vector=True, support=2.0, integration="gauss", intorder=7)
    return mesh.nvertices, *error_norms(judge, d, problem.displacement, problem.stress,
                                        problem.E, problem.nu, problem.plane,
                                        modulo_rigid=True)


def block_field(x):
    """A quadratic displacement of the unit cube that solves Navier's equations
    without body force (harmonic and divergence free): loaded by its traction
    alone, so the load is equilibrated whatever the nodal weights."""
    x, y, z = x[0], x[1], x[2]
    return 1e-3 * np.stack([x ** 2 - y ** 2 - 2 * x * z,
                            y ** 2 - z ** 2 - 2 * x * y,
                            z ** 2 - x ** 2 - 2 * y * z])


def block_field_gradient(x):
    x, y, z = x[0], x[1], x[2]
    return 2e-3 * np.stack([np.stack([x - z, -y, -x]),
                            np.stack([-y, y - x, -z]),
                            np.stack([-x, -z, z - y])])


def block_errors(n, scheme):
    """Linear elasticity on the block with :func:`block_field` (traction on
    the whole boundary, rigid motions fixed at three corners): relative L²
    errors of u and ∇u, measured with Gauss degree 6 on the tetrahedra (same
    particles and shape functions)."""
    from skfem import LinearForm
    from skfem.helpers import dot

    from skfem_rkpm import Assembler, RKBasis, asm, isotropic_tangent, solve
    from skfem_rkpm.approximation.nodal_integration import stabilization_matrix
    from skfem_rkpm.meshes import box
    from skfem_rkpm.verification.studies import cube_corner_dofs

    mesh = box(1.0, 1.0, 1.0, n, n, n, kind="tet")
    lam, mu = 1.0, 1.0
    C = isotropic_tangent(lam, mu, 3)
    basis = RKBasis(mesh, vector=True, support=2.0, **BLOCK_ACCURACY_SCHEMES[scheme])
    K = Assembler(basis).bilinear(C)
    if basis.stabilization:
        K = K + basis.stabilization * stabilization_matrix(basis.nodal_quadrature, C, 3)

    def stress(x):
        G = block_field_gradient(x)
        eps = 0.5 * (G + np.swapaxes(G, 0, 1))
        tr = np.einsum("ii...->...", eps)
        return lam * tr * np.eye(3).reshape(3, 3, *[1] * (G.ndim - 2)) + 2 * mu * eps

    @LinearForm
    def load(v, w):
        return dot(np.einsum("ij...,j...->i...", stress(np.asarray(w.x)), w.n), v)

    f = asm(load, basis.boundary())
    d = solve(K, f, basis, D=cube_corner_dofs(mesh), x=block_field(mesh.p).T.ravel())
    judge = RKBasis(mesh, vector=True, support=2.0, integration="gauss", intorder=6)
    u = judge.interpolate(d)
    x = np.asarray(judge.global_coordinates())
    w = np.asarray(judge.dx)
    ue, ge = block_field(x), block_field_gradient(x)

    def norm(a):
        return np.sqrt(np.sum(a ** 2 * w))

    return (norm(np.asarray(u) - ue) / norm(ue),
            norm(np.asarray(u.grad) - ge) / norm(ge))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[15, 30, 60])
    parser.add_argument("--cases", nargs="+", default=["ring", "square"],
                        choices=list(CASES))
    parser.add_argument("--block-sizes", type=int, nargs="+", default=[6, 10, 14],
                        help="cells across the block (3D case)")
    parser.add_argument("--levels", type=int, nargs="+", default=[2, 4, 8])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--parts", nargs="+", default=["cost", "accuracy"],
                        choices=["cost", "accuracy", "block_accuracy",
                                 "stabilization_update"])
    args = parser.parse_args()
    print(f"load: {os.getloadavg()[0]:.1f} (1-minute average, 2 cores)\n")
    if "cost" in args.parts:
        cost_table(args)
    if "accuracy" in args.parts:
        accuracy_table(args)
    if "block_accuracy" in args.parts:
        block_accuracy_table(args)
    if "stabilization_update" in args.parts:
        stabilization_update_table(args)


def stabilization_update_table(args):
    print("Stabilized SCNI (α = 1e-3) by moduli, compressed 30 %; CPU ms, median of "
          f"{args.repeat}:\n")
    print("| case | particles | moduli | evaluate ms | step update ms |")
    print("|---|---:|---|---:|---:|")
    for case in args.cases:
        for n in (args.block_sizes if case == "block" else args.sizes):
            for moduli, r in time_stabilization_update(case, n, args.repeat).items():
                print(f"| {case} | {r['particles']} | {moduli} | {r['evaluate']:.1f} | "
                      f"{r['update']:.1f} |", flush=True)


def block_accuracy_table(args):
    print("Block (3D tetrahedra, support 2), quadratic Navier solution loaded by its "
          "traction, errors on Gauss degree 6:\n")
    print("| cells across | scheme | particles | L2 error of u | L2 error of grad u |")
    print("|---:|---|---:|---:|---:|")
    for n in args.block_sizes:
        for s in BLOCK_ACCURACY_SCHEMES:
            e, g = block_errors(n, s)
            print(f"| {n} | {s} | {(n + 1) ** 3} | {e:.3e} | {g:.3e} |")


def cost_table(args):
    print("Compressed 30 % (every point plastic); CPU ms, median of "
          f"{args.repeat}:\n")
    print("| case | scheme | particles | material points | local functions | "
          "material ms | assembly ms | material + assembly ms | / Gauss+VCI | "
          "evaluate ms | setup ms |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for case in args.cases:
        for n in (args.block_sizes if case == "block" else args.sizes):
            rows = {s: time_iteration(case, n, s, args.repeat) for s in case_schemes(case)}
            ref = rows["Gauss+VCI"]["material"] + rows["Gauss+VCI"]["assembly"]
            for s, r in rows.items():
                both = r["material"] + r["assembly"]
                print(f"| {case} | {s} | {r['particles']} | {r['points']} | {r['pairs']} | "
                      f"{r['material']:.1f} | {r['assembly']:.1f} | {both:.1f} | "
                      f"{both / ref:.3f} | {r['evaluate']:.1f} | {r['setup']:.0f} |")
    print(f"\nTarget: SCNI material + assembly at most {TARGET_RATIO:g} of Gauss+VCI.\n")


def accuracy_table(args):
    from skfem_rkpm.verification import plate_with_hole, timoshenko_beam

    for title, problem, levels in [
            ("Timoshenko beam (support 2, Gauss degree 4)", timoshenko_beam(), args.levels),
            ("Plate with a hole (Kirsch, graded gmsh triangles, support 2, Gauss degree 4)",
             plate_with_hole(), [2 * level for level in args.levels])]:
        print(f"{title}, errors on Gauss points of degree 7:\n")
        print("| level | scheme | particles | energy error | L2 error |")
        print("|---:|---|---:|---:|---:|")
        for level in levels:
            for s in BEAM_SCHEMES:
                n, l2, energy = elastic_errors(problem, level, s)
                print(f"| {level} | {s} | {n} | {energy:.3e} | {l2:.3e} |", flush=True)
        print()


if __name__ == "__main__":
    main()
