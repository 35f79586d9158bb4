"""The ring compression (built-in scene, μ = 0.15) at 50, 100, 200 and 1000 load
steps, RKPM and FEM: wall time, Newton iterations per step, and the final
inner-diameter change against the 1000-step run of the same method.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/ring_steps.py [--steps 50 100 200 1000]
      [--friction 0.15]                                             (~3 minutes)
Prints a Markdown table.
"""

import argparse
import time

from skfem_rkpm.runs.runner import build, run
from skfem_rkpm.runs.scene import builtin_scenes, load_scene
from _whole_runs import ring_id_change


def ring(method, steps, friction):
    """Final inner-diameter change (%), steps, iterations and seconds of one run."""
    scene = load_scene(builtin_scenes()["ring"],
                       [f"tools.platen.friction={friction}", f"steps.count={steps}",
                        "output.fields=false", "output.figures=false"])
    sim = build(scene, method)
    start = time.perf_counter()
    result = run(sim, progress=False)
    seconds = time.perf_counter() - start
    change = ring_id_change(result.gauges[-1])
    iterations = sum(r.iterations for r in result.history)
    return result.completed, change, len(result.history), iterations, seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, nargs="+", default=[50, 100, 200, 1000])
    parser.add_argument("--friction", default="0.15")
    args = parser.parse_args()
    print("| method | steps | completed | ID change % | difference to the finest | "
          "Newton iterations | iterations/step | wall time s |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for method in ("rkpm", "fem"):
        runs = {n: ring(method, n, args.friction) for n in args.steps}
        finest = runs[max(args.steps)][1]
        for n, (done, change, nsteps, its, seconds) in runs.items():
            print(f"| {method} | {n} | {done} | {change:.3f} | {change - finest:+.3f} | "
                  f"{its} | {its / nsteps:.2f} | {seconds:.1f} |", flush=True)


if __name__ == "__main__":
    main()
