"""Upsetting of a cylinder between flat rough platens: RKPM against FEM.

A steel cylinder (radius 10 mm, height 20 mm) is upset to 45 % height
reduction between rigid platens with Coulomb friction μ = 0, μ = 0.3 and
perfect stick (Chen et al. 1998, Sec. 4.3 and 5.3-5.4).  By symmetry the
upper half is modelled (axisymmetric, symmetry plane z = 0 at mid-height);
the top and the free side may both touch the platen, so the side folds over
onto it when friction holds the end face back.  The same 10 x 10 mesh runs
with an RK basis (support 2.0) and with Q1 finite elements, both with F-bar
locking control, and nodal contact collocation (the paper's).

Prints the platen force against the height reduction and the Newton
iteration counts, and saves ``contact_block_upsetting.png`` with the
barrelled shapes (full cross-sections, RK and FEM overlaid, one panel per
friction case) and the force curves.

Run:  python examples/block_upsetting.py [--n 10] [--steps 30] [--reduction 0.45]
                                         [--model axisymmetric] [--out DIR]
"""

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from skfem import Basis, ElementQuad1, ElementVector  # noqa: E402

from skfem_rkpm import RKBasis, transformation  # noqa: E402
from skfem_rkpm.mechanics.rigid_contact import RigidContact  # noqa: E402
from skfem_rkpm.mechanics.tools import Platen  # noqa: E402
from skfem_rkpm.mechanics.materials import J2Material, linear  # noqa: E402
from skfem_rkpm.mechanics.problem import SolidProblem  # noqa: E402
from skfem_rkpm.meshes import rectangle  # noqa: E402
from skfem_rkpm.solvers.newton import Prescribed, newton_steps  # noqa: E402

RADIUS, HALF_HEIGHT = 10.0, 10.0  # mm
MATERIAL = dict(E=200e3, nu=0.3, yield_stress=250.0, hardening=1000.0)  # MPa
FRICTION = {"μ = 0": 0.0, "μ = 0.3": 0.3, "stick": "stick"}
METHODS = ("RKPM", "FEM")


def basis_for(method, mesh, model):
    if method == "RKPM":
        return RKBasis(mesh, vector=True, support=2.0, axisymmetric=model == "axisymmetric")
    return Basis(mesh, ElementVector(ElementQuad1()), intorder=2)


def upset(method, friction, n, steps, reduction, model):
    """One run; returns the mesh, the problem, the result and the contact."""
    mesh = rectangle(RADIUS, HALF_HEIGHT, n, n)
    material = J2Material(MATERIAL["E"], MATERIAL["nu"],
                          linear(MATERIAL["yield_stress"], MATERIAL["hardening"]))
    problem = SolidProblem(basis_for(method, mesh, model), material, model,
                           locking="fbar")
    travel = reduction * HALF_HEIGHT
    platen = RigidContact(problem, Platen((0.0, HALF_HEIGHT), (0.0, -1.0),
                                          motion=(0.0, -travel), name="platen"),
                          slaves=["top", "right"], friction=friction)
    conditions = [Prescribed("bottom", 1, 0.0),  # mid-height symmetry plane
                  Prescribed("left", 0, 0.0)]  # axis (or symmetry plane)
    start = time.perf_counter()
    result = newton_steps(problem, conditions, steps=steps, contributions=[platen])
    result.seconds = time.perf_counter() - start
    return mesh, problem, result, platen


def free_boundary(mesh):
    """Vertices of the free surface of the quarter section, in order: the
    side from the mid-plane up, then the end face from the rim to the axis."""
    p, tol = mesh.p, 1e-9 * RADIUS
    side = np.flatnonzero(np.abs(p[0] - p[0].max()) < tol)
    top = np.flatnonzero(np.abs(p[1] - p[1].max()) < tol)
    return np.concatenate([side[np.argsort(p[1, side])], top[np.argsort(-p[0, top])][1:]])


def deformed_outline(mesh, problem, d):
    """Current positions of the free boundary particles, ``X + Λᵀ d`` (Eq. 3.32)."""
    u = (transformation(problem.basis) @ d).reshape(-1, 2).T
    return (mesh.p + u)[:, free_boundary(mesh)]


def force_curve(result, reduction):
    """Height reduction [%] and platen force [kN] after every step."""
    t = np.array([r.t for r in result.history])
    force = np.array([-r.reactions["platen"][1] for r in result.history]) / 1e3
    return 100 * reduction * t, force


def frictionless_exact(reduction):
    """Platen force [kN] of homogeneous frictionless upsetting (axisymmetric):
    log strain ε = ln(1 - δ), ε̄ᵖ from ε̄ᵖ + σ_y(ε̄ᵖ)/E = -ε, force
    σ_y(ε̄ᵖ) π R² / (1 - δ) (elastic: -E ε instead of σ_y)."""
    E, sy, H = MATERIAL["E"], MATERIAL["yield_stress"], MATERIAL["hardening"]
    eps = -np.log(1.0 - reduction)
    alpha = max((eps - sy / E) / (1.0 + H / E), 0.0)
    stress = min(E * eps, sy + H * alpha)
    return stress * np.pi * RADIUS**2 / (1.0 - reduction) / 1e3


