"""The billet at real sizes: where an iteration goes as the unknowns grow.

Runs ``billet_3d`` (RKPM or FEM Hex1) at ``geometry.divisions`` in this
process, fields and figures off, with the clocks of
``iteration_share.py`` (assembly, factorizations, solid, contact,
prediction, all of Newton; CPU seconds, ``time.process_time``), and
records

* *build*: ``runner.build`` (mesh, basis, assembler, tools), CPU seconds;
* the parts per iteration (all iterations of all attempts);
* iterations, sub-steps, cut-backs and the platen force (whole billet,
  4x the modelled eighth) at the steps done;
* the peak resident memory of the process (``VmHWM``) and its CPU seconds
  (imports included).

``--tangents N`` stops before the tangent N + 1 is formed, inside a step;
the whole iteration is then per tangent (the whole runs of the billet
form one tangent per iteration: the ``calls`` recorded say how many).
``--steps N`` stops after N converged steps of the scene's 50 (the
first steps of the whole run, same step size): enough to measure an
iteration of a size that takes too long to complete, and project the
whole run from the iterations of a smaller size.

A run stopped by SIGINT or SIGTERM (``timeout``) or out of memory still
reports what it measured, marked ``stopped``.  Each case appends one JSON
line to ``--json``; ``--figure PATH`` draws from that file, against the
unknowns, the whole iteration and each part per call (one tangent, one
factorization, one solid or contact evaluation); a factorization that ran
out of memory is drawn as a lower bound (an open triangle).

``--reuse on`` solves with the last factorization kept as the
preconditioner of GMRES (``steps.reuse_factorization``); the row then has
the reused matrices, GMRES iterations and fallbacks (``reuse``).

One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/real_size.py --method fem --divisions 16 8 12 --steps 5 --json j.jsonl
      python benchmarks/real_size.py --from-json j.jsonl --figure docs/figures/real_size_billet.png
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from _timing import resident_mb  # noqa: E402
from iteration_share import PARTS, _Clock, _instrument  # noqa: E402



class _Enough(Exception):
    """Raised from the step callback once ``--steps`` steps are done."""


def _stop_after(runner, steps, done, patches):
    """Make ``runner.newton_steps`` collect its converged steps in ``done``
    and stop after ``steps`` of them (None: run to the end)."""
    inner = runner.newton_steps

    def limited(*args, on_step=None, **kwargs):
        def counted(record, d, evaluation):
            on_step(record, d, evaluation)
            done.append(record)
            if steps and len(done) >= steps:
                raise _Enough
        return inner(*args, on_step=counted, **kwargs)

    patches.append((runner, "newton_steps", inner))
    runner.newton_steps = limited


def _stop_at_tangent(problem, tangents, patches):
    """Stop the run before its tangent number ``tangents + 1`` is formed."""
    inner = problem.Evaluation.K
    formed = []

    def K(self):
        if self._form_tangent is not None:
            if len(formed) >= tangents:
                raise _Enough
            formed.append(1)
        return inner.fget(self)

    patches.append((problem.Evaluation, "K", inner))
    problem.Evaluation.K = property(K)


def _watch_factors(backend, seen, patches):
    """Keep in ``seen`` the size of the last matrix factored, its entries
    and, for SuperLU, the entries of its factors."""
    inner = backend.Solver._factor_timed

    def factor(self, A):
        out = inner(self, A)
        lu = getattr(self, "_lu", None)
        seen.update(n=int(A.shape[0]), nnz=int(getattr(A, "nnz", A.size)),
                    factor_nnz=int(lu.L.nnz + lu.U.nnz) if hasattr(lu, "L") else None,
                    solver=self.describe())
        print(f"factorization {self.stats['factorizations']}: {seen}, "
              f"CPU {time.process_time():.1f} s, peak {resident_mb():.0f} MB",
              file=sys.stderr, flush=True)
        return out

    patches.append((backend.Solver, "_factor_timed", inner))
    backend.Solver._factor_timed = factor


def _watch_reuse(patches, solvers):
    """Keep in ``solvers`` the linear solver the run makes (for the counts of
    its reused factorizations)."""
    from skfem_rkpm.runs import runner
    inner = runner._linear_solver

    def made(sim):
        solver = inner(sim)
        solvers.append(solver)
        return solver

    patches.append((runner, "_linear_solver", inner))
    runner._linear_solver = made


def measure(method, divisions, steps=None, tangents=None, reuse="off"):
    """One case: a dict of the measured numbers (see the module docstring)."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()["billet_3d"], [
        "output.fields=false", "output.figures=false", f"steps.reuse_factorization={reuse}",
        f"geometry.divisions=[{','.join(str(int(n)) for n in divisions)}]"])
    load = os.getloadavg()[0]
    start = time.process_time()
    sim = runner.build(scene, method)
    build = time.process_time() - start
    unknowns = int(sim.problem.N)
    build_mb = resident_mb()
    print(f"built: {unknowns} unknowns, {build:.1f} s, peak {build_mb:.0f} MB",
          file=sys.stderr, flush=True)
    clock, patches, history = _Clock(), [], []
    _stop_after(runner, steps, history, patches)
    _instrument(clock, patches)
    from skfem_rkpm.solvers import backend
    factored = {}
    _watch_factors(backend, factored, patches)
    solvers = []
    _watch_reuse(patches, solvers)
    if tangents:
        from skfem_rkpm.mechanics import problem
        _stop_at_tangent(problem, tangents, patches)
    stopped = None
    try:
        runner.run(sim, None, progress=False)
    except _Enough:
        pass
    except (KeyboardInterrupt, MemoryError) as err:  # a time limit (SIGINT, SIGTERM) or the cap
        stopped = type(err).__name__
    finally:
        for owner, name, value in reversed(patches):
            setattr(owner, name, value)
    row = _summary(method, divisions, unknowns, build, build_mb, load, clock, history,
                   steps, tangents)
    row["factored"], row["stopped"] = factored, stopped
    row["reuse_factorization"] = reuse
    row["reuse"] = getattr(solvers[0], "reuse_stats", None) if solvers else None
    row["residuals"] = [r.residuals for r in history]
    row["gmres_per_solve"] = [b.iterations for b in getattr(solvers[0], "_backends", {}).values()
                              if hasattr(b, "refactor")] if solvers else []
    return row


