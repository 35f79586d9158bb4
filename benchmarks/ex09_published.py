"""scikit-fem's ex09 as published (3D Poisson on 16³ vertices of tetrahedra,
conjugate gradients without and with ILU) with FEM and with the documented
swap, ``RKBasis(mesh, element, interpolating=True)``: CPU time and peak
memory of the whole script, by part.

Each run is a fresh process (``--child``), whose peak resident memory
(``VmHWM``) is its own.  Times are CPU seconds of the process
(``time.process_time``: user and system); the whole script includes the
imports' share of nothing (the clock starts at the mesh).  Variants:

- ``fem``: ``Basis(m, e)``, ``laplace.assemble(basis)`` as published;
- ``rk``: the swapped basis with ``skfem_rkpm.asm(laplace, basis)`` in place
  of ``laplace.assemble(basis)`` (what the warning advises);
- ``rk-published``: the swapped basis with ``laplace.assemble(basis)`` as
  published (scikit-fem's loop over pairs of local functions; minutes).

With ``--stages`` the swapped basis's build is also split by stage (CPU
seconds and peak resident memory while the stage ran; the peak is reset
before each stage through ``/proc/self/clear_refs``): the geometry, the shape
functions and their pairs, the cell-particle lists, the (symmetric) VCI
correction, the padded per-cell layout, then the assembly and the solve.

Also reported: the pairs of the basis, its local functions per cell and
the error of u(½, ½, ½) (``basis.probes``; not a vertex of 16³) against the
series value 0.0562128298 (tests/test_skfem_examples.py).

Run:  python benchmarks/ex09_published.py [--variants fem rk] [--repeat 3] [--n 16]
      [--stages]
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
from _timing import resident_mb  # noqa: E402

CUBE_CENTRE = 0.0562128298


#: (module, function, stage) timed by ``--stages``: the module attribute is
#: replaced by a wrapper, so calls from inside the package are seen
STAGES = (("skfem_rkpm.approximation.basis", "cell_geometry", "geometry"),
          ("skfem_rkpm.approximation.basis", "facet_geometry", "geometry"),
          ("skfem_rkpm.approximation.basis", "shape_functions", "shape functions + pairs"),
          ("skfem_rkpm.approximation.cell_layout", "cell_particles", "cell particles"),
          ("skfem_rkpm.approximation.basis", "vci_gradients", "VCI"),
          ("skfem_rkpm.approximation.cell_layout", "padded", "padded layout"))


def _reset_peak():
    """Reset this process's peak resident memory (``VmHWM``) to the current
    one; False where the kernel does not allow it."""
    try:
        with open("/proc/self/clear_refs", "w") as refs:
            refs.write("5")
        return True
    except OSError:
        return False


class Stages:
    """CPU seconds and peak resident MB of each stage, summed over calls."""

    def __init__(self):
        self.cpu, self.peak, self.overall = {}, {}, 0.0

    def wrap(self, module_name, name, stage):
        import importlib

        module = importlib.import_module(module_name)
        inner = getattr(module, name)

        def timed(*args, **kwargs):
            if getattr(self, "_inside", False):  # nested: counted by the outer stage
                return inner(*args, **kwargs)
            self.mark()
            self._inside, start = True, time.process_time()
            try:
                return inner(*args, **kwargs)
            finally:
                self._inside = False
                self.cpu[stage] = self.cpu.get(stage, 0.0) + time.process_time() - start
                self.peak[stage] = max(self.peak.get(stage, 0.0), resident_mb())
                self.mark()

        setattr(module, name, timed)

    def mark(self):
        """Fold the peak so far into the overall peak, then reset it."""
        self.overall = max(self.overall, resident_mb())
        _reset_peak()

    def run(self, stage, fun):
        self.mark()
        start = time.process_time()
        out = fun()
        self.cpu[stage] = time.process_time() - start
        self.peak[stage] = resident_mb()
        self.mark()
        return out


def child(variant, n, stages=False):
    from skfem import (Basis, ElementTetP1, MeshTet, build_pc_ilu, condense, solve,
                       solver_iter_pcg)
    from skfem.models.poisson import laplace, unit_load

    import skfem_rkpm
    from skfem_rkpm import RKBasis

    warnings.simplefilter("ignore")
    timer = Stages() if stages and variant != "fem" and _reset_peak() else None
    if timer is not None:
        for module_name, name, stage in STAGES:
            timer.wrap(module_name, name, stage)
    clock = {}
    start = time.process_time()
    p = np.linspace(0, 1, n)
    m = MeshTet.init_tensor(*(p,) * 3)
    e = ElementTetP1()
    basis = Basis(m, e) if variant == "fem" else RKBasis(m, e, interpolating=True)
    clock["basis"] = time.process_time() - start
    if variant == "rk" and timer is not None:
        A = timer.run("assembly", lambda: skfem_rkpm.asm(laplace, basis))
        b = skfem_rkpm.asm(unit_load, basis)
    elif variant == "rk":
        A, b = skfem_rkpm.asm(laplace, basis), skfem_rkpm.asm(unit_load, basis)
    else:
        A, b = laplace.assemble(basis), unit_load.assemble(basis)
    clock["assembly"] = time.process_time() - start - clock["basis"]
    I = m.interior_nodes()
    x = 0. * b.copy()
    Aint, bint = condense(A, b, I=I, expand=False)
    for pc in [None, build_pc_ilu(Aint, drop_tol=1e-3)]:
        x[I] = solve(Aint, bint, solver=solver_iter_pcg(M=pc))
    total = time.process_time() - start
    clock["solve"] = total - clock["basis"] - clock["assembly"]
    value = (basis.probes(np.full((3, 1), 0.5)) @ x)[0]
    peak = resident_mb() if timer is None else max(timer.overall, resident_mb())
    out = dict(variant=variant, total=total, peak_mb=peak, nnz=int(A.nnz),
               error=abs(value - CUBE_CENTRE) / CUBE_CENTRE, **clock)
    if variant != "fem":
        out.update(pairs=basis.npairs, nloc=int(basis.element_nodes.shape[0]),
                   points=int(basis.X.shape[-1]), cells=int(basis.nelems))
    if timer is not None:
        out["stages"] = {stage: [timer.cpu[stage], timer.peak[stage]] for stage in timer.cpu}
        out["stages"]["build, other"] = [clock["basis"] - sum(
            cpu for stage, (cpu, _) in out["stages"].items() if stage != "assembly"),
            float("nan")]
    print("RESULT " + json.dumps(out), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=["fem", "rk"],
                        choices=["fem", "rk", "rk-published"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--n", type=int, default=16, help="vertices per edge (ex09: 16)")
    parser.add_argument("--stages", action="store_true",
                        help="split the RK basis build by stage (CPU s, peak MB)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.n, args.stages)
        return
    print(f"load average {os.getloadavg()}; CPU s, median of {args.repeat} processes")
    print(f"{'variant':>13} {'total s':>8} {'basis s':>8} {'asm s':>8} {'solve s':>8} "
          f"{'peak MB':>8} {'rel. error':>10} {'pairs':>10} {'nloc':>5}")
    for variant in args.variants:
        runs = []
        for _ in range(args.repeat):
            done = subprocess.run([sys.executable, __file__, "--child", variant, "--n",
                                   str(args.n)] + ["--stages"] * args.stages,
                                  capture_output=True, text=True)
            lines = [s for s in done.stdout.splitlines() if s.startswith("RESULT ")]
            if not lines:
                print(f"{variant:>13} failed: "
                      f"{(done.stderr.strip().splitlines() or ['no output'])[-1]}")
                break
            runs.append(json.loads(lines[-1][len("RESULT "):]))
        if not runs:
            continue
        r = {k: (float(np.median([run[k] for run in runs]))
                 if isinstance(runs[0][k], (int, float)) else runs[0][k]) for k in runs[0]}
        print(f"{variant:>13} {r['total']:>8.2f} {r['basis']:>8.2f} {r['assembly']:>8.2f} "
              f"{r['solve']:>8.2f} {r['peak_mb']:>8.0f} {r['error']:>10.1e} "
              f"{int(r.get('pairs', 0)):>10} {int(r.get('nloc', 0)):>5}", flush=True)
        if "stages" in runs[0]:
            print(f"{'':>13} stage: CPU s, peak MB while it ran (medians of {len(runs)})")
            for stage in runs[0]["stages"]:
                cpu, peak = (float(np.median([run["stages"][stage][i] for run in runs]))
                             for i in range(2))
                print(f"{'':>13} {stage:>24} {cpu:>7.2f} {peak:>7.0f}")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
