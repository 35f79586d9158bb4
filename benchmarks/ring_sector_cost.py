"""Where the RKPM ring sector's CPU goes: factorizations, solves and the rest.

Runs ``skfem-rkpm run ring_sector`` (RKPM, 3696 unknowns, weak symmetry
planes, one of them skew) in this process for its first ``--steps`` load
steps at the scene's own step size (``steps.count`` and the platen's travel
cut in proportion), fields and figures off, once per ``--reuse`` mode of
``steps.reuse_factorization``, and reports:

* the Newton iterations of all attempts;
* the factorizations (all of them: the tangents', those of the touching and
  stick predictions, the fallbacks of a reused factorization), the
  triangular solves with the factors (a solve with several right-hand sides
  counts once), the matrices solved by GMRES with an earlier factorization
  (*reused*), their GMRES iterations and fallbacks;
* CPU seconds (``time.process_time``) of the Newton loop, of the tangent
  assembly, of the factorizations, of the solves and the rest of Newton
  (residual evaluations, GMRES work outside the solves, contact, conditions);
* the inner-diameter change and the full-ring force at the last step.

``--whole`` runs the whole scene instead, in a fresh process per mode
(``_whole_runs.run_scene``): whole-process CPU, peak memory, iterations and
the result.  ``--repeat N`` runs each case N times and reports medians.
One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/ring_sector_cost.py                    (~4 minutes)
      python benchmarks/ring_sector_cost.py --steps 10 --reuse off on
      python benchmarks/ring_sector_cost.py --whole --reuse auto  (~5-10 minutes a mode)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from _whole_runs import history, ring_id_change, run_scene  # noqa: E402
from iteration_share import _Clock, _instrument  # noqa: E402

#: the scene's load steps and the platen's travel (mm) over them
SCENE_STEPS, TRAVEL = 100, 10.0

COUNTS = ("factorizations", "solves", "reused", "gmres_iterations", "fallbacks")


def _solver_counts(solver):
    """The counts of ``COUNTS`` over the backends of an ``auto`` solver."""
    backends = getattr(solver, "_backends", {}).values() or [solver]
    return {k: sum(b.stats.get(k, 0) for b in backends) for k in COUNTS}


def measure(steps, reuse):
    """Counts, CPU seconds per part and the result of the first ``steps``
    load steps with ``reuse_factorization = reuse``."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene
    from skfem_rkpm.solvers import backend

    settings = ["output.fields=false", "output.figures=false",
                f"steps.reuse_factorization={reuse}"]
    if steps < SCENE_STEPS:
        settings += [f"steps.count={steps}",
                     f"tools.platen.motion=[0.0, 0.0, {-TRAVEL * steps / SCENE_STEPS}]"]
    sim = runner.build(load_scene(builtin_scenes()["ring_sector"], settings), "rkpm")
    clock, patches = _Clock(), []
    clock.seconds["solve"] = 0.0
    clock.depth["solve"] = clock.calls["solve"] = 0
    _instrument(clock, patches)
    made = []

    def linear_solver(sim, original=runner._linear_solver):
        made.append(original(sim))
        return made[-1]

    patches += [(runner, "_linear_solver", runner._linear_solver),
                (backend.Solver, "solve", backend.Solver.solve)]
    runner._linear_solver = linear_solver
    backend.Solver.solve = clock.wrap("solve", backend.Solver.solve)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            runner.run(sim, Path(tmp) / "run", progress=False)
            rows, totals = history(Path(tmp) / "run")
    finally:
        for owner, name, value in reversed(patches):
            setattr(owner, name, value)
    counts = _solver_counts(made[0])
    seconds = dict(clock.seconds)
    seconds["rest"] = seconds["Newton"] - sum(seconds[p] for p in
                                              ("assembly", "factorization", "solve"))
    last = rows[-1]
    return dict(counts, iterations=totals["all iterations"], steps=totals["steps"],
                cutbacks=totals["cut-backs"], seconds=seconds,
                result=f"ID {ring_id_change(last):+.3f} %, "
                       f"F {-24e-3 * float(last['reaction platen z']):.2f} kN")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10,
                        help="first load steps of the scene's 100 (default %(default)s)")
    parser.add_argument("--reuse", nargs="*", default=["off", "on"],
                        help="steps.reuse_factorization modes (default: %(default)s)")
    parser.add_argument("--whole", action="store_true", help="whole runs, fresh processes")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    if args.whole:
        print("| reuse | whole-process CPU s | peak MB | steps | all iterations | "
              "cut-backs | result |")
        print("|---|---:|---:|---:|---:|---:|---|")
        for mode in args.reuse:
            with tempfile.TemporaryDirectory() as tmp:
                runs = [run_scene("ring_sector", "rkpm",
                                  [f"steps.reuse_factorization={mode}"], Path(tmp) / f"r{k}")
                        for k in range(args.repeat)]
                rows, totals = history(Path(tmp) / "r0")
            last = rows[-1]
            print(f"| {mode} | {statistics.median(r[0] for r in runs):.1f} | "
                  f"{max(r[1] for r in runs):.0f} | {totals['steps']} | "
                  f"{totals['all iterations']} | {totals['cut-backs']} | "
                  f"ID {ring_id_change(last):+.3f} %, "
                  f"F {-24e-3 * float(last['reaction platen z']):.2f} kN |", flush=True)
        print(f"load average at end: {os.getloadavg()[0]:.1f}")
        return
    parts = ("Newton", "assembly", "factorization", "solve", "rest")
    print(f"first {args.steps} of {SCENE_STEPS} load steps; CPU seconds")
    print("| reuse | iterations | factorizations | solves | reused | GMRES iterations | "
          "fallbacks | " + " | ".join(parts) + " | result |")
    print("|---|" + "---:|" * (6 + len(parts)) + "---|")
    for mode in args.reuse:
        runs = [measure(args.steps, mode) for _ in range(args.repeat)]
        first = runs[0]
        per = {p: statistics.median(r["seconds"][p] for r in runs) for p in parts}
        print(f"| {mode} | {first['iterations']} | "
              + " | ".join(str(first[k]) for k in COUNTS) + " | "
              + " | ".join(f"{per[p]:.1f}" for p in parts)
              + f" | {first['result']} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
