"""Regenerate every figure of the documentation and print its tables.

Run from the repository root::

    MPLBACKEND=Agg python docs/figures/make_figures.py            # all figures
    MPLBACKEND=Agg python docs/figures/make_figures.py patch beam # some of them

The PNG files are written next to this script.  The convergence and
boundary-condition studies also print the tables quoted in
``docs/verification.md``.  Everything runs in well under a minute on two cores.
"""

import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LogNorm, TwoSlopeNorm  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402
from skfem import (Basis, ElementQuad1, ElementQuad2, ElementTriP1,  # noqa: E402
                   ElementTriP2, ElementVector, LinearForm, asm)
from skfem.helpers import dot  # noqa: E402
from skfem.visuals.matplotlib import draw  # noqa: E402

from skfem_rkpm import (Assembler, RKBasis, SingularMomentError,  # noqa: E402
                        isotropic_tangent, local_spacing, rk_shape_functions,
                        solve)
from skfem_rkpm.verification.elasticity import (error_norms, lame, solve_elasticity,  # noqa: E402
                                   stress_from_voigt)
from skfem_rkpm.approximation.kernels import cubic_spline, quartic_spline  # noqa: E402
from skfem_rkpm.meshes import gmsh_plate_with_hole, rectangle  # noqa: E402
from skfem_rkpm.verification import (convergence_study, plate_with_hole,  # noqa: E402
                                     rates, rigid_motion_dofs, solve_problem,
                                     timoshenko_beam)

HERE = Path(__file__).resolve().parent
plt.rcParams.update({"figure.dpi": 110, "savefig.dpi": 110, "font.size": 9,
                     "axes.grid": True, "grid.alpha": 0.3})


def save(fig, name):
    fig.savefig(HERE / name, bbox_inches="tight")
    plt.close(fig)
    print(f"  wrote docs/figures/{name}")


# ---------------------------------------------------------------------------
# 1D shape functions, kernels and consistency (Eq. 2.27-2.38, 3.12)
# ---------------------------------------------------------------------------

NODES_1D = np.linspace(0.0, 1.0, 11)
H_1D = 0.1
#: order -> normalized support; order 2 needs c > 2 (see the caption)
SUPPORT_1D = {0: 2.0, 1: 2.0, 2: 3.0}


def shape_functions_1d():
    x = np.linspace(0.0, 1.0, 1001)
    try:  # why order 2 is drawn with c = 3
        rk_shape_functions(x[None], NODES_1D[None], 2.0 * H_1D, order=2, dilation=2.0)
    except SingularMomentError as err:
        print(f"    order 2 with c = 2: {err}")
    fig, ax = plt.subplots(2, 4, figsize=(13, 5.2), constrained_layout=True)

    z = np.linspace(0.0, 1.2, 241)
    for kernel, name in ((cubic_spline, "cubic B-spline, Eq. (3.12)"),
                         (quartic_spline, "quartic spline")):
        phi, dphi = kernel(z)
        ax[0, 0].plot(z, phi, label=name)
        ax[1, 0].plot(z, dphi, label=name)
    ax[0, 0].set(title="kernel φ(z), z = |X − X_I| / a", xlabel="z")
    ax[1, 0].set(title="dφ/dz", xlabel="z")
    ax[0, 0].legend()

    for col, order in enumerate((0, 1, 2), start=1):
        c = SUPPORT_1D[order]
        t = rk_shape_functions(x[None], NODES_1D[None], c * H_1D, order=order)
        A, G = t.matrix().toarray(), t.gradient_matrix(0).toarray()
        for I in range(len(NODES_1D)):
            style = {0: dict(lw=2.0, color="tab:blue", label="Ψ_0 (end particle)"),
                     5: dict(lw=2.0, color="tab:orange", label="Ψ_5 (x_I = 0.5)")
                     }.get(I, dict(lw=0.7, color="0.6"))
            ax[0, col].plot(x, A[:, I], **style)
            ax[1, col].plot(x, G[:, I], **style)
        ax[0, col].plot(NODES_1D, 0 * NODES_1D, "ko", ms=3)
        names = {0: "Shepard, Eq. (2.32)", 1: "linear basis", 2: "quadratic basis"}
        ax[0, col].set(title=f"Ψ_I, order {order} ({names[order]}), c = {c:g}",
                       xlabel="x")
        ax[1, col].set(title=f"dΨ_I/dx, order {order}, c = {c:g}", xlabel="x")
    ax[0, 1].legend(loc="upper right", fontsize=7)
    save(fig, "shape_functions_1d.png")


