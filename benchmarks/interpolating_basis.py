"""Interpolating RK basis against the standard one: accuracy and build cost.

Poisson's problem -Δu = f with u = sin(2x) eʸ on the unit square (n × n
quadrilaterals, uniform and with interior vertices moved at random by up to
0.3 of the spacing), u prescribed at every boundary particle:

- standard RK (VCI) through ``skfem_rkpm.solve`` (the transformation method),
- interpolating RK (VCI) through scikit-fem's own ``condense``,
- bilinear FEM (Q1) through scikit-fem's ``condense``,

L² and H¹-seminorm errors with the basis' Gauss rule (degree 4); the same
on n³ hexahedra of the unit cube.  Then the
CPU time (``time.process_time``, median of ``--repeat``) of building the
scalar basis on the square and the vector basis on n³ hexahedra, standard
and interpolating; of the shape table alone (numpy path, both); and the
errors at 32² for several normalized supports.  Last, the choice of the
construction: the errors of the interpolant ``Σ_I N_I u(X_I)`` at 32² and
64² (Gauss degree 6) for several primitive windows and radii, and for
interpolating MLS with the singular weights ``φ(z)/z^α`` (Lancaster &
Šalkauskas; evaluated only off the particles, where they are finite), and
the Galerkin errors for smaller primitive radii.

Run:  python benchmarks/interpolating_basis.py          (~1 minute)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402
from _timing import median_cpu  # noqa: E402
import skfem  # noqa: E402
from skfem import (Basis, ElementQuad1, LinearForm, MeshHex, MeshQuad, asm,  # noqa: E402
                   condense, solve)
from skfem.models.poisson import laplace  # noqa: E402

import skfem_rkpm  # noqa: E402
from skfem_rkpm import RKBasis, rk_shape_functions  # noqa: E402
from skfem_rkpm.approximation.interpolating import (interpolating_shape_functions,  # noqa: E402
                                                    primitive_radius)
from skfem_rkpm.approximation.kernels import cubic_spline  # noqa: E402
from skfem_rkpm.meshes import local_spacing  # noqa: E402


def exact(x):
    return np.sin(2 * x[0]) * np.exp(x[1])


def exact_grad(x):
    return np.array([2 * np.cos(2 * x[0]) * np.exp(x[1]), np.sin(2 * x[0]) * np.exp(x[1])])


@LinearForm
def load(v, w):
    return 3 * np.sin(2 * w.x[0]) * np.exp(w.x[1]) * v


def square(n, distortion=0.0, seed=0):
    mesh = MeshQuad.init_tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    if distortion:
        p = mesh.p.copy()
        inner = np.setdiff1d(np.arange(p.shape[1]), mesh.boundary_nodes())
        rng = np.random.default_rng(seed)
        p[:, inner] += distortion / n * rng.uniform(-1, 1, (2, len(inner)))
        mesh = MeshQuad(p, mesh.t)
    return mesh


def errors(basis, d):
    field = basis.interpolate(d)
    x = np.asarray(basis.global_coordinates())
    w = basis.dx
    return (np.sqrt(np.sum((np.asarray(field) - exact(x)) ** 2 * w)),
            np.sqrt(np.sum(((field.grad - exact_grad(x)) ** 2).sum(0) * w)))


def solve_standard(mesh, support=2.0, order=1, solution=exact, source=load, measure=errors):
    basis = RKBasis(mesh, support=support, order=order)
    K, f, D = asm(laplace, basis.trial, basis), asm(source, basis), basis.get_dofs()
    return measure(basis, skfem_rkpm.solve(K, f, basis, D=D, x=solution(basis.nodes[:, D])))


def solve_plain(basis, solution=exact, source=load, measure=errors):
    """As a scikit-fem script: coefficients are nodal values."""
    K = asm(laplace, getattr(basis, "trial", basis), basis)
    D = basis.get_dofs()
    return measure(basis, solve(*condense(K, asm(source, basis), x=solution(basis.doflocs),
                                          D=D)))


def linear(x):
    return 1.0 + 2.0 * x[0] - 3.0 * x[1]


@LinearForm
def no_load(v, w):
    return 0.0 * v


def boundary_miss(basis, d, solution=exact):
    """Largest |u_h - u| at the boundary particles and at the facet midpoints."""
    D = basis.get_dofs()
    mesh = basis.mesh
    facets = mesh.facets[:, mesh.boundary_facets()]
    mid = 0.5 * (mesh.p[:, facets[0]] + mesh.p[:, facets[1]])
    at = lambda x: basis.probes(x) @ d - solution(x)  # noqa: E731
    return np.abs(at(basis.nodes[:, D])).max(), np.abs(at(mid)).max()


def field_miss(basis, d):
    """Largest |u_h - u| at the quadrature points for the linear u."""
    return (np.abs(np.asarray(basis.interpolate(d))
                   - linear(np.asarray(basis.global_coordinates()))).max(),)



def accuracy(sizes):
    print("| mesh | n | standard L² | standard H¹ | interpolating L² | interpolating H¹ "
          "| Q1 FEM L² | Q1 FEM H¹ |")
    print("|---|---|---|---|---|---|---|---|")
    for distortion in (0.0, 0.3):
        for n in sizes:
            mesh = square(n, distortion)
            cols = (solve_standard(mesh) + solve_plain(RKBasis(mesh, interpolating=True))
                    + solve_plain(Basis(mesh, ElementQuad1(), intorder=4)))
            label = "uniform" if not distortion else f"distorted {distortion}"
            print(f"| {label} | {n}² | " + " | ".join(f"{e:.2e}" for e in cols) + " |")


def boundary(n):
    print(f"\n{n}², uniform: | case | at boundary particles | at boundary facet midpoints "
          "| linear u, all boundary values prescribed: max error inside |")
    print("|---|---|---|---|")
    mesh = square(n)
    std = (solve_standard(mesh, measure=boundary_miss)
           + solve_standard(square(8, 0.3), solution=linear, source=no_load,
                            measure=field_miss))
    itp = (solve_plain(RKBasis(mesh, interpolating=True), measure=boundary_miss)
           + solve_plain(RKBasis(square(8, 0.3), interpolating=True), solution=linear,
                         source=no_load, measure=field_miss))
    naive = (solve_plain(RKBasis(mesh), measure=boundary_miss)
             + solve_plain(RKBasis(square(8, 0.3)), solution=linear, source=no_load,
                           measure=field_miss))
    for label, cols in (("standard, skfem_rkpm.solve", std),
                        ("interpolating, skfem.condense", itp),
                        ("standard, skfem.condense (fixes coefficients)", naive)):
        print(f"| {label} | " + " | ".join(f"{e:.1e}" for e in cols) + " |")


def second_order(sizes, support=2.5):
    print(f"\n| order 2, support {support} | n | standard L² | standard H¹ "
          "| interpolating L² | interpolating H¹ |")
    print("|---|---|---|---|---|---|")
    for n in sizes:
        mesh = square(n)
        cols = solve_standard(mesh, support, 2) + solve_plain(
            RKBasis(mesh, support=support, order=2, interpolating=True))
        print(f"| uniform | {n}² | " + " | ".join(f"{e:.2e}" for e in cols) + " |")


def supports(n):
    print("\n| normalized support | standard L² | standard H¹ | interpolating L² "
          "| interpolating H¹ |")
    print("|---|---|---|---|---|")
    mesh = square(n)
    for c in (1.5, 1.75, 2.0, 2.5, 3.0):
        cols = solve_standard(mesh, c) + solve_plain(RKBasis(mesh, support=c,
                                                             interpolating=True))
        print(f"| {c} | " + " | ".join(f"{e:.2e}" for e in cols) + " |")


def build_cost(sizes, cubes, repeat):
    print("\n| basis | particles | standard build (s) | interpolating build (s) | ratio "
          "| standard table, numpy (s) | interpolating table (s) | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    cases = [(f"square {n}², scalar", square(n), False) for n in sizes]
    cases += [(f"cube {n}³, vector", MeshHex.init_tensor(*[np.linspace(0, 1, n + 1)] * 3),
               True) for n in cubes]
    for label, mesh, vector in cases:
        std = median_cpu(lambda: RKBasis(mesh, vector=vector), repeat)[0]
        itp = median_cpu(lambda: RKBasis(mesh, vector=vector, interpolating=True), repeat)[0]
        x = np.asarray(RKBasis(mesh, integration="gauss").global_coordinates())
        x = x.reshape(mesh.dim(), -1)
        radius = 2.0 * local_spacing(mesh)
        t_std = median_cpu(lambda: rk_shape_functions(x, mesh.p, radius, backend="numpy"),
                           repeat)[0]
        t_itp = median_cpu(lambda: interpolating_shape_functions(x, mesh.p, radius), repeat)[0]
        print(f"| {label} | {mesh.nvertices} | {std:.3f} | {itp:.3f} | {itp / std:.2f} "
              f"| {t_std:.3f} | {t_itp:.3f} | {t_itp / t_std:.2f} |")


def cone(z):
    z = np.asarray(z, dtype=float)
    return np.where(z < 1, 1 - z, 0.0), np.where(z < 1, -1.0, 0.0)


def smoothstep(z):
    z = np.asarray(z, dtype=float)
    return (np.where(z < 1, 1 - 3 * z**2 + 2 * z**3, 0.0),
            np.where(z < 1, -6 * z + 6 * z**2, 0.0))


def singular(alpha):
    """The cubic window divided by z^α: infinite at its particle."""
    def window(z):
        z = np.asarray(z, dtype=float)
        phi, dphi = cubic_spline(z)
        with np.errstate(divide="ignore", invalid="ignore"):
            return phi / z**alpha, dphi / z**alpha - alpha * phi / z**(alpha + 1)
    return window


def constructions(sizes):
    print("\n| construction (interpolant of u) | n | L² | H¹ |")
    print("|---|---|---|---|")
    for n in sizes:
        mesh = square(n)
        x = np.asarray(RKBasis(mesh, integration="gauss", intorder=6)
                       .global_coordinates()).reshape(2, -1)
        w = RKBasis(mesh, integration="gauss", intorder=6).dx.ravel()
        radius = 2.0 * local_spacing(mesh)
        d = primitive_radius(mesh.p, radius)
        cases = [("standard RK (not interpolating)",
                  lambda: rk_shape_functions(x, mesh.p, radius, backend="numpy"))]
        for label, window in (("cubic", None), ("quartic", "quartic"), ("cone 1 - z", cone),
                              ("smoothstep", smoothstep)):
            cases.append((f"Chen 2003, primitive {label}, radius d_K",
                          lambda window=window: interpolating_shape_functions(
                              x, mesh.p, radius, primitive_window=window)))
        for fraction in (0.75, 0.5):
            cases.append((f"Chen 2003, primitive cubic, radius {fraction} d_K",
                          lambda fraction=fraction: interpolating_shape_functions(
                              x, mesh.p, radius, primitive=fraction * d)))
        for alpha in (2, 4):
            cases.append((f"interpolating MLS, weight φ/z^{alpha}",
                          lambda alpha=alpha: rk_shape_functions(
                              x, mesh.p, radius, kernel=singular(alpha), backend="numpy",
                              rcond_min=0.0)))
        u = exact(mesh.p)
        for label, build in cases:
            table = build()
            value = table.matrix() @ u
            grad = np.array([table.gradient_matrix(k) @ u for k in range(2)])
            l2 = np.sqrt(np.sum((value - exact(x)) ** 2 * w))
            h1 = np.sqrt(np.sum(((grad - exact_grad(x)) ** 2).sum(0) * w))
            print(f"| {label} | {n}² | {l2:.2e} | {h1:.2e} |")


def accuracy_3d(sizes):
    """The same problem on n³ hexahedra of the unit cube (u does not depend
    on z, so f is the same); forms through ``skfem_rkpm.asm``."""
    print("\n| mesh | n | standard L² | standard H¹ | interpolating L² | interpolating H¹ "
          "| Q1 FEM L² | Q1 FEM H¹ |")
    print("|---|---|---|---|---|---|---|---|")

    def errors3(basis, d):
        field = basis.interpolate(d)
        x = np.asarray(basis.global_coordinates())
        gradient = np.concatenate([exact_grad(x), np.zeros((1,) + x.shape[1:])])
        return (np.sqrt(np.sum((np.asarray(field) - exact(x)) ** 2 * basis.dx)),
                np.sqrt(np.sum(((field.grad - gradient) ** 2).sum(0) * basis.dx)))

    for n in sizes:
        mesh = MeshHex.init_tensor(*[np.linspace(0, 1, n + 1)] * 3)
        cols = []
        for basis in (RKBasis(mesh), RKBasis(mesh, interpolating=True),
                      Basis(mesh, skfem.ElementHex1(), intorder=4)):
            K = skfem_rkpm.asm(laplace, getattr(basis, "trial", basis), basis)
            f, D = skfem_rkpm.asm(load, basis), basis.get_dofs()
            if getattr(basis, "interpolating", True):
                d = solve(*condense(K, f, x=exact(basis.doflocs), D=D))
            else:
                d = skfem_rkpm.solve(K, f, basis, D=D, x=exact(basis.nodes[:, D]))
            cols += errors3(basis, d)
        print(f"| cube | {n}³ | " + " | ".join(f"{e:.2e}" for e in cols) + " |")


def primitive_fractions(sizes):
    """Galerkin errors with the primitive radii scaled by a fraction of the
    default (not an option of RKBasis: patched in for this measurement)."""
    from unittest import mock

    import skfem_rkpm.approximation.basis as basis_module

    print("\n| primitive radius | mesh | n | L² | H¹ |")
    print("|---|---|---|---|---|")
    for fraction in (1.0, 0.75, 0.5):
        def scaled(flag, nodes, radius, fraction=fraction):
            return fraction * primitive_radius(nodes, radius) if flag else None
        with mock.patch.object(basis_module, "basis_primitive_radius", scaled):
            for distortion in (0.0, 0.3):
                for n in sizes:
                    cols = solve_plain(RKBasis(square(n, distortion), interpolating=True))
                    label = "uniform" if not distortion else f"distorted {distortion}"
                    print(f"| {fraction} d_K | {label} | {n}² | "
                          + " | ".join(f"{e:.2e}" for e in cols) + " |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} (1 min)\n")
    accuracy((16, 32, 64))
    accuracy_3d((4, 8, 12))
    boundary(32)
    second_order((16, 32, 64))
    supports(32)
    build_cost((32, 64, 128), (6, 10), args.repeat)
    constructions((32, 64))
    primitive_fractions((32, 64))


if __name__ == "__main__":
    main()
