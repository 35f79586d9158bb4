"""Speed against accuracy on a plastic problem: plane strain upsetting.

A unit square block (plane strain, E = 200 GPa, ν = 0.3, J2 plasticity with
linear hardening σ_y = 300 MPa, H = 2000 MPa) is compressed by 10 % of its
height between rigid sticking platens: both displacement components are
prescribed on the nodes of the bottom (zero) and top sides (``u_y = -0.1``,
``u_x = 0``), in 10 equal load steps.  The platen force per unit depth (the
sum of the reactions of ``top[1]``) at the end is the quantity compared.  The
sticking corners make the deformation inhomogeneous (barrelling, dead zones
under the platens, shear bands), so the force depends on the discretization
and converges only slowly; homogeneous compression would be exact for every
method and show nothing.

Methods on ``rectangle(1, 1, n, n)`` meshes (``kind="tri"`` for T3 and T6):

* RK: ``RKBasis(mesh, vector=True, support=c, order=k, intorder=q,
  integration=...)`` with ``locking="fbar"`` (what ``locking = "auto"``
  picks for RKPM unless a tool slides), and two runs without F-bar;
* FEM: Q1 (2x2 Gauss), Q1 with F-bar, Q2 (3x3), T3 (3 points), T6 (6 points).

Reference: Q1 with F-bar on 32², 64² and 128² cells, extrapolated with the
observed rate (Richardson); its uncertainty is taken as the size of the
extrapolation step from the finest run.  The same 10 load steps are used
everywhere, so the step error is not part of the difference.

Times are CPU seconds of the process (``time.process_time``) for the basis,
the problem setup and the whole incremental solution (``newton_steps``,
default ``auto`` linear solver), fastest of up to 3 runs for runs below
2 s.  One core: the thread variables are set before numpy is imported.

Run:  python benchmarks/plastic_trade.py                   (~15 minutes)
      python benchmarks/plastic_trade.py --levels 4 8 16 --reference 16 32 64   (~2 minutes)
      python benchmarks/plastic_trade.py --figure docs/figures/plastic_trade.png
"""

import os

# one core: must be set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REDUCTION = 0.1
STEPS = 10
E, NU, SIGMA_Y, HARDENING = 200e3, 0.3, 300.0, 2000.0

# label: (kind, basis options, locking); intorder 2 / 4 / 6 / 10: 2x2 / 3x3 / 4x4 / 6x6
RK_METHODS = {
    "RK1 c=1.5 3x3 VCI F-bar": ("rk", dict(support=1.5), "fbar"),
    "RK1 c=2 3x3 VCI F-bar": ("rk", dict(support=2.0), "fbar"),
    "RK1 c=3 3x3 VCI F-bar": ("rk", dict(support=3.0), "fbar"),
    "RK1 c=4 4x4 VCI F-bar": ("rk", dict(support=4.0, intorder=6), "fbar"),
    "RK1 c=2 3x3 Gauss F-bar": ("rk", dict(support=2.0, integration="gauss"), "fbar"),
    "RK1 c=2 2x2 VCI F-bar": ("rk", dict(support=2.0, intorder=2), "fbar"),
    "RK1 c=2 4x4 VCI F-bar": ("rk", dict(support=2.0, intorder=6), "fbar"),
    "RK1 c=2 6x6 VCI F-bar": ("rk", dict(support=2.0, intorder=10), "fbar"),
    "RK2 c=3 4x4 VCI F-bar": ("rk", dict(support=3.0, order=2, intorder=6), "fbar"),
    "RK1 c=2 3x3 VCI": ("rk", dict(support=2.0), None),
    "RK1 c=3 3x3 VCI": ("rk", dict(support=3.0), None),
    # nodal integration: one point per particle, no F-bar (nothing to average)
    "RK1 c=2 SCNI": ("rk", dict(support=2.0, integration="scni"), None),
    "RK1 c=2 SCNI α=1e-3": ("rk", dict(support=2.0, integration="scni",
                                       stabilization=1e-3), None),
    "RK1 c=2 SCNI Voronoi": ("rk", dict(support=2.0, integration="scni",
                                        smoothing="voronoi"), None),
    "RK1 c=2 DNI": ("rk", dict(support=2.0, integration="dni"), None),
}
FEM_METHODS = {
    "Q1": ("Q1", {}, None),
    "Q1 F-bar": ("Q1", {}, "fbar"),
    "Q2": ("Q2", {}, None),
    "T3": ("T3", {}, None),
    "T6": ("T6", {}, None),
}
METHODS = {**RK_METHODS, **FEM_METHODS}


