"""Cost of one Newton iteration of the finite-strain solid: RK vs FEM Q1.

One iteration of :func:`skfem_rkpm.solvers.newton.newton_steps` evaluates the solid
at the current coefficients and solves the linearized constrained system.
This script times its four parts separately, on plane strain meshes of the
unit square (``rectangle(1, 1, n, n)``) with about 1e3, 1e4 and 1e5 nodes:

* *kinematics*: ``assembler.gradient(d)`` and ``deformation_gradient`` (Eq. 3.30);
* *material*: ``J2Material.update(F, state)`` (log strain, return map,
  consistent tangent ``A = ∂P/∂F``, a 3x3x3x3 tensor per point);
* *assembly*: ``to_assembler`` plus ``assembler.linear(P)`` (internal force)
  and ``assembler.bilinear(A)`` (tangent);
* *solve*: ``solve_constrained(K, r, C, g)``, the sparse saddle-point
  system with the sticking platens (both components prescribed on the nodes
  of the bottom and top sides) as constraints.

Bases: ``RKBasis(mesh, vector=True, support=2.0)`` with ``intorder=4``
(default, 9 Gauss points per cell) and ``intorder=2`` (4 points, the FEM
rule), and ``Basis(mesh, ElementVector(ElementQuad1()), intorder=2)``.
Material: E = 200 GPa, ν = 0.3, Swift hardening (the paper's sheet).

State: the homogeneous plane strain compression by 10 % (isochoric:
stretches 1/0.9 and 0.9) plus random noise of 1e-3 of the cell size on every
coefficient, evaluated from the virgin state: every point is on the plastic
branch of the return map and of the tangent, as in a real plastic step.

Each part is timed three times and the fastest run is reported (fewer if
one case exceeds ``--budget`` seconds).  Every (size, basis) case runs in a
fresh process with its address space capped (``--max-gb``), so that peak
memory can be reported per case and an oversized case fails with a
MemoryError instead of exhausting the machine; a failing or timed-out case
is reported and the larger sizes of that basis are skipped.  One core: the
thread variables are set before numpy is imported.

Measured (docs/benchmarks/scaling.md, "Newton iteration cost"): the sparse solve is
83-98 % of an RK iteration from 1e4 nodes on; at 1e5 nodes the RK
factorization needs 12-15 GB and about 9 minutes, so with the default cap
the RK cases stop there with a reported failure.

Run:  python benchmarks/newton_iteration.py                 (~15 minutes)
      python benchmarks/newton_iteration.py --nodes 1e3 1e4 4e4 1e5   (~30 minutes)
      python benchmarks/newton_iteration.py --nodes 1e3 1e4           (~1 minute)
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

BASES = ("RK, intorder 4 (default)", "RK, intorder 2", "FEM Q1")
PARTS = ("kinematics", "material", "assembly", "solve")


def build(nodes, kind):
    """Mesh, basis, problem, constraints and the evaluation point."""
    import scipy.sparse as sp
    from skfem import Basis, ElementQuad1, ElementVector

    from skfem_rkpm import RKBasis
    from skfem_rkpm.approximation.constraints import nodal_constraint
    from skfem_rkpm.mechanics.materials import J2Material, swift
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import rectangle

    n = int(round(np.sqrt(nodes))) - 1
    mesh = rectangle(1.0, 1.0, n, n)
    if kind == "FEM Q1":
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    else:
        basis = RKBasis(mesh, vector=True, support=2.0,
                        intorder=4 if "intorder 4" in kind else 2)
    problem = SolidProblem(basis, J2Material(200e3, 0.3, swift(589.0, 1e-4, 0.216)),
                           "plane_strain")
    groups = [nodal_constraint(basis, side, c) for side in ("bottom", "top")
              for c in (0, 1)]
    C = sp.vstack([g.C for g in groups], format="csr")
    g = np.concatenate([np.full(len(grp), -0.1 if k == 3 else 0.0)
                        for k, grp in enumerate(groups)])
    # homogeneous compression: linear fields are reproduced exactly by RK
    # coefficients equal to the nodal values, so d = u(X_I) for both bases
    X = np.asarray(basis.doflocs)[:, ::2]
    u = np.stack([(1 / 0.9 - 1) * X[0], -0.1 * X[1]], axis=1).ravel()
    rng = np.random.default_rng(0)
    d = u + 1e-3 / n * rng.standard_normal(u.size)
    return mesh, basis, problem, C, g, d


def iteration(problem, C, g, d, times):
    """One Newton iteration, every part timed into ``times`` (lists).

    Returns the tangent, the new state and the error of the solve (None if
    it succeeded); a failed solve is timed up to the failure.
    """
    from skfem_rkpm.solvers.constrained import solve_constrained
    from skfem_rkpm.mechanics.kinematics import deformation_gradient, to_assembler

    asm = problem.assembler
    t0 = time.perf_counter()
    F = deformation_gradient(asm.gradient(d), problem.model)
    t1 = time.perf_counter()
    P, tau, state, A = problem.material.update(F, problem.state, tangent=True)
    t2 = time.perf_counter()
    P_ext, A_ext = to_assembler(P, A, problem.model, problem.shape)
    del A
    f_int = asm.linear(P_ext)
    K = asm.bilinear(A_ext)
    del A_ext
    t3 = time.perf_counter()
    error = None
    try:
        solve_constrained(K, -f_int, C, g - C @ d)
    except (MemoryError, SystemError, RuntimeError) as err:
        error = f"{type(err).__name__}: {err}"
    t4 = time.perf_counter()
    for part, a, b in zip(PARTS, (t0, t1, t2, t3), (t1, t2, t3, t4)):
        times[part].append(b - a)
    return K, state, error


def lu_fill(K, C):
    """Entries of the sparse LU factors of the saddle-point matrix, as
    ``linear_solve`` factors it (same ordering and pivoting options)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    A = sp.bmat([[sp.csr_matrix(K), C.T], [C, None]], format="csc")
    lu = splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
              options=dict(SymmetricMode=True))
    return lu.L.nnz + lu.U.nnz, A.nnz


