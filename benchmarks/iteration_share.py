"""Where a Newton iteration of a whole run goes: assembly, factorization and the rest.

Runs a scene in this process (``skfem_rkpm.runs.runner.run``, fields and
figures off) and adds up the CPU time (``time.process_time``) of

* *Newton*: all of ``newton_steps`` (every attempt, cut-backs included);
* *assembly*: forming the solid's tangent (material tangent, F-bar terms,
  local matrices and their sum; ``Evaluation.K`` the first time it is read);
* *factorization*: every factorization of the linear solver;
* *solid*: ``SolidProblem.evaluate`` (stress update and internal force);
* *contact*: the tools' ``evaluate`` (force and tangent), including the
  evaluations of the stick prediction;
* *prediction*: the touching and stick predictions of each update;

and reports them per iteration (all iterations of all attempts), with
the factorizations per iteration (the touching and stick predictions solve
again) and *iteration / (assembly + one factorization)*: the target is at
most 2 for FEM (the rest of an iteration: residual evaluations, contact,
conditions, the predictions' solves).
``--repeat N`` runs each case N times and reports the median of each part.
One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/iteration_share.py                       (~2 minutes)
      python benchmarks/iteration_share.py --cases "billet_3d fem" --repeat 3
      python benchmarks/iteration_share.py --cases "ring rkpm" --set tools.platen.friction=stick
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

CASES = ("billet_3d fem", "billet_3d rkpm", "ring fem", "ring rkpm")
PARTS = ("Newton", "assembly", "factorization", "solid", "contact", "prediction")


class _Clock:
    """CPU seconds of the wrapped calls, outermost calls only."""

    def __init__(self):
        self.seconds = dict.fromkeys(PARTS, 0.0)
        self.depth = dict.fromkeys(PARTS, 0)
        self.calls = dict.fromkeys(PARTS, 0)

    def wrap(self, part, function):
        def timed(*args, **kwargs):
            self.depth[part] += 1
            start = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                self.depth[part] -= 1
                if self.depth[part] == 0:
                    self.seconds[part] += time.process_time() - start
                    self.calls[part] += 1
        return timed


def _instrument(clock, patches):
    """Wrap the measured functions; ``patches`` collects what to restore."""
    from skfem_rkpm.mechanics import problem, rigid_contact, surface_contact
    from skfem_rkpm.runs import runner
    from skfem_rkpm.solvers import backend

    def put(owner, name, value):
        patches.append((owner, name, owner.__dict__[name]))
        setattr(owner, name, value)

    put(runner, "newton_steps", clock.wrap("Newton", runner.newton_steps))
    put(backend.Solver, "_factor_timed",
        clock.wrap("factorization", backend.Solver._factor_timed))
    put(problem.SolidProblem, "evaluate", clock.wrap("solid", problem.SolidProblem.evaluate))
    original_K = problem.Evaluation.K.fget

    def K(self):
        if self._form_tangent is None:
            return original_K(self)
        return clock.wrap("assembly", original_K)(self)

    put(problem.Evaluation, "K", property(K))
    for cls in (rigid_contact.RigidContact, surface_contact.SurfaceContact):
        put(cls, "evaluate", clock.wrap("contact", cls.__dict__["evaluate"]))
    put(rigid_contact.RigidContact, "touching",
        clock.wrap("prediction", rigid_contact.RigidContact.touching))
    put(surface_contact.SurfaceContact, "sticking",
        clock.wrap("prediction", surface_contact.SurfaceContact.sticking))


def measure(scene_name, method, settings):
    """Seconds per part and the iterations of one whole run."""
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()[scene_name],
                       ["output.fields=false", "output.figures=false", *settings])
    sim = runner.build(scene, method)
    clock, patches = _Clock(), []
    _instrument(clock, patches)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            runner.run(sim, Path(tmp) / "run", progress=False)
            rows = (Path(tmp) / "run" / "history.csv").read_text().splitlines()
    finally:
        for owner, name, value in reversed(patches):
            setattr(owner, name, value)
    header = rows[0].split(",")
    column = header.index("all iterations")
    iterations = sum(int(r.split(",")[column]) for r in rows[1:])
    return clock.seconds, iterations, clock.calls["factorization"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(CASES),
                        help="'SCENE METHOD' pairs (default: %(default)s)")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    print("| case | iterations | " + " | ".join(f"{p} ms" for p in PARTS)
          + " | factorizations per iteration | iteration / (assembly + one factorization) |")
    print("|---|---:|" + "---:|" * len(PARTS) + "---:|---:|")
    for case in args.cases:
        scene, method = case.split()
        runs = [measure(scene, method, args.set) for _ in range(args.repeat)]
        iterations = runs[0][1]
        per = {p: 1e3 * statistics.median(r[0][p] / r[1] for r in runs) for p in PARTS}
        count = runs[0][2] / iterations
        share = per["Newton"] / (per["assembly"] + per["factorization"] / count)
        print(f"| {case} | {iterations} | " + " | ".join(f"{per[p]:.1f}" for p in PARTS)
              + f" | {count:.2f} | {share:.2f} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
