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

Also reported: the pairs of the basis, its local functions per cell and
the error of u(½, ½, ½) (``basis.probes``; not a vertex of 16³) against the
series value 0.0562128298 (tests/test_skfem_examples.py).

Run:  python benchmarks/ex09_published.py [--variants fem rk] [--repeat 3] [--n 16]
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


def child(variant, n):
    from skfem import (Basis, ElementTetP1, MeshTet, build_pc_ilu, condense, solve,
                       solver_iter_pcg)
    from skfem.models.poisson import laplace, unit_load

    import skfem_rkpm
    from skfem_rkpm import RKBasis

    warnings.simplefilter("ignore")
    clock = {}
    start = time.process_time()
    p = np.linspace(0, 1, n)
    m = MeshTet.init_tensor(*(p,) * 3)
    e = ElementTetP1()
    basis = Basis(m, e) if variant == "fem" else RKBasis(m, e, interpolating=True)
    clock["basis"] = time.process_time() - start
    if variant == "rk":
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
    out = dict(variant=variant, total=total, peak_mb=resident_mb(), nnz=int(A.nnz),
               error=abs(value - CUBE_CENTRE) / CUBE_CENTRE, **clock)
    if variant != "fem":
        out.update(pairs=basis.npairs, nloc=int(basis.element_nodes.shape[0]),
                   points=int(basis.X.shape[-1]), cells=int(basis.nelems))
    print("RESULT " + json.dumps(out), flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=["fem", "rk"],
                        choices=["fem", "rk", "rk-published"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--n", type=int, default=16, help="vertices per edge (ex09: 16)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.n)
        return
    print(f"load average {os.getloadavg()}; CPU s, median of {args.repeat} processes")
    print(f"{'variant':>13} {'total s':>8} {'basis s':>8} {'asm s':>8} {'solve s':>8} "
          f"{'peak MB':>8} {'rel. error':>10} {'pairs':>10} {'nloc':>5}")
    for variant in args.variants:
        runs = []
        for _ in range(args.repeat):
            done = subprocess.run([sys.executable, __file__, "--child", variant, "--n",
                                   str(args.n)], capture_output=True, text=True)
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
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
