"""Run the whole benchmark suite and write its tables and figures into docs/.

Every script in ``benchmarks/`` runs in a process of its own (one core:
``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` are
1, ``MPLBACKEND=Agg``), with the settings the results in
``docs/benchmarks/`` were measured with, or with smaller sizes under
``--quick``.  The Markdown tables each script prints are saved as
``<out>/<script>.md``, headed by the command, the date, the commit, the
load average before and after, and the CPU and wall seconds of the run;
``<out>/index.md`` lists the runs.  Figures go to ``docs/figures/`` (full
runs) or to ``<out>`` (``--quick``), so that a quick check never
overwrites the figures of the documentation.

Run (from the repository root):

    python benchmarks/run_all.py              # everything, about 1.5 hours of CPU
    python benchmarks/run_all.py --quick      # smaller sizes, about 9 minutes of CPU
    python benchmarks/run_all.py --only shape_rate plastic_trade
    python benchmarks/run_all.py --list       # the scripts and their arguments

Default output: ``docs/benchmarks/runs/`` (full) and ``docs/benchmarks/quick/``
(``--quick``); the pages of ``docs/benchmarks/`` itself are written by hand
and never overwritten.  A script that fails is reported (its last error
lines are saved with its output) and the others still run; the exit code is
1 if any failed.
"""

import argparse
import datetime
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# name: (full arguments, quick arguments, estimated CPU minutes full / quick);
# "{figures}" is replaced by the folder of the figures.  Scripts of benchmarks/
# missing here run with their defaults in both modes.
SUITE = {
    "locking_study": ([], ["prandtl", "compression", "cook"], (12, 1)),
    "shape_rate": ([], ["--max-points", "1e5", "--repeat", "2"], (2, 0.5)),
    "assembly_time": ([], ["--sizes", "20", "40", "80"], (2, 0.5)),
    "newton_iteration": (["--nodes", "1e3", "1e4", "4e4"], ["--nodes", "1e3", "1e4"],
                         (10, 1)),
    "elasticity_trade": (["--out", "{figures}"], ["--levels", "4", "8", "16", "--out",
                                                  "{figures}"], (3, 0.5)),
    "ring_iteration": ([], ["--repeat", "5"], (1, 1)),
    "ring_steps": ([], ["--steps", "50", "100", "200"], (2, 1)),
    "linear_solvers": ([], ["--dofs", "1e3", "1e4"], (30, 3)),
    "cost_growth": (["--figure", "{figures}/cost_growth.png"],
                    ["--sizes", "1e3", "3e3", "1e4", "3e4", "--sizes-3d", "1e3", "3e3",
                     "--figure", "{figures}/cost_growth.png"], (20, 3)),
    "plastic_trade": (["--figure", "{figures}/plastic_trade.png"],
                      ["--levels", "4", "8", "16", "--reference", "16", "32", "64",
                       "--figure", "{figures}/plastic_trade.png"], (3, 1)),
    "petsc_mpi": ([], ["--sizes", "50"], (10, 2)),
    "form_assembly": ([], ["--no-skfem", "--repeat", "3"], (1.5, 0.5)),
    "skfem_examples": ([], ["--repeat", "1"], (1, 0.5)),
    "published_examples": ([], ["--repeat", "1"], (1, 0.3)),
    "surface_projection": ([], ["--points", "2e3", "--repeat", "3"], (1, 0.2)),
    "vci_symmetry": ([], ["--levels", "4", "8", "--supports", "2", "--repeat", "1"],
                     (6, 0.5)),
    "basis_build": ([], ["--sizes", "1e4", "17227", "--repeat", "1"], (3, 0.5)),
    "basis_memory": (["--particles", "1e5"], ["--particles", "17227"], (0.5, 0.1)),
    "interpolating_basis": ([], ["--repeat", "1"], (0.5, 0.3)),
    "saddle_point": ([], ["--scene", "billet_3d", "--repeat", "1"], (1, 0.2)),
    "dynamic_ring": (["--figure", "{figures}/dynamic_ring.png"], ["--quick", "--repeat", "1"],
                     (15, 0.5)),
    "run_overhead": ([], ["--cases", "ring", "billet fem", "--repeat", "1"], (2, 0.5)),
}

#: Python modules a script needs beyond the package's own dependencies; the
#: script is reported as skipped where one is missing
REQUIRES = {"petsc_mpi": ["petsc4py", "mpi4py"]}


def discover():
    """The suite's scripts, then any other script of benchmarks/ (defaults)."""
    others = sorted(p.stem for p in HERE.glob("*.py")
                    if p.stem not in SUITE and p.stem != "run_all" and not p.stem.startswith("_"))
    return {**SUITE, **{name: ([], [], (None, None)) for name in others}}


def missing_modules(name):
    import importlib.util

    return [m for m in REQUIRES.get(name, []) if importlib.util.find_spec(m) is None]


