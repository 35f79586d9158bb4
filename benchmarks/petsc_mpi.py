"""PETSc (MUMPS) against the serial solvers, and 1 against 2 MPI ranks.

Two parts, both on the ring scene (``skfem-rkpm run ring``: axisymmetric,
box supports of 3 particle spacings, 16 Gauss points per cell, friction
0.15, J2 perfect plasticity, rigid platen):

* *paper resolution* (15 x 10 cells, 352 unknowns): the ring is compressed
  by 10 of its 100 load steps, then the linear solve of one Newton iteration
  (``solve_constrained(K + K_c, r, C, g)``) is timed with ``dense``,
  ``superlu`` and ``petsc`` (MUMPS, one process): the first call (with
  PETSc's symbolic analysis) and the fastest of ``--repeat`` further calls
  with the kept solver (same pattern, the case of every Newton iteration
  after the first);
* *refined rings* (``--sizes``: cells in x, the y cells and the support
  scale with it; default 50 and 160 cells: 1,734 and 17,227 particles,
  9.9 and 98 times the paper's 176): the first ``--steps`` load steps of
  the 100 (default 1), run with ``superlu`` on one process, and with
  ``petsc`` under ``mpiexec -n 1`` and ``mpiexec -n 2``.  Reported: Newton
  iterations (and cut-backs), the seconds per linear solve (analysis + factorization +
  solves with refinement, over the factorizations, on rank 0), the wall
  time of the steps, and the largest difference of the final
  displacements and the final platen force between the runs, relative to
  their largest value.

Only the linear solve is distributed: assembly and material updates are
replicated on every rank, so the whole-run time cannot fall by more than
the solve's share.

Run:  python benchmarks/petsc_mpi.py --sizes 50      (~2 minutes)
      python benchmarks/petsc_mpi.py --sizes 160 --skip-paper --no-superlu
                                                     (~45 minutes on 2 cores)
      python benchmarks/petsc_mpi.py                 (adds SuperLU at 160 cells:
                                                      over 20 minutes, 6 GB)
      SKFEM_RKPM_MPIEXEC=/path/to/mpiexec python benchmarks/petsc_mpi.py

Needs petsc4py built with MPI (docs/benchmarks/partitioned.md, "PETSc and MPI").
"""

import os

# one core per process: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402