def make_problem(kind, n, options, locking):
    from skfem import (Basis, ElementQuad1, ElementQuad2, ElementTriP1, ElementTriP2,
                       ElementVector)

    from skfem_rkpm import RKBasis
    from skfem_rkpm.mechanics.materials import J2Material, linear
    from skfem_rkpm.mechanics.problem import SolidProblem
    from skfem_rkpm.meshes import rectangle

    mesh = rectangle(1.0, 1.0, n, n, kind="tri" if kind in ("T3", "T6") else "quad")
    if kind == "rk":
        basis = RKBasis(mesh, vector=True, **options)
    else:
        element, intorder = {"Q1": (ElementQuad1, 2), "Q2": (ElementQuad2, 4),
                             "T3": (ElementTriP1, 2), "T6": (ElementTriP2, 4)}[kind]
        basis = Basis(mesh, ElementVector(element()), intorder=intorder)
    material = J2Material(E, NU, linear(SIGMA_Y, HARDENING))
    return SolidProblem(basis, material, "plane_strain", locking=locking)


def upset(kind, n, options, locking):
    """One run: (completed, force per depth, dofs, CPU s, Newton iterations, message)."""
    from skfem_rkpm.solvers.newton import Prescribed, newton_steps

    start = time.process_time()
    problem = make_problem(kind, n, options, locking)
    conditions = [Prescribed("bottom", 0, 0.0), Prescribed("bottom", 1, 0.0),
                  Prescribed("top", 0, 0.0), Prescribed("top", 1, -REDUCTION)]
    result = newton_steps(problem, conditions, steps=STEPS)
    seconds = time.process_time() - start
    force = -result.history[-1].reactions["top[1]"] if result.history else np.nan
    return dict(completed=bool(result.completed), force=float(force), dofs=int(problem.N),
                seconds=seconds, iterations=sum(r.iterations for r in result.history),
                t=float(result.history[-1].t) if result.history else 0.0,
                message=result.message)


def measure(label, n, repeat=3, fast=2.0):
    kind, options, locking = METHODS[label]
    try:
        best = upset(kind, n, options, locking)
    except Exception as err:  # reported in the table, e.g. a singular moment matrix
        return dict(method=label, n=n, completed=False, error=f"{type(err).__name__}: {err}")
    for _ in range(repeat - 1):
        if best["seconds"] > fast:
            break
        again = upset(kind, n, options, locking)
        best["seconds"] = min(best["seconds"], again["seconds"])
    return dict(method=label, n=n, **best)


