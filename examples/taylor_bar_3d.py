"""The Taylor bar as a 3D quarter against the axisymmetric bar: the table
and the figure of docs/dynamics.md ("3D quarter bar").

Reads the ``history.csv`` of four finished runs (the 3D quarter and the
axisymmetric section, RKPM and FEM) and prints, for each, the final length
(``top z`` or ``top y``), the foot radius (``foot x``), the explicit
steps and the largest change of the energy balance over the peak kinetic
energy; draws the foot radius and the length against time.

Run the four first (each writes ``history.csv`` to its folder):

    skfem-rkpm run taylor_bar_3d --out results/taylor_bar_3d-rkpm
    skfem-rkpm run taylor_bar_3d --method fem --out results/taylor_bar_3d-fem
    skfem-rkpm run taylor_bar --set dynamics.output_interval=5e-6 --out results/taylor_bar-rkpm
    skfem-rkpm run taylor_bar --method fem --set dynamics.output_interval=5e-6 \\
        --out results/taylor_bar-fem

then:  python examples/taylor_bar_3d.py results --figure docs/figures/taylor_bar_3d.png
(folders other than ``RESULTS/taylor_bar[_3d]-METHOD``: --folders 3D_RKPM 3D_FEM AXI_RKPM AXI_FEM)
"""

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

RUNS = [("3D quarter", "RKPM", "taylor_bar_3d-rkpm", "z"), ("3D quarter", "FEM Hex1",
        "taylor_bar_3d-fem", "z"), ("axisymmetric", "RKPM", "taylor_bar-rkpm", "y"),
        ("axisymmetric", "FEM Q1", "taylor_bar-fem", "y")]


def history(folder):
    """The rows of ``folder/history.csv`` as dicts of floats."""
    with open(Path(folder) / "history.csv", newline="", encoding="utf-8") as handle:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="?", default="results",
                        help="the folder holding the four run folders")
    parser.add_argument("--folders", nargs=4, metavar="FOLDER",
                        help="the run folders: 3D RKPM, 3D FEM, axisymmetric RKPM, FEM")
    parser.add_argument("--figure", default="taylor_bar_3d.png")
    args = parser.parse_args()
    folders = args.folders or [Path(args.results) / run[2] for run in RUNS]
    fig, (ax_r, ax_l) = plt.subplots(1, 2, figsize=(10, 4.2))
    print("| model | method | steps | length mm | foot radius mm | "
          "max \\|balance error\\| / peak kinetic |")
    print("|---|---|---:|---:|---:|---:|")
    for (model, method, _, axis), folder in zip(RUNS, folders):
        rows = history(folder)
        t = np.array([r["time"] for r in rows]) * 1e6
        foot = np.array([r["foot x"] for r in rows])
        top = np.array([r[f"top {axis}"] for r in rows])
        peak = max(r["kinetic"] for r in rows)
        error = max(abs(r["balance error"]) for r in rows) / peak
        print(f"| {model} | {method} | {int(rows[-1]['step']):,} | {top[-1]:.3f} | "
              f"{foot[-1]:.3f} | {error:.1e} |")
        style = dict(marker="o" if model == "3D quarter" else None, ms=4,
                     ls="-" if model == "3D quarter" else "--",
                     label=f"{model}, {method}")
        ax_r.plot(t, foot, **style)
        ax_l.plot(t, top, **style)
    ax_r.set_ylabel("foot radius (mm)")
    ax_l.set_ylabel("length (mm)")
    for ax in (ax_r, ax_l):
        ax.set_xlabel("time (µs)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Taylor bar, 227 m/s: 3D quarter (3 + 3 cells across, 50 along) "
                 "against axisymmetric (5 x 50)")
    fig.tight_layout()
    fig.savefig(args.figure, dpi=120)
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
