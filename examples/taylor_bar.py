"""The Taylor bar: a copper rod hits a rigid frictionless wall at 227 m/s.

Explicit central differences (skfem_rkpm.solvers.explicit) with the lumped
mass, axisymmetric, RKPM and FEM Q1 (both F-bar), penalty contact with the
wall and the axis held by the projection of CentralDifference.  Bar
L0 = 32.4 mm, R0 = 3.2 mm; E = 117 GPa, ν = 0.35, ρ = 8930 kg/m³,
σy = 400 + 100 ε̄ᵖ MPa; 80 µs.  Units mm, N, MPa, s (density in t/mm³).

Prints the final length (the axis point at the top), the radius of the
impact face (the corner that starts at (R0, 0)), the largest ε̄ᵖ, the CPU
time, the steps and the energy balance; draws the deformed bars coloured by
ε̄ᵖ.

Run:  python examples/taylor_bar.py                       (~1 minute)
      python examples/taylor_bar.py --cells 10 100 --figure docs/figures/taylor_bar.png
"""

import argparse
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from skfem import Basis, ElementQuad1, ElementVector  # noqa: E402

from skfem_rkpm import RKBasis  # noqa: E402
from skfem_rkpm.approximation.constraints import nodal_constraint  # noqa: E402
from skfem_rkpm.mechanics.materials import J2Material, linear  # noqa: E402
from skfem_rkpm.mechanics.problem import SolidProblem  # noqa: E402
from skfem_rkpm.mechanics.rigid_contact import RigidContact  # noqa: E402
from skfem_rkpm.mechanics.tools import Platen  # noqa: E402
from skfem_rkpm.meshes import rectangle  # noqa: E402
from skfem_rkpm.runs.plot import plot_deformed  # noqa: E402
from skfem_rkpm.solvers.explicit import CentralDifference  # noqa: E402

R0, L0, V0, RHO, DURATION = 3.2, 32.4, 227e3, 8.93e-9, 80e-6


def taylor_bar(method, cells):
    """Run the bar; returns (problem, last record, records, CPU seconds)."""
    mesh = rectangle(R0, L0, *cells)
    if method == "fem":
        basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    else:
        basis = RKBasis(mesh, vector=True, support=2.0, axisymmetric=True)
    problem = SolidProblem(basis, J2Material(117e3, 0.35, linear(400.0, 100.0)),
                           model="axisymmetric", locking="fbar")
    wall = RigidContact(problem, Platen([0.0, 0.0], [0.0, 1.0], name="wall"),
                        slaves=["bottom", "right"], factor=1.0)
    scheme = CentralDifference(problem, RHO, contacts=[wall],
                               constraints=[nodal_constraint(basis, "left", 0)])
    v = np.zeros(basis.N)
    v[1::2] = -V0
    start = time.process_time()
    records = scheme.run(np.zeros(basis.N), v, duration=DURATION,
                         output_interval=DURATION / 8)
    return problem, records, time.process_time() - start


def displacements_at(problem, d, points):
    """Displacements (2, n) of the body at reference points (2, n)."""
    basis = problem.basis
    if isinstance(basis, RKBasis):
        u = basis.probes(points) @ d
        return u.reshape(2, -1)
    X = basis.doflocs[:, 0::2]
    nearest = [np.argmin(((X - p[:, None]) ** 2).sum(axis=0)) for p in points.T]
    return np.stack([d[0::2][nearest], d[1::2][nearest]])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs=2, default=[5, 50],
                        metavar=("NR", "NZ"), help="cells across the radius and along")
    parser.add_argument("--figure", default="taylor_bar.png")
    args = parser.parse_args()
    points = np.array([[R0, 0.0], [0.0, L0]]).T  # foot, top
    fig, axes = plt.subplots(1, 2, figsize=(7, 6), sharey=True)
    print("| method | cells | unknowns | steps | CPU s | length mm | foot radius mm | "
          "max ε̄ᵖ | energy balance / peak kinetic |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for ax, method in zip(axes, ("rkpm", "fem")):
        problem, records, cpu = taylor_bar(method, args.cells)
        last = records[-1]
        u = displacements_at(problem, last.d, points)
        balance = np.array([r.balance for r in records])
        peak = max(r.kinetic for r in records)
        print(f"| {method} | {args.cells[0]} x {args.cells[1]} | {problem.N} | {last.step} | "
              f"{cpu:.1f} | {L0 + u[1, 1]:.3f} | {R0 + u[0, 0]:.3f} | "
              f"{problem.state.alpha.max():.2f} | "
              f"{np.abs(balance - balance[0]).max() / peak:.1e} |", flush=True)
        art = plot_deformed(ax, problem, last.d, f"{method.upper()}, 80 µs", vmax=3.0)
        ax.set_xlabel("r (mm)")
    axes[0].set_ylabel("z (mm)")
    fig.colorbar(art, ax=axes, label="equivalent plastic strain ε̄ᵖ")
    fig.savefig(args.figure, dpi=120)
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