def reference(levels):
    """Richardson extrapolation of Q1 F-bar on the three finest ``levels``."""
    runs = [measure("Q1 F-bar", n, repeat=1) for n in levels]
    f = [r["force"] for r in runs]
    out = dict(runs=runs, finest=f[-1])
    if len(f) >= 3 and all(r["completed"] for r in runs):
        d1, d2 = f[-3] - f[-2], f[-2] - f[-1]
        ratio = levels[-1] / levels[-2]
        if d1 * d2 > 0 and abs(d1) > abs(d2):
            rate = np.log(d1 / d2) / np.log(ratio)
            value = f[-1] - d2 / (ratio**rate - 1.0)
            out.update(rate=float(rate), value=float(value),
                       uncertainty=float(abs(value - f[-1])))
            return out
    out.update(rate=None, value=f[-1], uncertainty=abs(f[-1] - f[-2]) if len(f) > 1 else None)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[4, 8, 16, 32],
                        help="cells per side")
    parser.add_argument("--reference", type=int, nargs="+", default=[32, 64, 128],
                        help="cells per side of the Q1 F-bar reference runs")
    parser.add_argument("--methods", nargs="+", default=list(METHODS),
                        help="labels of the methods to run")
    parser.add_argument("--max-seconds", type=float, default=60.0,
                        help="skip a method's finer levels once a run took longer")
    parser.add_argument("--figure", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    import scipy
    import skfem
    print(f"Python {platform.python_version()}, numpy {np.__version__}, scipy "
          f"{scipy.__version__}, scikit-fem {skfem.__version__}; one thread, CPU seconds; "
          f"load average at start {' '.join(f'{x:.1f}' for x in os.getloadavg())}\n",
          flush=True)
    start = time.process_time()
    ref = reference(sorted(args.reference))
    print("Reference, Q1 F-bar: " + ", ".join(
        f"{r['n']}²: {r['force']:.3f} ({r['dofs']:,} dofs, {r['seconds']:.1f} s"
        + ("" if r["completed"] else f", stopped at t = {r['t']:.3g}") + ")"
        for r in ref["runs"]))
    if ref["rate"] is not None:
        print(f"observed rate {ref['rate']:.2f}; extrapolated {ref['value']:.3f} "
              f"± {ref['uncertainty']:.2f} ({100 * ref['uncertainty'] / ref['value']:.2f} %)")
    else:
        print(f"no clean rate: the finest run {ref['value']:.3f} is taken, "
              f"± {ref['uncertainty']}")
    print(f"load average after the reference: "
          f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}\n", flush=True)
    F_ref = ref["value"]

    records = []
    for label in args.methods:
        for n in sorted(args.levels):
            r = measure(label, n)
            r["load"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
            if r.get("completed"):
                r["error"] = abs(r["force"] - F_ref) / F_ref
            records.append(r)
            print(f"{label}, {n}²: " + (
                f"{r['force']:.2f}, error {100 * r['error']:.2f} %, {r['dofs']} dofs, "
                f"{r['seconds']:.2f} s, {r['iterations']} iterations"
                if r.get("completed") else
                r.get("error") if isinstance(r.get("error"), str) else
                f"stopped at t = {r['t']:.3g}: {r['message']}"), flush=True)
            if not r.get("completed") or r["seconds"] > args.max_seconds:
                break
    total = time.process_time() - start

    print(f"\nPlane strain upsetting, {100 * REDUCTION:g} % height reduction between sticking "
          f"platens, {STEPS} load steps; reference force {F_ref:.2f} ± "
          f"{ref['uncertainty']:.2f} per unit depth\n")
    print("| method | cells | dofs | CPU s | Newton iterations | force | relative error |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in records:
        if not r.get("completed"):
            why = (r["error"] if isinstance(r.get("error"), str)
                   else f"stopped at t = {r['t']:.3g}")
            print(f"| {r['method']} | {r['n']}² | {r.get('dofs', '')} | | | {why} | |")
            continue
        print(f"| {r['method']} | {r['n']}² | {r['dofs']:,} | {r['seconds']:.3g} | "
              f"{r['iterations']} | {r['force']:.2f} | {r['error']:.2e} |")
    print(f"\nwhole script: {total:.0f} CPU s; load average at the end "
          f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    if args.json:
        args.json.write_text(json.dumps(dict(reference=ref, records=records), indent=1))
    if args.figure:
        figure(records, ref, args.figure)
        print(f"figure: {args.figure}")


def figure(records, ref, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_dofs, ax_time) = plt.subplots(1, 2, figsize=(14, 6))
    colors = plt.get_cmap("tab20").colors
    for i, method in enumerate(dict.fromkeys(r["method"] for r in records)):
        rows = [r for r in records if r["method"] == method and r.get("completed")]
        if not rows:
            continue
        rk = method.startswith("RK")
        style = dict(marker="o" if rk else "s", ls="-" if rk else "--",
                     color=colors[(2 * i) % 20 + (2 * i) // 20 % 2], ms=4)
        if rk and "F-bar" not in method:
            style.update(ls=":", marker="x")
        err = [r["error"] for r in rows]
        ax_dofs.loglog([r["dofs"] for r in rows], err, label=method, **style)
        ax_time.loglog([r["seconds"] for r in rows], err, label=method, **style)
    band = ref["uncertainty"] / ref["value"] if ref.get("uncertainty") else None
    for ax, label in ((ax_dofs, "degrees of freedom"),
                      (ax_time, "CPU seconds: basis + setup + 10 load steps")):
        if band:
            ax.axhline(band, color="0.5", lw=0.8, ls="-.")
            ax.text(ax.get_xlim()[0] if False else 0.02, band, " reference uncertainty",
                    transform=ax.get_yaxis_transform(), va="bottom", fontsize=7, color="0.4")
        ax.set_xlabel(label)
        ax.set_ylabel("relative error of the platen force")
        ax.grid(True, which="both", alpha=0.3)
    ax_dofs.set_title("Plane strain upsetting (10 %, sticking): error vs dofs")
    ax_time.set_title("error vs CPU time (one core)")
    ax_time.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
