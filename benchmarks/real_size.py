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
the parts are then per tangent (whole runs of the billet form 0.9-1 tangent
per iteration: the ``calls`` recorded say how many).
``--steps N`` stops after N converged steps of the scene's 50 (the
first steps of the whole run, same step size): enough to measure an
iteration of a size that takes too long to complete; the projection of
the whole run is ``build + (time per iteration) x (iterations of the whole
run at the next smaller size)`` and is printed as such.

Each case appends one JSON line to ``--json``; ``--figure PATH`` draws
the parts per iteration against the unknowns from that file.

One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/real_size.py --method fem --divisions 16 8 12 --steps 5 --json j.jsonl
      python benchmarks/real_size.py --from-json j.jsonl --figure docs/figures/real_size.png
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from _timing import resident_mb  # noqa: E402
from iteration_share import PARTS, _Clock, _instrument  # noqa: E402

SHOWN = ("Newton", "assembly", "factorization", "solid", "contact")


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


def measure(method, divisions, steps=None, tangents=None):
    """One case: a dict of the measured numbers (see the module docstring)."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()["billet_3d"], [
        "output.fields=false", "output.figures=false",
        f"geometry.divisions=[{','.join(str(int(n)) for n in divisions)}]"])
    load = os.getloadavg()[0]
    start = time.process_time()
    sim = runner.build(scene, method)
    build = time.process_time() - start
    unknowns = int(sim.problem.N)
    build_mb = resident_mb()
    clock, patches, history = _Clock(), [], []
    _stop_after(runner, steps, history, patches)
    _instrument(clock, patches)
    if tangents:
        from skfem_rkpm.mechanics import problem
        _stop_at_tangent(problem, tangents, patches)
    try:
        runner.run(sim, None, progress=False)
    except _Enough:
        pass
    finally:
        for owner, name, value in reversed(patches):
            setattr(owner, name, value)
    return _summary(method, divisions, unknowns, build, build_mb, load, clock, history,
                    steps, tangents)


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


def figure(rows, path):
    """Parts per iteration against the unknowns, FEM and RKPM, log-log."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), sharey=True)
    for ax, method, title in zip(axes, ("fem", "rkpm"), ("FEM Hex1", "RKPM")):
        cases = sorted((r for r in rows if r["method"] == method),
                       key=lambda r: r["unknowns"])
        for part, marker in zip(SHOWN, "osd^v"):
            n = [r["unknowns"] for r in cases]
            ms = [r["per_iteration_ms"][part] for r in cases]
            ax.loglog(n, ms, marker=marker, label="whole iteration" if part == "Newton"
                      else part)
        for r in cases:
            if r["steps_asked"] or r.get("tangents_asked"):
                what = (f"first {r['tangents']} tangents" if r.get("tangents_asked")
                        else f"first {r['steps_done']} steps")
                ax.annotate(what, (r["unknowns"],
                            r["per_iteration_ms"]["Newton"]), textcoords="offset points",
                            xytext=(-60, 8), fontsize=8)
        ax.set_title(f"billet_3d, {title}")
        ax.set_xlabel("unknowns")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("CPU per Newton iteration (ms)")
    axes[1].legend(fontsize=8)
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
    parser.add_argument("--json", type=Path, default=None, help="append the case here")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="no run: draw the cases of this file")
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    if args.from_json is None:
        row = measure(args.method, args.divisions, args.steps, args.tangents)
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