def kernel_estimate(x, nodes, c):
    """Discrete kernel estimate Eq. (2.2) and its x-derivative: Φ_a normalized
    to unit integral, nodal volumes ΔV_I (half at the end particles), no
    correction function."""
    h = nodes[1] - nodes[0]
    a = c * h
    diff = x[:, None] - nodes[None, :]
    phi, dphi = cubic_spline(np.abs(diff) / a)
    volume = np.full(len(nodes), h)
    volume[[0, -1]] = h / 2
    scale = volume / (0.5 * a)  # ∫ φ(|x|/a) dx = a / 2 in 1D
    return phi * scale, dphi * np.sign(diff) / a * scale


def consistency_1d():
    x = np.linspace(0.0, 1.0, 2001)
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
    cases = []
    for n, color in ((11, "tab:blue"), (21, "tab:cyan")):
        nodes = np.linspace(0.0, 1.0, n)
        A, G = kernel_estimate(x, nodes, 2.0)
        cases.append((f"kernel estimate (2.2), {n} particles", A, G, nodes,
                      dict(ls="--", color=color)))
    for order, color in ((0, "tab:green"), (1, "tab:red")):
        t = rk_shape_functions(x[None], NODES_1D[None], 2.0 * H_1D, order=order)
        cases.append((f"RK order {order}, 11 particles", t.matrix().toarray(),
                      t.gradient_matrix(0).toarray(), NODES_1D, dict(color=color)))
    for label, A, G, nodes, style in cases:
        errors = (A @ np.ones(len(nodes)) - 1, A @ nodes - x, G @ nodes - 1)
        for a, e in zip(ax, errors):
            a.semilogy(x, np.maximum(np.abs(e), 1e-16), lw=1.2, label=label, **style)
    ax[0].set(title="|Σ Ψ_I(x) − 1|   (Eq. 2.33)", xlabel="x", ylim=(5e-17, 10))
    ax[1].set(title="|Σ Ψ_I(x) x_I − x|   (Eq. 2.36)", xlabel="x", ylim=(5e-17, 10))
    ax[2].set(title="|Σ dΨ_I/dx(x) x_I − 1|   (Eq. 2.38)", xlabel="x",
              ylim=(5e-17, 10))
    ax[0].legend(loc="center", fontsize=8, framealpha=0.95)
    save(fig, "consistency_1d.png")


# ---------------------------------------------------------------------------
# 2D shape functions on a perturbed grid: radial and box supports
# ---------------------------------------------------------------------------

