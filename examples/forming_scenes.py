"""The paper's sheet stretching and upsetting scenes (Chen et al. 1998,
Sec. 5.1, 5.2 and 5.4), run from their scene files with figures.

    python examples/forming_scenes.py punch      [--method rkpm|fem] [--set KEY=VALUE ...]
    python examples/forming_scenes.py hemisphere [--set tools.punch.friction=0.3]
    python examples/forming_scenes.py upsetting

Writes ``scene_<name>[_<tag>]_*.png`` into ``--out`` (default
``docs/figures``): the punch force against the punch travel, the deformed
shape, and for the sheets the longitudinal true strain along the sheet at
several depths and the residual norms of the Newton iterations of the step
nearest to 27 mm.  For the cylindrical punch the strain is compared with the
frictionless membrane estimate (:func:`membrane_strain`).  Prints the numbers
quoted in ``docs/forming_scenes.md``.
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

RP, CD, RD, H = 50.8, 59.18, 6.35, 1.0  # punch, die opening, die shoulder, sheet (mm)


def membrane_strain(depth, clamp=70.0):
    """Uniform longitudinal true strain of a frictionless membrane (plane
    strain) stretched by the cylindrical punch to ``depth``.

    Without friction the membrane tension is the same everywhere, so is the
    strain: ``ε = ln(L / L0)`` with ``L`` the length of the mid-surface path
    from the centre to the clamp, an arc on the punch (radius ``Rp + h/2``),
    the common tangent of punch and die shoulder (radius ``Rd + h/2``), an
    arc on the shoulder and the flat flange to the clamp.
    """
    r1, r2 = RP + H / 2, RD + H / 2
    P = np.array([0.0, H + RP - depth])  # punch centre
    D = np.array([CD + RD, -RD])  # die shoulder centre
    v = P - D
    dist = np.linalg.norm(v)
    alpha = np.arccos((r1 + r2) / dist)
    u = v / dist
    c, s = np.cos(-alpha), np.sin(-alpha)  # the tangent rises from the punch to the die
    n = np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])
    T1, T2 = P - r1 * n, D + r2 * n
    wrap = np.arctan2(-n[0], n[1])  # the same on punch and shoulder
    length = r1 * wrap + np.linalg.norm(T2 - T1) + r2 * wrap + (clamp - (CD + RD))
    return np.log(length / clamp)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", choices=("punch", "hemisphere", "upsetting"))
    parser.add_argument("--method", choices=("rkpm", "fem"), default="rkpm")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--tag", default="", help="suffix of the figure names")
    parser.add_argument("--out", default="docs/figures")
    parser.add_argument("--run-dir", default=None, help="write the run's files here")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = f"scene_{args.scene}" + (f"_{args.tag}" if args.tag else "")

    scene = load_scene(builtin_scenes()[args.scene], args.set)
    sim = build(scene, args.method)
    travel = -scene["tools.punch"]["motion"][1]
    start = time.perf_counter()
    result = run(sim, args.run_dir, progress=False)
    seconds = time.perf_counter() - start
    history = result.history
    if not history:
        raise SystemExit(f"{scene['model']['title']} ({sim.method}): {result.message}")
    depth = np.array([r.t * travel for r in history])
    force = np.array([-r.reactions["punch"][1] for r in history])
    its = [r.iterations for r in history]
    print(f"{scene['model']['title']} ({sim.method}, {sim.basis.N} dofs): {result.message}; "
          f"{len(history)} steps, {sum(its)} Newton iterations "
          f"(mean {np.mean(its):.1f}, max {max(its)}), "
          f"{sum(r.cutbacks for r in history)} cut-backs, {seconds:.1f} s")
    print(f"punch travel {depth[-1]:.2f} mm, punch force {force[-1]:.6g}")

    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(depth, force, "o-", ms=3)
    ax.set_xlabel("punch travel [mm]")
    ax.set_ylabel("punch force [N/mm]" if scene["model"]["type"] == "plane_strain"
                  else "punch force [N]")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / f"{name}_force.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 3.5) if args.scene != "upsetting" else (4, 5))
    art = plot_deformed(ax, sim.problem, result.d,
                        f"{scene['model']['title']}, travel {depth[-1]:.1f} mm")
    x = sim.mesh.p + nodal_displacements(sim.basis, result.d).T
    for contact in sim.tools:
        outline = contact.tool.outline(history[-1].t, extent=40.0)
        ax.plot(outline[0], outline[1], color="0.4", lw=1.5)
    pad = 3.0
    ax.set_xlim(x[0].min() - pad, x[0].max() + pad)
    ax.set_ylim(x[1].min() - pad, x[1].max() + pad)
    fig.colorbar(art, ax=ax, label="ε̄ᵖ", shrink=0.8)
    fig.tight_layout()
    fig.savefig(out / f"{name}_shape.png", dpi=120)
    plt.close(fig)

    if args.scene == "upsetting":
        return
    axisymmetric = scene["model"]["type"] == "axisymmetric"
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for target in (5, 10, 15, 20, 25, 30):
        k = int(np.argmin(np.abs(depth - target)))
        if abs(depth[k] - target) > 0.5:
            continue
        s = sheet_strains(sim.basis, result.solutions[k], axisymmetric)
        ax.plot(s.longitudinal_X, s.longitudinal, "-", label=f"{depth[k]:.0f} mm")
        if args.scene == "punch":
            ax.axhline(membrane_strain(depth[k]), color=ax.lines[-1].get_color(), ls=":",
                       lw=1)
    final = sheet_strains(sim.basis, result.d, axisymmetric)
    print(f"longitudinal strain at the end: max {final.longitudinal.max():.4f} at "
          f"X = {final.longitudinal_X[np.argmax(final.longitudinal)]:.2f} mm, "
          f"at the centre {final.longitudinal[0]:.4f}; thickness strain min "
          f"{final.thickness.min():.4f}")
    if args.scene == "punch":
        print(f"membrane estimate at {depth[-1]:.2f} mm: {membrane_strain(depth[-1]):.4f}")
    ax.set_xlabel("initial position X [mm]")
    ax.set_ylabel("longitudinal true strain")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="punch travel" + (" (dotted: membrane)"
                                                  if args.scene == "punch" else ""))
    fig.tight_layout()
    fig.savefig(out / f"{name}_strain.png", dpi=120)
    plt.close(fig)

    k = int(np.argmin(np.abs(depth - 27.0)))
    print(f"residual norms at {depth[k]:.2f} mm (relative): "
          + " ".join(f"{r:.3e}" for r in history[k].residuals))


if __name__ == "__main__":
    main()
