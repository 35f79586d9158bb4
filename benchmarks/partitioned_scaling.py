"""Partitioned assembly on 1, 2 and 4 MPI ranks: time, memory and messages per rank.

The problem: plastic upsetting of a square block (plane strain, J2 with
linear hardening, F-bar) between rough platens, the top moved down by ``--compression`` (3 %)
in ``--steps`` load steps (3), Newton to the paper's tolerance 1e-6; RK basis of order 1, radial cubic supports of
``--support`` nodal spacings, VCI, ``--cells`` x ``--cells`` cells (about
``cells²`` particles).  Each rank builds its part of the basis, updates its
material points and assembles its cells (skfem_rkpm.solvers.partitioned);
PETSc's MUMPS factors the summed tangent.

Every rank reports, for its whole process (imports included): CPU seconds
(user + system), peak resident memory (VmHWM), the seconds of the basis
build and of the Newton steps, its cells, the tangent entries it assembles
and how many of them belong to rows of other ranks (sent by PETSc's COO
assembly), and the bytes it contributes to the sums over the ranks per
Newton iteration (the internal force and the tangent's diagonal are
vectors of all dofs).  The driver runs ``mpiexec -n P`` for each ``--ranks``
P (more ranks than cores oversubscribe them: the time per rank then
includes waiting for a core), checks that the final coefficients of every
P agree with those of the first, and prints one table row per P.

Run:  python benchmarks/partitioned_scaling.py --cells 100 --ranks 1 2 4
      SKFEM_RKPM_MPIEXEC=/path/to/mpiexec python benchmarks/partitioned_scaling.py

Needs petsc4py and mpi4py built for the same MPI (bash .ci/run-mpi).
"""

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time

import numpy as np
from _timing import resident_mb


def cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def worker(args):
    from mpi4py import MPI
    from skfem import ElementQuad1, ElementVector

    from skfem_rkpm import RKBasis
    from skfem_rkpm.mechanics.materials import J2Material, linear
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import rectangle
    from skfem_rkpm.solvers.newton import Prescribed, newton_steps
    from skfem_rkpm.solvers.partitioned import (DistributedLU, MPIReduction,
                                                PartitionedSolid, partition)

    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    mesh = rectangle(1.0, 1.0, args.cells, args.cells)
    parts = partition(mesh, size)
    reduction = MPIReduction(comm)
    clock = time.perf_counter()
    basis = RKBasis(mesh, ElementVector(ElementQuad1()), support=args.support,
                    elements=parts.cells_of(rank), reduction=reduction)
    build = time.perf_counter() - clock
    problem = SolidProblem(basis, J2Material(200e3, 0.3, linear(250.0, 1000.0)),
                           "plane_strain", locking="fbar")
    solid = PartitionedSolid(problem, reduction, rank)
    conditions = [Prescribed("bottom", 0), Prescribed("bottom", 1),
                  Prescribed("top", 0), Prescribed("top", 1, -args.compression)]
    solver = DistributedLU(parts, reduction)
    clock = time.perf_counter()
    result = newton_steps(solid, conditions, steps=args.steps, tol=1e-6,
                          linear_solver=solver)
    newton = time.perf_counter() - clock
    K = problem.assembler.matrix(problem._local).tocoo() if problem._local is not None else None
    owner = parts.dof_owners(2)
    entries = 0 if K is None else K.nnz
    remote = 0 if K is None else int(np.sum(owner[K.row] != rank))
    report = dict(rank=rank, ranks=size, cpu=cpu_seconds(), peak_mb=resident_mb(), build=build,
                  newton=newton, cells=int(basis.nelems), points=int(problem.npoints),
                  entries=int(entries), remote_entries=remote,
                  iterations=sum(r.spent_iterations for r in result.history),
                  completed=bool(result.completed), dofs=int(problem.N),
                  sum_bytes_per_iteration=int(2 * 8 * problem.N),
                  factor_seconds=solver.stats["factor_seconds"],
                  factorizations=solver.stats["factorizations"])
    reports = comm.gather(report, root=0)
    if rank == 0:
        np.save(args.out, result.d)
        print(json.dumps(reports))


def mpiexec():
    return os.environ.get("SKFEM_RKPM_MPIEXEC") or shutil.which("mpiexec")


def mpi_environment():
    """One BLAS thread per rank; Open MPI allowed to start as root."""
    return dict(os.environ, OPENBLAS_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
                OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def launch(ranks):
    text = subprocess.run([mpiexec(), "--version"], capture_output=True, text=True)
    text = text.stdout + text.stderr
    extra = ["--oversubscribe"] if "Open MPI" in text or "OpenRTE" in text else []
    return [mpiexec(), *extra, "-n", str(ranks)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=100)
    parser.add_argument("--support", type=float, default=2.0)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--compression", type=float, default=0.03,
                        help="top displacement over the block's height")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", default="partitioned_d.npy", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    env = mpi_environment()
    first = None
    print(f"upsetting, {args.cells}x{args.cells} cells, support {args.support}, "
          f"{args.compression:.0%} in {args.steps} steps; load {os.getloadavg()[0]:.1f} at the start")
    print("| P | dofs | cells/rank | CPU s/rank (max) | peak MB/rank (max) | sum of peaks MB "
          "| basis s | Newton s | iterations | factor s | remote entries % | Δd vs first P |")
    for ranks in args.ranks:
        out = f"/tmp/partitioned_d_{ranks}.npy"
        command = [*launch(ranks), sys.executable, os.path.abspath(__file__), "--worker",
                   "--cells", str(args.cells), "--support", str(args.support),
                   "--steps", str(args.steps), "--compression", str(args.compression),
                   "--out", out]
        done = subprocess.run(command, capture_output=True, text=True, env=env)
        if done.returncode != 0:
            print(f"P = {ranks} failed: {done.stderr[-2000:]}")
            continue
        reports = json.loads(done.stdout.strip().splitlines()[-1])
        d = np.load(out)
        first = d if first is None else first
        diff = np.abs(d - first).max() / np.abs(first).max()
        print(f"| {ranks} | {reports[0]['dofs']} | "
              f"{min(r['cells'] for r in reports)}-{max(r['cells'] for r in reports)} | "
              f"{max(r['cpu'] for r in reports):.1f} | {max(r['peak_mb'] for r in reports):.0f} | "
              f"{sum(r['peak_mb'] for r in reports):.0f} | "
              f"{max(r['build'] for r in reports):.1f} | {max(r['newton'] for r in reports):.1f} | "
              f"{reports[0]['iterations']} | {max(r['factor_seconds'] for r in reports):.1f} | "
              f"{100 * sum(r['remote_entries'] for r in reports) / max(sum(r['entries'] for r in reports), 1):.1f} | "
              f"{diff:.1e} |")
        sys.stdout.flush()
        with open(f"/tmp/partitioned_reports_{ranks}.json", "w") as handle:
            json.dump(reports, handle)


if __name__ == "__main__":
    main()
