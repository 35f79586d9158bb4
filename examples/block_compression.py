"""Plane strain upsetting of a square block between sticking platens: RKPM
against bilinear finite elements, each with and without F-bar.

The block (1 x 1 mm, E = 200 GPa, ν = 0.3, Swift hardening
σ_y = 589 (1e-4 + ε̄ᵖ)^0.216 MPa) is compressed by 40 % of its height in
20 equal steps.  Both displacement components are prescribed on the nodes of
the bottom (fixed) and top (moving down) sides: the platens stick.  All four
methods use the same 12 x 12 background mesh (169 particles / nodes):

* ``RKPM``: ``RKBasis(mesh, vector=True, support=2.0)`` (linear basis, cubic
  spline kernel, 3 x 3 Gauss points per cell, VCI test gradients);
* ``RKPM F-bar``: the same with ``SolidProblem(..., locking="fbar")``;
* ``FEM Q1`` and ``FEM Q1 F-bar``: ``Basis(mesh, ElementVector(ElementQuad1()),
  intorder=2)``.

Fold-over.  With sticking platens the free sides bulge, and from about 20 %
reduction on the side surface next to each platen rolls over onto it.
Without contact the side nodes pass through the platen and the corner cells
invert (``--fold none`` shows it: the F-bar runs stop at 25-35 %
reduction).  By default the side particles meet the two platens as rigid tools
(:class:`skfem_rkpm.mechanics.rigid_contact.RigidContact`, nodal collocation,
default penalty): with perfect stick (``--fold stick``) or frictionless
(``--fold slip``).  The platen force is the reaction of the prescribed top
nodes plus the contact force of the top platen on the folded sides.

Prints one row per method (final force per unit depth, Newton iterations,
wall time).  Writes into ``--out``:

* ``block_compression.png``: equivalent plastic strain on the deformed
  configuration (RK: particles at ``X + Λᵀ d``, coloured by the average of
  the cell values around them; FEM: the deformed mesh) and the force against
  the reduction;
* per method ``<name>.xdmf`` / ``.h5`` (every step: displacements, cell
  averages of Cauchy stress, von Mises stress and ε̄ᵖ; open in ParaView) and
  ``<name>_history.csv`` (one row per step; its ``seconds`` include writing
  the fields).

Run:  python examples/block_compression.py [--out DIR] [--steps 20] [--cells 12]
      [--fold stick|slip|none]                                     (~20 s)
"""

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from skfem import Basis, ElementQuad1, ElementVector  # noqa: E402

from skfem_rkpm import RKBasis  # noqa: E402
from skfem_rkpm.runs.io import (FieldWriter, cell_averages, nodal_displacements,  # noqa: E402
                           write_history)
from skfem_rkpm.mechanics.rigid_contact import RigidContact  # noqa: E402
from skfem_rkpm.mechanics.tools import Platen  # noqa: E402
from skfem_rkpm.mechanics.materials import J2Material, swift  # noqa: E402
from skfem_rkpm.mechanics.problem import SolidProblem  # noqa: E402
from skfem_rkpm.meshes import rectangle  # noqa: E402
from skfem_rkpm.solvers.newton import Prescribed, newton_steps  # noqa: E402

E, NU = 200e3, 0.3  # MPa
HARDENING = swift(589.0, 1e-4, 0.216)
HEIGHT, REDUCTION = 1.0, 0.4  # mm, fraction of the height

METHODS = {  # name: (basis factory, locking)
    "RKPM": (lambda m: RKBasis(m, vector=True, support=2.0), None),
    "RKPM F-bar": (lambda m: RKBasis(m, vector=True, support=2.0), "fbar"),
    "FEM Q1": (lambda m: Basis(m, ElementVector(ElementQuad1()), intorder=2), None),
    "FEM Q1 F-bar": (lambda m: Basis(m, ElementVector(ElementQuad1()), intorder=2),
                     "fbar"),
}


def platens(problem, fold):
    """The two rigid platens, acting on the free sides once they fold over:
    ``"stick"`` (perfect stick), ``"slip"`` (frictionless) or ``"none"``."""
    if fold == "none":
        return []
    friction = "stick" if fold == "stick" else 0.0
    bottom = Platen((0.0, 0.0), (0.0, 1.0), name="bottom platen")
    top = Platen((0.0, HEIGHT), (0.0, -1.0), motion=(0.0, -REDUCTION * HEIGHT),
                 name="top platen")
    return [RigidContact(problem, tool, slaves=["left", "right"], friction=friction)
            for tool in (bottom, top)]


def run(name, mesh, steps, fold, out):
    make_basis, locking = METHODS[name]
    start = time.perf_counter()
    basis = make_basis(mesh)
    problem = SolidProblem(basis, J2Material(E, NU, HARDENING), "plane_strain",
                           locking=locking)
    stroke = -REDUCTION * HEIGHT
    conditions = [Prescribed("bottom", 0, 0.0), Prescribed("bottom", 1, 0.0),
                  Prescribed("top", 0, 0.0), Prescribed("top", 1, stroke)]
    slug = name.lower().replace(" ", "_").replace("-", "")
    output = {"seconds": 0.0, "extra": []}

    contacts = platens(problem, fold)
    with FieldWriter(out / f"{slug}.xdmf", problem) as fields:
        def write(record, d, evaluation):  # after every converged step; timed apart
            tick = time.perf_counter()
            fields.write(record.t, d)
            output["extra"].append({
                "height": HEIGHT * (1 - REDUCTION * record.t),
                "max penetration": max((c.penetration() for c in contacts), default=0.0)})
            output["seconds"] += time.perf_counter() - tick

        result = newton_steps(problem, conditions, steps=steps, contributions=contacts,
                              on_step=write)
    seconds = time.perf_counter() - start - output["seconds"]
    write_history(out / f"{slug}_history.csv", result.history, extra=output["extra"])

    def force(record):  # platen force per unit depth, compression positive
        folded = record.reactions.get("top platen", (0.0, 0.0))[1]
        return -(record.reactions["top[1]"] + folded)

    iterations = sum(r.iterations for r in result.history)
    return {
        "name": name, "basis": basis, "problem": problem, "result": result,
        "reduction": [0.0] + [REDUCTION * r.t for r in result.history],
        "force": [0.0] + [force(r) for r in result.history],
        "iterations": iterations, "steps": len(result.history),
        "cutbacks": sum(r.cutbacks for r in result.history),
        "seconds": seconds, "slug": slug,
    }


