"""Construction rate of RK shape functions, in (point, node) pairs per second.

Setup: particles on a uniform square (cube) grid over the unit square (cube),
evaluation points drawn uniformly at random in the same domain, about four
points per particle (like four quadrature points per background cell).
Linear basis, cubic kernel, radial supports of normalized size 2.0
(radius 2h), gradients included.  Everything runs on one core.

``--backend numpy|numba|both`` chooses the implementation (default: both
when numba is installed, else numpy; ``pip install -e ".[fast]"``).  The
time of the neighbour search (``skfem_rkpm.approximation.shape.find_pairs``, or
``skfem_rkpm.approximation._shape_numba.find_pairs`` for the compiled kernel) is measured
inside the same call by wrapping the module attribute, so
``search + rest = total`` exactly.  The compile time of the compiled kernel
is measured in a fresh process with an empty cache (``--compile-time``).  Each size is run once to warm up
(first touch of fresh memory is expensive on virtual machines) and then
timed ``--repeat`` times; the fastest run is reported.  Times are CPU
seconds of the process by default (``--clock cpu``, ``time.process_time``):
for this single-threaded work they equal the wall time on an idle machine
and do not grow when other processes share the cores; ``--clock wall``
measures elapsed time instead.

Run:  python benchmarks/shape_rate.py            (all sizes, ~2-4 minutes)
      python benchmarks/shape_rate.py --max-points 100000 --backend numba
      python benchmarks/shape_rate.py --compile-time
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402

import skfem_rkpm.approximation.shape as shape  # noqa: E402
from skfem_rkpm.approximation.shape import rk_shape_functions  # noqa: E402

TARGET = 5e6  # pairs per second on one core (numpy path)
TARGET_COMPILED = 1e7  # with the compiled kernel
CLOCKS = {"cpu": time.process_time, "wall": time.perf_counter}
clock = CLOCKS["cpu"]


def particle_grid(dim, npoints):
    """Uniform grid on [0, 1]^dim with about npoints / 4 particles, and h."""
    n = max(2, int(round((npoints / 4) ** (1.0 / dim))))
    t = np.linspace(0.0, 1.0, n)
    nodes = np.array([a.ravel() for a in np.meshgrid(*[t] * dim, indexing="ij")])
    return nodes, t[1] - t[0]


class SearchTimer:
    """Wrap the ``find_pairs`` of the backend to accumulate its time during
    one call."""

    def __init__(self, backend="numpy"):
        if backend == "numba":
            from skfem_rkpm.approximation import _shape_numba as module
        else:
            module = shape
        self.module = module
        self.inner = module.find_pairs
        self.seconds = 0.0

    def __call__(self, *args, **kwargs):
        t = clock()
        out = self.inner(*args, **kwargs)
        self.seconds += clock() - t
        return out

    def __enter__(self):
        self.module.find_pairs = self
        return self

    def __exit__(self, *exc):
        self.module.find_pairs = self.inner


def measure(npoints, dim=2, order=1, support=2.0, repeat=3, seed=0,
            backend="numpy"):
    """Best-of-``repeat`` timing of one rk_shape_functions call."""
    nodes, h = particle_grid(dim, npoints)
    x = np.random.default_rng(seed).uniform(0.0, 1.0, (dim, npoints))
    best = None
    for run in range(repeat + 1):  # run 0 warms up
        with SearchTimer(backend) as timer:
            t = clock()
            table = rk_shape_functions(x, nodes, support * h, order=order,
                                       kernel="cubic", support="radial",
                                       gradients=True, backend=backend)
            total = clock() - t
        if run and (best is None or total < best[0]):
            best = (total, timer.seconds)
        if run == 0 and total > 20.0:  # too slow to repeat: keep the first run
            best = (total, timer.seconds)
            break
    npairs = len(table.indices)
    nbytes = sum(a.nbytes for a in (table.indptr, table.indices, table.values,
                                    table.grads))
    del table
    total, search = best
    return dict(backend=backend, dim=dim, order=order, support=support,
                npoints=npoints,
                nnodes=nodes.shape[1], npairs=npairs, total=total,
                search=search, rest=total - search,
                rate=npairs / total, us_per_point=1e6 * total / npoints,
                table_mb=nbytes / 2**20,
                peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)


HEADER = ("| backend | dim | order | c | npoints | particles | npairs | pairs/point | "
          "seconds | search s | rest s | pairs/s | µs/point | search % | "
          "table MB | peak RSS MB |")


def row(r):
    return (f"| {r['backend']} | {r['dim']} | {r['order']} | {r['support']:.1f} | {r['npoints']:,} | "
            f"{r['nnodes']:,} | {r['npairs']:,} | {r['npairs'] / r['npoints']:.1f} | "
            f"{r['total']:.4f} | {r['search']:.4f} | {r['rest']:.4f} | "
            f"{r['rate']:.2e} | {r['us_per_point']:.2f} | "
            f"{100 * r['search'] / r['total']:.0f} | {r['table_mb']:.1f} | "
            f"{r['peak_mb']:.0f} |")


COMPILE_SCRIPT = """
import time
t0 = time.process_time()
import numpy as np
from skfem_rkpm.approximation.shape import rk_shape_functions
x = np.random.default_rng(0).uniform(0, 1, ({dim}, 1000))
t = np.linspace(0, 1, 16)
nodes = np.array([a.ravel() for a in np.meshgrid(*[t] * {dim}, indexing="ij")])
t1 = time.process_time()
rk_shape_functions(x, nodes, {c} / 15, order={order}, backend="{backend}")
t2 = time.process_time()
rk_shape_functions(x, nodes, {c} / 15, order={order}, backend="{backend}")
t3 = time.process_time()
print(t1 - t0, t2 - t1, t3 - t2)
"""


def first_call(dim, order, c, backend, cache_dir):
    """CPU seconds of (imports, first call, second call) in a new process."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run(
        [sys.executable, "-c", COMPILE_SCRIPT.format(dim=dim, order=order, c=c,
                                                    backend=backend)],
        env=env, check=True, capture_output=True, text=True).stdout
    return [float(v) for v in out.split()]


