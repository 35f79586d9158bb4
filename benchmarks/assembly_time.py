"""Stiffness assembly time: RK basis vs bilinear FEM on the same meshes.

Vector linear elasticity (E = 1, ν = 0.3) on ``MeshQuad.init_tensor``
meshes of the unit square with 20², 40², 80² and 160² cells:

* RK: ``RKBasis(mesh, vector=True, support=2.0, intorder=4)`` (VCI test
  gradients), plus the same basis with ``intorder=2``, i.e. the quadrature
  of the FEM basis;
* FEM: ``Basis(mesh, ElementVector(ElementQuad1()), intorder=2)``.

Measured per basis: construction of the basis, construction of
``skfem_rkpm.Assembler`` (sparsity pattern and scatter map), and
``Assembler.bilinear(isotropic_tangent(λ, μ, 2))``.  Each is run three
times and the fastest run is reported (on virtual machines the first touch
of fresh memory can make single runs several times slower).  On the two
smallest meshes scikit-fem's own ``asm`` with ``linear_elasticity`` is timed
as well and its matrix compared with the vectorized one.  Times are CPU
seconds of the process by default (``--clock cpu``, ``time.process_time``):
for this single-threaded work they equal the wall time on an idle machine
and do not grow when other processes share the cores; ``--clock wall``
measures elapsed time instead.

``--tangents`` adds a table of ``bilinear`` alone for the other tangent
layouts it supports: a tangent per quadrature point (as in the Newton
solver), the axisymmetric gradient with its hoop row, and 3D cells
(tetrahedra and hexahedra, scalar and vector fields).

Run:  python benchmarks/assembly_time.py              (~1-2 minutes)
      python benchmarks/assembly_time.py --sizes 20 40
      python benchmarks/assembly_time.py --sizes 160 --tangents
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import inspect  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import skfem  # noqa: E402
from skfem import (Basis, ElementQuad1, ElementVector, MeshHex, MeshQuad,  # noqa: E402
                   MeshTet, asm)
from skfem.models.elasticity import lame_parameters, linear_elasticity  # noqa: E402

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent  # noqa: E402

SKFEM_ASM_MAX_CELLS = 40 * 40
CLOCKS = {"cpu": time.process_time, "wall": time.perf_counter}
clock = CLOCKS["cpu"]


def best_of(n, f):
    """Run ``f`` n times; return (fastest time, last result)."""
    times = []
    for _ in range(n):
        t = clock()
        out = f()
        times.append(clock() - t)
    return min(times), out


def rk_default_intorder():
    return inspect.signature(RKBasis.__init__).parameters["intorder"].default


def variants():
    """(label, kind, factory(mesh)) of the bases compared."""
    default = rk_default_intorder()
    label4 = "RK c=2, intorder 4" + (" (default)" if default == 4 else "")
    out = [
        (label4, "rk", lambda m: RKBasis(m, vector=True, support=2.0, intorder=4)),
        ("RK c=2, intorder 2", "rk",
         lambda m: RKBasis(m, vector=True, support=2.0, intorder=2)),
        ("FEM Q1, intorder 2", "fem",
         lambda m: Basis(m, ElementVector(ElementQuad1()), intorder=2)),
    ]
    if default not in (2, 4):
        out.insert(1, (f"RK c=2, default (intorder {default})", "rk",
                       lambda m: RKBasis(m, vector=True, support=2.0)))
    return out


def measure(n, label, kind, factory, lam, mu):
    t = np.linspace(0.0, 1.0, n + 1)
    mesh = MeshQuad.init_tensor(t, t)
    t_basis, basis = best_of(3, lambda: factory(mesh))
    t_init, assembler = best_of(3, lambda: Assembler(basis))
    C = isotropic_tangent(lam, mu, 2)
    t_bil, K = best_of(3, lambda: assembler.bilinear(C))
    nqp = basis.X.shape[-1]
    nloc = assembler.layout.element_nodes.shape[0]
    r = dict(cells=mesh.nelements, label=label, kind=kind, dofs=assembler.N,
             nqp=nqp, nbf=nloc * assembler.layout.ncomp, t_basis=t_basis,
             t_init=t_init, t_bil=t_bil, nnz_row=assembler.nnz / assembler.N,
             t_asm=None, diff=None)
    if mesh.nelements <= SKFEM_ASM_MAX_CELLS:
        form = linear_elasticity(lam, mu)
        if kind == "rk":
            t_asm, Ks = best_of(2, lambda: asm(form, basis.trial, basis))
        else:
            t_asm, Ks = best_of(2, lambda: asm(form, basis))
        r["t_asm"] = t_asm
        r["diff"] = abs(Ks - K).max() / abs(K).max()
    r["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return r


def tangent_cases(lam, mu):
    """(label, factory() -> (basis, axisymmetric, C, per point?)) of the extra cases."""
    t = np.linspace(0.0, 1.0, 161)
    quad = MeshQuad.init_tensor(t, t)
    ring = MeshQuad.init_tensor(1.0 + t, t)  # x is the radius, away from the axis
    tets = MeshTet.init_tensor(*[np.linspace(0.0, 1.0, 6)] * 3)
    hexes = MeshHex.init_tensor(*[np.linspace(0.0, 1.0, 9)] * 3)

    def plane():
        b = RKBasis(quad, vector=True, support=2.0, intorder=4)
        return b, False, isotropic_tangent(lam, mu, 2), True

    def axisymmetric():
        b = RKBasis(ring, vector=True, support=2.0, intorder=4)
        # components r, z; gradient rows r, z and the hoop row
        return b, True, isotropic_tangent(lam, mu, 3)[:2, :, :2, :], True

    def scalar3d(mesh):
        b = RKBasis(mesh, support=2.0, intorder=2)
        return b, False, np.eye(3)[None, :, None, :], False

    def vector3d(mesh):
        b = RKBasis(mesh, vector=True, support=2.0, intorder=2)
        return b, False, isotropic_tangent(lam, mu, 3), False

    return [
        ("160² quads, RK vector, tangent per point", plane),
        ("160² quads, RK vector, axisymmetric, tangent per point", axisymmetric),
        ("5³·6 tetrahedra, RK scalar", lambda: scalar3d(tets)),
        ("5³·6 tetrahedra, RK vector", lambda: vector3d(tets)),
        ("8³ hexahedra, RK vector", lambda: vector3d(hexes)),
    ]


def measure_tangents(lam, mu):
    print()
    print("bilinear with other tangent layouts (best of 3):")
    print()
    head = "| case | cells | local fns | qp/cell | gradient rows | bilinear s |"
    print(head)
    print("|" + "---|" * (head.count(" | ") + 1))
    rng = np.random.default_rng(0)
    for label, factory in tangent_cases(lam, mu):
        basis, axisymmetric, C, per_point = factory()
        assembler = Assembler(basis, axisymmetric=axisymmetric)
        L = assembler.layout
        if per_point:  # (c, l, c, m, nelems, nqp), varying like a plastic tangent
            C = C[..., None, None] * (1.0 + 0.1 * rng.uniform(size=L.dx.shape))
        t_bil, _ = best_of(3, lambda: assembler.bilinear(C))
        nloc, nelems = L.element_nodes.shape
        print(f"| {label} | {nelems:,} | {nloc * L.ncomp} | {L.dx.shape[1]} | "
              f"{L.dim} | {t_bil:.4f} |", flush=True)


HEADER = ("| cells | basis | dofs | qp/cell | local fns | basis s | Assembler s | "
          "bilinear s | nnz/row | skfem asm s | asm / bilinear | rel. diff | "
          "peak RSS MB |")


def row(r):
    asm_s = "" if r["t_asm"] is None else f"{r['t_asm']:.3f}"
    gain = "" if r["t_asm"] is None else f"{r['t_asm'] / r['t_bil']:.0f}x"
    diff = "" if r["diff"] is None else f"{r['diff']:.0e}"
    return (f"| {r['cells']:,} | {r['label']} | {r['dofs']:,} | {r['nqp']} | "
            f"{r['nbf']} | {r['t_basis']:.3f} | {r['t_init']:.3f} | "
            f"{r['t_bil']:.4f} | {r['nnz_row']:.1f} | {asm_s} | {gain} | {diff} | "
            f"{r['peak_mb']:.0f} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 80, 160],
                        help="cells per side (default 20 40 80 160)")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="cpu",
                        help="cpu: process CPU time (default); wall: elapsed time")
    parser.add_argument("--tangents", action="store_true",
                        help="also time bilinear with other tangent layouts")
    args = parser.parse_args()
    global clock
    clock = CLOCKS[args.clock]
    lam, mu = lame_parameters(1.0, 0.3)

    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"scipy {scipy.__version__}, scikit-fem {skfem.__version__}, "
          f"{os.cpu_count()} cores visible, OMP/OPENBLAS/MKL_NUM_THREADS=1")
    print("vector linear elasticity, E = 1, nu = 0.3; local fns = vector local "
          "functions per cell (padded); rel. diff = max|K_asm - K| / max|K|; "
          f"{args.clock} clock")
    print()
    print(HEADER)
    print("|" + "---|" * (HEADER.count(" | ") + 1))
    results = []
    for n in args.sizes:
        for label, kind, factory in variants():
            r = measure(n, label, kind, factory, lam, mu)
            results.append(r)
            print(row(r), flush=True)

    print()
    print("RK / FEM ratios (same mesh):")
    print()
    head = ("| cells | RK basis | basis | Assembler | bilinear | "
            "basis + Assembler + bilinear | nnz/row |")
    print(head)
    print("|" + "---|" * (head.count(" | ") + 1))
    for n in args.sizes:
        same = [r for r in results if r["cells"] == n * n]
        fem = next(r for r in same if r["kind"] == "fem")
        for rk in (r for r in same if r["kind"] == "rk"):
            total_rk = rk["t_basis"] + rk["t_init"] + rk["t_bil"]
            total_fem = fem["t_basis"] + fem["t_init"] + fem["t_bil"]
            print(f"| {n * n:,} | {rk['label']} | {rk['t_basis'] / fem['t_basis']:.0f} | "
                  f"{rk['t_init'] / fem['t_init']:.0f} | "
                  f"{rk['t_bil'] / fem['t_bil']:.0f} | {total_rk / total_fem:.0f} | "
                  f"{rk['nnz_row'] / fem['nnz_row']:.1f} |")
    if args.tangents:
        measure_tangents(lam, mu)


if __name__ == "__main__":
    main()
