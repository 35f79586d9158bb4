"""The cost of an explicit step against one internal-force evaluation, on the
3D quarter Taylor bar (``taylor_bar_3d``, RKPM and FEM).

Runs :class:`~skfem_rkpm.solvers.explicit.CentralDifference` on the scene
(no output files) over ``--duration`` and measures, by the CPU time of
the process (``time.process_time``) around each part: the internal and
contact force evaluations (one a step), the stable-step estimates (the
tangent at the current state, the Lanczos products) and the whole loop.
The table gives per step, per force evaluation and per estimate CPU
milliseconds, the Lanczos products per estimate and the ratio step / force
evaluation (the loop's CPU over its steps, estimates included, over the
CPU of one force evaluation), the median of ``--repeat`` runs.

``--estimate assembled`` estimates as before the tangent products: the
tangent assembled as a sparse matrix, its symmetric part scaled and handed
to ARPACK with its default 20 Lanczos vectors, started from the last
eigenvector (``operator``: the default, the products without the matrix).
The last column is the largest ratio of the step taken over an interval to
the critical step ``2/ω`` estimated at its end (above 1: the interval ended
above the stable step; ``CentralDifference.estimates``).  Run with
``PYTHONPATH`` at an older checkout of the package and ``--estimate
assembled`` to measure that code's estimates at its fixed interval.

Run:  python benchmarks/explicit_step_cost.py                       (~2 min)
      python benchmarks/explicit_step_cost.py --estimate assembled operator
      python benchmarks/explicit_step_cost.py --duration 8e-5 --repeat 1   (the full run)
"""

import argparse
import os
import time

import numpy as np
import scipy.sparse as sp

from skfem_rkpm.mechanics.mass import scaled_largest
from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.explicit_run import explicit_scheme, initial_velocity
from skfem_rkpm.runs.scene import builtin_scenes, load_scene


def assembled_frequency2(scheme):
    """The estimate before the products: ``ω²`` of the assembled ``K_sym``."""
    def frequency2(d, state=None):
        K = sp.csr_matrix(scheme.problem.evaluate(d, state).K)
        if scheme._mode is None:
            scheme._mode = np.random.default_rng(0).standard_normal(K.shape[0])
        omega2, scheme._mode = scaled_largest(0.5 * (K + K.T), scheme.mass, scheme._mode,
                                              tol=1e-6)
        return omega2
    return frequency2


class Clock:
    """CPU seconds and calls of a wrapped function."""

    def __init__(self, fun):
        self.fun, self.seconds, self.calls = fun, 0.0, 0

    def __call__(self, *args, **kwargs):
        start = time.process_time()
        try:
            return self.fun(*args, **kwargs)
        finally:
            self.seconds += time.process_time() - start
            self.calls += 1


def one_run(method, duration, estimate):
    scene = load_scene(builtin_scenes()["taylor_bar_3d"], [f"dynamics.duration={duration}"])
    sim = build(scene, method=method)
    scheme = explicit_scheme(sim)
    if estimate == "assembled":
        scheme.body_frequency2 = assembled_frequency2(scheme)
    forces = scheme._forces = Clock(scheme._forces)
    estimates = scheme.body_frequency2 = Clock(scheme.body_frequency2)
    start = time.process_time()
    records = scheme.run(np.zeros(sim.problem.N), initial_velocity(sim), duration=duration)
    loop = time.process_time() - start
    steps = records[-1].step
    over = [e.taken / e.critical for e in getattr(scheme, "estimates", []) if e.taken]
    return dict(N=sim.problem.N, steps=steps, step=loop / steps,
                over=max(over) if over else float("nan"),
                force=forces.seconds / forces.calls, estimates=estimates.calls,
                estimate=estimates.seconds / estimates.calls,
                products=getattr(scheme, "products", 0) / estimates.calls or float("nan"),
                ratio=(loop / steps) / (forces.seconds / forces.calls),
                dt=(records[0].dt, records[-1].dt))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", default=["rkpm", "fem"])
    parser.add_argument("--estimate", nargs="+", default=["operator"],
                        choices=["operator", "assembled"])
    parser.add_argument("--duration", type=float, default=1e-5)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"load {os.getloadavg()[0]:.1f}; taylor_bar_3d over {args.duration * 1e6:g} µs, "
          f"median of {args.repeat} runs")
    print("| method | estimate | unknowns | steps | estimates | Lanczos products / estimate | "
          "CPU ms / step | ms / force evaluation | ms / estimate | step / force | "
          "first, last Δt µs | max step taken / critical at the next estimate |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for method in args.methods:
        for estimate in args.estimate:
            runs = [one_run(method, args.duration, estimate) for _ in range(args.repeat)]
            med = {k: float(np.median([r[k] for r in runs])) for k in
                   ("step", "force", "estimate", "ratio", "products")}
            r = runs[0]
            print(f"| {method.upper()} | {estimate} | {r['N']:,} | {r['steps']} | "
                  f"{r['estimates']} | {med['products']:.0f} | {med['step'] * 1e3:.1f} | "
                  f"{med['force'] * 1e3:.1f} | {med['estimate'] * 1e3:.0f} | "
                  f"{med['ratio']:.2f} | {r['dt'][0] * 1e6:.4f}, {r['dt'][1] * 1e6:.4f} | "
                  f"{r['over']:.3f} |",
                  flush=True)
    print(f"load {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
