"""The figures of docs/forming_3d.md from the run folders of the 3D scenes.

Run the scenes first (about an hour of CPU on one core), then this script::

    skfem-rkpm run ring --out runs/ring-rkpm
    skfem-rkpm run ring --method fem --out runs/ring-fem
    skfem-rkpm run ring_sector --out runs/ring_sector-rkpm
    skfem-rkpm run ring_sector --method fem --out runs/ring_sector-fem
    skfem-rkpm run billet_3d --out runs/billet_3d-rkpm
    skfem-rkpm run billet_3d --set 'discretization.locking="none"' --out runs/billet_3d-rkpm-none
    skfem-rkpm run billet_3d --method fem --out runs/billet_3d-fem
    skfem-rkpm run stretch_3d --out runs/stretch_3d-rkpm
    skfem-rkpm run stretch_3d --method fem --out runs/stretch_3d-fem
    MPLBACKEND=Agg python docs/figures/make_forming_3d.py runs

A missing run folder leaves its curve out.
"""

import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = Path(__file__).parent


def history(folder):
    path = Path(folder) / "history.csv"
    if not path.is_file():
        return None
    rows = list(csv.DictReader(open(path, newline="")))
    return {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}


def ring_figure(runs):
    """Inner-diameter change and full-ring force against height reduction:
    the axisymmetric ring and the 15° sector, RKPM and FEM."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    curves = {"ring-rkpm": ("axisymmetric, RKPM", "C0", "-", "y", 1.0),
              "ring-fem": ("axisymmetric, FEM Q1", "C1", "-", "y", 1.0),
              "ring_sector-rkpm": ("3D sector, RKPM", "C0", "--", "z", 24.0),
              "ring_sector-fem": ("3D sector, FEM Hex1", "C1", "--", "z", 24.0)}
    for name, (label, color, style, axis, copies) in curves.items():
        h = history(runs / name)
        if h is None:
            continue
        reduction = 50.0 * h["t"]
        left.plot(reduction, 100.0 * (h["inner_mid x"] / 30.0 - 1.0), color=color,
                  ls=style, label=label)
        right.plot(reduction, -copies * h[f"reaction platen {axis}"] / 1e3, color=color,
                   ls=style, label=label)
    left.set_ylabel("inner diameter change (%)")
    right.set_ylabel("platen force, full ring (kN)")
    for ax in (left, right):
        ax.set_xlabel("height reduction (%)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Ring compression, μ = 0.15: the 3D sector against the axisymmetric ring")
    fig.tight_layout()
    return fig


def billet_figure(runs):
    """Platen force (whole billet) against height reduction."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    curves = {"billet_3d-rkpm": ("RKPM, F-bar", "C0", "-"),
              "billet_3d-rkpm-none": ("RKPM, no F-bar", "C0", ":"),
              "billet_3d-fem": ("FEM Hex1, F-bar", "C1", "-")}
    for name, (label, color, style) in curves.items():
        h = history(runs / name)
        if h is not None:
            ax.plot(50.0 * h["t"], -4.0 * h["reaction platen z"] / 1e3, color=color,
                    ls=style, label=label)
    reduction = np.linspace(0.0, 50.0, 101)
    ax.plot(reduction, 100.0 * 800.0 / (1.0 - reduction / 100.0) / 1e3, "k--", lw=0.8,
            label="frictionless (homogeneous)")
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("platen force, whole billet (kN)")
    ax.set_title("Rectangular billet 40 x 20 x 30 mm, μ = 0.3")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def stretch_figure(runs):
    """Punch force (whole sheet) against punch travel."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for name, label, color in (("stretch_3d-rkpm", "RKPM", "C0"),
                               ("stretch_3d-fem", "FEM Hex1", "C1")):
        h = history(runs / name)
        if h is not None:
            ax.plot(15.0 * h["t"], 4.0 * h["reaction punch z"] / 1e3, color=color,
                    label=label)
    ax.set_xlabel("punch travel (mm)")
    ax.set_ylabel("punch force, whole sheet (kN)")
    ax.set_title("Square sheet over a ball punch (R = 25 mm), μ = 0.1")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def main():
    runs = Path(sys.argv[1] if len(sys.argv) > 1 else "runs")
    for name, make in (("forming_3d_ring.png", ring_figure),
                       ("forming_3d_billet.png", billet_figure),
                       ("forming_3d_stretch.png", stretch_figure)):
        fig = make(runs)
        fig.savefig(HERE / name, dpi=110)
        plt.close(fig)
        print("wrote", HERE / name)


if __name__ == "__main__":
    main()
