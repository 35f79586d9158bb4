"""Cylindrical cup, first draw stage, with a blank holder at constant force
(built-in scene ``cup_draw``): RKPM and FEM side by side.

    python examples/cup_draw.py [--set KEY=VALUE ...] [--out DIR]   (~2 minutes)

Runs the scene with both methods and writes into ``--out`` (default
``docs/figures``):

* ``scene_cup_draw_force.png``: punch force and blank-holder force against
  the punch travel;
* ``scene_cup_draw_drawin.png``: draw-in of the blank edge and travel of the
  force-driven holder against the punch travel;
* ``scene_cup_draw_shape.png``: the drawn blank at the end, RK particles
  coloured by the equivalent plastic strain, FEM outline in red, tools in grey;
* ``scene_cup_draw_thickness.png``: thickness strain along the blank at the end.

Prints the numbers quoted in ``docs/forming_scenes.md``.
"""

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from skfem_rkpm.runs.io import nodal_displacements  # noqa: E402
from skfem_rkpm.runs.plot import plot_deformed  # noqa: E402
from skfem_rkpm.runs.runner import build, run  # noqa: E402
from skfem_rkpm.runs.scene import builtin_scenes, load_scene  # noqa: E402
from skfem_rkpm.runs.sheet import sheet_strains  # noqa: E402

COLORS = {"rkpm": "C0", "fem": "C3"}
LABELS = {"rkpm": "RKPM", "fem": "FEM Q1"}
BLANK_RADIUS = 50.0


def run_method(settings, method):
    """One run of the scene; prints its summary line."""
    scene = load_scene(builtin_scenes()["cup_draw"], settings)
    sim = build(scene, method)
    start = time.process_time()
    result = run(sim, progress=False)
    cpu = time.process_time() - start
    history = result.history
    its = [r.iterations for r in history]
    travel = -scene["tools.punch"]["motion"][1]
    depth = np.array([r.t * travel for r in history])
    punch = np.array([-r.reactions["punch"][1] for r in history])
    holder = np.array([-r.reactions["holder"][1] for r in history])
    die = np.array([r.reactions["die"][1] for r in history])
    draw_in = np.array([BLANK_RADIUS - g["rim x"] for g in result.gauges])
    lift = np.array([g["holder travel"] for g in result.gauges])
    print(f"{LABELS[method]} ({sim.basis.N} dofs, locking {sim.problem.locking}): "
          f"{result.message}; {len(history)} steps, {sum(its)} Newton iterations "
          f"(mean {np.mean(its):.1f}, max {max(its)}), "
          f"{sum(r.cutbacks for r in history)} cut-backs, {cpu:.1f} s CPU")
    print(f"  at {depth[-1]:.2f} mm: punch {punch[-1]:.1f} N (peak {punch.max():.1f} N), "
          f"holder {holder[-1]:.3f} N, die {die[-1]:.1f} N, "
          f"axial balance {np.abs(die - punch - holder).max():.2e} N, "
          f"draw-in {draw_in[-1]:.3f} mm, holder travel {lift[-1]:+.4f} mm")
    strains = sheet_strains(sim.basis, result.d, axisymmetric=True)
    print(f"  thickness strain: min {strains.thickness.min():.4f}, at the pole "
          f"{strains.thickness[0]:.4f}, at the rim {strains.thickness[-1]:+.4f}")
    return dict(sim=sim, result=result, depth=depth, punch=punch, holder=holder,
                draw_in=draw_in, lift=lift, strains=strains)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--out", default="docs/figures")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    settings = [*args.set, "output.fields=false", "output.figures=false"]
    runs = {m: run_method(settings, m) for m in ("rkpm", "fem")}

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for m, r in runs.items():
        ax.plot(r["depth"], r["punch"] / 1e3, "-", color=COLORS[m],
                label=f"punch, {LABELS[m]}")
        ax.plot(r["depth"], r["holder"] / 1e3, "--", color=COLORS[m],
                label=f"blank holder, {LABELS[m]}")
    ax.set_xlabel("punch travel [mm]")
    ax.set_ylabel("force [kN] (full circumference)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "scene_cup_draw_force.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for m, r in runs.items():
        ax.plot(r["depth"], r["draw_in"], "-", color=COLORS[m], label=f"draw-in, {LABELS[m]}")
        ax.plot(r["depth"], r["lift"], ":", color=COLORS[m],
                label=f"holder travel (down +), {LABELS[m]}")
    ax.set_xlabel("punch travel [mm]")
    ax.set_ylabel("displacement [mm]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "scene_cup_draw_drawin.png", dpi=120)
    plt.close(fig)

    rk, fem = runs["rkpm"], runs["fem"]
    fig, ax = plt.subplots(figsize=(8, 3.8))
    art = plot_deformed(ax, rk["sim"].problem, rk["result"].d,
                        f"cup draw at {rk['depth'][-1]:.1f} mm (RKPM; FEM outline red)")
    sim = fem["sim"]
    x = sim.mesh.p + nodal_displacements(sim.basis, fem["result"].d).T
    for edge in sim.mesh.facets[:, sim.mesh.boundary_facets()].T:
        ax.plot(x[0, edge], x[1, edge], color="r", lw=0.8)
    for contact in rk["sim"].tools:
        tool = getattr(contact, "contact", contact).tool  # force-driven: the wrapped contact
        outline = tool.outline(rk["result"].history[-1].t, extent=40.0)
        ax.plot(outline[0], outline[1], color="0.4", lw=1.5)
    ax.set_xlim(-1.0, BLANK_RADIUS + 2.0)
    ax.set_ylim(x[1].min() - 3.0, 6.0)
    ax.set_xlabel("r [mm]")
    ax.set_ylabel("z [mm]")
    fig.colorbar(art, ax=ax, label="ε̄ᵖ", shrink=0.8)
    fig.tight_layout()
    fig.savefig(out / "scene_cup_draw_shape.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for m, r in runs.items():
        s = r["strains"]
        ax.plot(s.X, s.thickness, "-", color=COLORS[m], label=LABELS[m])
    ax.set_xlabel("initial radius R [mm]")
    ax.set_ylabel("thickness true strain")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "scene_cup_draw_thickness.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
