"""Where the memory of an RK basis goes: a resident-memory trace of one build
and the bytes each array the finished basis keeps holds per shape-function pair.

Setup as ``basis_build.py``: ``RKBasis(mesh, vector=True, support=3.0,
intorder=7)`` (order 1, cubic kernel, 4 x 4 Gauss points per cell, VCI) on the
160:106 rectangle scaled to ``--particles``; or, with ``--dim 3``,
``RKBasis(mesh, vector=True)`` on a cube of ``n³`` hexahedra (defaults:
support and 27 Gauss points per cell).  One build in this process, one core.

A thread reads ``VmRSS`` (``/proc/self/status``) every ``--interval``
seconds while the basis is built; the phases are marked by wrapping the
functions the basis calls (``shape``: the shape tables; ``vci``: the
correction; ``layout``: the padded per-cell layout).  After the build, the
basis's arrays are listed with their bytes per pair (a pair: one particle
reaching one quadrature point), after ``basis.trial`` (the uncorrected trial
gradients that the non-symmetric VCI tangent reads) has been formed; the
peaks and the bytes kept are given after the build and with the trial
basis.  ``--figure`` writes the trace (resident GB against seconds, phases
shaded; ``--against FILE`` adds the trace of another build saved with
``--json``, e.g. of another version of the package put first on
``PYTHONPATH``); ``--json`` the numbers.

Run:  python benchmarks/basis_memory.py --particles 1e5 --figure docs/figures/basis_memory_2d.png
      python benchmarks/basis_memory.py --dim 3 --cells 30
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from _timing import resident_mb  # noqa: E402
from basis_build import divisions, npairs  # noqa: E402

PHASES = ("shape", "vci", "layout")


class Trace:
    """Resident memory sampled by a thread, and the phases marked on it."""

    def __init__(self, interval):
        self.interval = interval
        self.samples, self.phases = [], []
        self.start = time.perf_counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def now(self):
        return time.perf_counter() - self.start

    def _run(self):
        while not self._stop.is_set():
            self.samples.append((self.now(), resident_mb("VmRSS")))
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()

    def wrap(self, name, function):
        def wrapper(*args, **kwargs):
            begin = self.now()
            try:
                return function(*args, **kwargs)
            finally:
                self.phases.append((name, begin, self.now()))
        return wrapper


def arrays_of(obj, name, seen, depth=0):
    """``(name, nbytes)`` of the numpy arrays an object holds that own their
    memory (views of a listed array are not counted twice)."""
    if id(obj) in seen or depth > 4:
        return []
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        owner = obj if obj.base is None else obj.base
        if id(owner) in seen and owner is not obj:
            return []
        seen.add(id(owner))
        return [(name, owner.nbytes)] if owner.nbytes > 0 else []
    if sp.issparse(obj):
        return [x for k in ("data", "indices", "indptr") if hasattr(obj, k)
                for x in arrays_of(getattr(obj, k), f"{name}.{k}", seen, depth + 1)]
    if isinstance(obj, (list, tuple)):
        return [x for i, v in enumerate(obj) for x in arrays_of(v, f"{name}[{i}]", seen,
                                                                  depth + 1)]
    if isinstance(obj, dict):
        return [x for k, v in obj.items() for x in arrays_of(v, f"{name}[{k!r}]", seen,
                                                               depth + 1)]
    if hasattr(obj, "__dict__") and type(obj).__module__.startswith(("skfem", "numpy")):
        return [x for k, v in vars(obj).items()
                for x in arrays_of(v, f"{name}.{k}", seen, depth + 1)]
    return []


def megabytes(arrays):
    """MB of a list of ``(name, nbytes)``."""
    return sum(b for _, b in arrays) / 2**20


def build(args, trace):
    import skfem_rkpm.approximation.basis as basis_module
    from skfem_rkpm import RKBasis
    from skfem_rkpm.approximation import cell_layout

    basis_module.shape_functions = trace.wrap("shape", basis_module.shape_functions)
    basis_module.vci_gradients = trace.wrap("vci", basis_module.vci_gradients)
    cell_layout.padded = trace.wrap("layout", cell_layout.padded)
    cell_layout.cell_particles = trace.wrap("layout", cell_layout.cell_particles)
    if args.dim == 3:
        from skfem import MeshHex
        mesh = MeshHex.init_tensor(*(np.linspace(0, 1, args.cells + 1),) * 3)
        return RKBasis(mesh, vector=True)
    from skfem_rkpm.meshes import rectangle
    nx, ny = divisions(int(args.particles))
    mesh = rectangle(nx / 100, ny / 100, nx, ny)
    return RKBasis(mesh, vector=True, support=3.0, intorder=7)


def figure(out, path, against=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, rss = np.array(out["samples"]).T
    fig, ax = plt.subplots(figsize=(7, 3.6))
    colors = dict(shape="tab:blue", vci="tab:orange", layout="tab:green")
    labelled = set()
    for name, begin, end in out["phases"]:
        ax.axvspan(begin, end, color=colors[name], alpha=0.25,
                   label=None if name in labelled else name)
        labelled.add(name)
    ax.plot(t, rss / 1024, color="k", lw=1.2, label=f"resident memory ({out['label']})")
    ax.axhline((out["build_kept_mb"] + out["before_mb"]) / 1024, color="tab:red", ls="--",
               lw=1, label="arrays the basis keeps after its build")
    if against is not None:  # the trace of another version, its phases not shaded
        t, rss = np.array(against["samples"]).T
        ax.plot(t, rss / 1024, color="0.5", lw=1.2, ls=":",
                label=f"resident memory ({against.get('label', 'other build')})")
    ax.set_xlabel("time since the build started (s, wall)")
    ax.set_ylabel("resident memory (GB)")
    ax.set_title(f"RKBasis build, {out['particles']:,} particles, "
                 f"{out['pairs']:.2e} pairs ({out['dim']}D, VCI)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dim", type=int, choices=(2, 3), default=2)
    parser.add_argument("--particles", type=float, default=1e5, help="2D")
    parser.add_argument("--cells", type=int, default=30, help="3D: cells per side")
    parser.add_argument("--interval", type=float, default=0.02)
    parser.add_argument("--figure", default=None)
    parser.add_argument("--json", default=None)
    parser.add_argument("--label", default="this version", help="of the trace in the figure")
    parser.add_argument("--against", default=None,
                        help="JSON of another build (--json) drawn in the figure too")
    args = parser.parse_args()
    try:  # load the compiled kernel (if installed) before the trace
        from skfem_rkpm.approximation.shape import rk_shape_functions
        rk_shape_functions(np.zeros((2, 1)), np.eye(2, 3) * 0.1, 1.0, backend="numba")
    except ImportError:
        pass
    before = resident_mb("VmRSS")
    with Trace(args.interval) as trace:
        clock = time.process_time()
        basis = build(args, trace)
        cpu = time.process_time() - clock
    pairs = npairs(basis)
    built = dict(peak_mb=resident_mb(), kept_mb=megabytes(arrays_of(basis, "basis", set())))
    trial = basis.trial
    seen = set()
    kept = arrays_of(basis, "basis", seen)
    kept += [(n.replace("basis", "basis.trial", 1), b)
             for n, b in arrays_of(trial, "basis", seen)]
    out = dict(dim=args.dim, particles=int(basis.nnodes), pairs=pairs,
               cells=int(basis.nelems), nqp=int(basis.X.shape[-1]), nloc=int(
                   basis.element_nodes.shape[0]),
               cpu_s=cpu, before_mb=before, build_peak_mb=built["peak_mb"],
               build_kept_mb=built["kept_mb"], peak_mb=resident_mb(),
               after_mb=resident_mb("VmRSS"), kept_mb=megabytes(kept),
               load=os.getloadavg(), samples=trace.samples, phases=trace.phases,
               label=args.label)
    print(f"{out['particles']:,} particles, {pairs:.3e} pairs, {out['cells']:,} cells x "
          f"{out['nqp']} points, {out['nloc']} local functions per cell; build {cpu:.1f} CPU s; "
          f"load {out['load'][0]:.2f}")
    print(f"resident before {before:.0f} MB, after the basis and its trial basis "
          f"{out['after_mb']:.0f} MB")
    print(f"arrays of the basis and its trial basis {'MB':>18s} {'B/pair':>7s}")
    for name, nbytes in sorted(kept, key=lambda x: -x[1]):
        if nbytes >= 0.5 * pairs:
            print(f"{name:55s} {nbytes / 2**20:9.1f} {nbytes / pairs:7.1f}")
    small = sum(b for _, b in kept if b < 0.5 * pairs)
    print(f"{'the rest (each below 0.5 B/pair)':55s} {small / 2**20:9.1f} {small / pairs:7.1f}")
    for label, mb in (("kept by the basis after its build", out["build_kept_mb"]),
                      ("kept by the basis and its trial basis", out["kept_mb"]),
                      ("peak of the build above the start", out["build_peak_mb"] - before),
                      ("peak with the trial basis above the start", out["peak_mb"] - before)):
        print(f"{label:55s} {mb:9.1f} {mb * 2**20 / pairs:7.1f}")
    for name in PHASES:
        spans = [(b, e) for n, b, e in trace.phases if n == name]
        top = max((r for t, r in trace.samples for b, e in spans if b <= t <= e),
                  default=float("nan"))
        print(f"phase {name:7s} {sum(e - b for b, e in spans):6.1f} s wall, resident up to "
              f"{top:.0f} MB")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f)
    if args.figure:
        against = None
        if args.against:
            with open(args.against) as f:
                against = json.load(f)
        figure(out, args.figure, against)


if __name__ == "__main__":
    main()