def _summary(method, divisions, unknowns, build, build_mb, load, clock, history, steps,
             tangents=None):
    iterations = sum(r.spent_iterations or r.iterations for r in history)
    # stopped inside a step: per tangent formed instead of per iteration
    per = clock.calls["assembly"] if tangents else iterations
    # the platen's force on the modelled eighth, (Fx, Fy, Fz) in N: the whole
    # billet's press force is 4 |Fz|, here in kN
    # (load factor t = 1: 50 % height reduction)
    forces = {f"{round(50 * r.t)} %": 4e-3 * abs(float(r.reactions["platen"][-1]))
              for r in history if abs(50 * r.t - round(50 * r.t)) < 1e-9
              and round(50 * r.t) in (25, 50) and "platen" in r.reactions}
    return {
        "method": method, "divisions": list(divisions), "unknowns": unknowns,
        "steps_done": len(history), "steps_asked": steps, "tangents_asked": tangents,
        "tangents": clock.calls["assembly"], "calls": clock.calls,
        "attempts": sum(r.attempts for r in history),
        "cutbacks": sum(r.cutbacks for r in history),
        "iterations": iterations, "factorizations": clock.calls["factorization"],
        "process_cpu_s": time.process_time(), "build_s": build, "build_peak_mb": build_mb, "peak_mb": resident_mb(),
        "seconds": clock.seconds,
        "per_iteration_ms": {p: 1e3 * clock.seconds[p] / max(per, 1) for p in PARTS},
        "force_kN": forces, "load_start": load, "load_end": os.getloadavg()[0],
    }


#: the parts drawn: (label, part, per what) -- per call of the part, so that
#: the first steps (more factorizations per iteration: the predictions) and
#: whole runs compare
DRAWN = (("whole iteration", "Newton", "iteration"), ("tangent (assembly)", "assembly", "call"),
         ("one factorization", "factorization", "call"), ("solid evaluation", "solid", "call"),
         ("contact evaluation", "contact", "call"))


def per_call(row, part, per):
    """CPU seconds of ``part`` per iteration (per tangent for a run stopped
    inside a step) or per call, and whether it is only a lower bound (a
    factorization that did not finish)."""
    seconds = row["seconds"][part]
    if per == "iteration":
        count = row["tangents"] if row.get("tangents_asked") else row["iterations"]
        return seconds / max(count, 1), False
    unfinished = part == "factorization" and row.get("stopped") and not row["factored"]
    return seconds / max(row["calls"][part], 1), bool(unfinished)


def figure(rows, path):
    """Parts per iteration or call against the unknowns, FEM and RKPM, log-log."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharey=True)
    for ax, method, title in zip(axes, ("fem", "rkpm"), ("FEM Hex1", "RKPM")):
        cases = sorted((r for r in rows if r["method"] == method),
                       key=lambda r: r["unknowns"])
        for (label, part, per), marker in zip(DRAWN, "osd^v"):
            points = [(r["unknowns"], *per_call(r, part, per)) for r in cases]
            done = [(n, t) for n, t, low in points if not low]
            if part == "Newton":  # a run stopped in its first tangent has no iteration
                done = [(n, t) for (n, t), r in zip(done, cases) if r["tangents"] > 1]
            line, = ax.loglog(*zip(*done), marker=marker, label=f"{label} (per {per})")
            for n, t, low in points:
                if low:
                    ax.plot(n, t, marker="^", ms=11, color=line.get_color(), mfc="none")
                    ax.annotate("not finished:\nout of memory\n(14 GB cap)", (n, t),
                                textcoords="offset points", xytext=(-80, -32), fontsize=7)
        ax.set_title(f"billet_3d, {title}")
        ax.set_xlabel("unknowns")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("CPU seconds (one core)")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", choices=("fem", "rkpm"), default="rkpm")
    parser.add_argument("--divisions", type=int, nargs=3, default=[8, 4, 6])
    parser.add_argument("--steps", type=int, default=None,
                        help="stop after this many converged steps (default: all)")
    parser.add_argument("--tangents", type=int, default=None,
                        help="stop before this many + 1 tangents are formed; the parts are "
                             "then per tangent, not per iteration")
    parser.add_argument("--reuse", choices=("off", "on", "auto"), default="off",
                        help="steps.reuse_factorization: GMRES preconditioned by the last "
                             "factorization (default off: every tangent factored)")
    parser.add_argument("--json", type=Path, default=None, help="append the case here")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="no run: draw the cases of this file")
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    if args.from_json is None:
        row = measure(args.method, args.divisions, args.steps, args.tangents, args.reuse)
        print(json.dumps(row, indent=1), flush=True)
        if args.json is not None:
            with open(args.json, "a", encoding="utf-8") as out:
                out.write(json.dumps(row) + "\n")
        rows = [row]
    else:
        rows = [json.loads(line) for line in args.from_json.read_text().splitlines() if line]
    if args.figure is not None:
        figure(rows, args.figure)


if __name__ == "__main__":
    main()
