"""Sparse linear solver backends on RK and FEM elasticity tangents.

Matrices: the small-strain elasticity tangent
``Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2))`` (E = 200 GPa,
ν = 0.3) on ``rectangle(1, 1, n, n)`` with the left side clamped by the
augmented Lagrangian term, ``A = K + ρ CᵀC`` with ``C`` the nodal constraints
of both components on the left side and ``ρ`` as in
:func:`skfem_rkpm.solvers.constrained.solve_saddle_point` (so that every backend,
including the SPD-only ones, gets the same nonsingular matrix).  Bases:

* ``rk``: ``RKBasis(mesh, vector=True, support=2.0)``, VCI integration
  (the default; the Petrov-Galerkin tangent is *not* symmetric,
  |A - Aᵀ|/|A| ≈ 1e-4, so CHOLMOD is not applicable and AMG uses GMRES);
* ``rk-gauss``: the same with ``integration="gauss"``: symmetric positive
  definite;
* ``fem``: ``Basis(mesh, ElementVector(ElementQuad1()), intorder=2)``.

For each backend of :mod:`skfem_rkpm.solvers.linear` the script times, in a fresh
process (so that the peak resident memory is that of one backend):

* *factor*: the first ``factor(A)`` (symbolic analysis + numeric factorization);
* *refactor*: ``factor(A')`` with the same pattern and other values (``A + 0.01 diag(A)``, as
  in a Newton iteration), which reuses the analysis where the backend allows;
* *solve*: ``solve(b)`` for one right-hand side;
* *peak MB*: the peak resident memory of the process minus the resident
  memory before the first ``factor`` (the two matrices and the right-hand
  side); ``0`` where the peak was set while the matrices were loaded;
* *rel. residual* ``|A x - b| / |b|``.

scipy's default ``spsolve`` (SuperLU, COLAMD, partial pivoting) runs as the
reference at the sizes where it takes less than ``--budget`` seconds; *×
spsolve* is its time over the backend's factor + solve.  A backend whose
time at one size exceeds ``--budget`` is not run at larger sizes.  One core
(the thread variables are set to 1 before numpy is imported); times are CPU
seconds of the process (``time.process_time``) and wall seconds.

Run:  python benchmarks/linear_solvers.py                      (~30 minutes)
      python benchmarks/linear_solvers.py --dofs 1e3 1e4        (~1 minute)
      python benchmarks/linear_solvers.py --cases rk --dofs 2e5 --no-reference --backends pardiso
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402


def build(case, dofs):
    """The matrix ``K + ρ CᵀC`` of ``case`` with about ``dofs`` unknowns."""
    from skfem import Basis, ElementQuad1, ElementVector
    from skfem.models.elasticity import lame_parameters

    from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
    from skfem_rkpm.approximation.constraints import nodal_constraint
    from skfem_rkpm.solvers.constrained import _penalty
    from skfem_rkpm.meshes import rectangle

    n = max(2, int(round(np.sqrt(dofs / 2.0) - 1)))
    mesh = rectangle(1.0, 1.0, n, n)
    if case == "fem":
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    else:
        basis = RKBasis(mesh, vector=True, support=2.0,
                        integration="gauss" if case == "rk-gauss" else "vci")
    lam, mu = lame_parameters(200e3, 0.3)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2)).tocsr()
    C = sp.vstack([nodal_constraint(basis, "left", i).C for i in range(2)]).tocsr()
    A = (K + _penalty(K, C) * (C.T @ C)).tocsr()
    A.sum_duplicates()
    A.sort_indices()
    return A


def child(path, backend):
    """Time one backend on the matrix in ``path``; print a JSON line."""
    from skfem_rkpm.solvers.linear import make_solver

    A = sp.load_npz(path).tocsr()
    b = np.random.default_rng(0).normal(size=A.shape[0])
    # the second matrix: same pattern, other values (as the next Newton iteration)
    A2 = (A + sp.diags(0.01 * A.diagonal())).tocsr()
    A2.sort_indices()
    with open("/proc/self/status") as status:  # resident memory now, in MB
        base = next(int(line.split()[1]) for line in status
                    if line.startswith("VmRSS")) / 1024
    out = {}

    def timed(fn):
        c, w = time.process_time(), time.perf_counter()
        result = fn()
        return result, time.process_time() - c, time.perf_counter() - w

    if backend == "spsolve":
        from scipy.sparse.linalg import spsolve
        x, cpu, wall = timed(lambda: spsolve(A.tocsc(), b))
        out.update(factor=cpu, factor_wall=wall, solve=0.0, refactor=None)
    else:
        solver = make_solver(backend)
        _, out["factor"], out["factor_wall"] = timed(lambda: solver.factor(A))
        x, out["solve"], _ = timed(lambda: solver.solve(b))
        _, out["refactor"], _ = timed(lambda: solver.factor(A2))
        x2 = solver.solve(b)
        out["residual2"] = float(np.linalg.norm(A2 @ x2 - b) / np.linalg.norm(b))
        solver.factor(A)
        out["analyses"] = solver.stats["analyses"]
        out["describe"] = solver.describe()
    out["residual"] = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base
    print("RESULT " + json.dumps(out))


def run_child(path, backend, budget):
    cmd = [sys.executable, __file__, "--child", path, backend]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=10 * budget)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {10 * budget:.0f} s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"error": (proc.stderr.strip().splitlines() or ["no output"])[-1][:120]}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--dofs", nargs="+", type=float, default=[1e3, 1e4, 5e4, 2e5])
    p.add_argument("--cases", nargs="+", default=["rk", "rk-gauss", "fem"])
    p.add_argument("--backends", nargs="+", default=None)
    p.add_argument("--budget", type=float, default=120.0,
                   help="seconds per factorization beyond which larger sizes are skipped")
    p.add_argument("--no-reference", action="store_true",
                   help="do not run scipy's default spsolve (slow at large sizes)")
    p.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        return child(*args.child)

    from skfem_rkpm.solvers.linear import available
    backends = args.backends or available()
    print("backends:", ", ".join(backends))
    print("\n| case | dofs | nnz/row | backend | factor s | refactor s | solve s | "
          "peak MB | rel. residual | × spsolve |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            slow = set()
            for dofs in args.dofs:
                A = build(case, dofs)
                path = os.path.join(tmp, f"{case}-{int(dofs)}.npz")
                sp.save_npz(path, A)
                n, nnz = A.shape[0], A.nnz
                del A
                ref = None
                reference = [] if args.no_reference else ["spsolve"]
                for backend in reference + list(backends):
                    if backend in slow or (backend == "dense" and n > 12000):
                        continue  # dense LU: n² doubles, 1 GB at 12k
                    r = run_child(path, backend, args.budget)
                    if "error" in r:
                        print(f"| {case} | {n:,} | {nnz / n:.0f} | {backend} | "
                              f"{r['error']} | | | | | |", flush=True)
                        slow.add(backend)
                        continue
                    total = r["factor"] + r["solve"]
                    if backend == "spsolve":
                        ref = total
                    ratio = f"{ref / total:.1f}" if ref else "–"
                    refac = f"{r['refactor']:.3g}" if r.get("refactor") is not None else "–"
                    print(f"| {case} | {n:,} | {nnz / n:.0f} | {backend} | {r['factor']:.3g} | "
                          f"{refac} | {r['solve']:.3g} | {r['peak_mb']:.0f} | "
                          f"{r['residual']:.1e} | {ratio} |", flush=True)
                    if r["factor"] > args.budget / 8:  # the next size costs ~8x more
                        slow.add(backend)


if __name__ == "__main__":
    main()
