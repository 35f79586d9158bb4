"""Implicit against explicit dynamics on the elastic bar on a rigid wall.

The bar of ``benchmarks/explicit_bar.py``: plane strain, ν = 0, L = 10 mm on
2 × 40 cells, steel (E = 200 GPa, ρ = 7850 kg/m³), onto a rigid wall at
v0 = 10 m/s, penalty factor 1, over 3 L/c0.  d'Alembert: contact for 2L/c0
under ρ c0 v0 A, rebound at −v0.  For FEM Q1 and RK (support 2, Gauss):

- explicit central differences at 0.9 of the stable step (lumped mass);
- the implicit trapezoidal rule in the Newton loop at Courant numbers
  ``c0 Δt / h`` of 0.5, 1, 2 and 4 (lumped mass), and HHT-α (α = −0.1) at 1.

The table gives the median CPU seconds of ``--repeat`` runs, the steps (and
Newton iterations), the contact time, the mean force and the L1 error of the
wall force against d'Alembert (over 3 L/c0, relative to ρ c0 v0 A · 2L/c0),
the kinetic energy given back and the largest change of the energy balance
over the peak kinetic energy.  ``--figure`` draws the HHT-α damping ratio
against Ω = ω Δt, measured on a spring in the Newton loop against the
amplification matrix, and the implicit bar's energies over time.

Run:  python benchmarks/implicit_bar.py                  (~1 min of CPU)
      python benchmarks/implicit_bar.py --figure docs/figures/implicit_dynamics.png
"""

import argparse
import os
import time

import numpy as np
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.mass import lumped_mass
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.solvers.explicit import CentralDifference
from skfem_rkpm.solvers.newton import newton_steps
from skfem_rkpm.solvers.time_integration import Newmark
from skfem_rkpm.verification.oscillators import LinearSprings, principal_root, prony

E, RHO, L, V0 = 200e3, 7.85e-9, 10.0, 1e4
C0 = np.sqrt(E / RHO)
PLATEAU = RHO * C0 * V0 * 1.0  # ρ c0 v0 A, A = 1 mm²


def setup(method, cells):
    mesh = MeshQuad.init_tensor(np.linspace(0, 1, 3), np.linspace(0, L, cells + 1))
    b = (Basis(mesh.with_defaults(), ElementVector(ElementQuad1()), intorder=2)
         if method == "fem" else
         RKBasis(mesh.with_defaults(), vector=True, support=2.0, integration="gauss"))
    problem = SolidProblem(b, J2Material(E, 0.0), model="plane_strain")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=1.0)
    v = np.zeros(b.N)
    v[1::2] = -V0
    return problem, wall, v


def explicit(method, cells):
    problem, wall, v = setup(method, cells)
    rows = [(0.0, 0.0, 0.0, 0.0)]
    records = CentralDifference(problem, RHO, contacts=[wall]).run(
        np.zeros(problem.N), v, duration=3 * L / C0, output_interval=0.005 * L / C0,
        on_output=lambda r: rows.append((r.time, r.forces["platen"][1], r.kinetic,
                                         r.balance)))
    t, f, kinetic, balance = np.array(rows[1:]).T
    return dict(t=t, force=f, kinetic=kinetic, balance=balance,
                steps=records[-1].step, iterations=0)


def implicit(method, cells, courant, alpha=0.0):
    problem, wall, v = setup(method, cells)
    duration = 3 * L / C0
    steps = int(round(duration / (courant * (L / cells) / C0)))
    mass = lumped_mass(problem.assembler, RHO)
    scheme = Newmark(problem, mass, duration, v0=v, alpha=alpha, contributions=[wall])
    forces = [0.0]  # the wall force (y) at the start and after each step
    result = newton_steps(problem, steps=steps, tol=1e-8, contributions=[wall],
                          increment=scheme,
                          on_step=lambda *_: forces.append(wall.resultants()["platen"][1]))
    if not result.completed:
        raise RuntimeError(result.message)
    records = scheme.records
    t, f = np.array([r.time for r in records]), np.array(forces)
    return dict(t=t, force=f, kinetic=np.array([r.kinetic for r in records]),
                balance=np.array([r.balance for r in records]), steps=len(result.history),
                iterations=sum(r.iterations for r in result.history), records=records)


def dalembert(t):
    return np.where(t <= 2 * L / C0, PLATEAU, 0.0)


