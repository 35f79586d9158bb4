"""Lumped masses of RK and FEM bases: which keeps the patch test, and the
stable step of central differences each allows.

For a unit square of n x n cells (plane strain, E = 1, ν = 0.3, ρ = 1) and
a unit cube of n³ cells (3D), with FEM (Q1 / Hex1) and order-1 RK bases at
several supports (Gauss quadrature, so that K is symmetric), the table
lists:

- the critical step ``2/ω_max`` in units of ``h / c_d`` (``h`` the cell
  size, ``c_d`` the dilatational wave speed) with the consistent mass, the
  generalized row-sum mass ``m_I = ∫ ρ Ψ_I`` and the nodal row-sum mass
  ``m̂ = Λ⁻¹ m`` (Eq. 3.38's ``M̂`` lumped), and the Gershgorin bound of the
  row-sum mass (a stable step that needs no eigenvalue solve);
- the smallest ``m̂`` over the largest (a negative one makes the nodal
  lumping useless);
- the acceleration patch test: the largest error of the acceleration field
  ``Σ Ψ_I a_I`` at the quadrature points, relative to its largest value, for
  the linear body force ``ρ b(X) = 1 + X + 2Y (+ 3Z)`` applied as loads
  ``∫ ρ b Ψ_I``; the consistent mass reproduces a linear field exactly.

Run:  python benchmarks/mass_lumping.py              (~1 minute)
      python benchmarks/mass_lumping.py --cells 8 --supports 2
"""

import argparse

import numpy as np
from scipy.sparse.linalg import splu
from skfem import Basis, ElementHex1, ElementQuad1, ElementVector, MeshHex, MeshQuad
from skfem.models.elasticity import lame_parameters

from skfem_rkpm import Assembler, RKBasis, isotropic_tangent
from skfem_rkpm.mechanics.mass import (consistent_mass, critical_time_step,
                                       gershgorin_time_step, lumped_mass,
                                       nodal_lumped_mass, nodal_mass_matrix)


def mesh(dim, n):
    t = np.linspace(0.0, 1.0, n + 1)
    return MeshQuad.init_tensor(t, t) if dim == 2 else MeshHex.init_tensor(t, t, t)


def patch_error(basis, A, how):
    """Largest error of the acceleration field under a linear body force."""
    X = np.asarray(basis.global_coordinates())
    dim = X.shape[0]
    b = 1.0 + sum((k + 1) * X[k] for k in range(dim))  # at the quadrature points
    L = A.layout
    # f_(I, c=0) = ∫ b Ψ_I, applied to the first component only
    local = np.zeros((L.element_nodes.shape[1], L.element_nodes.shape[0], dim))
    local[:, :, 0] = np.einsum("aeq,eq->ea", L.values, b * L.dx)
    f = A.scatter(local.reshape(local.shape[0], -1).T)
    if how == "consistent":
        a = splu(consistent_mass(A, 1.0).tocsc()).solve(f)
    elif how == "row sum":
        a = f / lumped_mass(A, 1.0)
    else:  # nodal: â = Λ⁻¹ f / m̂, then the coefficients d = Λ⁻ᵀ â
        lam_t = splu(basis.nodal_matrix.T.tocsc())
        a_hat = lam_t.solve(f) / nodal_lumped_mass(basis, A, 1.0)
        a = splu(basis.nodal_matrix.tocsc()).solve(a_hat)
    field = np.einsum("aeq,ea->eq", L.values, a[A.element_dofs[0::dim]].T)
    return float(np.abs(field - b).max() / np.abs(b).max())


def row(dim, n, method, support):
    lam, mu = lame_parameters(1.0, 0.3)
    cd, h = np.sqrt(lam + 2 * mu), 1.0 / n
    m_ = mesh(dim, n)
    if method == "fem":
        element = ElementQuad1() if dim == 2 else ElementHex1()
        basis = Basis(m_, ElementVector(element), intorder=2)
    else:
        basis = RKBasis(m_, vector=True, support=support, integration="gauss")
    A = Assembler(basis)
    K = A.bilinear(isotropic_tangent(lam, mu, dim))
    m = lumped_mass(A, 1.0)
    unit = h / cd
    steps = [critical_time_step(K, consistent_mass(A, 1.0)) / unit,
             critical_time_step(K, m) / unit]
    if method == "fem":
        steps.append(steps[-1])
        m_ratio = 1.0
        nodal_patch = patch_error(basis, A, "row sum")
    else:
        m_hat = nodal_lumped_mass(basis, A, 1.0)
        m_ratio = m_hat.min() / m_hat.max()
        steps.append(critical_time_step(K, nodal_mass_matrix(basis, m_hat)) / unit
                     if m_hat.min() > 0 else float("nan"))
        nodal_patch = patch_error(basis, A, "nodal")
    label = "FEM" if method == "fem" else f"RK a = {support:g}"
    return (f"| {dim}D, {n} cells | {label} | {basis.N} | "
            + " | ".join(f"{s:.3f}" for s in steps)
            + f" | {gershgorin_time_step(K, m) / unit:.3f} | {m_ratio:.3f} | "
            f"{patch_error(basis, A, 'consistent'):.1e} | {patch_error(basis, A, 'row sum'):.1e}"
            f" | {nodal_patch:.1e} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[8, 16])
    parser.add_argument("--cells-3d", type=int, nargs="+", default=[4])
    parser.add_argument("--supports", type=float, nargs="+", default=[1.5, 2.0, 2.5, 3.0])
    args = parser.parse_args()
    print("Critical steps in units of h / c_d; patch errors relative to max |b|.\n")
    print("| mesh | basis | unknowns | Δt consistent | Δt row sum | Δt nodal | "
          "Δt Gershgorin (row sum) | min m̂ / max m̂ | patch consistent | patch row sum | "
          "patch nodal |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for dim, sizes in ((2, args.cells), (3, args.cells_3d)):
        for n in sizes:
            print(row(dim, n, "fem", None), flush=True)
            for a in args.supports:
                print(row(dim, n, "rk", a), flush=True)


if __name__ == "__main__":
    main()