def print_table(runs, reduction, model):
    unit = "kN" if model == "axisymmetric" else "kN/mm"
    print(f"\nplaten force [{unit}] against height reduction ({model})")
    names = [f"{m} {f}" for f in FRICTION for m in METHODS]
    exact = model == "axisymmetric"
    print(f"{'reduction':>9s} " + " ".join(f"{name:>14s}" for name in names)
          + (f" {'exact μ = 0':>12s}" if exact else ""))
    levels = np.linspace(0.0, 100 * reduction, 6)[1:]
    curves = {name: force_curve(runs[name][2], reduction) for name in names}
    for level in levels:
        cells = []
        for name in names:
            r, f = curves[name]
            cells.append(f"{np.interp(level, r, f, right=np.nan):14.2f}")
        print(f"{level:8.1f}% " + " ".join(cells)
              + (f" {frictionless_exact(level / 100):12.2f}" if exact else ""))
    print(f"\n{'run':14s} {'steps':>5s} {'Newton':>6s} {'mean':>5s} {'max':>4s} "
          f"{'cut-backs':>9s} {'penetration':>11s} {'time [s]':>8s}")
    for name in names:
        _, _, result, platen = runs[name]
        its = [r.iterations for r in result.history]
        cuts = sum(r.cutbacks for r in result.history)
        status = "" if result.completed else f"  stopped: {result.message}"
        print(f"{name:14s} {len(its):5d} {sum(its):6d} {np.mean(its):5.1f} {max(its):4d} "
              f"{cuts:9d} {platen.penetration():11.2e} {result.seconds:8.1f}{status}")


def plot(runs, reduction, path):
    fig, axes = plt.subplots(1, len(FRICTION) + 1, figsize=(4.2 * (len(FRICTION) + 1), 4.4))
    styles = {"RKPM": dict(color="C0", lw=1.6, marker="o", ms=2.5),
              "FEM": dict(color="C3", lw=1.0, ls="--")}
    for ax, case in zip(axes, FRICTION):
        for method in METHODS:
            mesh, problem, result, platen = runs[f"{method} {case}"]
            xy = deformed_outline(mesh, problem, result.d)
            for sx in (1, -1):  # mirror about the axis and the mid-plane
                for sy in (1, -1):
                    ax.plot(sx * xy[0], sy * xy[1], **styles[method],
                            label=method if sx == sy == 1 else None)
            top = HALF_HEIGHT + platen.tool.translation(result.history[-1].t)[1]
        for sign in (1, -1):  # the platens, as bands beyond their surfaces
            ax.fill_between([-1.6 * RADIUS, 1.6 * RADIUS], sign * top,
                            sign * (top + 0.12 * HALF_HEIGHT), color="0.8", lw=0)
        original = np.array([[-RADIUS, RADIUS, RADIUS, -RADIUS, -RADIUS],
                             [-HALF_HEIGHT, -HALF_HEIGHT, HALF_HEIGHT, HALF_HEIGHT,
                              -HALF_HEIGHT]])
        ax.plot(*original, color="0.6", lw=0.8, ls=":")
        ax.set_title(f"{case}, {100 * reduction:.0f} % reduction")
        ax.set_aspect("equal")
        ax.set_xlabel("r [mm]" if runs[f"RKPM {case}"][1].model == "axisymmetric"
                      else "x [mm]")
        ax.legend(loc="center", fontsize=8, title="particles / nodes", title_fontsize=7)
    axes[0].set_ylabel("z [mm]")
    ax = axes[-1]
    for case in FRICTION:
        for method in METHODS:
            r, f = force_curve(runs[f"{method} {case}"][2], reduction)
            ax.plot(r, f, "-" if method == "RKPM" else "--",
                    color={"μ = 0": "C2", "μ = 0.3": "C1", "stick": "C4"}[case],
                    label=f"{method}, {case}")
    ax.set_xlabel("height reduction [%]")
    ax.set_ylabel("platen force [kN]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=10, help="cells per side")
    parser.add_argument("--steps", type=int, default=30, help="load steps")
    parser.add_argument("--reduction", type=float, default=0.45, help="height reduction")
    parser.add_argument("--model", default="axisymmetric",
                        choices=("axisymmetric", "plane_strain"))
    parser.add_argument("--out", default=".", help="folder of the figure")
    args = parser.parse_args()
    runs = {}
    for case, friction in FRICTION.items():
        for method in METHODS:
            runs[f"{method} {case}"] = upset(method, friction, args.n, args.steps,
                                             args.reduction, args.model)
    print_table(runs, args.reduction, args.model)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "contact_block_upsetting.png"
    plot(runs, args.reduction, path)
    print(f"\nsaved {path}")


if __name__ == "__main__":
    main()
