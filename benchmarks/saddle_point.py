"""Factor + solve of the saddle-point system of a coarse 3D RKPM scene.

The system is that of a Newton iteration of ``skfem-rkpm run SCENE``:
``[[K, Cᵀ], [C, 0]] [d; -λ] = [f; g]`` with ``K`` the scene's tangent at
the start (elastic, RK with VCI: not symmetric), ``C`` the rows of its
prescribed conditions as :func:`skfem_rkpm.solvers.newton.newton_steps`
stacks them (the ring sector: weak symmetry conditions on three planes,
two of them skew), ``f`` a random load (seeded) and ``g = 0``.  Timed
(CPU seconds, ``time.process_time``, median of ``--repeat`` runs, each
from scratch: factorization and one solve):

* ``before``: SuperLU on the saddle-point matrix, MMD ordering of AᵀA + A
  in symmetric mode, pivot threshold 0.01 (the ``superlu`` backend as it
  factored the saddle point);
* ``(a)``: SuperLU on the saddle-point matrix with its other orderings:
  COLAMD with partial pivoting, MMD of AᵀA in symmetric mode;
* ``(c) after``: :func:`~skfem_rkpm.solvers.constrained.solve_saddle_point`
  with the ``superlu`` backend: ``K + ρCᵀC`` factored, GMRES on the Schur
  complement of the multipliers, refined to a backward error of 1e-12;
* ``(d)``: ``K + ρCᵀC`` factored and the dense Schur complement
  ``C K_ρ⁻¹ Cᵀ`` formed from ``len(C)`` solves, then a dense solve;
* ``(e)``: UMFPACK (``umfpack`` backend, if ``cvxopt`` is installed) on the
  saddle-point matrix as it is (what ``solve_saddle_point`` does with it),
  and on ``K + ρCᵀC`` with GMRES on the Schur complement as in ``(c)``;
* for scale: the factorization of ``K + ρCᵀC`` alone, and of ``K`` alone.

For each: entries in the LU factors, pivots off the diagonal (rows
exchanged by SuperLU's threshold pivoting), and the distance of ``d`` and
``λ`` from the ``before`` solution.  ``(b)``, eliminating the conditions by
a pivot column per row, is checked for applicability: the number of rows
that have a column no other row uses.

Run:  python benchmarks/saddle_point.py                       (~1 minute)
      python benchmarks/saddle_point.py --scene billet_3d --repeat 3
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.sparse.linalg import splu  # noqa: E402


def scene_system(scene, settings):
    """``K, C`` of the scene's first Newton iteration (see the module docstring)."""
    from skfem_rkpm.approximation.constraints import ConstraintSet
    from skfem_rkpm.runs.build import build
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    sim = build(load_scene(builtin_scenes()[scene], settings), "rkpm")
    problem = sim.problem
    K = problem.evaluate(np.zeros(problem.N)).K.tocsr()
    groups = [p.constraint(problem.basis) for p in sim.prescribed]
    C = ConstraintSet(groups, problem.N, [p.name for p in sim.prescribed]).C.tocsr()
    return K, C


def superlu(A, **options):
    """SuperLU of ``A`` with ``options``; the LU object."""
    return splu(sp.csc_matrix(A), **options)


SYMMETRIC_MMD = dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                     options=dict(SymmetricMode=True))


