"""How far each discretization takes the ring past the fold (docs/large_deformation.md).

The paper's ring (Sec. 5.3, 15 x 10 cells, the paper's resolution) pressed
to 80 % of its height in 140 steps, with stick friction and with μ = 0.3,
by RKPM (Gauss + VCI; SCNI with median dual and Voronoi cells; Gauss + VCI
re-referenced at θ = 0.5, also with re-dilated supports, the state copied
point by point and no F-bar; SCNI re-referenced) and FEM Q1.  Each run
goes to its own folder under ``--out`` (a finished one is reused: its
``status.txt`` and ``history.csv`` are read, nothing else); the script
prints the table of where each stopped and why and draws the height
reduction reached per method.

    python benchmarks/reach_study.py --out results/reach [--figure docs/figures/large_deformation_reach.png]
"""

import argparse
import csv
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

METHODS = {
    "RKPM Gauss+VCI": ("rkpm", []),
    "RKPM Gauss+VCI, no F-bar": ("rkpm", ["discretization.locking=none"]),
    "RKPM SCNI": ("rkpm", ["discretization.integration=scni"]),
    "RKPM SCNI, Voronoi cells": ("rkpm", ["discretization.integration=scni",
                                          "discretization.smoothing=voronoi"]),
    "RKPM Gauss+VCI, re-referenced": ("rkpm", ["discretization.rereference=0.5"]),
    "RKPM SCNI, re-referenced": ("rkpm", ["discretization.integration=scni",
                                          "discretization.rereference=0.5"]),
    "RKPM Gauss+VCI, re-referenced, re-dilated, copied, no F-bar": (
        "rkpm", ["discretization.rereference=0.5",
                 "discretization.rereference_supports=spacing",
                 "discretization.rereference_transfer=points",
                 "discretization.locking=none"]),
    "FEM Q1": ("fem", []),
}
FOLDERS = {
    "RKPM Gauss+VCI": "vci",
    "RKPM Gauss+VCI, no F-bar": "vci_nofbar",
    "RKPM SCNI": "scni",
    "RKPM SCNI, Voronoi cells": "voronoi",
    "RKPM Gauss+VCI, re-referenced": "reref",
    "RKPM SCNI, re-referenced": "reref_scni",
    "RKPM Gauss+VCI, re-referenced, re-dilated, copied, no F-bar": "reref_best",
    "FEM Q1": "fem",
}
FRICTIONS = {"stick": "stick", "μ = 0.3": "0.3"}
COMMON = ["tools.platen.motion=[0.0,-16.0]", "steps.count=140", "output.fields=false",
          "output.figures=false"]
TRAVEL, HEIGHT = 16.0, 20.0


def run_one(out, friction, method, settings):
    """Run one case into ``out`` unless a finished run is there."""
    from skfem_rkpm.runs.runner import build, run
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    status = out / "status.txt"
    if status.is_file() and not status.read_text().startswith("running"):
        return None
    scene = load_scene(builtin_scenes()["ring"],
                       [f"tools.platen.friction={friction}", *COMMON, *settings])
    clock = time.process_time()
    run(build(scene, method), out, progress=False)
    return time.process_time() - clock


def summary(out):
    """(height reduction reached %, inner-mid radius, status first lines) of a run folder."""
    rows = list(csv.DictReader(open(out / "history.csv", newline="")))
    t = float(rows[-1]["t"]) if rows else 0.0
    inner = float(rows[-1]["inner_mid x"]) if rows else 30.0
    return 100.0 * t * TRAVEL / HEIGHT, inner, (out / "status.txt").read_text().strip()


def ending(status):
    """How a run ended, in a few words, from its ``status.txt``."""
    lines = status.splitlines()
    cause = next((line[len("cause: "):] for line in lines if line.startswith("cause: ")),
                 None)
    if cause is not None:
        text = "stopped: " + re.sub(r" \(.*", "", cause.split(";")[0])[:80]
    else:
        folded = re.search(r"\((\d+) of (\d+) cells folded\)", lines[0])
        text = "completed" + (f", {folded[1]} of {folded[2]} cells folded at the end"
                              if folded else "")
    rebuilds = re.search(r"re-referenced (\d+) times", status)
    if rebuilds:
        text += f"; {rebuilds[1]} rebuilds"
    refused = re.search(r"a rebuild at t = ([\d.]+) was refused", status)
    if refused:
        text += f", one refused at t = {refused[1]} (folded cell)"
    return text


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/reach"))
    parser.add_argument("--figure", type=Path)
    parser.add_argument("--no-run", action="store_true",
                        help="only read the finished runs under --out (skip the others)")
    args = parser.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    results = {}
    for fname, friction in FRICTIONS.items():
        for name, (method, settings) in METHODS.items():
            out = args.out / f"{friction}-{FOLDERS[name]}"
            if args.no_run and not (out / "history.csv").is_file():
                continue
            seconds = None if args.no_run else run_one(out, friction, method, settings)
            results[fname, name] = summary(out)
            if seconds is not None:
                print(f"{fname}, {name}: {seconds:.1f} s CPU", file=sys.stderr)
    print("| friction | method | height reduction reached | inner-mid radius there (mm) | "
          "how it ended |")
    print("|---|---|---|---|---|")
    for (fname, name), (reached, inner, status) in results.items():
        print(f"| {fname} | {name} | {reached:.1f} % | {inner:.2f} | {ending(status)} |")
    if args.figure:
        import matplotlib.pyplot as plt

        names = list(METHODS)
        fig, ax = plt.subplots(figsize=(8.5, 4.4))
        height = 0.38
        for k, fname in enumerate(FRICTIONS):
            values = [results.get((fname, name), (0.0,))[0] for name in names]
            ax.barh(np.arange(len(names)) + (k - 0.5) * height, values, height,
                    label=fname)
        ax.axvline(80.0, color="k", ls="--", lw=1, label="target 80 %")
        ax.set_yticks(np.arange(len(names)), names)
        ax.invert_yaxis()
        ax.set_xlabel("height reduction reached (%)")
        ax.set_xlim(0, 85)
        ax.set_title("Ring 6:3:2, 15 x 10 cells, 140 steps to 80 %")
        ax.legend(loc="lower right", fontsize=8)
        fig.tight_layout()
        args.figure.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.figure, dpi=120)


if __name__ == "__main__":
    main()