def run_case(nodes, kind, repeat, budget):
    """Measure one (size, basis) case; returns a dict (printed as JSON)."""
    start = time.perf_counter()
    mesh, basis, problem, C, g, d = build(nodes, kind)
    setup = time.perf_counter() - start
    times = {part: [] for part in PARTS}
    spent = time.perf_counter()
    for k in range(repeat):
        K, state, error = iteration(problem, C, g, d, times)
        if k == 0:
            plastic = float(np.mean(state.alpha > 0))
            nnz = K.nnz
        if error is not None or time.perf_counter() - spent > budget:
            break
        if k < repeat - 1:
            del K
    out = {
        "nodes": int(mesh.nvertices), "basis": kind, "dofs": int(problem.N),
        "points": int(problem.npoints), "nnz_row": nnz / problem.N,
        "plastic": plastic, "setup": setup, "runs": len(times["solve"]),
        **{part: min(v) for part, v in times.items()},
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    if error is not None:
        out["solve_error"] = error
    else:
        factors, entries = lu_fill(K, C)
        out["lu_entries"], out["lu_fill"] = factors, factors / entries
    return out


def child(args):
    """Run one case in this process (called by the parent with --case)."""
    limit = int(args.max_gb * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        out = run_case(args.case_nodes, args.case_basis, args.repeat, args.budget)
    except MemoryError:
        out = {"error": f"MemoryError (address space capped at {args.max_gb:g} GB)"}
    print("RESULT " + json.dumps(out))


def spawn(nodes, kind, args):
    command = [sys.executable, __file__, "--case-nodes", str(nodes), "--case-basis",
               kind, "--repeat", str(args.repeat), "--budget", str(args.budget),
               "--max-gb", str(args.max_gb)]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, capture_output=True, text=True,
                              timeout=args.timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {args.timeout:g} s"}
    lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
    if done.returncode or not lines:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return {"error": f"exit code {done.returncode}: {tail}"}
    out = json.loads(lines[-1][len("RESULT "):])
    out["wall"] = time.perf_counter() - start
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=float, nargs="+", default=[1e3, 1e4, 1e5])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--budget", type=float, default=180.0,
                        help="stop repeating a case after this many seconds")
    parser.add_argument("--timeout", type=float, default=900.0,
                        help="give up on a case (setup included) after this many seconds")
    parser.add_argument("--max-gb", type=float, default=12.0)
    parser.add_argument("--case-nodes", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--case-basis", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case_basis is not None:
        return child(args)

    import scipy
    import skfem
    print(f"Python {platform.python_version()}, numpy {np.__version__}, "
          f"scipy {scipy.__version__}, scikit-fem {skfem.__version__}; one thread\n")
    results, skipped = [], set()
    for nodes in sorted(args.nodes):
        for kind in BASES:
            if kind in skipped:
                continue
            out = spawn(nodes, kind, args)
            out.setdefault("basis", kind)
            out.setdefault("target", nodes)
            if "error" in out:
                skipped.add(kind)
                print(f"{kind}, {nodes:.0e} nodes: {out['error']}; larger sizes skipped",
                      flush=True)
            elif "solve_error" in out:
                print(f"{kind}, {out['nodes']} nodes: the sparse solve failed after "
                      f"{out['solve']:.0f} s ({out['solve_error']}); peak "
                      f"{out['peak_mb']:.0f} MB; larger sizes skipped", flush=True)
                skipped.add(kind)
            else:
                total = sum(out[p] for p in PARTS)
                print(f"{kind}, {out['nodes']} nodes: {total:.3f} s per iteration "
                      f"(best of {out['runs']}; setup {out['setup']:.1f} s, "
                      f"case {out['wall']:.0f} s, peak {out['peak_mb']:.0f} MB)",
                      flush=True)
            results.append(out)
    report(results)


def report(results):
    print("\n| nodes | basis | dofs | qp | nnz/row | kinematics s | material s | "
          "assembly s | solve s | iteration s | solve % | LU entries | peak MB |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in results:
        if "error" in r:
            print(f"| {r['target']:.0e} | {r['basis']} | | | | | | | | "
                  f"{r['error']} | | | |")
            continue
        head = (f"| {r['nodes']:,} | {r['basis']} | {r['dofs']:,} | {r['points']:,} | "
                f"{r['nnz_row']:.1f} | {r['kinematics']:.3g} | {r['material']:.3g} | "
                f"{r['assembly']:.3g} | ")
        if "solve_error" in r:
            print(head + f"failed after {r['solve']:.0f} s: {r['solve_error']} | | | | "
                  f"{r['peak_mb']:.0f} |")
            continue
        total = sum(r[p] for p in PARTS)
        print(head + f"{r['solve']:.3g} | {total:.3g} | "
              f"{100 * r['solve'] / total:.0f} | {r['lu_entries'] / 1e6:.1f}M "
              f"({r['lu_fill']:.0f}x) | {r['peak_mb']:.0f} |")
    print("\nRK / FEM Q1 time ratios on the same mesh:\n")
    print("| nodes | RK basis | kinematics | material | assembly | solve | iteration | "
          "iteration without solve |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|")

    def ratio(x):
        return f"{x:.0f}" if x >= 10 else f"{x:.1f}"

    fem = {r["nodes"]: r for r in results if r["basis"] == "FEM Q1" and "error" not in r}
    for r in results:
        if r["basis"] == "FEM Q1" or "error" in r or r["nodes"] not in fem:
            continue
        q = fem[r["nodes"]]
        failed = "solve_error" in r or "solve_error" in q
        cells = [ratio(r[p] / q[p]) for p in PARTS[:3]]
        if failed:
            cells += ["—", "—"]
        else:
            cells += [ratio(r["solve"] / q["solve"]),
                      ratio(sum(r[p] for p in PARTS) / sum(q[p] for p in PARTS))]
        cells.append(ratio(sum(r[p] for p in PARTS[:3]) / sum(q[p] for p in PARTS[:3])))
        print(f"| {r['nodes']:,} | {r['basis'][4:]} | " + " | ".join(cells) + " |")
    if any(r["plastic"] < 1 for r in results if "error" not in r):
        print("\nnote: not every point is plastic: "
              + ", ".join(f"{r['basis']} {r['nodes']}: {100 * r['plastic']:.0f} %"
                          for r in results if "error" not in r))


if __name__ == "__main__":
    main()
