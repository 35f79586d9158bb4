"""RKPM versus FEM on the same meshes: Timoshenko's cantilever and Kirsch's
plate with a hole, both loaded by their exact tractions.

Prints a table (dofs, relative L2 and energy errors, observed orders, wall
time) and saves ``elasticity_convergence.png`` with the errors against the
cell size and against the wall time.

Run:  python examples/elasticity_rkpm_vs_fem.py [--levels 4 8 16] [--out DIR]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from skfem import (Basis, ElementQuad1, ElementQuad2, ElementTriP1,  # noqa: E402
                   ElementTriP2, ElementVector)

from skfem_rkpm import RKBasis  # noqa: E402
from skfem_rkpm.verification import (convergence_study, plate_with_hole,  # noqa: E402
                                     rates, timoshenko_beam)


def rk(support, order=1, intorder=4, integration="vci"):
    return lambda m: RKBasis(m, vector=True, support=support, order=order,
                             intorder=intorder, integration=integration)


def fem(element, intorder=4):
    return lambda m: Basis(m, ElementVector(element()), intorder=intorder)


RK_METHODS = {
    "RK1 c=2 (vci)": rk(2.0),
    "RK1 c=2 (gauss)": rk(2.0, integration="gauss"),
    "RK1 c=3 (vci)": rk(3.0),
    "RK2 c=3 (vci)": rk(3.0, order=2, intorder=6),
}
PROBLEMS = {
    "Timoshenko beam (quads)": (timoshenko_beam(), {
        **RK_METHODS, "Q1": fem(ElementQuad1, 2), "Q2": fem(ElementQuad2)}),
    "Plate with a hole (gmsh triangles)": (plate_with_hole(), {
        **RK_METHODS, "T3": fem(ElementTriP1, 2), "T6": fem(ElementTriP2)}),
}


def print_table(title, records):
    print(f"\n{title}")
    print(f"{'method':17s} {'level':>5s} {'dofs':>6s} {'L2 error':>10s} "
          f"{'order':>5s} {'energy':>10s} {'order':>5s} {'time [s]':>8s}")
    for method in dict.fromkeys(r["method"] for r in records):
        rows = [r for r in records if r["method"] == method]
        l2 = [float("nan")] + rates(records, method, "l2")
        en = [float("nan")] + rates(records, method, "energy")
        for r, a, b in zip(rows, l2, en):
            print(f"{method:17s} {r['level']:5d} {r['dofs']:6d} {r['l2']:10.3e} "
                  f"{a:5.2f} {r['energy']:10.3e} {b:5.2f} {r['seconds']:8.3f}")


def plot(results, path):
    fig, axes = plt.subplots(len(results), 3, figsize=(15, 4.5 * len(results)))
    for row, (title, records) in zip(axes, results.items()):
        for method in dict.fromkeys(r["method"] for r in records):
            rows = [r for r in records if r["method"] == method]
            style = "o-" if method.startswith("RK") else "s--"
            h = [r["h"] for r in rows]
            row[0].loglog(h, [r["l2"] for r in rows], style, label=method)
            row[1].loglog(h, [r["energy"] for r in rows], style, label=method)
            row[2].loglog([r["seconds"] for r in rows], [r["energy"] for r in rows],
                          style, label=method)
        for ax, xlabel, ylabel in zip(row, ["cell size h", "cell size h", "wall time [s]"],
                                      ["relative L2 error", "relative energy error",
                                       "relative energy error"]):
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", alpha=0.3)
        row[0].set_title(title)
        row[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[4, 8, 16])
    parser.add_argument("--out", type=Path, default=Path("."))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    for title, (problem, methods) in PROBLEMS.items():
        results[title] = convergence_study(problem, methods, args.levels)
        print_table(title, results[title])
    path = args.out / "elasticity_convergence.png"
    plot(results, path)
    print(f"\nfigure: {path}")


if __name__ == "__main__":
    main()