def methods(K, C, f, g):
    """name -> function returning ``(d, λ, lu or None)``."""
    from skfem_rkpm.solvers.constrained import _penalty, solve_saddle_point
    from skfem_rkpm.solvers.linear import available, make_solver

    N = K.shape[0]
    A = sp.bmat([[K, C.T], [C, None]]).tocsc()
    b = np.concatenate([f, g])
    rho = _penalty(K, C)

    def direct(**options):
        def run():
            lu = superlu(A, **options)
            x = lu.solve(b)
            return x[:N], -x[N:], lu
        return run

    def augmented():
        d, lam = solve_saddle_point(make_solver("superlu"), K, f, C, g)
        return d, lam, None

    def dense_schur():
        Krho = (K + rho * (C.T @ C)).tocsc()
        lu = superlu(Krho, **SYMMETRIC_MMD)
        X = lu.solve(C.T.toarray())
        S = C @ X
        rhs = f + rho * (C.T @ g)
        d0 = lu.solve(rhs)
        lam = np.linalg.solve(S, g - C @ d0)
        return lu.solve(rhs + C.T @ lam), lam, lu

    def umfpack_direct():
        d, lam = solve_saddle_point(make_solver("umfpack"), K, f, C, g)
        return d, lam, None

    def umfpack_augmented():
        from skfem_rkpm.solvers.constrained import _augmented_lagrangian
        solver = make_solver("umfpack")
        Krho = (K + rho * (C.T @ C)).tocsr()
        d, lam = _augmented_lagrangian(solver, solver, K, Krho, rho, f, C, g, 1e-12, 200)
        return d, lam, None

    extra = {}
    if "umfpack" in available():
        extra = {"(e) UMFPACK: saddle point factored as it is": umfpack_direct,
                 "(e) UMFPACK: K + ρCᵀC, GMRES on the Schur complement": umfpack_augmented}
    return {
        "before: saddle point, MMD(AᵀA+A), symmetric mode": direct(**SYMMETRIC_MMD),
        "(a) saddle point, COLAMD, partial pivoting": direct(permc_spec="COLAMD"),
        "(a) saddle point, MMD(AᵀA), symmetric mode": direct(
            permc_spec="MMD_ATA", diag_pivot_thresh=0.01, options=dict(SymmetricMode=True)),
        "(c) after: K + ρCᵀC, GMRES on the Schur complement": augmented,
        "(d) K + ρCᵀC, dense Schur complement (len(C) solves)": dense_schur,
    } | extra


def private_pivot_rows(C):
    """Rows of ``C`` with a column that no other row uses (option (b))."""
    C = sp.csr_matrix(C)
    C.eliminate_zeros()
    used = np.diff(sp.csc_matrix(C).indptr)
    private = (used == 1).astype(np.int64)
    return int(np.count_nonzero(abs(C).astype(bool).astype(np.int64) @ private))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="ring_sector")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="scene settings, as for skfem-rkpm run")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    K, C = scene_system(args.scene, args.set)
    N, m = K.shape[0], C.shape[0]
    f = np.random.default_rng(0).normal(size=N) * abs(K).max()
    g = np.zeros(m)
    print(f"{args.scene} (RKPM): {N} unknowns, {K.nnz / N:.0f} entries per row of K; "
          f"{m} condition rows, {C.nnz / m:.0f} entries per row; |K - Kᵀ|/|K| = "
          f"{abs(K - K.T).max() / abs(K).max():.1e}")
    print(f"(b) rows with a pivot column no other row uses: {private_pivot_rows(C)} of {m}")
    print()
    print("| method | CPU s (median) | LU entries | off-diagonal pivots | d vs before | "
          "λ vs before |")
    print("|---|---|---|---|---|---|")
    reference = None
    for name, run in methods(K, C, f, g).items():
        times = []
        for _ in range(args.repeat):
            clock = time.process_time()
            d, lam, lu = run()
            times.append(time.process_time() - clock)
        if reference is None:
            reference = d, lam
        entries = (f"{lu.L.nnz + lu.U.nnz:,}" if lu is not None
                   else "–" if name.startswith("(e)") else "(K + ρCᵀC's)")
        pivots = str(int(np.sum(lu.perm_r != lu.perm_c))) if lu is not None else "-"
        dd = np.linalg.norm(d - reference[0]) / np.linalg.norm(reference[0])
        dl = np.linalg.norm(lam - reference[1]) / np.linalg.norm(reference[1])
        print(f"| {name} | {statistics.median(times):.3f} | {entries} | {pivots} | "
              f"{dd:.1e} | {dl:.1e} |", flush=True)
    from skfem_rkpm.solvers.constrained import _penalty
    for name, M in (("K + ρCᵀC alone (factor)", K + _penalty(K, C) * (C.T @ C)),
                    ("K alone (factor)", K)):
        times = []
        try:
            for _ in range(args.repeat):
                clock = time.process_time()
                lu = superlu(M, **SYMMETRIC_MMD)
                times.append(time.process_time() - clock)
        except RuntimeError as err:
            print(f"| {name} | ({err}) | | | | |")
            continue
        print(f"| {name} | {statistics.median(times):.3f} | {lu.L.nnz + lu.U.nnz:,} | "
              f"{int(np.sum(lu.perm_r != lu.perm_c))} | | |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