def l1_error(t, force):
    """∫ |F − F_exact| dt over [0, 3L/c0] / (ρ c0 v0 A · 2L/c0), on a fine
    grid with the run's force linearly interpolated."""
    fine = np.linspace(0.0, 3 * L / C0, 30001)
    error = np.abs(np.interp(fine, t, force) - dalembert(fine))
    return np.trapezoid(error, fine) / (PLATEAU * 2 * L / C0)


def measure(label, run, repeat):
    times = []
    for _ in range(repeat):
        start = time.process_time()
        out = run()
        times.append(time.process_time() - start)
    t, f = out["t"], out["force"]
    touching = f > 1e-6 * f.max()
    mean = np.trapezoid(f, t) / (2 * L / C0) / PLATEAU
    kinetic, balance = out["kinetic"], out["balance"]
    print(f"| {label} | {np.median(times):.2f} | {out['steps']} | {out['iterations'] or '—'} | "
          f"{t[touching].max() / (2 * L / C0):.3f} | {mean:.3f} | {l1_error(t, f):.3f} | "
          f"{kinetic[-1] / kinetic[0]:.3f} | "
          f"{np.abs(balance - balance[0]).max() / kinetic.max():.1e} |", flush=True)
    return out


def hht_curves(alphas=(-0.05, -0.1, -0.3), omegas=np.geomspace(0.05, 3.0, 12)):
    """ξ̄(Ω) measured on a spring in the Newton loop and from the matrix."""
    out = {}
    for alpha in alphas:
        measured = []
        for Omega in omegas:
            problem = LinearSprings([[1.0]])
            d0 = np.array([1.0])
            scheme = Newmark(problem, np.ones(1), 300 * Omega, d0=d0, alpha=alpha)
            result = newton_steps(problem, steps=300, tol=1e-12, d0=d0, increment=scheme)
            measured.append(prony(np.r_[1.0, [s[0] for s in result.solutions]])[1])
        fine = np.geomspace(omegas[0], omegas[-1], 200)
        out[alpha] = (omegas, np.array(measured), fine,
                      np.array([principal_root(x, alpha)[1] for x in fine]))
    return out


def figure(path, bar_run):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for alpha, (omegas, measured, fine, theory) in hht_curves().items():
        line, = left.loglog(fine, theory, label=f"α = {alpha:g}, amplification matrix")
        left.loglog(omegas, measured, "o", color=line.get_color(), mfc="none",
                    label=f"α = {alpha:g}, measured")
    left.set_xlabel("Ω = ω Δt (1)")
    left.set_ylabel("algorithmic damping ratio ξ̄ (1)")
    left.set_title("HHT-α on a spring, in the Newton loop")
    left.legend(fontsize=7)
    records = bar_run["records"]
    t = np.array([r.time for r in records]) * 1e6
    series = {"kinetic": [r.kinetic for r in records],
              "internal (elastic)": [r.internal for r in records],
              "contact": [r.contact for r in records],
              "balance T + W_int + W_c − W_ext": [r.balance for r in records]}
    for name, values in series.items():
        right.plot(t, np.array(values), label=name)  # N·mm = mJ
    right.set_xlabel("time (µs)")
    right.set_ylabel("energy (mJ)")
    right.set_title("RK bar on a rigid wall, trapezoidal, Courant 1")
    right.legend(fontsize=7)
    fig.tight_layout()
    tmp = f"{path}.tmp-{os.getpid()}.png"
    fig.savefig(tmp, dpi=120)
    os.replace(tmp, path)
    print(f"figure: {path}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=40)
    parser.add_argument("--courant", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--figure", default=None)
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.1f}; CPU seconds are medians of "
          f"{args.repeat} runs (time.process_time)")
    print("| run | CPU s | steps | Newton iterations | contact time / (2L/c0) | "
          "mean force / (ρ c0 v0 A) | L1 force error | kinetic energy given back | "
          "balance error / peak kinetic |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    keep = None
    for method in ("fem", "rk"):
        name = method.upper()
        measure(f"{name} explicit", lambda: explicit(method, args.cells), args.repeat)
        for c in args.courant:
            out = measure(f"{name} trapezoidal, Courant {c:g}",
                          lambda: implicit(method, args.cells, c), args.repeat)
            if method == "rk" and c == 1.0:
                keep = out
        measure(f"{name} HHT α = −0.1, Courant 1",
                lambda: implicit(method, args.cells, 1.0, alpha=-0.1), args.repeat)
    print(f"load average after: {os.getloadavg()[0]:.1f}")
    if args.figure:
        figure(args.figure, keep if keep is not None else implicit("rk", args.cells, 1.0))


if __name__ == "__main__":
    main()
