"""Any scikit-fem form on an RK basis: skfem_rkpm.asm against Assembler and skfem.asm.

Two tables:

1. 3D Poisson, ``laplace`` on ``RKBasis(MeshTet().refined(3))`` (8³ cubes of
   tetrahedra, default support and quadrature): ``skfem_rkpm.asm(laplace,
   basis.trial, basis)`` on a fresh basis (its sparsity pattern built in the
   call) and again (pattern cached on the basis), ``Assembler(basis)
   .bilinear`` with the identity tangent (pattern included), and scikit-fem's
   own ``skfem.asm`` (its loop over pairs of local functions; once, it takes
   seconds; ``--no-skfem`` leaves it out).  Target: ``skfem_rkpm.asm`` ≤ 0.5 s.
2. Every form of ``skfem.models`` on 2D and 3D RK bases: ``skfem_rkpm.asm``
   (pattern cached) against the dedicated ``Assembler`` call on the same basis
   (pattern built beforehand) where one exists (``laplace``, ``vector_laplace``
   and ``linear_elasticity``: ``bilinear``; ``mass``: ``mass``); target
   within 3x.  Forms between different spaces (``divu``, ``curluv``) and the
   linear forms (``unit_load``, ``rot``, ``vrot``) have no Assembler
   counterpart: their time is shown next to that of ``laplace`` on the same
   basis.  Every matrix is compared with the Assembler's (or, on the
   smallest mesh, with ``skfem.asm``): rel. diff = max|A - B| / max|B|.

Times are CPU seconds (``time.process_time``), medians of ``--repeat`` runs.

Run:  python benchmarks/form_assembly.py               (~1 minute + 20 s of skfem.asm)
      python benchmarks/form_assembly.py --no-skfem --repeat 3
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import skfem  # noqa: E402
from skfem import MeshQuad, MeshTet  # noqa: E402
from skfem.models import (laplace, linear_elasticity, mass, unit_load,  # noqa: E402
                          vector_laplace)
from skfem.models.general import curluv, divu, rot, vrot  # noqa: E402

import skfem_rkpm  # noqa: E402
from skfem_rkpm import Assembler, RKBasis, isotropic_tangent  # noqa: E402

clock = time.process_time


def timed(f, repeat):
    """Median CPU time of ``repeat`` calls of ``f`` and the last result."""
    times = []
    for _ in range(repeat):
        t = clock()
        out = f()
        times.append(clock() - t)
    return float(np.median(times)), out


def rel_diff(A, B):
    A = A.toarray() if hasattr(A, "toarray") else np.asarray(A)
    B = B.toarray() if hasattr(B, "toarray") else np.asarray(B)
    return np.abs(A - B).max() / np.abs(B).max()


def poisson_3d(args):
    mesh = MeshTet().refined(3)
    eye = np.eye(3)[None, :, None, :]
    first, cached, assembler = [], [], []
    for _ in range(args.repeat):
        basis = RKBasis(mesh)
        basis.trial  # the exact-gradient twin is part of the basis
        t = clock()
        K = skfem_rkpm.asm(laplace, basis.trial, basis)
        first.append(clock() - t)
        t = clock()
        skfem_rkpm.asm(laplace, basis.trial, basis)
        cached.append(clock() - t)
        t = clock()
        K_ref = Assembler(basis).bilinear(eye)
        assembler.append(clock() - t)
    print(f"3D Poisson: MeshTet().refined(3), {mesh.nelements} tetrahedra, {basis}")
    print()
    print("| call | CPU s (median of %d) | rel. diff to Assembler |" % args.repeat)
    print("|---|---|---|")
    print(f"| skfem_rkpm.asm, fresh basis (pattern built) | {np.median(first):.3f} "
          f"| {rel_diff(K, K_ref):.1e} |")
    print(f"| skfem_rkpm.asm, again (pattern cached) | {np.median(cached):.3f} | |")
    print(f"| Assembler(basis).bilinear (pattern built) | {np.median(assembler):.3f} | |")
    if not args.no_skfem:
        t = clock()
        K_loop = skfem.asm(laplace, basis.trial, basis)
        print(f"| skfem.asm (loop over pairs, once) | {clock() - t:.2f} "
              f"| {rel_diff(K_loop, K_ref):.1e} |")
    print()


def models(args):
    lam, mu = 0.7, 1.3
    cases = [("2D quads 32x32", MeshQuad().refined(5), 2),
             ("3D tets 4^3 cubes", MeshTet().refined(2), 3)]
    print("Every skfem.models form; pattern cached / built beforehand; ratio = "
          "skfem_rkpm.asm / Assembler")
    print()
    print("| mesh | form | bases (trial, test) | skfem_rkpm.asm s | Assembler s | ratio "
          "| rel. diff |")
    print("|---|---|---|---|---|---|---|")
    for label, mesh, dim in cases:
        s, v = RKBasis(mesh), RKBasis(mesh, vector=True)
        A_s, A_v = Assembler(s), Assembler(v)
        A_s.bilinear(np.eye(dim)[None, :, None, :])  # patterns built
        A_v.bilinear(isotropic_tangent(lam, mu, dim))
        vlap = np.einsum("cd,lm->cldm", np.eye(dim), np.eye(dim))
        ws = s.interpolate(s.project(lambda x: np.sin(2 * x[0]) * x[1]))
        wv = v.interpolate(v.project(lambda x: np.array([x[1] ** 2, x[0] * x[1],
                                                         x[0]][:dim])))
        rows = [
            ("laplace", laplace, (s.trial, s), lambda: A_s.bilinear(
                np.eye(dim)[None, :, None, :])),
            ("mass", mass, (s,), lambda: A_s.mass()),
            ("vector_laplace", vector_laplace, (v.trial, v), lambda: A_v.bilinear(vlap)),
            ("linear_elasticity", linear_elasticity(lam, mu), (v.trial, v),
             lambda: A_v.bilinear(isotropic_tangent(lam, mu, dim))),
            ("divu", divu, (v.trial, s), None),
            ("curluv", curluv, (s.trial, v) if dim == 2 else (v.trial, v), None),
            ("unit_load", unit_load, (s,), None),
            ("rot", rot, (s,) if dim == 2 else (v,), None),
            ("vrot", vrot, (v,) if dim == 2 else (v,), None),
        ]
        reference_time = None
        for name, form, bases, dedicated in rows:
            kwargs = {}
            if name == "rot":
                kwargs = {"w": wv}
            elif name == "vrot":
                kwargs = {"w": ws if dim == 2 else wv}
            skfem_rkpm.asm(form, *bases, **kwargs)  # pattern cached
            t_asm, M = timed(lambda: skfem_rkpm.asm(form, *bases, **kwargs), args.repeat)
            names = ", ".join("v.trial" if b is v.trial else "v" if b is v else
                              "s.trial" if b is s.trial else "s" for b in bases)
            if dedicated is not None:
                t_ref, M_ref = timed(dedicated, args.repeat)
                if name == "laplace":
                    reference_time = t_ref
                print(f"| {label} | {name} | {names} | {t_asm:.4f} | {t_ref:.4f} "
                      f"| {t_asm / t_ref:.2f} | {rel_diff(M, M_ref):.1e} |")
            else:
                print(f"| {label} | {name} | {names} | {t_asm:.4f} | (laplace: "
                      f"{reference_time:.4f}) | {t_asm / reference_time:.2f} | |")
    print()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-skfem", action="store_true",
                        help="leave out the slow skfem.asm loop")
    args = parser.parse_args()
    print(f"numpy {np.__version__}, scikit-fem {skfem.__version__}, "
          f"OMP/OPENBLAS/MKL_NUM_THREADS=1, load average {os.getloadavg()}")
    print()
    poisson_3d(args)
    models(args)


if __name__ == "__main__":
    main()
