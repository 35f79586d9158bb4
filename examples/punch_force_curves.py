"""Punch force against punch travel for several finished runs (paper Fig. 9).

Reads ``history.csv`` of each run folder (``skfem-rkpm run ... --out DIR`` or
``examples/forming_scenes.py ... --run-dir DIR``) and draws one curve per
run, e.g. the hemispherical punch without and with friction::

    python examples/punch_force_curves.py results/hemi-mu0 results/hemi-mu03 \\
        --labels "μ = 0" "μ = 0.3" --out docs/figures/scene_hemisphere_friction.png

A run that stopped early is drawn as far as it got.
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402



def force_curve(run_dir, tool="punch"):
    """Travel (mm, ≥ 0) and force magnitude along the travel of ``tool``."""
    path = Path(run_dir) / "history.csv"
    columns = path.read_text().splitlines()[0].split(",")
    rows = np.atleast_2d(np.loadtxt(path, delimiter=",", skiprows=1))
    travel = -rows[:, columns.index(f"{tool} dy")]
    force = -rows[:, columns.index(f"reaction {tool} y")]
    return np.concatenate([[0.0], travel]), np.concatenate([[0.0], force])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--labels", nargs="+")
    parser.add_argument("--tool", default="punch")
    parser.add_argument("--unit", default="kN", choices=("N", "kN"))
    parser.add_argument("--out", type=Path, default=Path("punch_force_curves.png"))
    args = parser.parse_args()
    labels = args.labels or [run.name for run in args.runs]
    if len(labels) != len(args.runs):
        parser.error(f"{len(args.runs)} runs but {len(labels)} labels")
    scale = 1e-3 if args.unit == "kN" else 1.0
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for run, label in zip(args.runs, labels):
        travel, force = force_curve(run, args.tool)
        ax.plot(travel, scale * force, label=label)
        print(f"{label}: {travel[-1]:.2f} mm, {force[-1] * scale:.4g} {args.unit}")
    ax.set_xlabel(f"{args.tool} travel [mm]")
    ax.set_ylabel(f"{args.tool} force [{args.unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
