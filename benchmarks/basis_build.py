"""Time and peak memory of building an RK basis, by phase, from 1e4 to 1e6 particles.

Setup (the 17k-particle case of docs/benchmarks/basis_build.md):
a rectangle of 160 x 106 cells (17,227 particles) scaled to the requested
number of particles at the same aspect ratio, ``RKBasis(mesh, vector=True,
support=3.0, intorder=7)``: order 1, cubic kernel, radial supports,
4 x 4 Gauss points per cell, VCI.  Each size runs in a fresh process
(``--child``) whose peak resident memory (``VmHWM`` of ``/proc/self/status``)
is its own; the compiled shape kernel (numba, if installed) is loaded by a
small build first, so its loading (about 1 s, once per process) is not
counted.  Times are CPU seconds of the process (``time.process_time``), the
median of ``--repeat`` builds up to 2e4 particles and one build above.

Phases, measured by wrapping the functions the basis calls (``shape``:
``shape_functions`` at the cell and boundary Gauss points and the
particles; ``vci``: ``vci_gradients``; ``layout``: the padded per-cell
layout; the rest of the build is the remainder).  ``sys s`` is the part of the
total spent in the kernel (``os.times``), mostly page faults of the large
fresh arrays: on a shared machine it varies from build to build with the
memory traffic of the other jobs.

One core: the thread variables are set before numpy is imported.  To time
another version of the package, put it first on ``PYTHONPATH``.

Run:  python benchmarks/basis_build.py                      (1e4, 1.7e4, 1e5; ~3 min)
      python benchmarks/basis_build.py --sizes 1e4 17227 1e5 1e6
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from _timing import resident_mb  # noqa: E402

PHASES = ("shape", "vci", "layout")


def divisions(particles):
    """Cells (nx, ny) of aspect 160:106 with about ``particles`` vertices."""
    ratio = 106 / 160
    # solve (nx + 1)(ratio nx + 1) = particles for nx
    nx = max(2, int(round((-(1 + ratio) + np.sqrt((1 + ratio) ** 2 - 4 * ratio
                                                  * (1 - particles))) / (2 * ratio))))
    return nx, max(2, int(round(ratio * nx)))


def child(particles, repeat):
    """Build the basis ``repeat`` times; print one JSON line."""
    import skfem_rkpm.approximation.basis as basis_module
    from skfem_rkpm import RKBasis
    from skfem_rkpm.meshes import rectangle

    spent = dict.fromkeys(PHASES, 0.0)

    def timed(name, function):
        def wrapper(*args, **kwargs):
            start = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                spent[name] += time.process_time() - start
        return wrapper

    basis_module.shape_functions = timed("shape", basis_module.shape_functions)
    basis_module.vci_gradients = timed("vci", basis_module.vci_gradients)
    from skfem_rkpm.approximation import cell_layout

    cell_layout.padded = timed("layout", cell_layout.padded)
    cell_layout.cell_particles = timed("layout", cell_layout.cell_particles)

    try:  # load the compiled kernel (if installed) outside the timing
        from skfem_rkpm.approximation.shape import rk_shape_functions
        rk_shape_functions(np.zeros((2, 1)), np.eye(2, 3) * 0.1, 1.0, backend="numba")
    except ImportError:
        pass
    nx, ny = divisions(particles)
    mesh = rectangle(nx / 100, ny / 100, nx, ny)
    runs = []
    for _ in range(repeat):
        for name in PHASES:
            spent[name] = 0.0
        basis = None
        start, kernel = time.process_time(), os.times().system
        basis = RKBasis(mesh, vector=True, support=3.0, intorder=7)
        total = time.process_time() - start
        runs.append(dict(total=total, sys=os.times().system - kernel, **spent))
    out = {"particles": int(mesh.nvertices), "cells": [nx, ny],
           "pairs": int(npairs(basis)), "runs": len(runs),
           "peak_mb": resident_mb()}
    for key in runs[0]:
        out[key] = float(np.median([run[key] for run in runs]))
    print("RESULT " + json.dumps(out), flush=True)


def npairs(basis):
    """Shape-function pairs of a basis (older versions: its table's length)."""
    return getattr(basis, "npairs", None) or len(basis.table.indices)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e4, 17227, 1e5])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--timeout", type=float, default=1800)
    parser.add_argument("--child", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(int(args.child), args.repeat)
        return
    print(f"load average {os.getloadavg()}")
    print(f"{'particles':>10} {'pairs':>10} {'runs':>4} {'total s':>8} "
          + " ".join(f"{p + ' s':>8}" for p in PHASES) + f" {'rest s':>8} {'sys s':>8}"
          + f" {'peak MB':>8}")
    for size in args.sizes:
        repeat = args.repeat if size <= 2e4 else 1
        try:
            done = subprocess.run(
                [sys.executable, __file__, "--child", str(int(size)), "--repeat",
                 str(repeat)], capture_output=True, text=True, timeout=args.timeout)
        except subprocess.TimeoutExpired:
            print(f"{int(size):>10} timed out after {args.timeout:.0f} s")
            continue
        lines = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
        if not lines:
            tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
            print(f"{int(size):>10} failed: {tail}")
            continue
        r = json.loads(lines[-1][len("RESULT "):])
        rest = r["total"] - sum(r[p] for p in PHASES)
        print(f"{r['particles']:>10} {r['pairs']:>10} {r['runs']:>4} {r['total']:>8.2f} "
              + " ".join(f"{r[p]:>8.2f}" for p in PHASES)
              + f" {rest:>8.2f} {r.get('sys', float('nan')):>8.2f} {r['peak_mb']:>8.0f}",
              flush=True)
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
