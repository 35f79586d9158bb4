"""GMRES on the RKPM tangent of the billet, preconditioned by the FEM Hex1
tangent of the same background mesh (particles = mesh nodes).

The lever for the 42k RKPM billet, whose own factorization ran out of
memory: the Hex1 tangent has about a tenth of the entries and its factors
a fifth.  Both tangents at the undeformed state (elastic), the normal
components on the three symmetry planes pinned (rows and columns removed:
nodal values for FEM, coefficients at the plane's particles for RKPM, which
is what a preconditioner needs); right-preconditioned GMRES (no restart) on
``K_rk x = b`` to a relative residual ``--rtol``, preconditioned by

* the SuperLU factorization of ``K_fem``,
* smoothed-aggregation AMG of ``K_fem`` (pyamg, one V-cycle per iteration,
  constants as near null space),
* the SuperLU factorization of ``K_rk`` itself (one iteration: the check).

``b``: a random vector, and ``K_rk`` times a smooth displacement field.
CPU seconds (``time.process_time``), one core.

Run:  python benchmarks/rk_fem_preconditioner.py --divisions 16 8 12
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.sparse.linalg import splu  # noqa: E402


def tangents(divisions):
    """``K_rk``, ``K_fem`` (free rows) and the free dofs' coordinates."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    out = {}
    for method in ("fem", "rkpm"):
        scene = load_scene(builtin_scenes()["billet_3d"], [
            "output.fields=false", "output.figures=false",
            f"geometry.divisions=[{','.join(str(int(n)) for n in divisions)}]"])
        sim = runner.build(scene, method)
        K = sp.csr_matrix(sim.problem.evaluate(np.zeros(sim.problem.N)).K)
        out[method] = (K, np.asarray(sim.basis.doflocs))
        del sim
    (K_fem, x_fem), (K_rk, x_rk) = out["fem"], out["rkpm"]
    if K_fem.shape != K_rk.shape or not np.allclose(x_fem, x_rk):
        raise SystemExit("the particles are not the mesh nodes in the same order")
    component = np.arange(K_fem.shape[0]) % 3
    pinned = np.isclose(x_fem[component, np.arange(K_fem.shape[0])], 0.0)
    free = np.flatnonzero(~pinned)
    return K_rk[free][:, free].tocsr(), K_fem[free][:, free].tocsr(), x_fem[:, free]


def run_gmres(A, precondition, b, rtol, maxiter):
    from skfem_rkpm.solvers.reuse import preconditioned_gmres
    clock = time.process_time()
    x, its, ok = preconditioned_gmres(A.dot, precondition, b, rtol, maxiter)
    return its, ok, time.process_time() - clock, np.linalg.norm(b - A @ x) / np.linalg.norm(b)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--divisions", type=int, nargs=3, default=[16, 8, 12])
    parser.add_argument("--rtol", type=float, default=1e-9)
    parser.add_argument("--maxiter", type=int, default=400)
    args = parser.parse_args()
    load = os.getloadavg()[0]
    K_rk, K_fem, x = tangents(args.divisions)
    rng = np.random.default_rng(0)
    smooth = np.sin(np.pi * x[0] / 40) * np.cos(np.pi * x[1] / 20) * (x[2] / 15 + 0.2)
    rhs = {"random": rng.standard_normal(K_rk.shape[0]), "smooth field": K_rk @ smooth}
    rows = dict(divisions=args.divisions, n=int(K_rk.shape[0]), nnz_rk=int(K_rk.nnz),
                nnz_fem=int(K_fem.nnz), rtol=args.rtol, load_start=load, cases={})
    preconditioners = {}
    clock = time.process_time()
    lu = splu(K_fem.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
              options=dict(SymmetricMode=True))
    preconditioners["SuperLU of K_fem"] = (lu.solve, time.process_time() - clock,
                                           int(lu.L.nnz + lu.U.nnz))
    try:
        import pyamg
        clock = time.process_time()
        ml = pyamg.smoothed_aggregation_solver(K_fem, symmetry="symmetric", max_coarse=500)
        preconditioners["pyamg SA of K_fem"] = (
            lambda r: ml.solve(r, maxiter=1, tol=1e-30, cycle="V"),
            time.process_time() - clock, None)
    except ImportError:
        pass
    clock = time.process_time()
    own = splu(K_rk.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
               options=dict(SymmetricMode=True))
    preconditioners["SuperLU of K_rk (itself)"] = (own.solve, time.process_time() - clock,
                                                   int(own.L.nnz + own.U.nnz))
    for name, (apply, setup, factors) in preconditioners.items():
        for label, b in rhs.items():
            its, ok, seconds, residual = run_gmres(K_rk, apply, b, args.rtol, args.maxiter)
            rows["cases"][f"{name} / {label}"] = dict(setup_s=setup, factor_entries=factors,
                                                      iterations=its, converged=ok,
                                                      gmres_s=seconds, residual=residual)
            print(f"{name:28s} {label:13s} setup {setup:7.2f} s  {its:4d} its "
                  f"{'ok' if ok else 'NOT converged'}  GMRES {seconds:7.2f} s  "
                  f"residual {residual:.1e}", flush=True)
    rows["load_end"] = os.getloadavg()[0]
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