def shape_functions_2d():
    mesh = rectangle(1.0, 1.0, 10, 10, perturb=0.3)
    nodes = mesh.p
    c = 2.0
    radius = c * local_spacing(mesh)
    interior = int(np.argmin(np.sum((nodes - 0.5) ** 2, axis=0)))
    corner = int(np.argmin(np.sum(nodes ** 2, axis=0)))
    views = ((interior, "interior", nodes[:, interior] - 0.3, nodes[:, interior] + 0.3),
             (corner, "corner", np.array([-0.02, -0.02]), np.array([0.4, 0.4])))

    fig, ax = plt.subplots(2, 2, figsize=(9.5, 8.6), constrained_layout=True)
    for row, shape in enumerate(("radial", "box")):
        for col, (I, where, lo, hi) in enumerate(views):
            gx = np.linspace(max(lo[0], 0.0), min(hi[0], 1.0), 161)
            gy = np.linspace(max(lo[1], 0.0), min(hi[1], 1.0), 161)
            X, Y = np.meshgrid(gx, gy)
            A = rk_shape_functions(np.array([X.ravel(), Y.ravel()]), nodes, radius,
                                   order=1, support=shape, gradients=False).matrix()
            psi = A[:, I].toarray().reshape(X.shape)
            a = ax[row, col]
            norm = TwoSlopeNorm(vmin=min(psi.min(), -1e-3), vcenter=0.0, vmax=psi.max())
            cs = a.contourf(X, Y, psi, levels=21, cmap="RdBu_r", norm=norm)
            a.plot(*nodes, "k.", ms=4)
            a.plot(*nodes[:, I], "y*", ms=14, mec="k")
            r = radius[I]
            outline = (Circle(nodes[:, I], r, fill=False, ls="--") if shape == "radial"
                       else Rectangle(nodes[:, I] - r, 2 * r, 2 * r, fill=False, ls="--"))
            a.add_patch(outline)
            a.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), aspect="equal",
                  title=f"{where} particle, {shape} support\n"
                        f"Ψ_I in [{psi.min():.2g}, {psi.max():.3f}]")
            a.grid(False)
            fig.colorbar(cs, ax=a, shrink=0.8, format="%.2f")
    fig.suptitle(f"Order-1 RK shape function, cubic kernel, c = {c:g}, perturbed "
                 "grid (dashed: support)")
    save(fig, "shape_functions_2d.png")


# ---------------------------------------------------------------------------
# background mesh, particles, quadrature points, one support
# ---------------------------------------------------------------------------

def particles_and_quadrature():
    meshes = [("rectangle(1, 1, 10, 10, perturb=0.3): quadrilaterals",
               rectangle(1.0, 1.0, 10, 10, perturb=0.3), [(0.5, 0.5)]),
              ("gmsh_plate_with_hole(1, 5, 5/8, h_hole=5/32): triangles",
               gmsh_plate_with_hole(1.0, 5.0, 5 / 8, h_hole=5 / 32),
               [(1.3, 0.6), (3.6, 3.0)])]
    fig, ax = plt.subplots(1, 2, figsize=(12, 5.6), constrained_layout=True)
    for a, (title, mesh, near) in zip(ax, meshes):
        basis = RKBasis(mesh, support=2.0, intorder=4)
        xq = np.asarray(basis.global_coordinates()).reshape(2, -1)
        draw(mesh, ax=a, color="0.6", linewidth=0.6)
        a.plot(*xq, ".", color="tab:orange", ms=1.5, label="quadrature points")
        a.plot(*mesh.p, "o", color="tab:blue", ms=3, label="particles (vertices)")
        for k, point in enumerate(near):
            I = int(np.argmin(np.sum((mesh.p - np.array(point)[:, None]) ** 2, axis=0)))
            a.add_patch(Circle(mesh.p[:, I], basis.radius[I], fill=False, lw=1.5,
                               color="tab:red",
                               label="support a_I = 2 h_I" if k == 0 else None))
            a.plot(*mesh.p[:, I], "*", color="tab:red", ms=12)
            inside = np.linalg.norm(xq - mesh.p[:, [I]], axis=0) < basis.radius[I]
            a.plot(*xq[:, inside], ".", color="tab:red", ms=2)
        a.set(title=f"{title}\n{basis.nnodes} particles, {xq.shape[1]} quadrature "
                    f"points, up to {basis.element_nodes.shape[0]} particles per cell",
              aspect="equal")
        a.grid(False)
        a.legend(loc="upper right", fontsize=7, framealpha=0.9)
    save(fig, "particles_and_quadrature.png")