def particle_values(mesh, cell_values):
    """Average of the cell values around every vertex (volume weighted)."""
    area = mesh_area(mesh)
    total = np.zeros(mesh.nvertices)
    weight = np.zeros(mesh.nvertices)
    for corner in mesh.t:
        np.add.at(total, corner, area * cell_values)
        np.add.at(weight, corner, area)
    return total / weight


def mesh_area(mesh):
    x, y = mesh.p[:, mesh.t]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=0) - np.roll(x, -1, axis=0) * y,
                               axis=0))


def plot(runs, mesh, path):
    fig = plt.figure(figsize=(12, 9))
    grid = fig.add_gridspec(3, 3, height_ratios=[1.0, 1.0, 1.25],
                            width_ratios=[1.0, 1.0, 0.035], hspace=0.4, wspace=0.12)
    values = {}
    for r in runs:
        problem = r["problem"]
        cells = cell_averages(problem.state.alpha, problem.assembler.layout.dx)
        x = mesh.p + nodal_displacements(r["basis"], r["result"].d).T
        values[r["name"]] = (x, cells)
    norm = matplotlib.colors.Normalize(0.0, max(c.max() for _, c in values.values()))
    cmap = plt.get_cmap("viridis")
    for k, r in enumerate(runs):
        ax = fig.add_subplot(grid[k // 2, k % 2])
        x, cells = values[r["name"]]
        if "RK" in r["name"]:
            ax.scatter(*x, c=particle_values(mesh, cells), cmap=cmap, norm=norm,
                       s=30, edgecolors="k", linewidths=0.3, zorder=3)
        else:
            ax.add_collection(PolyCollection(x.T[mesh.t.T], array=cells, cmap=cmap,
                                             norm=norm, edgecolors="k",
                                             linewidths=0.3))
        ax.plot([0, 1, 1, 0, 0], [0, 0, HEIGHT, HEIGHT, 0], ":", color="0.5", lw=1)
        for y in (0.0, HEIGHT - r["reduction"][-1]):
            ax.axhline(y, color="0.35", lw=2.5, zorder=1)
        ax.set_xlim(-0.6, 1.6)
        ax.set_ylim(-0.06, HEIGHT + 0.04)
        ax.set_aspect("equal")
        ax.set_title(f"{r['name']} ({100 * r['reduction'][-1]:.0f} %, "
                     f"largest cell value {cells.max():.2f})", fontsize=10)
        if k % 2 == 0:
            ax.set_ylabel("y [mm]")
        if k >= 2:
            ax.set_xlabel("x [mm]")
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap),
                       cax=fig.add_subplot(grid[:2, 2]))
    bar.set_label("equivalent plastic strain ε̄ᵖ (cell averages)")
    ax = fig.add_subplot(grid[2, :2])
    styles = {"RKPM": "o-", "RKPM F-bar": "o-", "FEM Q1": "s--", "FEM Q1 F-bar": "s--"}
    for r in runs:
        ax.plot(100 * np.array(r["reduction"]), r["force"], styles[r["name"]],
                ms=3.5, label=r["name"])
    ax.set_xlabel("height reduction [%]")
    ax.set_ylabel("platen force [N/mm depth]")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.suptitle("Plane strain upsetting between sticking platens: particles (RK) and "
                 "mesh (FEM) on the deformed\nconfiguration, original block dotted; "
                 "platen force against height reduction", fontsize=11, y=0.95)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."))
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--cells", type=int, default=12)
    parser.add_argument("--fold", choices=("stick", "slip", "none"), default="stick")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    mesh = rectangle(1.0, HEIGHT, args.cells, args.cells)
    runs = [run(name, mesh, args.steps, args.fold, args.out) for name in METHODS]

    print(f"\n{args.cells}x{args.cells} cells, {mesh.nvertices} particles / nodes, "
          f"{args.steps} steps, fold-over contact: {args.fold}")
    print(f"| method | reduction | final force [N/mm] | Newton iterations | "
          f"iterations/step | cut-backs | wall time [s] |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in runs:
        done = 100 * r["reduction"][-1]
        print(f"| {r['name']} | {done:.1f} %{'' if r['result'].completed else ' (failed)'}"
              f" | {r['force'][-1]:.1f} | {r['iterations']} | "
              f"{r['iterations'] / max(r['steps'], 1):.1f} | {r['cutbacks']} | "
              f"{r['seconds']:.2f} |")
        if not r["result"].completed:
            print(f"    {r['name']}: {r['result'].message}")
    path = args.out / "block_compression.png"
    plot(runs, mesh, path)
    print(f"\nfigure: {path}\nfields and histories: {args.out.resolve()}")


if __name__ == "__main__":
    main()
