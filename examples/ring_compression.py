"""Ring compression (Chen et al. 1998, Sec. 5.3): μ = 0, 0.15, 0.3 and stick,
RKPM against FEM on the same mesh.

Runs the built-in ``ring`` scene once per method and friction condition and
writes, to ``--out`` (default ``results/ring-study``):

* ``ring_shapes.png``: final shapes of the four friction cases (paper Fig. 13),
  RK particles coloured by equivalent plastic strain, FEM outline in red;
* ``ring_stick_progress.png``: progressive shapes under stick (Fig. 14) and the
  equivalent plastic strain at the end (Fig. 15), RKPM;
* ``ring_calibration.png``: the friction calibration chart, change of the
  inner diameter at mid-height against the height reduction, one curve per μ
  and method;
* ``ring_force.png``: platen force against height reduction;
* ``ring_study.csv``: every step of every run (the numbers behind the charts);
* ``ring_study.md``: one row per run (how far it got, ID change, force,
  Newton iterations, wall time);
* one output folder per run (``history.csv``, ``status.txt``).

Run:  python examples/ring_compression.py [--scene ring|ring_refined]
      [--methods rkpm fem] [--steps 100] [--set key=value ...] [--out DIR]
                                                             (~3 minutes)
"""

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from skfem_rkpm.runs.io import nodal_displacements  # noqa: E402
from skfem_rkpm.runs.plot import nodal_plastic_strain, plot_deformed  # noqa: E402
from skfem_rkpm.runs.runner import build, run  # noqa: E402
from skfem_rkpm.runs.scene import builtin_scenes, load_scene  # noqa: E402

FRICTIONS = ["0.0", "0.15", "0.3", "stick"]
HEIGHT, INNER_RADIUS = 20.0, 30.0  # quarter model: mid-plane to contact face
STYLE = {"rkpm": "-", "fem": "--"}


def ring_run(friction, method, steps, settings, out, name="ring"):
    """One run of a built-in ring scene; returns (simulation, result)."""
    scene = load_scene(builtin_scenes()[name],
                       [f"tools.platen.friction={friction}", f"steps.count={steps}",
                        "output.fields=false", "output.figures=false", *settings])
    sim = build(scene, method)
    return sim, run(sim, out / f"{method}-mu-{friction}", progress=False)


def calibration_points(sim, result):
    """Height reduction, inner-diameter change at mid-height (both %) and
    platen force (kN, full ring) of every converged step, from t = 0."""
    travel = -np.asarray(sim.scene["tools.platen"]["motion"])[1]
    rows = [(0.0, 0.0, 0.0)]
    for record, gauges in zip(result.history, result.gauges):
        rows.append((100.0 * record.t * travel / HEIGHT,
                     100.0 * (gauges["inner_mid x"] - INNER_RADIUS) / INNER_RADIUS,
                     -record.reactions["platen"][1] / 1e3))
    return np.array(rows)


def boundary_outline(basis, d):
    """Deformed boundary edges (2, 2, nedges) of the mesh, from nodal values."""
    mesh = basis.mesh
    x = mesh.p + nodal_displacements(basis, d).T
    return x[:, mesh.facets[:, mesh.boundary_facets()]]