def load_average():
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def commit():
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, capture_output=True, text=True).stdout.strip()
        return out + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run(name, arguments, out, timeout):
    """Run one script; write ``out/<name>.md``; return a summary dict."""
    command = [sys.executable, str(HERE / f"{name}.py"), *arguments]
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1", MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    shown = " ".join(["python", f"benchmarks/{name}.py", *arguments])
    print(f"== {shown}", flush=True)
    load_before, started = load_average(), datetime.datetime.now()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter()
    try:
        done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=timeout)
        stdout, stderr, code = done.stdout, done.stderr, done.returncode
    except subprocess.TimeoutExpired as err:
        stdout = (err.stdout or b"").decode() if isinstance(err.stdout, bytes) else (
            err.stdout or "")
        stderr, code = f"stopped after {timeout:g} s (--timeout)", "timeout"
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    ok = code == 0
    head = [f"# {name}", "",
            f"Command: `{shown}`  ",
            f"Started {started:%Y-%m-%d %H:%M}, commit `{commit()}`, "
            f"{os.cpu_count()} cores visible, one thread per process.  ",
            f"Load average (1, 5, 15 min) before: {load_before}; after: {load_average()}.  ",
            f"CPU {cpu:.0f} s (this script and the processes it started), wall {wall:.0f} s."
            + ("" if ok else f"  \n**Failed** (exit code {code})."), "", ""]
    body = stdout.rstrip() + "\n"
    if not ok:
        tail = "\n".join(stderr.strip().splitlines()[-20:])
        body += f"\nLast lines of the error output:\n\n```text\n{tail}\n```\n"
    (out / f"{name}.md").write_text("\n".join(head) + body)
    print(f"   {'ok' if ok else 'FAILED'}: {cpu:.0f} CPU s, {wall:.0f} s wall -> "
          f"{out / f'{name}.md'}", flush=True)
    return dict(name=name, command=shown, ok=ok, cpu=cpu, wall=wall, load=load_before)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (~10 minutes)")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        help="run these scripts only (names as in --list)")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder of the tables (default docs/benchmarks/runs, with "
                             "--quick docs/benchmarks/quick)")
    parser.add_argument("--figures", type=Path, default=None,
                        help="folder of the figures (default docs/figures, with --quick "
                             "the tables' folder)")
    parser.add_argument("--timeout", type=float, default=3 * 3600.0,
                        help="stop a script after this many seconds")
    parser.add_argument("--list", action="store_true", help="print the suite and exit")
    args = parser.parse_args()

    out = args.out or ROOT / "docs" / "benchmarks" / ("quick" if args.quick else "runs")
    out = out.resolve()
    figures = (args.figures or (out if args.quick else ROOT / "docs" / "figures")).resolve()
    suite = discover()
    names = args.only or list(suite)
    unknown = [name for name in names if name not in suite]
    if unknown:
        parser.error(f"no benchmark {', '.join(unknown)}; there are {', '.join(suite)}")
    if args.list:
        for name in names:
            full, quick, (m_full, m_quick) = suite[name]
            need = f"; needs {', '.join(REQUIRES[name])}" if name in REQUIRES else ""
            print(f"{name}: full {' '.join(full) or '(defaults)'}"
                  + (f" (~{m_full:g} CPU min)" if m_full else "")
                  + f"; --quick {' '.join(quick) or '(defaults)'}"
                  + (f" (~{m_quick:g} CPU min)" if m_quick else "") + need)
        return 0
    out.mkdir(parents=True, exist_ok=True)
    figures.mkdir(parents=True, exist_ok=True)

    def relative(path):
        return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)

    summaries = []
    for name in names:
        full, quick, _ = suite[name]
        arguments = [a.replace("{figures}", relative(figures))
                     for a in (quick if args.quick else full)]
        missing = missing_modules(name)
        if missing:
            shown = " ".join(["python", f"benchmarks/{name}.py", *arguments])
            print(f"== {shown}\n   skipped: {', '.join(missing)} not installed", flush=True)
            (out / f"{name}.md").write_text(
                f"# {name}\n\nCommand: `{shown}`  \nSkipped on "
                f"{datetime.datetime.now():%Y-%m-%d %H:%M}: {', '.join(missing)} not "
                "installed (see docs/benchmarks/partitioned.md).\n")
            summaries.append(dict(name=name, command=shown, ok=None, cpu=0.0, wall=0.0,
                                  load=load_average()))
            continue
        summaries.append(run(name, arguments, out, args.timeout))

    index = out / "index.md"
    lines = [f"# Benchmark runs{' (--quick)' if args.quick else ''}", "",
             f"`python benchmarks/run_all.py{' --quick' if args.quick else ''}`, "
             f"{datetime.datetime.now():%Y-%m-%d %H:%M}, commit `{commit()}`; "
             f"figures in `{relative(figures)}`.", "",
             "| script | command | result | CPU s | wall s | load average before |",
             "|---|---|---|---:|---:|---|"]
    if index.exists() and args.only:  # keep the rows of the scripts not rerun
        kept = [line for line in index.read_text().splitlines()
                if line.startswith("| [") and line.split("]")[0][3:] not in names]
        lines += kept
    for s in summaries:
        result = {True: "ok", False: "failed", None: "skipped"}[s["ok"]]
        lines.append(f"| [{s['name']}]({s['name']}.md) | `{s['command']}` | "
                     f"{result} | {s['cpu']:.0f} | {s['wall']:.0f} | {s['load']} |")
    ran = [s for s in summaries if s["ok"] is not None]
    lines += ["", f"Total: {sum(s['cpu'] for s in ran):.0f} CPU s, "
                  f"{sum(s['wall'] for s in ran):.0f} s wall."]
    index.write_text("\n".join(lines) + "\n")
    print(f"index: {relative(index)}")
    return 0 if all(s["ok"] is not False for s in summaries) else 1


if __name__ == "__main__":
    sys.exit(main())
