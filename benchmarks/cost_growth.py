"""Cost growth from 1e3 to 1e6 particles: basis, assembly, material, solve.

Plane strain unit square, ``rectangle(1, 1, n, n)`` with ``(n + 1)²``
particles (nodes), for

* ``RK``: ``RKBasis(mesh, vector=True)``, the default basis (normalized
  support 2, order 1, cubic kernel, 3x3 Gauss points per cell, VCI);
* ``Q1``: ``Basis(mesh, ElementVector(ElementQuad1()), intorder=2)`` on the
  same mesh.

Parts, each timed in CPU seconds of the process (``time.process_time``),
fastest of ``--repeat`` runs (fewer once a part has used ``--budget``
seconds):

* *basis*: building the basis (RK: shape tables at the cell and boundary
  Gauss points and at the particles, VCI correction, per-cell layout; Q1:
  scikit-fem's ``Basis``);
* *pattern*: ``SolidProblem(...)``, i.e. ``Assembler(basis)``: sparsity
  pattern and scatter map, built once per mesh;
* *kinematics*: ``assembler.gradient(d)``, ``deformation_gradient``, ``det F``;
* *material*: ``J2Material.update(F, state, entries=...)`` with the
  consistent tangent (Swift hardening, E = 200 GPa, ν = 0.3), at a state
  where every Gauss point is on the plastic branch: the homogeneous plane
  strain compression by 10 % plus noise of 1e-3 of the cell size on every
  coefficient, from the virgin state (as in ``newton_iteration.py``);
* *assembly*: internal force and tangent matrix, as ``SolidProblem.evaluate``
  forms them (``from_entries``, ``assembler.linear``, ``local_bilinear``
  into the kept buffer, ``matrix``);
* *solve*: the linearized saddle-point system with sticking platens (both
  components prescribed on the nodes of the bottom and top sides),
  ``solve_saddle_point(make_solver(name), K, -f, C, g)`` with a fresh
  solver (first factorization: analysis, factorization, solve), for the
  backends ``superlu``, ``pardiso`` and, for symmetric tangents (Q1),
  ``cholmod``, where installed.  ``make_solver("auto")`` picks dense LU up
  to 500 unknowns, PARDISO above 20,000 if installed, else CHOLMOD
  (symmetric) or SuperLU.

Every (size, basis) case runs in a fresh process with its address space
capped (``--max-gb``) and a time limit (``--timeout``); the tangent, the
constraints and the right-hand side are written to a temporary file and
every solver backend runs in a process of its own under the same limits, so
that its peak memory is its own.  A part that runs out of memory or time is
reported as such and the same part is not tried at larger sizes.  The
exponent ``p`` of ``t ≈ a N^p`` is the least-squares fit of ``log t``
against ``log N`` (N: particles) over the sizes that ran, and over those
from 1e4 particles on.

``--3d`` sizes: the RK basis alone (``RKBasis(MeshHex, vector=True)``,
3x3x3 Gauss points per hexahedron, VCI) on the unit cube with about 1e4,
3e4 and 1e5 particles.

One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/cost_growth.py                       (~40 minutes)
      python benchmarks/cost_growth.py --sizes 1e3 1e4 1e5 --sizes-3d 1e4   (~3 minutes)
      python benchmarks/cost_growth.py --figure docs/figures/cost_growth.png
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
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

METHODS = ("RK", "Q1")
PARTS = ("basis", "pattern", "kinematics", "material", "assembly")
BACKENDS = ("superlu", "pardiso", "cholmod")
clock = time.process_time


def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def timed(fn, repeat, budget):
    """Fastest of at most ``repeat`` calls (fewer once ``budget`` CPU seconds
    are spent); returns (seconds, runs, last result)."""
    best, runs, spent, out = np.inf, 0, 0.0, None
    for _ in range(repeat):
        out = None  # free the last result before the next build
        start = clock()
        out = fn()
        dt = clock() - start
        best, runs, spent = min(best, dt), runs + 1, spent + dt
        if spent > budget:
            break
    return best, runs, out


def side(particles, dim):
    """Cells per side for about ``particles`` particles on the unit square (cube)."""
    return max(2, int(round(particles ** (1.0 / dim))) - 1)


# -- one (size, basis) case, in a child process ---------------------------------
def emit(out):
    """Print what is measured so far (the parent keeps the last line, also when
    it stops the process at its time limit)."""
    print("RESULT " + json.dumps(out), flush=True)


def run_case(particles, method, repeat, budget, matrix_file, out):
    """Time the parts of one case into ``out`` (a dict, also on failure)."""
    import scipy.sparse as sp
    from skfem import Basis, ElementQuad1, ElementVector

    from skfem_rkpm import RKBasis
    from skfem_rkpm.approximation.constraints import nodal_constraint
    from skfem_rkpm.solvers.linear import available, is_symmetric, make_solver
    from skfem_rkpm.mechanics.kinematics import deformation_gradient, from_entries
    from skfem_rkpm.mechanics.materials import J2Material, swift
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import rectangle

    n = side(particles, 2)
    mesh = rectangle(1.0, 1.0, n, n)
    out.update(particles=int(mesh.nvertices), cells=int(mesh.nelements))

    def make_basis():
        if method == "Q1":
            return Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
        return RKBasis(mesh, vector=True)

    out["failed_part"] = "basis"
    out["basis"], out["basis_runs"], basis = timed(make_basis, repeat, budget)
    out["basis_mb"] = peak_mb()
    material = J2Material(200e3, 0.3, swift(589.0, 1e-4, 0.216))
    emit(out)
    out["failed_part"] = "pattern"
    out["pattern"], _, problem = timed(
        lambda: SolidProblem(basis, material, "plane_strain"), repeat, budget)
    asm = problem.assembler
    out.update(dofs=int(problem.N), points=int(problem.npoints))

    # homogeneous compression, exact for both bases with d = u(X_I), plus noise
    X = np.asarray(basis.doflocs)[:, ::2]
    u = np.stack([(1 / 0.9 - 1) * X[0], -0.1 * X[1]], axis=1).ravel()
    d = u + 1e-3 / n * np.random.default_rng(0).standard_normal(u.size)
    del X, u

    def kinematics():
        F = deformation_gradient(asm.gradient(d), problem.model)
        np.linalg.det(F)
        return F

    emit(out)
    out["failed_part"] = "kinematics"
    out["kinematics"], _, F = timed(kinematics, repeat, budget)
    emit(out)
    out["failed_part"] = "material"
    out["material"], _, (P, _, state, A) = timed(
        lambda: problem.material.update(F, problem.state, tangent=True,
                                        entries=problem.entries), repeat, budget)
    out["plastic"] = float(np.mean(state.alpha > 0))
    del F, state

    def assembly():
        P_ext, A_ext = from_entries(problem._at_entries(P), A, problem.model,
                                    problem.shape)
        f_int = asm.linear(P_ext)
        return f_int, problem._tangent_matrix(A_ext)

    emit(out)
    out["failed_part"] = "assembly"
    out["assembly"], _, (f_int, K) = timed(assembly, repeat, budget)
    del P, A
    out["nnz_row"] = K.nnz / K.shape[0]
    out["peak_mb"] = peak_mb()
    emit(out)
    out["failed_part"] = "saving the matrix"
    groups = [nodal_constraint(basis, s, c) for s in ("bottom", "top") for c in (0, 1)]
    C = sp.vstack([grp.C for grp in groups], format="csr")
    g = np.concatenate([np.full(len(grp), -0.1 if k == 3 else 0.0)
                        for k, grp in enumerate(groups)])
    out["symmetric"] = bool(is_symmetric(K, rtol=1e-10))
    out["auto"] = make_solver("auto").choose(sp.csr_matrix(
        (K.shape[0] + C.shape[0],) * 2))
    if out["auto"] == "superlu" and out["symmetric"] and "cholmod" in available():
        out["auto"] = "cholmod"
    K = K.tocsr()
    np.savez(matrix_file, data=K.data, indices=K.indices, indptr=K.indptr,
             shape=K.shape, Cdata=C.data, Cindices=C.indices, Cindptr=C.indptr,
             Cshape=C.shape, f=-f_int, g=g - C @ d)
    del out["failed_part"]


def run_solve(matrix_file, backend, repeat, budget, out):
    """Time ``solve_saddle_point`` with a fresh ``backend`` on the stored system."""
    import scipy.sparse as sp

    from skfem_rkpm.solvers.constrained import solve_saddle_point
    from skfem_rkpm.solvers.linear import make_solver

    z = np.load(matrix_file)
    K = sp.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=tuple(z["shape"]))
    C = sp.csr_matrix((z["Cdata"], z["Cindices"], z["Cindptr"]), shape=tuple(z["Cshape"]))
    f, g = z["f"], z["g"]
    del z
    before = peak_mb()
    stats = {}

    def solve():
        solver = make_solver(backend)
        x = solve_saddle_point(solver, K, f, C, g)[0]
        stats.update(solver.stats, describe=solver.describe())
        return x

    out["solve"], out["runs"], x = timed(solve, repeat, budget)
    out["residual"] = float(np.linalg.norm(C @ x - g) / max(np.linalg.norm(g), 1e-300))
    out["peak_mb"] = peak_mb()
    out["peak_mb_before"] = before
    out["describe"] = stats["describe"]


def child(args):
    limit = int(args.max_gb * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    out = {}
    try:
        if args.child == "case":
            run_case(args.particles, args.method, args.repeat, args.budget,
                     args.matrix_file, out)
        elif args.child == "solve":
            run_solve(args.matrix_file, args.backend, args.repeat, args.budget, out)
        else:
            run_3d(args.particles, args.repeat, args.budget, out)
    except MemoryError:
        out["error"] = f"out of memory (address space capped at {args.max_gb:g} GB)"
    except Exception as err:  # reported, not hidden: the parent prints it
        out["error"] = f"{type(err).__name__}: {err}"
    print("RESULT " + json.dumps(out), flush=True)


class Stopwatch:
    """Wrap ``module.name`` to add up the CPU time of its calls."""

    def __init__(self, module, name):
        self.module, self.name = module, name
        self.inner = getattr(module, name)
        self.seconds = 0.0

    def __call__(self, *args, **kwargs):
        start = clock()
        try:
            return self.inner(*args, **kwargs)
        finally:
            self.seconds += clock() - start

    def __enter__(self):
        setattr(self.module, self.name, self)
        return self

    def __exit__(self, *exc):
        setattr(self.module, self.name, self.inner)


def run_3d(particles, repeat, budget, out):
    """The 3D RK basis, with the time of the VCI correction and of its global
    sparse solve (``integration._balanced_coefficients``) in the same call."""
    from skfem import MeshHex

    import skfem_rkpm.approximation.basis as basis_module
    import skfem_rkpm.approximation.integration as integration
    from skfem_rkpm import RKBasis

    n = side(particles, 3)
    mesh = MeshHex.init_tensor(*[np.linspace(0.0, 1.0, n + 1)] * 3)
    out.update(particles=int(mesh.nvertices), cells=int(mesh.nelements))
    best = {}

    def build():
        with Stopwatch(basis_module, "vci_gradients") as vci, \
                Stopwatch(integration, "_balanced_coefficients") as balance:
            start = clock()
            basis = RKBasis(mesh, vector=True)
            total = clock() - start
        if not best or total < best["basis"]:
            best.update(basis=total, vci=vci.seconds, vci_solve=balance.seconds)
        return basis

    emit(out)
    _, out["basis_runs"], basis = timed(build, repeat, budget)
    out.update(best)
    out["points"] = int(np.asarray(basis.dx).size)
    out["dofs"] = int(basis.N)
    out["peak_mb"] = peak_mb()


def spawn(args, kind, **options):
    """Run one child; returns its dict (with 'error' on failure), its CPU and wall s."""
    command = [sys.executable, __file__, "--child", kind, "--repeat", str(args.repeat),
               "--budget", str(args.budget), "--max-gb", str(args.max_gb)]
    for key, value in options.items():
        command += [f"--{key.replace('_', '-')}", str(value)]
    start = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        done = subprocess.run(command, capture_output=True, text=True,
                              timeout=args.timeout)
    except subprocess.TimeoutExpired as err:
        lines = [line for line in (err.stdout or b"").decode().splitlines()
                 if line.startswith("RESULT ")]
        out = json.loads(lines[-1][len("RESULT "):]) if lines else {}
        out["error"] = f"over budget (stopped after {args.timeout:g} s)"
        return out
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
    out = json.loads(lines[-1][len("RESULT "):]) if lines else {}
    if done.returncode and "error" not in out:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        if done.returncode < 0:
            tail = f"killed by signal {-done.returncode} ({tail})"
        out["error"] = f"exit code {done.returncode}: {tail}"
    out["case_wall"] = time.perf_counter() - start
    out["case_cpu"] = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return out


def load_average():
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def fit(sizes, times, smallest=0):
    """Exponent p of t = a N^p over the (N, t) with N >= smallest; None if < 2."""
    pts = [(n, t) for n, t in zip(sizes, times) if t is not None and n >= smallest and t > 0]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="*",
                        default=[1e3, 3e3, 1e4, 3e4, 1e5, 3e5, 1e6],
                        help="particles in 2D")
    parser.add_argument("--sizes-3d", type=float, nargs="*", default=[1e4, 3e4, 1e5],
                        help="particles in 3D (RK basis only)")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--backends", nargs="+", default=list(BACKENDS))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--budget", type=float, default=60.0,
                        help="stop repeating a part after this many CPU seconds")
    parser.add_argument("--timeout", type=float, default=1200.0,
                        help="stop a case (or a solve) after this many seconds")
    parser.add_argument("--max-gb", type=float, default=14.0,
                        help="address-space cap of every case and solve process")
    parser.add_argument("--figure", type=Path, default=None,
                        help="write the log-log figure here (e.g. docs/figures/cost_growth.png)")
    parser.add_argument("--json", type=Path, default=None, help="also store the results")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="print the tables and draw the figure of stored results")
    parser.add_argument("--child", choices=("case", "solve", "3d"), help=argparse.SUPPRESS)
    parser.add_argument("--particles", type=float, help=argparse.SUPPRESS)
    parser.add_argument("--method", help=argparse.SUPPRESS)
    parser.add_argument("--backend", help=argparse.SUPPRESS)
    parser.add_argument("--matrix-file", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return child(args)
    if args.from_json:
        stored = json.loads(args.from_json.read_text())
        backends = [b for b in args.backends
                    if any(b in r.get("solves", {}) for r in stored["2d"])]
        report(stored["2d"], stored["3d"], backends)
        if args.figure:
            figure(stored["2d"], stored["3d"], backends, args.figure)
        return None

    import scipy
    import skfem

    from skfem_rkpm.solvers.linear import available

    installed = available()
    backends = [b for b in args.backends if b in installed]
    print(f"Python {platform.python_version()}, numpy {np.__version__}, scipy "
          f"{scipy.__version__}, scikit-fem {skfem.__version__}; one thread, CPU seconds; "
          f"cap {args.max_gb:g} GB and {args.timeout:g} s per process; backends "
          f"{', '.join(backends)}; load average at start {load_average()}\n", flush=True)
    results, failed = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for size in sorted(args.sizes):
            for method in args.methods:
                if failed.get((method, "case")):
                    continue
                matrix = os.path.join(tmp, f"{method}_{size:.0e}.npz")
                out = spawn(args, "case", particles=size, method=method, matrix_file=matrix)
                out.update(method=method, target=size, load=load_average(), solves={})
                if "error" in out:
                    where = out.get("failed_part", "the case")
                    out["error"] = f"{where}: {out['error']}"
                    failed[(method, "case")] = True
                    print(f"{method}, {size:.0e} particles: {out['error']}", flush=True)
                    results.append(out)
                    continue
                for backend in backends:
                    if backend == "cholmod" and not out["symmetric"]:
                        out["solves"][backend] = {"error": "not applicable (non-symmetric)"}
                        continue
                    if failed.get((method, backend)):
                        out["solves"][backend] = {"error": "skipped (failed at a smaller size)"}
                        continue
                    s = spawn(args, "solve", matrix_file=matrix, backend=backend)
                    s["load"] = load_average()
                    if "error" in s:
                        failed[(method, backend)] = True
                    out["solves"][backend] = s
                os.remove(matrix)
                solves = ", ".join(
                    f"{b} {s['solve']:.3g} s" if "error" not in s else f"{b}: {s['error']}"
                    for b, s in out["solves"].items())
                print(f"{method}, {out['particles']:,} particles: basis {out['basis']:.3g} s, "
                      f"pattern {out['pattern']:.3g} s, material {out['material']:.3g} s, "
                      f"assembly {out['assembly']:.3g} s; {solves}; case {out['case_wall']:.0f} s "
                      f"wall, load {out['load']}", flush=True)
                results.append(out)
        results_3d = []
        for size in sorted(args.sizes_3d):
            out = spawn(args, "3d", particles=size)
            out.update(target=size, load=load_average())
            print(f"3D RK basis, {size:.0e} particles: "
                  + (out["error"] if "error" in out else
                     f"{out['basis']:.3g} s ({out['points']:,} Gauss points, peak "
                     f"{out['peak_mb']:.0f} MB)"), flush=True)
            results_3d.append(out)
            if "error" in out:
                break
    report(results, results_3d, backends)
    if args.json:
        args.json.write_text(json.dumps({"2d": results, "3d": results_3d}, indent=1))
    if args.figure:
        figure(results, results_3d, backends, args.figure)
        print(f"\nfigure: {args.figure}")


def cell(x, digits=3):
    return "" if x is None else f"{x:.{digits}g}"


def short(message, length=90):
    """One line of at most ``length`` characters (for a table cell)."""
    message = " ".join(str(message).split())
    return message if len(message) <= length else message[:length - 3] + "..."


def solve_cell(s):
    if "error" in s:
        return short(s["error"])
    return f"{s['solve']:.3g}"


def series(results, method, key):
    """(particles, seconds or None) of one part of one method."""
    rows = [r for r in results if r["method"] == method]
    out = []
    for r in rows:
        n = r.get("particles", r["target"])
        if key in BACKENDS:
            s = r.get("solves", {}).get(key, {})
            out.append((n, s.get("solve")))
        else:
            out.append((n, r.get(key)))
    return out


def report(results, results_3d, backends):
    for method in METHODS:
        rows = [r for r in results if r["method"] == method]
        if not rows:
            continue
        print(f"\n{method}: CPU seconds per part (fastest of the runs; solve: first "
              "factorization and solve of the saddle-point system)\n")
        head = ("| particles | dofs | Gauss points | nnz/row | basis | pattern | kinematics "
                "| material | assembly | " + " | ".join(f"solve {b}" for b in backends)
                + " | auto picks | peak MB (case) | load avg |")
        print(head)
        print("|---:|---:|---:|---:|" + "---:|" * (5 + len(backends)) + "---|---:|---|")
        for r in rows:
            if "error" in r and "basis" not in r:
                print(f"| {r.get('particles', r['target']):,.0f} | | | | {short(r['error'])} "
                      f"| | | | |" + " |" * len(backends) + f" | | {r['load']} |")
                continue
            cells = [f"{r['particles']:,}", f"{r.get('dofs', 0):,}" if "dofs" in r else "",
                     f"{r.get('points', 0):,}" if "points" in r else "",
                     cell(r.get("nnz_row"), 3)]
            cells += [cell(r.get(p)) for p in PARTS]
            if "error" in r:
                cells[4 + len([p for p in PARTS if p in r])] = short(r["error"])
            cells += [solve_cell(r["solves"][b]) if b in r.get("solves", {}) else ""
                      for b in backends]
            cells += [r.get("auto", ""), f"{r['peak_mb']:.0f}" if "peak_mb" in r else "", r["load"]]
            print("| " + " | ".join(cells) + " |")
        print(f"\n{method}: peak memory of the solve processes (MB; the matrices "
              "loaded before the factorization take the first number)\n")
        print("| particles | " + " | ".join(backends) + " |")
        print("|---:|" + "---:|" * len(backends))
        for r in rows:
            if not r.get("solves"):
                continue
            cells = []
            for b in backends:
                s = r["solves"].get(b, {})
                cells.append("" if "error" in s or not s else
                             f"{s['peak_mb_before']:.0f} → {s['peak_mb']:.0f}")
            print(f"| {r['particles']:,} | " + " | ".join(cells) + " |")

    print("\nFitted exponent p of t ≈ a N^p (N particles; least squares of log t "
          "against log N over the sizes that ran; in brackets: from 1e4 particles on)\n")
    keys = list(PARTS) + list(backends)
    print("| basis | " + " | ".join(k if k in PARTS else f"solve {k}" for k in keys) + " |")
    print("|---|" + "---:|" * len(keys))
    for method in METHODS:
        if not any(r["method"] == method for r in results):
            continue
        cells = []
        for key in keys:
            pts = series(results, method, key)
            p_all = fit(*zip(*pts)) if pts else None
            p_big = fit(*zip(*pts), smallest=9000) if pts else None
            ran = [n for n, t in pts if t is not None]
            cells.append("" if p_all is None else
                         f"{p_all:.2f} ({cell(p_big, 3)}) to {max(ran):.0e}")
        print(f"| {method} | " + " | ".join(cells) + " |")

    print("\nRK / Q1 time ratio on the same mesh\n")
    print("| particles | " + " | ".join(keys) + " |")
    print("|---:|" + "---:|" * len(keys))
    q1 = {r["target"]: r for r in results if r["method"] == "Q1"}
    for r in results:
        if r["method"] != "RK" or r["target"] not in q1:
            continue
        q = q1[r["target"]]
        cells = []
        for key in keys:
            a = r.get(key) if key in PARTS else r.get("solves", {}).get(key, {}).get("solve")
            b = q.get(key) if key in PARTS else q.get("solves", {}).get(key, {}).get("solve")
            cells.append(f"{a / b:.1f}" if a and b else "")
        print(f"| {r.get('particles', r['target']):,.0f} | " + " | ".join(cells) + " |")

    print("\nAssembly + material against the fastest sparse factorization (the target: "
          "at most 1 from 1e5 particles on)\n")
    print("| particles | basis | material + assembly s | fastest solve s (backend) | ratio |")
    print("|---:|---|---:|---:|---:|")
    for r in results:
        if "material" not in r or "assembly" not in r:
            continue
        solves = {b: s["solve"] for b, s in r.get("solves", {}).items() if "solve" in s}
        if not solves:
            continue
        b = min(solves, key=solves.get)
        work = r["material"] + r["assembly"]
        print(f"| {r['particles']:,} | {r['method']} | {work:.3g} | {solves[b]:.3g} ({b}) | "
              f"{work / solves[b]:.2f} |")

    if results_3d:
        print("\n3D: RK basis (RKBasis(MeshHex, vector=True), 27 Gauss points per cell, VCI; "
              "*VCI s*: vci_gradients, *of which solve*: its global sparse solve)\n")
        print("| particles | cells | Gauss points | dofs | basis s | VCI s | of which solve s "
              "| µs per Gauss point | peak MB | load avg |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
        for r in results_3d:
            if "basis" not in r:
                print(f"| {r.get('particles', r['target']):,.0f} | {r.get('cells', '')} | | | "
                      f"{short(r.get('error', ''))} | | | | | {r['load']} |")
                continue
            print(f"| {r['particles']:,} | {r['cells']:,} | {r['points']:,} | {r['dofs']:,} | "
                  f"{r['basis']:.3g} | {cell(r.get('vci'))} | {cell(r.get('vci_solve'))} | "
                  f"{1e6 * r['basis'] / r['points']:.2f} | {r['peak_mb']:.0f} | {r['load']} |")
        pts = [(r["particles"], r["basis"]) for r in results_3d if "basis" in r]
        if len(pts) > 1:
            print(f"\nfitted exponent of the 3D basis: {fit(*zip(*pts)):.2f}")


def figure(results, results_3d, backends, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
    colors = {"basis": "C0", "pattern": "C7", "kinematics": "C8", "material": "C1",
              "assembly": "C2", "superlu": "C3", "pardiso": "C4", "cholmod": "C5"}
    for ax, method in zip(axes, METHODS):
        for key in list(PARTS) + list(backends):
            pts = [(n, t) for n, t in series(results, method, key) if t is not None]
            if not pts:
                continue
            n, t = zip(*pts)
            p = fit(n, t, smallest=9000) if len(pts) > 2 else fit(n, t)
            label = (key if key in PARTS else f"solve, {key}") + (
                f" (p = {p:.2f})" if p is not None else "")
            ax.loglog(n, t, "o-" if key in PARTS else "s--", color=colors[key], label=label)
        if method == "RK" and results_3d:
            pts = [(r["particles"], r["basis"]) for r in results_3d if "basis" in r]
            if pts:
                n, t = zip(*pts)
                ax.loglog(n, t, "^:", color="C0", label="basis, 3D hexahedra")
        ns = np.array([1e3, 1e6])
        ax.loglog(ns, 1e-3 * ns / 1e3, color="0.7", lw=0.8, ls=":", label="∝ N")
        ax.loglog(ns, 1e-3 * (ns / 1e3) ** 1.5, color="0.7", lw=0.8, ls="-.",
                  label="∝ N^1.5")
        ax.set_xlabel("particles (nodes)")
        ax.set_title({"RK": "RKBasis(mesh, vector=True) (c = 2, order 1, VCI)",
                      "Q1": "FEM Q1 on the same mesh"}[method])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("CPU seconds (one core)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