def smoothing_cells_figure():
    """Median dual and Voronoi smoothing cells of SCNI on one distorted mesh."""
    from skfem_rkpm.approximation.nodal_integration import smoothing_cells

    mesh = rectangle(1.0, 1.0, 6, 6, perturb=0.3)
    fig, ax = plt.subplots(1, 2, figsize=(11, 5.4), constrained_layout=True)
    for a, kind, title in zip(ax, ("median_dual", "voronoi"),
                              ("median dual cells (smoothing='median_dual')",
                               "Voronoi cells clipped to the mesh (smoothing='voronoi')")):
        cells = smoothing_cells(mesh, 2, kind).merged()
        draw(mesh, ax=a, color="0.75", linewidth=0.6)
        ends = cells.segment_ends
        a.plot(ends[0], ends[1], "-", color="tab:blue", lw=1.2)
        a.plot(*mesh.p, "o", color="tab:red", ms=3, label="particles (mesh vertices)")
        a.plot([], [], "-", color="tab:blue", label="smoothing cell boundaries")
        a.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8, ncol=2)
        a.set(title=title, xlabel="x [m]", ylabel="y [m]", aspect="equal")
        a.grid(False)
    save(fig, "smoothing_cells.png")


# ---------------------------------------------------------------------------
# linear patch test: Gauss vs VCI on a distorted mesh
# ---------------------------------------------------------------------------

LAM_P, MU_P = lame(1.0, 0.3, "strain")


def linear_field(x):
    return np.array([0.1 + 0.2 * x[0] - 0.3 * x[1], 0.05 - 0.2 * x[0] + 0.15 * x[1]])


LINEAR_GRAD = np.array([[0.2, -0.3], [-0.2, 0.15]])


def patch_solution(basis):
    """Load the body by the exact traction σ·n, fix rigid motions at 3 dofs."""
    eps = 0.5 * (LINEAR_GRAD + LINEAR_GRAD.T)
    sigma = LAM_P * np.trace(eps) * np.eye(2) + 2 * MU_P * eps

    @LinearForm
    def traction(v, w):
        return dot(np.einsum("ij,j...->i...", sigma, w.n), v)

    K = Assembler(basis).bilinear(isotropic_tangent(LAM_P, MU_P, 2))
    f = asm(traction, basis.boundary())
    p = basis.nodes
    a = int(np.argmin(p[0] ** 2 + p[1] ** 2))
    b = int(np.argmin(p[0] ** 2 + (p[1] - 1) ** 2))
    D = np.array([2 * a, 2 * a + 1, 2 * b])
    d = solve(K, f, basis, D=D, x=linear_field(p).T.ravel())
    grad = basis.interpolate(d).grad  # (2, 2, nelems, nqp)
    return np.sqrt(np.sum((grad - LINEAR_GRAD[:, :, None, None]) ** 2, axis=(0, 1)))


def patch_test():
    mesh = rectangle(1.0, 1.0, 10, 10, perturb=0.3)
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    norm = LogNorm(1e-16, 1e-1)
    for a, (integration, intorder) in zip(ax, (("gauss", 2), ("gauss", 4), ("vci", 2))):
        basis = RKBasis(mesh, vector=True, support=2.0, intorder=intorder,
                        integration=integration)
        err = patch_solution(basis)
        xq = np.asarray(basis.global_coordinates())
        draw(mesh, ax=a, color="0.7", linewidth=0.5)
        sc = a.scatter(xq[0].ravel(), xq[1].ravel(), c=np.maximum(err.ravel(), 1e-16),
                       s=10 if intorder == 2 else 5, norm=norm, cmap="viridis")
        a.set(title=f'integration="{integration}", intorder={intorder}\n'
                    f"max |∇u_h − ∇u| = {err.max():.1e}", aspect="equal")
        a.grid(False)
        print(f"    linear patch, {integration}, intorder {intorder}: "
              f"max gradient error {err.max():.2e}")
    fig.colorbar(sc, ax=ax, shrink=0.8, label="|∇u_h − ∇u| at each quadrature point "
                 "(|∇u| = 0.44)")
    save(fig, "patch_test.png")