def summary_table(runs):
    lines = ["| method | μ | status | height reduction % | ID change % | platen force kN "
             "| Newton iterations | iterations/step | wall time s |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for (method, friction), (sim, result) in runs.items():
        chart = calibration_points(sim, result)
        its = sum(r.iterations for r in result.history)
        status = "completed" if result.completed else "stopped"
        lines.append(f"| {method} | {friction} | {status} | {chart[-1, 0]:.1f} | "
                     f"{chart[-1, 1]:+.2f} | {chart[-1, 2]:.0f} | {its} | "
                     f"{its / max(len(result.history), 1):.1f} | "
                     f"{sum(r.seconds for r in result.history):.1f} |")
    return "\n".join(lines) + "\n"


def plot_shapes(runs, methods, path):
    reference = "rkpm" if "rkpm" in methods else methods[0]
    # the 99th percentile: a few corner particles would otherwise set the scale
    vmax = max(np.percentile(nodal_plastic_strain(r[0].problem), 99) for r in runs.values())
    fig, axes = plt.subplots(1, 4, figsize=(18, 4))
    for ax, friction in zip(axes, FRICTIONS):
        sim, result = runs[reference, friction]
        art = plot_deformed(ax, sim.problem, result.d, f"μ = {friction}", vmax=vmax,
                            show_cells=False)
        for method in methods:
            if method != reference:
                other, res = runs[method, friction]
                edges = boundary_outline(other.basis, res.d)
                ax.plot(edges[0], edges[1], color="tab:red", lw=1.0)
    fig.colorbar(art, ax=axes, label=f"equivalent plastic strain ({reference})")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def plot_progress(sim, result, path):
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    picks = np.unique(np.linspace(0, len(result.solutions) - 1, 6).astype(int))
    for k in picks:
        edges = boundary_outline(sim.basis, result.solutions[k])
        ax.plot(edges[0], edges[1], color=plt.cm.magma(0.85 * k / max(picks[-1], 1)),
                lw=1.2)
        ax.text(edges[0].max() + 0.5, edges[1].max(), f"{result.history[k].t * 50:.0f}%",
                fontsize=7)
    ax.set_aspect("equal")
    ax.set_title("stick: shapes at increasing height reduction")
    art = plot_deformed(ax2, sim.problem, result.d, "stick: equivalent plastic strain")
    fig.colorbar(art, ax=ax2)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def plot_charts(runs, out):
    fig, ax = plt.subplots(figsize=(6.5, 5))
    fig2, ax2 = plt.subplots(figsize=(6.5, 5))
    for k, friction in enumerate(FRICTIONS):
        for method in dict.fromkeys(m for m, _ in runs):
            chart = calibration_points(*runs[method, friction])
            label = f"{method}, μ = {friction}"
            ax.plot(chart[:, 0], chart[:, 1], STYLE[method], color=f"C{k}", label=label)
            ax2.plot(chart[:, 0], chart[:, 2], STYLE[method], color=f"C{k}", label=label)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("change of inner diameter at mid-height [%]")
    ax.set_title("ring friction calibration chart")
    ax2.set_ylabel("platen force, full ring [kN]")
    for a, f, name in ((ax, fig, "ring_calibration.png"), (ax2, fig2, "ring_force.png")):
        a.set_xlabel("height reduction [%]")
        a.grid(True, alpha=0.3)
        a.legend(fontsize=7)
        f.savefig(out / name, dpi=110, bbox_inches="tight")
        plt.close(f)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", choices=("rkpm", "fem"),
                        default=["rkpm", "fem"])
    parser.add_argument("--scene", choices=("ring", "ring_refined"), default="ring",
                        help="ring_refined: the corner-refined gmsh particles (Fig. 16-17)")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--out", type=Path, default=Path("results/ring-study"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    runs = {}
    for method in args.methods:
        for friction in FRICTIONS:
            runs[method, friction] = ring_run(friction, method, args.steps, args.set,
                                              args.out, args.scene)
            print(summary_table({(method, friction): runs[method, friction]})
                  .splitlines()[-1], flush=True)

    (args.out / "ring_study.md").write_text(summary_table(runs))
    with open(args.out / "ring_study.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", "friction", "height reduction %", "ID change %",
                         "platen force kN"])
        for (method, friction), (sim, result) in runs.items():
            for row in calibration_points(sim, result):
                writer.writerow([method, friction, *(f"{v:.5g}" for v in row)])
    plot_shapes(runs, args.methods, args.out / "ring_shapes.png")
    plot_progress(*runs[args.methods[0], "stick"], args.out / "ring_stick_progress.png")
    plot_charts(runs, args.out)
    print(f"figures, ring_study.md and ring_study.csv in {args.out}")


if __name__ == "__main__":
    main()
