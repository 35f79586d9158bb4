"""Linear solvers on 3D Hex1 elasticity tangents at the billet's sizes.

Matrix: the small-strain elasticity tangent (E = 200 GPa, ν = 0.3) of
``ElementVector(ElementHex1())`` on the billet_3d box (40 x 20 x 30 mm) with
``k`` times its divisions ``[8, 4, 6]`` per direction, the bottom face clamped
by elimination (``condense``): 9 x 5 x 7 nodes at k = 1, 5,967 unknowns of the
16 x 8 x 12 mesh at k = 2 and about 42,000 at k = 4, minus the clamped face (5,508 and 40,392).  The
"next Newton iteration" matrix is ``A' = A + 0.01 diag(A)``.

Per size (one core, CPU seconds of the process, ``time.process_time``):

* ``superlu``: :class:`skfem_rkpm.solvers.linear.SuperLU` (MMD ordering; the
  refactorization reuses the ordering), first factor, refactor of ``A'``, solve;
* ``ilu-gmres``: ``spilu`` (drop 1e-4, fill 10) + GMRES(50) to rtol 1e-10;
* ``lastlu-gmres``: GMRES on ``A'`` preconditioned by the factorization of ``A``
  (the "last factorization" lever), rtol 1e-10;
* ``amg``: :class:`skfem_rkpm.solvers.linear.AMG` (pyamg) if installed.

Reported: time, GMRES iterations, ``|A x - b| / |b|`` and the difference from
the SuperLU solution.  The peak resident memory of the whole process is printed
at the end (run one size per process to read it per size).

Run:  python benchmarks/solver_scaling_3d.py --k 2
      python benchmarks/solver_scaling_3d.py --k 4
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402


def build(k):
    """The clamped Hex1 elasticity tangent on the billet box with ``k`` x its divisions."""
    from skfem import Basis, ElementHex1, ElementVector, MeshHex, asm, condense
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    d = np.array([8, 4, 6]) * k
    mesh = MeshHex.init_tensor(*(np.linspace(0.0, s, n + 1) for s, n in zip((40.0, 20.0, 30.0), d)))
    basis = Basis(mesh, ElementVector(ElementHex1()))
    K = asm(linear_elasticity(*lame_parameters(200e3, 0.3)), basis)
    bottom = basis.get_dofs(lambda x: np.isclose(x[2], 0.0)).all()
    f = np.zeros(K.shape[0])
    f[basis.get_dofs(lambda x: np.isclose(x[2], 30.0)).nodal["u^3"]] = -1.0
    A, b, _, _ = condense(K, f, D=bottom)
    return A.tocsc(), b


def timed(fn):
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--k", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    from skfem_rkpm.solvers.linear import SuperLU, make_solver

    for k in args.k:
        (A, b), t_build = timed(lambda: build(k))
        A2 = A.copy()
        A2.setdiag(A.diagonal() * 1.01)
        n = A.shape[0]
        print(f"k={k}: {n} unknowns, {A.nnz / n:.0f} nonzeros per row, build {t_build:.2f} s")

        def res(M, x):
            return np.linalg.norm(M @ x - b) / np.linalg.norm(b)

        lu = SuperLU()
        _, t_f = timed(lambda: lu.factor(A))
        x_ref, t_s = timed(lambda: lu.solve(b))
        print(f"  superlu       factor {t_f:7.2f} s  solve {t_s:6.3f} s  res {res(A, x_ref):.1e}")
        lu2 = SuperLU()
        lu2.factor(A)
        _, t_rf = timed(lambda: lu2.factor(A2))
        x2_ref = lu2.solve(b)
        print(f"  superlu       refactor {t_rf:5.2f} s  res {res(A2, x2_ref):.1e}")

        def gmres(label, M, precond, reference):
            def run():
                P = spla.LinearOperator(M.shape, precond())
                it = []
                x, info = spla.gmres(M, b, M=P, rtol=1e-10, restart=50, maxiter=20,
                                     callback=lambda _: it.append(1), callback_type="pr_norm")
                return x, info, len(it)
            (x, info, it), t = timed(run)
            print(f"  {label:13s} total {t:8.2f} s  its {it:4d} info {info}  res {res(M, x):.1e}  "
                  f"|x-x_lu|/|x_lu| {np.linalg.norm(x - reference) / np.linalg.norm(reference):.1e}")

        # ILU is built inside the timed call; the last factorization is the one of A
        gmres("ilu-gmres", A, lambda: spla.spilu(A, drop_tol=1e-4, fill_factor=10).solve, x_ref)
        gmres("lastlu-gmres", A2, lambda: lu.solve, x2_ref)
        try:
            amg = make_solver("amg")
            _, t_f = timed(lambda: amg.factor(A))
            x, t_s = timed(lambda: amg.solve(b))
            print(f"  amg           setup {t_f:8.2f} s  solve {t_s:6.3f} s  res {res(A, x):.1e}  "
                  f"|x-x_lu|/|x_lu| {np.linalg.norm(x - x_ref) / np.linalg.norm(x_ref):.1e}")
        except Exception as err:  # backend not installed
            print(f"  amg           unavailable: {err}")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
