"""Nodal Dirichlet conditions on RK bases: null-space elimination
(``skfem_rkpm.condense`` then ``skfem.solve``) against the saddle-point
solve of the transformation method (``skfem_rkpm.solve``).

Poisson's problem -Δu = 1 on the unit square (n × n quadrilaterals) and the
unit cube (n³ hexahedra), order-1 RK bases with the default support,
``integration="vci_symmetric"``, every boundary value prescribed.  For each
mesh: the entries of ``K`` and of the reduced ``Zᵀ K Z``, the CPU time
(``time.process_time``, median of ``--repeat``) of condense + direct solve
(scikit-fem's default, SuperLU), of the saddle-point solve, and of
condense + scikit-fem's conjugate gradients without a preconditioner
(rtol 1e-10; the saddle-point matrix is indefinite, CG does not apply to it),
and the largest difference between the solutions.

Run:  python benchmarks/dirichlet_idioms.py          (~1 minute)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402
from _timing import median_cpu  # noqa: E402
import skfem  # noqa: E402
from skfem import MeshHex, MeshQuad, asm  # noqa: E402
from skfem.models.poisson import laplace, unit_load  # noqa: E402

import skfem_rkpm  # noqa: E402



def case(mesh, repeat):
    basis = skfem_rkpm.RKBasis(mesh, integration="vci_symmetric")
    K, f, D = asm(laplace, basis), asm(unit_load, basis), basis.get_dofs()
    t_condense, reduced = median_cpu(lambda: skfem_rkpm.condense(K, f, D=D, basis=basis), repeat)
    t_direct, d = median_cpu(lambda: skfem.solve(*reduced), repeat)
    t_saddle, ref = median_cpu(lambda: skfem_rkpm.solve(K, f, basis, D=D), repeat)
    t_cg, dcg = median_cpu(lambda: skfem.solve(*reduced, solver=skfem.solver_iter_pcg(rtol=1e-10)),
                      repeat)
    scale = np.abs(ref).max()
    return dict(N=basis.N, D=len(D), nnzK=K.nnz, nnzA=reduced[0].nnz,
                condense=t_condense, direct=t_direct, saddle=t_saddle, cg=t_cg,
                diff=np.abs(d - ref).max() / scale, diffcg=np.abs(dcg - ref).max() / scale)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"load: {os.getloadavg()[0]:.1f}")
    print("| mesh | N | len(D) | nnz K | nnz ZᵀKZ | condense s | + direct s | saddle point s "
          "| + CG s | rel. diff direct | rel. diff CG |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    meshes = [(f"square {n}²", MeshQuad.init_tensor(*(np.linspace(0, 1, n + 1),) * 2))
              for n in (32, 64, 128)]
    meshes += [(f"cube {n}³", MeshHex.init_tensor(*(np.linspace(0, 1, n + 1),) * 3))
               for n in (8, 12)]
    for label, mesh in meshes:
        r = case(mesh, args.repeat)
        print(f"| {label} | {r['N']} | {r['D']} | {r['nnzK']} | {r['nnzA']} "
              f"| {r['condense']:.3f} | {r['direct']:.3f} | {r['saddle']:.3f} | {r['cg']:.3f} "
              f"| {r['diff']:.1e} | {r['diffcg']:.1e} |", flush=True)


if __name__ == "__main__":
    main()
