"""The speed/accuracy trade on Timoshenko's cantilever: energy error against
wall time (basis, assembly and solve; best of 3) and against dofs, for RKPM at
several normalized supports, basis orders, quadrature orders and integration
schemes, and for FEM Q1, Q2, T3, T6 on the same meshes.

Run:  python benchmarks/elasticity_trade.py [--levels 4 8 16 32] [--out docs/figures]
Prints a table (Markdown) and writes elasticity_trade.png.
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from skfem import (Basis, ElementQuad1, ElementQuad2, ElementTriP1,  # noqa: E402
                   ElementTriP2, ElementVector)

from skfem_rkpm import RKBasis  # noqa: E402
from skfem_rkpm.verification import convergence_study, timoshenko_beam  # noqa: E402


def rk(support, order=1, intorder=4, integration="vci"):
    return lambda m: RKBasis(m, vector=True, support=support, order=order,
                             intorder=intorder, integration=integration)


def fem(element, intorder):
    return lambda m: Basis(m, ElementVector(element()), intorder=intorder)


QUAD_METHODS = {
    "RK1 c=1.5 q2": rk(1.5, intorder=2),
    "RK1 c=2 q2": rk(2.0, intorder=2),
    "RK1 c=2 q4": rk(2.0, intorder=4),
    "RK1 c=2 q4 gauss": rk(2.0, intorder=4, integration="gauss"),
    "RK1 c=3 q4": rk(3.0, intorder=4),
    "RK1 c=4 q6": rk(4.0, intorder=6),
    "RK2 c=3 q4": rk(3.0, order=2, intorder=4),
    "RK2 c=3 q6": rk(3.0, order=2, intorder=6),
    "Q1": fem(ElementQuad1, 2),
    "Q2": fem(ElementQuad2, 4),
}
TRI_METHODS = {"T3": fem(ElementTriP1, 2), "T6": fem(ElementTriP2, 4)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[4, 8, 16, 32])
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    records = (convergence_study(timoshenko_beam(), QUAD_METHODS, args.levels, repeat=3)
               + convergence_study(timoshenko_beam(kind="tri"), TRI_METHODS,
                                   args.levels, repeat=3))
    print("| method | level | dofs | L2 error | energy error | time [s] |")
    print("|---|---|---|---|---|---|")
    for r in records:
        print(f"| {r['method']} | {r['level']} | {r['dofs']} | {r['l2']:.3e} | "
              f"{r['energy']:.3e} | {r['seconds']:.3f} |")

    fig, (ax_time, ax_dofs) = plt.subplots(1, 2, figsize=(13, 5.5))
    for method in dict.fromkeys(r["method"] for r in records):
        rows = [r for r in records if r["method"] == method]
        style = "o-" if method.startswith("RK") else "s--"
        energy = [r["energy"] for r in rows]
        ax_time.loglog([r["seconds"] for r in rows], energy, style, label=method)
        ax_dofs.loglog([r["dofs"] for r in rows], energy, style, label=method)
    for ax, label in ((ax_time, "wall time: basis + assembly + solve [s]"),
                      (ax_dofs, "degrees of freedom")):
        ax.set_xlabel(label)
        ax.set_ylabel("relative energy error")
        ax.grid(True, which="both", alpha=0.3)
    ax_dofs.legend(fontsize=8, ncol=2)
    ax_time.set_title("Timoshenko beam: error vs time")
    ax_dofs.set_title("Timoshenko beam: error vs dofs")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "elasticity_trade.png", dpi=110)
    print(f"\nfigure: {args.out / 'elasticity_trade.png'}")


if __name__ == "__main__":
    main()