# ---------------------------------------------------------------------------
# convergence studies
# ---------------------------------------------------------------------------

def rk(support, order=1, intorder=4, integration="vci"):
    return lambda m: RKBasis(m, vector=True, support=support, order=order,
                             intorder=intorder, integration=integration)


def fem(element):
    return lambda m: Basis(m, ElementVector(element()), intorder=4)


STYLE = {"RK1 c=2": ("tab:blue", "o-"), "RK1 c=2 gauss": ("tab:cyan", "s--"),
         "RK2 c=3": ("tab:purple", "D-"), "Q1": ("tab:red", "v:"),
         "Q2": ("tab:orange", "^:"), "T3": ("tab:red", "v:"),
         "T6": ("tab:orange", "^:")}


def print_table(records, title):
    print(f"\n{title}\n")
    print("| method | level | dofs | h | L2 error | rate | energy error | rate | seconds |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for method in dict.fromkeys(r["method"] for r in records):
        rows = [r for r in records if r["method"] == method]
        l2r = [None] + rates(records, method, "l2")
        enr = [None] + rates(records, method, "energy")
        for r, p, q in zip(rows, l2r, enr):
            fp = "" if p is None else f"{p:.2f}"
            fq = "" if q is None else f"{q:.2f}"
            print(f"| {method} | {r['level']} | {int(r['dofs'])} | {r['h']:.3g} | "
                  f"{r['l2']:.2e} | {fp} | {r['energy']:.2e} | {fq} | "
                  f"{r['seconds']:.2f} |")


def plot_convergence(records, title, name):
    fig, ax = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    for method in dict.fromkeys(r["method"] for r in records):
        rows = [r for r in records if r["method"] == method]
        h = np.array([r["h"] for r in rows])
        n = np.array([r["dofs"] for r in rows], dtype=float)
        color, fmt = STYLE[method]
        for a, key in zip(ax[:2], ("l2", "energy")):
            slope = rates(records, method, key)[-1]
            a.loglog(h, [r[key] for r in rows], fmt, color=color,
                     label=f"{method}  (slope {slope:.2f})")
        ax[2].loglog(n, [r["energy"] for r in rows], fmt, color=color, label=method)
    ax[0].set(title=f"{title}: relative L² error", xlabel="largest cell diameter h")
    ax[1].set(title=f"{title}: relative energy error", xlabel="largest cell diameter h")
    ax[2].set(title="energy error vs number of dofs", xlabel="dofs")
    hs = sorted({r["h"] for r in records}, reverse=True)
    for a in ax[:2]:
        a.legend(fontsize=7, title="slope between the two finest levels",
                 title_fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15),
                 ncol=2)
        h_ticks(a, hs)
    ax[2].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2)
    ax[2].xaxis.set_minor_formatter(NullFormatter())
    save(fig, name)


def h_ticks(a, hs):
    """Label the x axis at the cell sizes used, coarse to fine."""
    a.set_xticks(hs, [f"{h:.3g}" for h in hs])
    a.minorticks_off()
    a.invert_xaxis()


def beam():
    methods = {"RK1 c=2": rk(2.0), "RK1 c=2 gauss": rk(2.0, integration="gauss"),
               "RK2 c=3": rk(3.0, order=2, intorder=6),
               "Q1": fem(ElementQuad1), "Q2": fem(ElementQuad2)}
    records = convergence_study(timoshenko_beam(), methods, [4, 8, 16, 32])
    print_table(records, "Timoshenko cantilever, quadrilateral background cells")
    plot_convergence(records, "Timoshenko beam", "convergence_beam.png")


