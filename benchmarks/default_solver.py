"""Which sparse solver the plain install should carry: wheels from PyPI on the
RK and FEM tangents of 1e4, 1.7e4 and 1e5 particles.

Matrices (``--build``, once per case and size, saved with
``scipy.sparse.save_npz`` in ``--dir``): plane strain elasticity (E = 200 GPa,
ν = 0.3) on the rectangle of ``benchmarks/basis_build.py`` (160 x 106 cells
scaled to the number of particles), left side clamped by nodal constraints
``C`` on both components.

* ``rk``: ``RKBasis(mesh, vector=True, support=3.0, intorder=7)`` (VCI, the
  default: the tangent is not symmetric);
* ``fem``: ``Basis(mesh, ElementVector(ElementQuad1()), intorder=2)``
  (symmetric positive definite);
* ``rk-friction``, ``fem-friction``: the same plus the tangent of penalty
  contact with Coulomb sliding friction on the top side,
  ``κ (Nᵀ N + μ Tᵀ N)`` with ``N``, ``T`` the nodal-value rows of the normal
  (y) and tangential (x) components there, ``μ = 0.3`` and ``κ = |diag K|``:
  the friction term ``μ κ Tᵀ N`` is not symmetric.

Systems (``--systems``):

* ``augmented``: ``A = K + ρ CᵀC`` (``ρ`` of
  :func:`skfem_rkpm.solvers.constrained._penalty`): factor, solve, refactor
  with the same pattern (``A + 0.01 diag(A)``, as the next Newton iteration);
* ``saddle``: ``solve_saddle_point(make_solver(backend), K, f, C, g)``, the
  constrained solve of every Newton iteration (direct factorization of
  ``[[K, Cᵀ], [C, 0]]`` or the augmented Lagrangian, as the backend does).

Each (matrix, system, backend) runs in a fresh process (``--child``) whose
peak resident memory (``VmHWM``) is reported, with the resident memory
after loading the matrices (``base``) subtracted in the *extra MB* column.
One core: thread variables set to 1 before numpy is imported; CPU seconds
(``time.process_time``).  A backend that passes ``--budget`` seconds (or
fails) at one size is not run at the larger sizes of that case.  Backends:
the ones of :mod:`skfem_rkpm.solvers.linear` by name (``superlu``,
``umfpack``, ``pardiso``, ``amg``), plus ``qdldl`` (``qdldl.Solver``,
LDLᵀ without pivoting: symmetric matrices only) and ``cvx-cholmod``
(CHOLMOD of the ``cvxopt`` wheel: symmetric positive definite only), timed
here directly.  ``--pythonpath`` adds a folder to the children's path (an
extra installed with ``pip install --target``, e.g. pypardiso, so that it
is measured without being installed in the environment).

Run:  python benchmarks/default_solver.py --build              (~3 minutes, 14 GB peak)
      python benchmarks/default_solver.py                      (~40 minutes)
      PYPARDISO_MKL_RT=/opt/pp/lib/libmkl_rt.so.3 python benchmarks/default_solver.py \
          --backends pardiso --pythonpath /opt/pp/lib/python3.11/site-packages
          (PARDISO installed aside with ``pip install --prefix /opt/pp pypardiso``)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from _timing import resident_mb  # noqa: E402

SIZES = (10000, 17227, 100000)
CASES = ("rk", "rk-friction", "fem", "fem-friction")
SYMMETRIC_ONLY = ("qdldl", "cvx-cholmod")


def divisions(particles):
    """Cells (nx, ny) of aspect 160:106 with about ``particles`` vertices
    (as ``benchmarks/basis_build.py``)."""
    ratio = 106 / 160
    nx = max(2, int(round((-(1 + ratio) + np.sqrt((1 + ratio) ** 2 - 4 * ratio
                                                  * (1 - particles))) / (2 * ratio))))
    return nx, max(2, int(round(ratio * nx)))


def path(folder, case, particles, what):
    return os.path.join(folder, f"{case}-{particles}-{what}.npz")


def build(case, particles, folder):
    """Save K, C (and the friction rows) of ``case``; print a JSON line."""
    from skfem import Basis, ElementQuad1, ElementVector
    from skfem.models.elasticity import lame_parameters

    from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
    from skfem_rkpm.approximation.constraints import nodal_constraint
    from skfem_rkpm.meshes import rectangle

    start = time.process_time()
    nx, ny = divisions(particles)
    mesh = rectangle(nx / 100, ny / 100, nx, ny)
    if case == "fem":
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    else:
        basis = RKBasis(mesh, vector=True, support=3.0, intorder=7)
    lam, mu = lame_parameters(200e3, 0.3)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2)).tocsr()
    C = sp.vstack([nodal_constraint(basis, "left", i).C for i in range(2)]).tocsr()
    T = nodal_constraint(basis, "top", 0).C.tocsr()
    N = nodal_constraint(basis, "top", 1).C.tocsr()
    for name, M in (("K", K), ("C", C), ("T", T), ("N", N)):
        sp.save_npz(path(folder, case, particles, name), M)
    print("RESULT " + json.dumps(dict(case=case, particles=int(mesh.nvertices), n=K.shape[0],
                                      nnz=int(K.nnz), seconds=time.process_time() - start,
                                      peak_mb=resident_mb())), flush=True)


def matrices(folder, case, particles):
    """K (with the friction tangent for ``*-friction``) and C."""
    base = case.removesuffix("-friction")
    K = sp.load_npz(path(folder, base, particles, "K")).tocsr()
    C = sp.load_npz(path(folder, base, particles, "C")).tocsr()
    if case.endswith("-friction"):
        T = sp.load_npz(path(folder, base, particles, "T")).tocsr()
        N = sp.load_npz(path(folder, base, particles, "N")).tocsr()
        kappa = np.abs(K.diagonal()).max()
        K = (K + kappa * (N.T @ N + 0.3 * (T.T @ N))).tocsr()
    return K, C


def direct(backend):
    """factor(A) -> solve(b) of the backends timed here (not in the package)."""
    if backend == "qdldl":
        import qdldl

        def factor(A):
            solver = qdldl.Solver(sp.csc_matrix(A))
            return solver.solve
        return factor
    if backend == "cvx-cholmod":
        import cvxopt
        from cvxopt import cholmod

        def factor(A):
            A = sp.coo_matrix(sp.tril(A))
            M = cvxopt.spmatrix(A.data, A.row.astype(int), A.col.astype(int), A.shape)
            F = cholmod.symbolic(M)
            cholmod.numeric(M, F)

            def solve(b):
                B = cvxopt.matrix(b.copy())
                cholmod.solve(F, B)
                return np.array(B).ravel()
            return solve
        return factor
    raise ValueError(backend)


def child(folder, case, particles, system, backend):
    """Time ``backend`` on one system; print a JSON line."""
    from skfem_rkpm.solvers.constrained import _penalty, solve_saddle_point
    from skfem_rkpm.solvers.linear import make_solver

    K, C = matrices(folder, case, int(particles))
    rng = np.random.default_rng(0)
    f = rng.normal(size=K.shape[0]) * np.abs(K.diagonal()).max() * 1e-3
    g = np.full(C.shape[0], 1e-3)
    rho = _penalty(K, C)
    A = (K + rho * (C.T @ C)).tocsr()
    A.sort_indices()
    A2 = (A + sp.diags(0.01 * A.diagonal())).tocsr()
    A2.sort_indices()
    base = resident_mb("VmRSS")
    out = dict(base_mb=base, n=A.shape[0], nnz_row=A.nnz / A.shape[0])
    cpu = time.process_time
    if system == "augmented" and backend in SYMMETRIC_ONLY:
        c0 = cpu()
        solve = direct(backend)(A)
        out["factor"] = cpu() - c0
        c0 = cpu()
        x = solve(f)
        out["solve"] = cpu() - c0
        c0 = cpu()
        direct(backend)(A2)
        out["refactor"] = cpu() - c0
    elif system == "augmented":
        solver = make_solver(backend)
        c0 = cpu()
        solver.factor(A)
        out["factor"] = cpu() - c0
        c0 = cpu()
        x = solver.solve(f)
        out["solve"] = cpu() - c0
        c0 = cpu()
        solver.factor(A2)
        out["refactor"] = cpu() - c0
        out["describe"] = solver.describe()
    else:
        solver = make_solver(backend)
        c0 = cpu()
        d, lam = solve_saddle_point(solver, K, f, C, g)
        out["factor"] = cpu() - c0
        out["solve"] = 0.0
        c0 = cpu()
        solve_saddle_point(solver, K, f * 1.1, C, g)  # the next Newton iteration
        out["refactor"] = cpu() - c0
        out["describe"] = solver.describe()
        r = np.concatenate([K @ d - C.T @ lam - f, C @ d - g])
        out["residual"] = float(np.linalg.norm(r) / np.linalg.norm(np.concatenate([f, g])))
    if system == "augmented":
        out["residual"] = float(np.linalg.norm(A @ x - f) / np.linalg.norm(f))
    out["peak_mb"] = resident_mb()
    print("RESULT " + json.dumps(out), flush=True)


def run_timed(args, budget, extra_path):
    env = dict(os.environ)
    if extra_path:
        env["PYTHONPATH"] = env.get("PYTHONPATH", "") + os.pathsep + extra_path
    try:
        proc = subprocess.run([sys.executable, __file__, *args], capture_output=True,
                              text=True, timeout=budget, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"not done after {budget:.0f} s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"error": (proc.stderr.strip().splitlines() or ["no output"])[-1][:140]}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--dir", default="/tmp/default-solver")
    p.add_argument("--sizes", nargs="+", type=int, default=list(SIZES))
    p.add_argument("--cases", nargs="+", default=list(CASES))
    p.add_argument("--systems", nargs="+", default=["augmented", "saddle"])
    p.add_argument("--backends", nargs="+",
                   default=["superlu", "umfpack", "pardiso", "amg", "qdldl", "cvx-cholmod"])
    p.add_argument("--budget", type=float, default=300.0,
                   help="wall seconds per run before it is stopped")
    p.add_argument("--pythonpath", default=None)
    p.add_argument("--build", action="store_true")
    p.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    p.add_argument("--build-child", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        return child(*args.child)
    if args.build_child:
        return build(args.build_child[0], int(args.build_child[1]), args.build_child[2])
    print(f"load average {os.getloadavg()}", flush=True)
    if args.build:
        os.makedirs(args.dir, exist_ok=True)
        for case in sorted({c.removesuffix("-friction") for c in args.cases}):
            for size in args.sizes:
                r = run_timed(["--build-child", case, str(size), args.dir], None, None)
                print(case, size, r, flush=True)
        return
    print("| case | particles | unknowns | nnz/row | system | backend | factor s | solve s "
          "| refactor s | peak MB | extra MB | rel. residual |")
    print("|---|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|")
    for case in args.cases:
        for system in args.systems:
            stopped = set()
            for size in args.sizes:
                for backend in args.backends:
                    if backend in stopped:
                        continue
                    if backend in SYMMETRIC_ONLY and (system != "augmented"
                                                      or not case.startswith("fem")
                                                      or case.endswith("friction")):
                        continue  # symmetric matrices only
                    r = run_timed(["--child", args.dir, case, str(size), system, backend],
                                  args.budget, args.pythonpath)
                    if "error" in r:
                        print(f"| {case} | {size:,} | | | {system} | {backend} | "
                              f"{r['error']} | | | | | |", flush=True)
                        stopped.add(backend)
                        continue
                    print(f"| {case} | {size:,} | {r['n']:,} | {r['nnz_row']:.0f} | {system} "
                          f"| {backend} | {r['factor']:.3g} | {r['solve']:.3g} | "
                          f"{r['refactor']:.3g} | {r['peak_mb']:.0f} | "
                          f"{r['peak_mb'] - r['base_mb']:.0f} | {r['residual']:.1e} |",
                          flush=True)
    print(f"load average {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
