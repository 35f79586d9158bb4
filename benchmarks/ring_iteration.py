"""Cost of one Newton iteration of the ring compression, RK vs FEM Q1.

The scene is the paper's ring (``skfem-rkpm run ring``, Chen et al. 1998,
Sec. 5.3) with sticking platens: axisymmetric, 15 x 10 cells, 16 x 11
particles (352 unknowns), box supports of 6 mm, 16 Gauss points per cell,
F-bar, J2 perfect plasticity, rigid platen contact.  RKPM and FEM Q1 run on
the same mesh and quadrature.

The ring is first compressed by ``--steps`` of the 100 load steps (default
10: the platen is in contact), then one iteration is timed part by part at
the first iterate of the next step (almost every point on the plastic
branch), each part ``--repeat`` times (the fastest run is reported):

* *kinematics*: ``assembler.gradient(d)``, ``deformation_gradient``
  (Eq. 3.30) and ``det F``;
* *material*: ``J2Material.update`` at ``F`` (log strain, return map,
  consistent tangent at the model's entries of ``F``);
* *assembly*: internal force ``assembler.linear`` and tangent
  ``assembler.local_bilinear`` + ``assembler.matrix``;
* *F-bar*: the rest of ``problem.evaluate`` (``F̄``, ``Â``, the rank-one
  cell terms), i.e. *evaluate* minus the three parts above;
* *evaluate*: ``problem.evaluate(d)`` as a whole, its tangent ``K`` formed
  (which ``evaluate`` does only when ``K`` is read);
* *contact*: ``RigidContact.evaluate(d, t)`` (force and tangent);
* *K + K_c*: the sum of the two sparse tangents;
* *solve*: ``solve_constrained(K, r, C, g)``, the saddle-point system with
  the symmetry-plane constraints;
* *iteration*: evaluate + contact + sum + solve, timed as one.

Targets: an RK iteration in at most 20 ms, at most 5 times the FEM
Q1 one; the whole stick ring (100 steps) in at most 15 s.  Times are CPU
milliseconds of the process (``--clock cpu``, the default; on one core they
equal the wall time of an idle machine and hardly grow when other processes
share the cores), or elapsed time with ``--clock wall``.  ``--full`` also
runs the whole stick ring for both methods (wall and CPU time, iterations,
evaluations, CPU ms per evaluation); ``--save FILE`` stores the tool force history of the full runs
and ``--compare FILE`` checks it against a stored one (relative difference at
the load factors both runs converged at, and at the end).

Run:  python benchmarks/ring_iteration.py            (~1 minute)
      python benchmarks/ring_iteration.py --full     (adds the full runs)
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

TARGET_ITERATION_MS = 20.0
TARGET_RATIO = 5.0
TARGET_FULL_S = 15.0
PARTS = ("kinematics", "material", "assembly", "F-bar", "evaluate", "contact",
         "K + K_c", "solve", "iteration")


def build(method, overrides=()):
    from skfem_rkpm.runs import runner
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    scene = load_scene(builtin_scenes()["ring"],
                       ["tools.platen.friction=stick", *overrides])
    return runner.build(scene, method)


def prepare(method, steps, overrides=()):
    """The ring after ``steps`` of its 100 load steps, and the first iterate
    of the next step (the last step's rate of change, as in
    :func:`~skfem_rkpm.solvers.newton.newton_steps`): (sim, d, t, C)."""
    from skfem_rkpm.solvers.newton import newton_steps

    sim = build(method, overrides)
    targets = np.linspace(0.0, 1.0, sim.scene["steps"]["count"] + 1)[1:steps + 2]
    result = newton_steps(sim.problem, sim.prescribed, load=sim.load, steps=targets[:-1],
                          contributions=sim.tools)
    if not result.completed:
        raise RuntimeError(f"{method}: {result.message}")
    groups = [p.constraint(sim.problem.basis) for p in sim.prescribed]
    C = sp.vstack([g.C for g in groups], format="csr")
    d, d_last = result.solutions[-1], result.solutions[-2]
    return sim, 2 * d - d_last, float(targets[-1]), C


CLOCK = {"cpu": time.process_time, "wall": time.perf_counter}
clock = CLOCK["cpu"]


def fastest(fn, repeat):
    """Fastest of ``repeat`` timed calls after one warm-up call, in ms."""
    fn()
    best = np.inf
    for _ in range(repeat):
        start = clock()
        fn()
        best = min(best, clock() - start)
    return 1e3 * best


def time_parts(sim, d, t, C, repeat):
    """Milliseconds of each part of one Newton iteration at ``d``."""
    from skfem_rkpm.solvers.constrained import solve_constrained
    from skfem_rkpm.mechanics.kinematics import deformation_gradient, from_entries

    problem, tool = sim.problem, sim.tools[0]
    asm = problem.assembler
    F = deformation_gradient(asm.gradient(d), problem.model)
    ev = problem.evaluate(d)
    f_c, K_c = tool.evaluate(d, t)
    K = ev.K + K_c
    r = -(ev.f_int + f_c)
    g = np.zeros(C.shape[0])
    P, _, _, A = problem.material.update(F, problem.state, entries=problem.entries)
    P_ext, A_ext = from_entries(problem._at_entries(P), A, problem.model, problem.shape)

    def kinematics():
        F = deformation_gradient(asm.gradient(d), problem.model)
        return np.linalg.det(F)

    def assembly():
        asm.linear(P_ext)
        return asm.matrix(asm.local_bilinear(A_ext))

    def iteration():
        ev = problem.evaluate(d)
        f_c, K_c = tool.evaluate(d, t)
        return solve_constrained(ev.K + K_c, -(ev.f_int + f_c), C, g)

    ms = {
        "kinematics": fastest(kinematics, repeat),
        "material": fastest(lambda: problem.material.update(
            F, problem.state, entries=problem.entries), repeat),
        "assembly": fastest(assembly, repeat),
        "evaluate": fastest(lambda: problem.evaluate(d).K, repeat),
        "contact": fastest(lambda: tool.evaluate(d, t), repeat),
        "K + K_c": fastest(lambda: ev.K + K_c, repeat),
        "solve": fastest(lambda: solve_constrained(K, r, C, g), repeat),
        "iteration": fastest(iteration, repeat),
    }
    ms["F-bar"] = ms["evaluate"] - ms["kinematics"] - ms["material"] - ms["assembly"]
    ms["plastic %"] = 100 * np.mean(problem.evaluate(d).state.alpha > problem.state.alpha)
    return ms


def full_run(method, overrides=()):
    """The whole stick ring: wall seconds, iterations, force history, result."""
    from skfem_rkpm.runs import runner

    sim = build(method, overrides)
    calls = [0]
    evaluate = sim.problem.evaluate

    def counted(*args, **kwargs):
        calls[0] += 1
        return evaluate(*args, **kwargs)

    sim.problem.evaluate = counted
    start, start_cpu = time.perf_counter(), time.process_time()
    result = runner.run(sim, out=None, progress=False)
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    iterations = sum(r.iterations for r in result.history)
    force = np.array([r.reactions[sim.tools[0].name] for r in result.history])
    return dict(wall=wall, cpu=cpu, iterations=iterations, evaluations=calls[0],
                steps=len(result.history), completed=result.completed,
                message=result.message, force=force,
                t=np.array([r.t for r in result.history]))


def iteration_table(args):
    ms = {}
    for method in ("rkpm", "fem"):
        sim, d, t, C = prepare(method, args.steps, args.set)
        ms[method] = time_parts(sim, d, t, C, args.repeat)
    print(f"Ring (stick{''.join(', ' + o for o in args.set)}), "
          f"one Newton iteration after {args.steps} steps "
          f"({args.clock} ms, fastest of {args.repeat}):\n")
    print("| part | RK ms | FEM Q1 ms | RK / FEM |")
    print("|---|---:|---:|---:|")
    for part in PARTS:
        rk, fem = ms["rkpm"][part], ms["fem"][part]
        print(f"| {part} | {rk:.2f} | {fem:.2f} | {rk / fem:.1f} |")
    print(f"\nPoints on the plastic branch: RK {ms['rkpm']['plastic %']:.0f} %, "
          f"FEM {ms['fem']['plastic %']:.0f} %")
    it_rk, it_fem = ms["rkpm"]["iteration"], ms["fem"]["iteration"]
    print(f"\nRK iteration {it_rk:.1f} ms: {it_rk / TARGET_ITERATION_MS:.2f} x the "
          f"{TARGET_ITERATION_MS:g} ms target; RK / FEM {it_rk / it_fem:.1f} "
          f"(target at most {TARGET_RATIO:g})")


def full_table(args):
    runs = {method: full_run(method, args.set) for method in ("rkpm", "fem")}
    print("\nWhole stick ring (100 steps):\n")
    print("| method | completed | steps | iterations | evaluations | wall s | CPU s "
          "| CPU ms / evaluation |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for method, run in runs.items():
        print(f"| {method} | {run['completed']} | {run['steps']} | {run['iterations']} "
              f"| {run['evaluations']} | {run['wall']:.1f} | {run['cpu']:.1f} "
              f"| {1e3 * run['cpu'] / run['evaluations']:.1f} |")
        if not run["completed"]:
            print(f"  ({run['message']})")
    print(f"(target: {TARGET_FULL_S:g} s)")
    if args.save:
        np.savez(args.save, **{f"{m}_{k}": run[k] for m, run in runs.items()
                               for k in ("force", "t")})
    if args.compare:
        stored = np.load(args.compare)
        for method, run in runs.items():
            compare_histories(method, stored[f"{method}_t"], stored[f"{method}_force"],
                              run["t"], run["force"], args.compare)


def compare_histories(method, t_ref, ref, t, force, name):
    """Print how far the force history ``(t, force)`` is from ``(t_ref, ref)``
    at the load factors both runs converged at (a cut-back taken by one run
    and not the other shifts the step numbers, not the load factors), and
    at the end of the runs, relative to the largest stored force."""
    common, i_ref, i = np.intersect1d(np.round(t_ref, 12), np.round(t, 12),
                                      return_indices=True)
    scale = np.abs(ref).max()
    diff = np.abs(force[i] - ref[i_ref]).max(axis=-1) / scale
    end = np.abs(force[-1] - ref[-1]).max() / scale if t[-1] == t_ref[-1] else np.nan
    print(f"{method}: force history vs {name}: {len(common)} common load factors of "
          f"{len(t_ref)} / {len(t)} steps; difference there: largest {diff.max():.2e}, "
          f"median {np.median(diff):.2e} of the largest force; at the end {end:.2e}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=10,
                        help="load steps (of 100) before the timed iteration")
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="further scene overrides, e.g. tools.platen.collocation=nodal")
    parser.add_argument("--clock", choices=sorted(CLOCK), default="cpu",
                        help="CPU seconds of the process (default) or elapsed time")
    parser.add_argument("--full", action="store_true",
                        help="also run the whole stick ring for both methods")
    parser.add_argument("--no-parts", action="store_true",
                        help="skip the timing of one iteration (with --full)")
    parser.add_argument("--save", help="store the force histories of --full (.npz)")
    parser.add_argument("--compare", help="compare --full with stored histories (.npz)")
    args = parser.parse_args()
    global clock
    clock = CLOCK[args.clock]

    if not args.no_parts:
        iteration_table(args)
    if args.full:
        full_table(args)


if __name__ == "__main__":
    main()
