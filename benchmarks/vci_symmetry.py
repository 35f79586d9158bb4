"""Symmetric VCI against the default VCI: accuracy, symmetry and build time.

For the elasticity convergence studies of ``skfem_rkpm.verification.studies``
(Timoshenko's cantilever on quadrilaterals and on triangles, Kirsch's plate
with a hole on triangles), order-1 RK bases with ``integration="vci"`` (the
default: corrected test gradients, exact trial gradients, Petrov-Galerkin)
and ``integration="vci_symmetric"`` (corrected gradients on both sides) are
solved at the same refinement levels and supports; the table lists the
relative L² and energy errors and the ratio symmetric / default.  A second
table gives the CPU time (``time.process_time``, median of ``--repeat``) of
the basis construction on a 100² quadrilateral mesh and on ``MeshTet
().refined(3)``, and |K - Kᵀ| / |K| of the Laplace matrix.

Run:  python benchmarks/vci_symmetry.py                 (~6 minutes)
      python benchmarks/vci_symmetry.py --levels 4 8 --supports 2
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from skfem import MeshQuad, MeshTet  # noqa: E402
from skfem.models import laplace  # noqa: E402

import skfem_rkpm  # noqa: E402
from skfem_rkpm import RKBasis  # noqa: E402
from skfem_rkpm.verification import (convergence_study, plate_with_hole,  # noqa: E402
                                     timoshenko_beam)

SCHEMES = ("vci", "vci_symmetric")


def accuracy(args):
    problems = [("Timoshenko, quads", timoshenko_beam(), args.levels),
                ("Timoshenko, triangles", timoshenko_beam(kind="tri"), args.levels),
                ("Kirsch, triangles", plate_with_hole(), args.levels)]
    print("| problem | c | level | dofs | L2 vci | L2 symmetric | ratio | energy vci "
          "| energy symmetric | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, problem, levels in problems:
        methods = {(c, s): (lambda c, s: lambda m: RKBasis(
            m, vector=True, support=c, integration=s))(c, s)
            for c in args.supports for s in SCHEMES}
        records = convergence_study(problem, methods, levels)
        by = {(r["method"], r["level"]): r for r in records}
        for c in args.supports:
            for level in levels:
                a, b = by[((c, "vci"), level)], by[((c, "vci_symmetric"), level)]
                print(f"| {name} | {c:g} | {level} | {a['dofs']} | {a['l2']:.3e} "
                      f"| {b['l2']:.3e} | {b['l2'] / a['l2']:.3f} | {a['energy']:.3e} "
                      f"| {b['energy']:.3e} | {b['energy'] / a['energy']:.4f} |")
    print()


def build_time(args):
    meshes = [("2D quads 100x100", MeshQuad.init_tensor(np.linspace(0, 1, 101),
                                                         np.linspace(0, 1, 101))),
              ("3D MeshTet().refined(3)", MeshTet().refined(3))]
    print(f"| mesh | integration | build CPU s (median of {args.repeat}) "
          "| K Laplace: max|K - Kᵀ| / max|K| |")
    print("|---|---|---|---|")
    for label, mesh in meshes:
        for scheme in SCHEMES:
            times = []
            for _ in range(args.repeat):
                t = time.process_time()
                basis = RKBasis(mesh, integration=scheme)
                times.append(time.process_time() - t)
            K = skfem_rkpm.asm(laplace, basis.trial, basis)
            asym = abs(K - K.T).max() / abs(K).max()
            print(f"| {label} | {scheme} | {np.median(times):.2f} | {asym:.1e} |")
    print()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[4, 8, 16])
    parser.add_argument("--supports", type=float, nargs="+", default=[1.5, 2.0, 3.0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()}")
    print()
    build_time(args)
    accuracy(args)


if __name__ == "__main__":
    main()
