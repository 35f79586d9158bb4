"""An elastic bar on a rigid wall, explicit, against d'Alembert's solution.

A plane-strain bar (ν = 0: a uniaxial wave) of length L = 10 mm and width
1 mm, steel (E = 200 GPa, ρ = 7850 kg/m³), hits a rigid wall at v0 = 10 m/s.
d'Alembert: contact for 2L/c0 under the force ρ c0 v0 A, then the bar leaves
at −v0.  For FEM Q1 and RK (support 2, Gauss) at 40 cells along the bar and
penalty factors 0.3, 1 and 10 (``ω_n = factor · E / h``), the table gives the
contact time, the mean force over 2L/c0, the kinetic energy given back, the
largest error of the energy balance over the peak kinetic energy, the steps
and the CPU time; ``--figure`` draws the force history of factor 1.

Run:  python benchmarks/explicit_bar.py                  (~30 s)
      python benchmarks/explicit_bar.py --figure docs/figures/explicit_bar.png
"""

import argparse
import time

import numpy as np
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.materials import J2Material
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.rigid_contact import RigidContact
from skfem_rkpm.mechanics.tools import Platen
from skfem_rkpm.solvers.explicit import CentralDifference

E, RHO, L, V0 = 200e3, 7.85e-9, 10.0, 1e4
C0 = np.sqrt(E / RHO)


def bar(method, factor, cells):
    mesh = MeshQuad.init_tensor(np.linspace(0, 1, 3), np.linspace(0, L, cells + 1))
    mesh = mesh.with_defaults()
    b = (Basis(mesh, ElementVector(ElementQuad1()), intorder=2) if method == "fem"
         else RKBasis(mesh, vector=True, support=2.0, integration="gauss"))
    problem = SolidProblem(b, J2Material(E, 0.0), model="plane_strain")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0]), slaves="bottom",
                        factor=factor)
    v = np.zeros(b.N)
    v[1::2] = -V0
    rows = []
    start = time.process_time()
    records = CentralDifference(problem, RHO, contacts=[wall]).run(
        np.zeros(b.N), v, duration=3 * L / C0, output_interval=0.005 * L / C0,
        on_output=lambda r: rows.append((r.time, r.forces["platen"][1], r.kinetic,
                                         r.balance)))
    return np.array(rows).T, records[-1].step, time.process_time() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=40)
    parser.add_argument("--factors", type=float, nargs="+", default=[0.3, 1.0, 10.0])
    parser.add_argument("--figure", default=None)
    args = parser.parse_args()
    print("| basis | penalty factor | contact time / (2L/c0) | mean force / (ρ c0 v0 A) | "
          "kinetic energy given back | balance error / peak kinetic | steps | CPU s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    curves = {}
    for factor in args.factors:
        for method in ("fem", "rk"):
            (t, force, kinetic, balance), steps, cpu = bar(method, factor, args.cells)
            touching = force > 1e-6 * force.max()
            mean = np.trapezoid(force, t) / (2 * L / C0) / (RHO * C0 * V0)
            print(f"| {method.upper()} | {factor:g} | {t[touching].max() / (2 * L / C0):.3f} | "
                  f"{mean:.3f} | {kinetic[-1] / kinetic[0]:.3f} | "
                  f"{np.abs(balance - balance[0]).max() / kinetic.max():.1e} | {steps} | "
                  f"{cpu:.1f} |", flush=True)
            if factor == 1.0:
                curves[method] = (t, force)
    if args.figure and curves:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6.5, 3.5))
        for method, (t, force) in curves.items():
            ax.plot(t * C0 / L, force / (RHO * C0 * V0), label=f"{method.upper()}, "
                    "penalty factor 1")
        ax.plot([0, 0, 2, 2, 3], [0, 1, 1, 0, 0], "k--", label="d'Alembert")
        ax.set_xlabel("time t c0 / L")
        ax.set_ylabel("wall force / (ρ c0 v0 A)")
        ax.set_title("Elastic bar on a rigid wall, central differences")
        ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=120)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
