"""Past the fold at two particle resolutions (docs/large_deformation.md).

The paper's ring (Sec. 5.3) under stick friction pressed to 80 % and under
μ = 0.3 pressed to 75 % by Lagrangian RKPM (Gauss + VCI), at the paper's
resolution (15 x 10 cells, 16 x 11 particles, support 6 mm = 3 h) and at
2x per direction (30 x 20 cells, 31 x 21 particles, support 3 mm = 3 h),
with the same load step (0.114 mm of platen travel).  Each case runs into
its own folder under ``--out`` (a finished one is reused: only its
``status.txt`` and ``history.csv`` are read); the script prints each
case's end, the CPU time and load of each run, the first height reduction
at which a drawn cell and the RK map itself fold (the ``history.csv``
columns ``drawn folded cells`` and ``map folded cells``), and at 50-80 %
height reduction the ID change and the platen force of both resolutions,
their differences and whether they meet the targets (2 points, 3 %).

    python benchmarks/fold_convergence.py --out results/foldconv [--case NAME ...]
        [--figure docs/figures/large_deformation_resolutions.png]
"""

import argparse
import csv
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_study import ending  # noqa: E402

HEIGHT, INNER = 20.0, 30.0      # quarter model: half height, inner radius (mm)
STEP = 16.0 / 140               # platen travel per load step (mm)
RESOLUTIONS = {"paper": ["geometry.divisions=[15,10]", "discretization.support=6.0"],
               "2x": ["geometry.divisions=[30,20]", "discretization.support=3.0"]}
FRICTIONS = {"stick": (["tools.platen.friction=stick"], 16.0),
             "stick70": (["tools.platen.friction=stick"], 14.0),
             "mu03": (["tools.platen.friction=0.3"], 15.0)}
OPTIONS = {"nofbar": ["discretization.locking=none"], "auto": [],
           "nofbar280": ["discretization.locking=none", "steps.count=280"]}
CASES = {f"{f}-{o}-{r}": (f, o, r) for f in FRICTIONS for o in OPTIONS for r in RESOLUTIONS}
COMMON = ["output.fields=false", "output.figures=false", "steps.max_iterations=40"]
#: the targets of two resolutions: ID change within 2 points, force within 3 %
TARGET_ID, TARGET_FORCE = 2.0, 3.0


def settings(case):
    """The ``--set`` list of one case."""
    friction, option, resolution = CASES[case]
    fset, travel = FRICTIONS[friction]
    steps = int(round(travel / STEP))
    return [*fset, f"tools.platen.motion=[0.0,-{travel}]", f"steps.count={steps}",
            *COMMON, *OPTIONS[option], *RESOLUTIONS[resolution]]


def run_case(out, case):
    """Run one case into ``out`` unless a finished run is there; CPU seconds or None."""
    from skfem_rkpm.runs.runner import build, run
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    status = out / "status.txt"
    if status.is_file() and not status.read_text().startswith("running"):
        return None
    scene = load_scene(builtin_scenes()["ring"], settings(case))
    load = os.getloadavg()[0]
    clock = time.process_time()
    run(build(scene, "rkpm"), out, progress=False)
    seconds = time.process_time() - clock
    print(f"{case}: {seconds:.1f} s CPU in the run, load {load:.1f} -> "
          f"{os.getloadavg()[0]:.1f}", file=sys.stderr, flush=True)
    return seconds


def history(out, travel):
    """(height reduction %, ID change %, platen force N, drawn folded cells,
    map folded cells, map det F min) along a run's history (the last three
    None for a history without those columns)."""
    rows = list(csv.DictReader(open(out / "history.csv", newline="")))
    t = np.array([float(r["t"]) for r in rows])
    inner = np.array([float(r["inner_mid x"]) for r in rows])
    force = np.abs([float(r["reaction platen y"]) for r in rows])
    folds = [np.array([float(r[key]) for r in rows]) if rows and key in rows[0] else None
             for key in ("drawn folded cells", "map folded cells", "map det F min")]
    return (100.0 * t * travel / HEIGHT, 100.0 * (inner - INNER) / INNER, force, *folds)


