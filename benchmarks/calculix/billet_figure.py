"""Platen force against height reduction: our billet_3d runs beside CalculiX's.

Reads run folders of ``skfem-rkpm run billet_3d`` (their history.csv) and
folders written by ``billet_3d.py --out`` (their billet.dat), and draws the
whole billet's platen force (kN) against the height reduction (%).

Run:  python benchmarks/calculix/billet_figure.py --out docs/figures/forming_3d_calculix.png \
          --ours "FEM Hex1 8x4x6=/tmp/fem" --ccx "C3D20R 8x4x6=/tmp/c3d20r" ...
"""

import argparse
import csv
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from billet_3d import PRESS, SIZE, read_dat  # noqa: E402


def ours(folder):
    rows = list(csv.DictReader(open(Path(folder) / "history.csv")))
    t = np.array([float(r["t"]) for r in rows])
    force = np.array([-4e-3 * float(r["reaction platen z"]) for r in rows])
    return t, force


def calculix(folder):
    t, force, _ = read_dat(Path(folder) / "billet.dat")
    return t, -4e-3 * force


def labelled(pairs):
    out = []
    for pair in pairs or []:
        label, _, folder = pair.partition("=")
        if not folder:
            raise SystemExit(f"expected LABEL=FOLDER, got {pair!r}")
        out.append((label, folder))
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--ours", action="append", help="LABEL=RUN_FOLDER")
    parser.add_argument("--ccx", action="append", help="LABEL=CALCULIX_FOLDER")
    args = parser.parse_args(argv)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    reduction = 100.0 * PRESS / SIZE[2]
    for label, folder in labelled(args.ours):
        t, force = ours(folder)
        ax.plot(reduction * t, force, "-", lw=1.8, label=label)
    for label, folder in labelled(args.ccx):
        t, force = calculix(folder)
        ax.plot(reduction * t, force, "--", lw=1.2, label="CalculiX " + label)
    h = np.linspace(0.0, reduction, 51)
    ax.plot(h, 100.0 * 800e-3 / (1.0 - h / 100.0), ":", color="k",
            label="frictionless, σ_y A")
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("platen force, whole billet (kN)")
    ax.set_xlim(0.0, reduction)
    ax.set_ylim(0.0, None)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = Path(args.out)
    with tempfile.NamedTemporaryFile(dir=out.parent, suffix=out.suffix, delete=False) as tmp:
        fig.savefig(tmp.name, dpi=110)
    os.replace(tmp.name, out)


if __name__ == "__main__":
    main()
