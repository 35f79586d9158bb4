"""The RK basis built in parts on 1, 2 and 4 MPI ranks: time and memory per rank.

A unit square (``--dim 2``, quadrilaterals) or cube (``--dim 3``,
hexahedra) of ``--cells`` cells per side, particles at the vertices, RK
order 1, radial cubic supports of ``--support`` spacings, VCI, Gauss rule
of degree ``--intorder``.  Each rank builds its part of the basis
(``RKBasis(..., elements=its cells, reduction=MPIReduction())``: shape
functions at its own points, VCI sums added over the ranks).  Reported per
rank: the seconds of the build (wall, slowest rank), and the peak resident
memory of the whole process (VmHWM: imports and the mesh included), the
largest over the ranks.  Each ``--ranks`` P is one ``mpiexec -n P`` run
(more ranks than cores oversubscribe them).

The defaults are ``RKBasis(MeshHex, vector=True)``'s: support 2, degree 4
(27 Gauss points per hexahedron).

Run:  python benchmarks/partitioned_basis.py --dim 3 --cells 46 --ranks 1 2 4
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
from _timing import resident_mb
from partitioned_scaling import launch, mpi_environment


def worker(args):
    from mpi4py import MPI
    from skfem import ElementHex1, ElementQuad1, ElementVector, MeshHex, MeshQuad

    from skfem_rkpm import RKBasis
    from skfem_rkpm.solvers.partitioned import MPIReduction, partition

    comm = MPI.COMM_WORLD
    mesh_type, element = (MeshQuad, ElementQuad1()) if args.dim == 2 else (MeshHex,
                                                                          ElementHex1())
    mesh = mesh_type.init_tensor(*[np.linspace(0.0, 1.0, args.cells + 1)] * args.dim)
    parts = partition(mesh, comm.Get_size())
    comm.Barrier()
    clock = time.perf_counter()
    basis = RKBasis(mesh, ElementVector(element), support=args.support,
                    intorder=args.intorder, elements=parts.cells_of(comm.Get_rank()),
                    reduction=MPIReduction(comm))
    seconds = time.perf_counter() - clock
    reports = comm.gather(dict(seconds=seconds, peak_mb=resident_mb(), cells=int(basis.nelems),
                               pairs=basis.npairs,
                               particles=int(mesh.nvertices)), root=0)
    if comm.Get_rank() == 0:
        print(json.dumps(reports))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, choices=(2, 3), default=3)
    parser.add_argument("--cells", type=int, default=46)
    parser.add_argument("--support", type=float, default=2.0)
    parser.add_argument("--intorder", type=int, default=4)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    env = mpi_environment()
    print(f"{args.dim}D, {args.cells} cells per side, support {args.support}, intorder "
          f"{args.intorder}; load {os.getloadavg()[0]:.1f} at the start")
    print("| P | particles | cells per rank | point-particle pairs per rank (max) "
          "| build s | peak MB per rank (max) | sum of the peaks MB |")
    for ranks in args.ranks:
        done = subprocess.run([*launch(ranks), sys.executable, os.path.abspath(__file__),
                               "--worker", "--dim", str(args.dim), "--cells", str(args.cells),
                               "--support", str(args.support),
                               "--intorder", str(args.intorder)],
                              capture_output=True, text=True, env=env)
        if done.returncode != 0:
            print(f"P = {ranks} failed: {done.stderr[-1500:]}")
            continue
        reports = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"| {ranks} | {reports[0]['particles']:,} | "
              f"{min(r['cells'] for r in reports):,}-{max(r['cells'] for r in reports):,} | "
              f"{max(r['pairs'] for r in reports):,} | "
              f"{max(r['seconds'] for r in reports):.1f} | "
              f"{max(r['peak_mb'] for r in reports):,.0f} | "
              f"{sum(r['peak_mb'] for r in reports):,.0f} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
