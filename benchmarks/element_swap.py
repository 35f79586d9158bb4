"""RKBasis(mesh, element) on quadratic elements against FEM: L² errors.

-Δu = 2π² sin πx sin πy on the unit square, u = 0 on the boundary, with
scikit-fem's Basis(mesh, element) (Gauss degree 6) and RKBasis(mesh,
element) at several supports, standard and interpolating; the table gives
the RK error over FEM's and the CPU seconds of the RK basis and solve.

Run:  python benchmarks/element_swap.py          (~15 s)
"""

import time

import numpy as np
from skfem import (Basis, ElementQuad2, ElementQuadS2, ElementTriP2, Functional, LinearForm,
                   MeshQuad, MeshTri, asm, condense, solve)
from skfem.models.poisson import laplace

import skfem_rkpm
from skfem_rkpm import RKBasis
from skfem_rkpm.verification.exact import sine_poisson
from skfem_rkpm.approximation.shape import SingularMomentError


load = LinearForm(lambda v, w: sine_poisson(w.x)[1] * v)
l2_error = Functional(lambda w: (w["uh"] - sine_poisson(w.x)[0]) ** 2)


def fem_error(mesh, element):
    fem = Basis(mesh, element, intorder=6)
    u = solve(*condense(asm(laplace, fem), asm(load, fem), D=fem.get_dofs()))
    return np.sqrt(l2_error.assemble(fem, uh=fem.interpolate(u)))


def rk_error(mesh, element, support, interpolating):
    start = time.process_time()
    rk = RKBasis(mesh, element, support=support, interpolating=interpolating)
    K = skfem_rkpm.asm(laplace, rk.trial, rk)
    d = solve(*skfem_rkpm.condense(K, skfem_rkpm.asm(load, rk), D=rk.get_dofs(), basis=rk))
    error = np.sqrt(l2_error.assemble(rk, uh=rk.interpolate(d)))
    return error, time.process_time() - start


def main():
    cases = [(MeshTri().refined(3), ElementTriP2()), (MeshTri().refined(4), ElementTriP2()),
             (MeshQuad().refined(3), ElementQuad2()), (MeshQuad().refined(3), ElementQuadS2())]
    print("| mesh | element | unknowns | support | interpolating | RK / FEM L² error | RK CPU s |")
    print("|---|---|---:|---:|---|---:|---:|")
    for mesh, element in cases:
        reference = fem_error(mesh, element)
        for interpolating in (False, True):
            for support in (2.0, 2.5, 3.0):
                name = f"| {mesh.nelements} {type(mesh).__name__[4:].lower()} | " \
                       f"{type(element).__name__[7:]} | {Basis(mesh, element).N} | " \
                       f"{support:g} | {interpolating} |"
                try:
                    error, cpu = rk_error(mesh, element, support, interpolating)
                except SingularMomentError:
                    print(name, "singular | |", flush=True)
                    continue
                print(name, f"{error / reference:.2f} | {cpu:.2f} |", flush=True)


if __name__ == "__main__":
    import warnings
    warnings.simplefilter("ignore")
    main()
