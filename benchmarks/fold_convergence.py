"""Past the fold at two particle resolutions (docs/large_deformation.md).

The paper's ring (Sec. 5.3) under stick friction pressed to 80 % and under
μ = 0.3 pressed to 75 % by Lagrangian RKPM (Gauss + VCI), at the paper's
resolution (15 x 10 cells, 16 x 11 particles, support 6 mm = 3 h) and at
2x per direction (30 x 20 cells, 31 x 21 particles, support 3 mm = 3 h),
with the same load step (0.114 mm of platen travel).  Each case runs into
its own folder under ``--out`` (a finished one is reused: only its
``status.txt`` and ``history.csv`` are read); the script prints each
case's end and, at 70 % and 80 % height reduction, the ID change and the
platen force of both resolutions and their differences.

    python benchmarks/fold_convergence.py --out results/foldconv [--case NAME ...]
        [--figure docs/figures/large_deformation_convergence.png]
"""

import argparse
import csv
import os
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
    clock = time.process_time()
    run(build(scene, "rkpm"), out, progress=False)
    return time.process_time() - clock


def history(out, travel):
    """(height reduction %, ID change %, platen force N) along a run's history."""
    rows = list(csv.DictReader(open(out / "history.csv", newline="")))
    t = np.array([float(r["t"]) for r in rows])
    inner = np.array([float(r["inner_mid x"]) for r in rows])
    force = np.abs([float(r["reaction platen y"]) for r in rows])
    return 100.0 * t * travel / HEIGHT, 100.0 * (inner - INNER) / INNER, force


def at(curve, reduction):
    """ID change and force interpolated at a height reduction (None past the end)."""
    r, idc, force = curve
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
            seconds = run_case(out, case)
            if seconds is not None:
                print(f"{case}: {seconds:.1f} s CPU", file=sys.stderr, flush=True)
        if (out / "history.csv").is_file():
            travel = FRICTIONS[CASES[case][0]][1]
            curves[case] = history(out, travel)
            status = (out / "status.txt").read_text().strip()
            print(f"| {case} | {curves[case][0][-1]:.1f} % | {ending(status)} |")
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
                print(f"| {friction} | {option} | {reduction:.0f} % | {i1:.1f} | {i2:.1f} | "
                      f"{i2 - i1:+.1f} | {f1 / 1e3:.0f} | {f2 / 1e3:.0f} | "
                      f"{100 * (f2 - f1) / f1:+.1f} % |")
    if args.figure and curves:
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
        for case, (r, idc, force) in curves.items():
            ls = "-" if case.endswith("paper") else "--"
            a1.plot(r, idc, ls, label=case)
            a2.plot(r, force / 1e3, ls, label=case)
        a1.set_xlabel("height reduction (%)")
        a1.set_ylabel("change of inner diameter at mid-height (%)")
        a2.set_xlabel("height reduction (%)")
        a2.set_ylabel("platen force, full ring (kN)")
        a1.legend(fontsize=7)
        fig.suptitle("Ring, RKPM Gauss+VCI: paper resolution (solid) and 2x (dashed)")
        fig.tight_layout()
        args.figure.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.figure, dpi=120)


if __name__ == "__main__":
    main()