def compile_times():
    """First call of each backend in a fresh process (1000 points)."""
    print("First call in a new process, 1000 points, CPU seconds "
          "(imports of skfem_rkpm, first call, second call):")
    print()
    print("| case | backend | imports s | first call s | second call s |")
    print("|---|---|---:|---:|---:|")
    cache_dir = tempfile.mkdtemp(prefix="numba-cache-")
    try:
        for dim, order, c in ((2, 1, 2.0), (2, 2, 2.5), (3, 1, 2.0)):
            for backend, label in (("numpy", "numpy"),
                                   ("numba", "numba, compiling (empty cache)"),
                                   ("numba", "numba, cached machine code")):
                imports, first, second = first_call(dim, order, c, backend,
                                                    cache_dir)
                print(f"| {dim}D, order {order} | {label} | {imports:.2f} | "
                      f"{first:.3f} | {second:.4f} |", flush=True)
    finally:
        shutil.rmtree(cache_dir, ignore_errors=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-points", type=float, default=1e6,
                        help="skip the 2D order-1 sizes above this (default 1e6)")
    parser.add_argument("--repeat", type=int, default=None,
                        help="timed runs per size (default: 20/10/5/2 by size)")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="cpu",
                        help="cpu: process CPU time (default); wall: elapsed time")
    have_numba = importlib.util.find_spec("numba") is not None
    parser.add_argument("--backend", choices=("numpy", "numba", "both"),
                        default="both" if have_numba else "numpy",
                        help="shape-function backend (default: both when numba "
                             "is installed, else numpy)")
    parser.add_argument("--compile-time", action="store_true",
                        help="only measure the first call in fresh processes")
    args = parser.parse_args()
    global clock
    clock = CLOCKS[args.clock]
    if args.compile_time:
        compile_times()
        return
    backends = ("numpy", "numba") if args.backend == "both" else (args.backend,)

    block = shape.POINTS_PER_BLOCK
    sizes = [10**3, 10**4, 10**5, 10**6]
    # 1e6: a whole number of solver blocks (245 x 4096 = 1,003,520 points)
    sizes = [s if s < 10**6 else -(-s // block) * block for s in sizes]
    sizes = [s for s in sizes if s <= args.max_points * 1.01]
    default_repeat = {10**3: 20, 10**4: 10, 10**5: 5}

    versions = ""
    if "numba" in backends:
        import numba
        versions = f", numba {numba.__version__}"
    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"scipy {scipy.__version__}{versions}, {os.cpu_count()} cores visible, "
          "OMP/OPENBLAS/MKL_NUM_THREADS=1")
    print("linear basis, cubic kernel, radial support c = 2.0 (radius 2h), "
          f"gradients, best of the timed runs, {args.clock} clock")
    print()
    print("2D, order 1:")
    print(HEADER)
    print("|" + "---|" * HEADER.count(" | ") + "---|")
    for n in sizes:
        for backend in backends:
            r = measure(n, repeat=args.repeat or default_repeat.get(n, 2),
                        backend=backend)
            print(row(r), flush=True)

    print()
    print("Other cases at 1e5 points (order 2 uses c = 2.5: with c = 2.0 the "
          "moment matrix is singular at points next to the edges, whose "
          "covering particles lie on two grid lines only):")
    print(HEADER)
    print("|" + "---|" * HEADER.count(" | ") + "---|")
    for dim, order, c in ((2, 2, 2.5), (3, 1, 2.0)):
        for backend in backends:
            r = measure(10**5, dim=dim, order=order, support=c,
                        repeat=args.repeat or 5, backend=backend)
            print(row(r), flush=True)
    print()
    print(f"target: {TARGET:.0e} pairs/s on one core (numpy), "
          f"{TARGET_COMPILED:.0e} (compiled kernel)")


if __name__ == "__main__":
    main()