def ring(cells=15, overrides=()):
    """The ring scene with ``cells`` cells in x (the paper: 15)."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    ny = int(round(cells * 10 / 15))
    settings = [f"geometry.divisions=[{cells},{ny}]",
                f"discretization.support={6.0 * 15 / cells:.6g}",
                "output.fields=false", "output.figures=false", *overrides]
    return runner.build(load_scene(builtin_scenes()["ring"], settings))


def steps(sim, count, solver):
    """The first ``count`` of the 100 load steps: (result, wall seconds)."""
    from skfem_rkpm.solvers.newton import newton_steps

    targets = np.linspace(0.0, 1.0, sim.scene["steps"]["count"] + 1)[1:count + 1]
    start = time.perf_counter()
    result = newton_steps(sim.problem, sim.prescribed, load=sim.load, steps=targets,
                          contributions=sim.tools, linear_solver=solver)
    wall = time.perf_counter() - start
    if not result.completed:
        raise RuntimeError(result.message)
    return result, wall


# -- paper resolution ----------------------------------------------------
def paper(args):
    from skfem_rkpm.solvers.constrained import solve_constrained
    from skfem_rkpm.solvers.linear import make_solver

    sim = ring()
    result, _ = steps(sim, 10, "auto")
    d = 2 * result.solutions[-1] - result.solutions[-2]
    t = 0.11
    ev = sim.problem.evaluate(d)
    K, f = ev.K, -ev.f_int
    for tool in sim.tools:
        f_c, K_c = tool.evaluate(d, t)
        K, f = K + K_c, f - f_c
    groups = [p.constraint(sim.problem.basis) for p in sim.prescribed]
    C = sp.vstack([g.C for g in groups] or [sp.csr_matrix((0, K.shape[0]))], format="csr")
    g = np.zeros(C.shape[0])
    print(f"Ring at paper resolution ({K.shape[0]} unknowns, {C.shape[0]} constraints, "
          f"{K.nnz / K.shape[0]:.0f} nonzeros per row), the solve of one Newton iteration "
          f"after 10 load steps (wall ms, fastest of {args.repeat} with the kept solver):\n")
    print("| backend | first call ms | per iteration ms | max |x - x_dense| / max |x_dense| |")
    print("|---|---:|---:|---:|")
    reference = None
    for name in ("dense", "superlu", "petsc"):
        solver = make_solver(name, points=sim.basis.doflocs) if name == "petsc" else \
            make_solver(name)
        start = time.perf_counter()
        x, _ = solve_constrained(K, f, C, g, solver=solver)
        first = time.perf_counter() - start
        best = np.inf
        for _ in range(args.repeat):
            start = time.perf_counter()
            x, _ = solve_constrained(K, f, C, g, solver=solver)
            best = min(best, time.perf_counter() - start)
        reference = x if reference is None else reference
        diff = np.abs(x - reference).max() / np.abs(reference).max()
        print(f"| {solver.describe()} | {1e3 * first:.2f} | {1e3 * best:.2f} | {diff:.1e} |")


# -- refined rings on 1 and 2 ranks ---------------------------------------
def worker(args):
    """One run (possibly one MPI rank of it); rank 0 writes a JSON record."""
    from skfem_rkpm.solvers.petsc import is_root, world
    from skfem_rkpm.solvers.linear import make_solver

    clock = time.perf_counter()
    sim = ring(args.cells)
    built = time.perf_counter() - clock
    solver = (make_solver(args.solver, points=sim.basis.doflocs)
              if args.solver.startswith("petsc") else make_solver(args.solver))
    result, wall = steps(sim, args.steps, solver)
    stats = solver.stats
    seconds = stats["analyze_seconds"] + stats["factor_seconds"] + stats["solve_seconds"]
    if is_root():
        force = np.atleast_1d(result.history[-1].reactions[sim.tools[0].name])
        record = dict(cells=args.cells, particles=sim.basis.N // 2, dofs=sim.basis.N,
                      solver=solver.describe(), ranks=world()[1], build=built, wall=wall,
                      iterations=sum(r.iterations for r in result.history),
                      records=len(result.history),
                      factorizations=stats["factorizations"], solve_seconds=seconds,
                      per_solve=seconds / max(stats["factorizations"], 1),
                      partition=[int(n) for n in getattr(solver, "partition", [])])
        Path(args.record).write_text(json.dumps(record))
        np.save(Path(args.record).with_suffix(".npy"), np.concatenate(
            [result.solutions[-1], force.ravel()]))


def mpiexec():
    found = os.environ.get("SKFEM_RKPM_MPIEXEC") or shutil.which("mpiexec")
    if found is None:
        sys.exit("no mpiexec on PATH (set SKFEM_RKPM_MPIEXEC)")
    return found


def launch(cells, count, solver, ranks, folder):
    record = Path(folder) / f"{cells}-{solver}-{ranks}.json"
    command = [sys.executable, __file__, "--worker", "--cells", str(cells), "--steps",
               str(count), "--solver", solver, "--record", str(record)]
    if ranks:
        command = [mpiexec(), "-n", str(ranks), *command]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    start = time.perf_counter()
    subprocess.run(command, check=True, env=env)
    total = time.perf_counter() - start
    data = json.loads(record.read_text())
    data["process"] = total
    data["result"] = np.load(record.with_suffix(".npy"))
    return data


def refined(args):
    print(f"\nRefined rings, the first {args.steps} of 100 load steps (wall seconds; "
          f"*per solve*: analysis + factorization + solves over the factorizations, "
          f"rank 0; *steps*: the load steps; *process*: the whole command with start-up, "
          f"model set-up and MPI launch):\n")
    print("| cells | particles | dofs | solver | ranks | Newton its | per solve s "
          "| steps s | process s | max diff vs 1 rank |")
    print("|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as folder:
        for cells in args.sizes:
            runs = [("petsc", 1), ("petsc", 2)]
            if not args.no_superlu:
                runs.insert(0, ("superlu", 0))
            records = [launch(cells, args.steps, s, n, folder) for s, n in runs]
            one = records[-2]["result"]  # petsc, 1 rank
            n = records[-2]["dofs"]
            for data in records:
                x = data["result"]
                dd = np.abs(x[:n] - one[:n]).max() / np.abs(one[:n]).max()
                df = np.abs(x[n:] - one[n:]).max() / np.abs(one[n:]).max()
                cuts = f" ({data['records'] - args.steps} cut)" if data["records"] > args.steps \
                    else ""
                part = f" ({'+'.join(map(str, data['partition']))} rows)" \
                    if len(data["partition"]) > 1 else ""
                print(f"| {cells} | {data['particles']:,} | {data['dofs']:,} | "
                      f"{data['solver']}{part} | {data['ranks'] if data['ranks'] else 1} | "
                      f"{data['iterations']}{cuts} | {data['per_solve']:.3f} | {data['wall']:.1f} | "
                      f"{data['process']:.1f} | d {dd:.1e}, force {df:.1e} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--sizes", type=int, nargs="*", default=[50, 160],
                        help="cells in x of the refined rings (none: skip them)")
    parser.add_argument("--steps", type=int, default=1)
    parser.add_argument("--skip-paper", action="store_true")
    parser.add_argument("--no-superlu", action="store_true",
                        help="refined rings: PETSc on 1 and 2 ranks only")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--cells", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--solver", help=argparse.SUPPRESS)
    parser.add_argument("--record", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    if not args.skip_paper:
        paper(args)
    if args.sizes:
        refined(args)


if __name__ == "__main__":
    main()