def hole():
    methods = {"RK1 c=2": rk(2.0), "RK1 c=2 gauss": rk(2.0, integration="gauss"),
               "RK2 c=3": rk(3.0, order=2, intorder=6),
               "T3": fem(ElementTriP1), "T6": fem(ElementTriP2)}
    records = convergence_study(plate_with_hole(), methods, [4, 8, 16])
    print_table(records, "Plate with a hole (Kirsch), graded gmsh triangles")
    plot_convergence(records, "plate with a hole", "convergence_hole.png")


# ---------------------------------------------------------------------------
# randomly perturbed particles: integration error, VCI and global balance
# ---------------------------------------------------------------------------

def perturbed():
    """Timoshenko beam on freshly perturbed grids (20 % of the spacing).

    Besides the errors, records the largest reaction at the three dofs that
    fix the rigid motion.  The loads are self-equilibrated, so an exactly
    balanced scheme has zero reactions there.
    """
    problem = timoshenko_beam()
    lam, mu = lame(problem.E, problem.nu, problem.plane)

    @LinearForm
    def traction(v, w):
        sig = stress_from_voigt(problem.stress(np.asarray(w.x)))
        return dot(np.einsum("ij...,j...->i...", sig, w.n), v)

    methods = {"RK1 c=2 vci, intorder 4": ("vci", 4), "RK1 c=2 vci, intorder 6": ("vci", 6),
               "RK1 c=2 gauss, intorder 4": ("gauss", 4),
               "RK1 c=2 gauss, intorder 6": ("gauss", 6)}
    levels = [4, 8, 16, 32]
    records = []
    for level in levels:
        mesh = rectangle(48.0, 12.0, 4 * level, level, origin=(0.0, -6.0), perturb=0.2)
        for label, (integration, intorder) in methods.items():
            basis = RKBasis(mesh, vector=True, support=2.0, intorder=intorder,
                            integration=integration)
            K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2))
            f = asm(traction, basis.boundary())
            D = rigid_motion_dofs(basis.nodes)
            x = problem.displacement(basis.nodes).T.ravel()[D]
            d, reactions = solve(K, f, basis, D=D, x=x, return_reactions=True)
            l2, energy = error_norms(basis, d, problem.displacement, problem.stress,
                                     problem.E, problem.nu, problem.plane,
                                     modulo_rigid=True)
            records.append(dict(method=label, level=level, h=48.0 / (4 * level),
                                l2=l2, energy=energy,
                                imbalance=np.abs(reactions).max() / 1000.0))
    print("\nTimoshenko beam on perturbed grids (perturb=0.2), traction-loaded\n")
    print("| method | level | L2 error | rate | energy error | rate | reaction / P |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for label in methods:
        rows = [r for r in records if r["method"] == label]
        l2r = [None] + rates(records, label, "l2")
        enr = [None] + rates(records, label, "energy")
        for r, p, q in zip(rows, l2r, enr):
            fp = "" if p is None else f"{p:.2f}"
            fq = "" if q is None else f"{q:.2f}"
            print(f"| {label} | {r['level']} | {r['l2']:.2e} | {fp} | {r['energy']:.2e} "
                  f"| {fq} | {r['imbalance']:.1e} |")

    fig, ax = plt.subplots(1, 3, figsize=(13, 4.2), constrained_layout=True)
    styles = dict(zip(methods, (("tab:blue", "o-"), ("tab:purple", "D-"),
                                ("tab:cyan", "s--"), ("tab:green", "^--"))))
    h = [48.0 / (4 * n) for n in levels]
    for label in methods:
        rows = [r for r in records if r["method"] == label]
        color, fmt = styles[label]
        for a, key in zip(ax, ("l2", "energy", "imbalance")):
            a.loglog(h, [max(r[key], 1e-16) for r in rows], fmt, color=color,
                     label=label)
    ax[0].set(title="relative L² error (modulo rigid motion)", xlabel="cell size")
    ax[1].set(title="relative energy error", xlabel="cell size")
    ax[2].set(title="largest spurious reaction / load P", xlabel="cell size")
    for a in ax:
        h_ticks(a, h)
    ax[2].legend(fontsize=7)
    save(fig, "convergence_beam_perturbed.png")


# ---------------------------------------------------------------------------
# clamped edge: nodal (transformation method) vs Nitsche
# ---------------------------------------------------------------------------

def dirichlet():
    problem = timoshenko_beam()

    def end_load(x):
        s = problem.stress(x)
        return np.array([s[0], s[2]])  # σ·n with n = (1, 0)

    levels = [4, 8, 16]
    results = {}
    print("\nTimoshenko beam clamped at x = 0 (exact displacement prescribed), "
          "loaded at x = L\n")
    print("| basis | level | nodal L2 | nodal energy | Nitsche L2 | Nitsche energy "
          "| traction-only L2 | traction-only energy |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for c, order, intorder in ((2.0, 1, 4), (3.0, 1, 4), (3.0, 2, 6)):
        label = f"RK{order} c={c:g}"
        for level in levels:
            basis = RKBasis(problem.mesh(level), vector=True, support=c, order=order,
                            intorder=intorder)
            row = {}
            for how in ("nodal", "nitsche"):
                d = solve_elasticity(basis, problem.E, problem.nu, "stress",
                                     displacement={"left": problem.displacement},
                                     traction={"right": end_load}, dirichlet=how)
                row[how] = error_norms(basis, d, problem.displacement, problem.stress,
                                       problem.E, problem.nu, "stress")
            row["traction"] = solve_problem(problem, basis)[1:]
            results.setdefault(label, []).append(row)
            print(f"| {label} | {level} | {row['nodal'][0]:.2e} | {row['nodal'][1]:.2e}"
                  f" | {row['nitsche'][0]:.2e} | {row['nitsche'][1]:.2e}"
                  f" | {row['traction'][0]:.2e} | {row['traction'][1]:.2e} |")

    fig, ax = plt.subplots(1, 2, figsize=(12, 4), constrained_layout=True)
    h = 48.0 / (4 * np.array(levels))
    colors = {"RK1 c=2": "tab:blue", "RK1 c=3": "tab:green", "RK2 c=3": "tab:purple"}
    for label, rows in results.items():
        for a, k in zip(ax, (0, 1)):
            a.loglog(h, [r["nodal"][k] for r in rows], "o--", color=colors[label],
                     label=f"{label} nodal (transformation)")
            a.loglog(h, [r["nitsche"][k] for r in rows], "s-", color=colors[label],
                     label=f"{label} Nitsche")
        # the traction-only L2 error is measured modulo rigid motions: energy only
        ax[1].loglog(h, [r["traction"][1] for r in rows], ":", color=colors[label],
                     lw=1, label=f"{label} traction-only reference")
    ax[0].set(title="clamped beam: relative L² error", xlabel="cell size")
    ax[1].set(title="clamped beam: relative energy error", xlabel="cell size")
    for a in ax:
        h_ticks(a, list(h))
    ax[1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    save(fig, "dirichlet_nodal_vs_nitsche.png")


FIGURES = {
    "shape1d": shape_functions_1d, "consistency": consistency_1d,
    "shape2d": shape_functions_2d, "particles": particles_and_quadrature,
    "patch": patch_test, "beam": beam, "hole": hole, "perturbed": perturbed,
    "dirichlet": dirichlet, "smoothing": smoothing_cells_figure,
}


def main(names):
    start = time.perf_counter()
    for name in names or FIGURES:
        t = time.perf_counter()
        print(f"{name}:")
        FIGURES[name]()
        print(f"  ({time.perf_counter() - t:.1f} s)")
    print(f"\nall done in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    unknown = [n for n in sys.argv[1:] if n not in FIGURES]
    if unknown:
        sys.exit(f"unknown figure(s) {unknown}; choose from {list(FIGURES)}")
    main(sys.argv[1:])