def first_fold(curve):
    """The height reductions (%) of the first steps with a folded drawn
    cell and with a folded map (None: none folds; "?": not recorded)."""
    r = curve[0]
    return tuple("not recorded" if count is None else
                 (f"{r[np.argmax(count > 0)]:.1f} %" if (count > 0).any() else "none")
                 for count in curve[3:5])


def at(curve, reduction):
    """ID change and force interpolated at a height reduction (None past the end)."""
    r, idc, force = curve[:3]
    if r[-1] < reduction - 1e-9:
        return None
    return float(np.interp(reduction, r, idc)), float(np.interp(reduction, r, force))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/foldconv"))
    parser.add_argument("--case", action="append", choices=sorted(CASES))
    parser.add_argument("--no-run", action="store_true")
    parser.add_argument("--figure", type=Path)
    args = parser.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    curves = {}
    for case in args.case or CASES:
        out = args.out / case
        if not args.no_run:
            run_case(out, case)
        if (out / "history.csv").is_file():
            travel = FRICTIONS[CASES[case][0]][1]
            curves[case] = history(out, travel)
            status = (out / "status.txt").read_text().strip()
            drawn, mapped = first_fold(curves[case])
            end = (status.splitlines()[0] if status.startswith(("running", "interrupted"))
                   else ending(status))
            print(f"| {case} | {curves[case][0][-1]:.1f} % | {end} | "
                  f"first drawn cell folded: {drawn} | first map fold: {mapped} |")
    for friction in FRICTIONS:
        for option in OPTIONS:
            pair = [curves.get(f"{friction}-{option}-{r}") for r in RESOLUTIONS]
            if None in pair:
                continue
            for reduction in (50.0, 60.0, 70.0, 75.0, 80.0):
                values = [at(c, reduction) for c in pair]
                if None in values:
                    continue
                (i1, f1), (i2, f2) = values
                df = 100 * (f2 - f1) / f1
                met = abs(i2 - i1) <= TARGET_ID and abs(df) <= TARGET_FORCE
                print(f"| {friction} | {option} | {reduction:.0f} % | {i1:.1f} | {i2:.1f} | "
                      f"{i2 - i1:+.1f} | {f1 / 1e3:.0f} | {f2 / 1e3:.0f} | "
                      f"{df:+.1f} % | {'yes' if met else 'no'} |")
    if args.figure and curves:
        figure(curves, args.figure)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    print(f"whole process: {usage.ru_utime + usage.ru_stime:.1f} s CPU, load now "
          f"{os.getloadavg()[0]:.1f}", file=sys.stderr)


def figure(curves, path):
    """ID change, platen force and the map's smallest det F against the
    height reduction, paper resolution solid, 2x dashed."""
    import matplotlib.pyplot as plt

    panels = 3 if any(c[5] is not None for c in curves.values()) else 2
    fig, axes = plt.subplots(1, panels, figsize=(4.8 * panels, 4))
    pairs = list(dict.fromkeys(case.rsplit("-", 1)[0] for case in curves))
    for case, curve in curves.items():
        r, idc, force = curve[:3]
        style = dict(ls="-" if case.endswith("paper") else "--",
                     color=f"C{pairs.index(case.rsplit('-', 1)[0])}", label=case)
        axes[0].plot(r, idc, **style)
        axes[1].plot(r, force / 1e3, **style)
        if panels == 3 and curve[5] is not None:
            axes[2].plot(r, curve[5], **style)
    axes[0].set_ylabel("change of inner diameter at mid-height (%)")
    axes[1].set_ylabel("platen force, full ring (kN)")
    if panels == 3:
        axes[2].axhline(0.0, color="k", lw=0.8)
        axes[2].set_ylabel("smallest det F of the RK map (sampled, 1)")
    for ax in axes:
        ax.set_xlabel("height reduction (%)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Ring, RKPM Gauss+VCI: paper resolution 15 x 10 cells (solid), "
                 "2x 30 x 20 (dashed)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
