"""Reference problems with closed-form solutions, solved on any basis.

Each problem loads the whole boundary with the exact traction ``σ·n`` and
removes the rigid motions by prescribing the exact displacement at three
nodal dofs.  The discrete solution then differs from the exact one only by
the approximation and integration errors of the method, which is what a
convergence study should measure.  (Prescribing displacements along a whole
edge adds the error of the boundary-condition method; see
:func:`skfem_rkpm.verification.elasticity.solve_elasticity`.)
"""

import time
from dataclasses import dataclass
from functools import partial

import numpy as np
from skfem import LinearForm
from skfem.helpers import dot

from ..assembly import Assembler, isotropic_tangent
from ..forms import asm
from ..solvers.constrained import solve
from .elasticity import error_norms, facet_basis, lame, stress_from_voigt
from .exact import (kirsch_displacement, kirsch_stress, timoshenko_displacement,
                    timoshenko_stress)
from ..meshes import gmsh_plate_with_hole, rectangle

__all__ = ["Problem", "timoshenko_beam", "plate_with_hole", "solve_problem",
           "rigid_motion_dofs", "cube_corner_dofs", "convergence_study", "rates"]


@dataclass
class Problem:
    """A plane elasticity problem with its exact solution.

    ``mesh(n)`` builds the background mesh of refinement level ``n``
    (``n`` cells through the characteristic length).
    """

    name: str
    E: float
    nu: float
    plane: str
    displacement: callable
    stress: callable
    mesh: callable


def timoshenko_beam(L=48.0, D=12.0, P=1000.0, E=3e7, nu=0.3, kind="quad"):
    """Timoshenko's cantilever (plane stress), ``4n x n`` cells."""
    return Problem(
        "timoshenko", E, nu, "stress",
        partial(timoshenko_displacement, L=L, D=D, P=P, E=E, nu=nu, plane="stress"),
        partial(timoshenko_stress, L=L, D=D, P=P),
        lambda n: rectangle(L, D, 4 * n, n, kind=kind, origin=(0.0, -D / 2)),
    )


def plate_with_hole(a=1.0, length=5.0, T=1.0, E=1e3, nu=0.3, kind="tri"):
    """Quarter of the infinite plate with a hole (Kirsch), plane stress.

    ``mesh(n)`` uses the cell size ``length / n`` at the far edges and a
    quarter of it on the hole (gmsh).
    """
    return Problem(
        "kirsch", E, nu, "stress",
        partial(kirsch_displacement, a=a, T=T, E=E, nu=nu, plane="stress"),
        partial(kirsch_stress, a=a, T=T),
        lambda n: gmsh_plate_with_hole(a, length, length / n, kind=kind,
                                       h_hole=length / n / 4),
    )


def rigid_motion_dofs(x):
    """Three dofs that fix the rigid motions of a 2D body with nodes ``x``.

    Both components at the node nearest the lower-left corner of the
    bounding box, and at the node farthest from it the component
    perpendicular to the line joining the two.
    """
    a = int(np.argmin(np.sum((x - x.min(axis=1, keepdims=True)) ** 2, axis=0)))
    b = int(np.argmax(np.sum((x - x[:, [a]]) ** 2, axis=0)))
    direction = x[:, b] - x[:, a]
    perpendicular = 1 if abs(direction[0]) >= abs(direction[1]) else 0
    return np.array([2 * a, 2 * a + 1, 2 * b + perpendicular])


def cube_corner_dofs(mesh):
    """Six dofs that fix the rigid motions of a 3D body in the unit cube
    (dofs interleaved, 3 per particle): all three at the particle nearest
    (0, 0, 0), y and z at the one nearest (1, 0, 0), z at the one nearest
    (0, 1, 0)."""
    corner = [int(np.argmin(np.linalg.norm(mesh.p - np.array(q)[:, None], axis=0)))
              for q in ((0, 0, 0), (1, 0, 0), (0, 1, 0))]
    return np.r_[3 * corner[0] + np.arange(3), 3 * corner[1] + 1, 3 * corner[1] + 2,
                 3 * corner[2] + 2]


def solve_problem(problem, basis):
    """Solve ``problem`` on ``basis``; return (coefficients, l2 error, energy error).

    The L² error is measured modulo rigid motions (see :func:`error_norms`).
    """
    lam, mu = lame(problem.E, problem.nu, problem.plane)
    K = Assembler(basis).bilinear(isotropic_tangent(lam, mu, 2))

    @LinearForm
    def traction(v, w):
        sig = stress_from_voigt(problem.stress(np.asarray(w.x)))
        return dot(np.einsum("ij...,j...->i...", sig, w.n), v)

    f = asm(traction, facet_basis(basis))
    nodes = basis.doflocs[:, ::2]
    D = rigid_motion_dofs(nodes)
    values = problem.displacement(nodes).T.ravel()[D]
    d = solve(K, f, basis, D=D, x=values)
    l2, energy = error_norms(basis, d, problem.displacement, problem.stress,
                             problem.E, problem.nu, problem.plane,
                             modulo_rigid=True)
    return d, l2, energy


def convergence_study(problem, methods, levels, repeat=1):
    """Solve ``problem`` with every method on every refinement level.

    Parameters
    ----------
    problem : Problem
    methods : dict
        ``{label: mesh -> basis}``.
    levels : sequence of int
        Refinement levels passed to ``problem.mesh``.
    repeat : int
        Time each run this many times and keep the fastest.

    Returns
    -------
    list of dict
        One record per run: ``method``, ``level``, ``dofs``, ``h`` (largest
        cell diameter), ``l2``, ``energy`` and ``seconds`` (basis, assembly
        and solve).
    """
    records = []
    for level in levels:
        mesh = problem.mesh(level)
        for label, make in methods.items():
            seconds = np.inf
            for _ in range(repeat):
                start = time.perf_counter()
                basis = make(mesh)
                _, l2, energy = solve_problem(problem, basis)
                seconds = min(seconds, time.perf_counter() - start)
            records.append(dict(method=label, level=level, dofs=basis.N,
                                h=_largest_cell(mesh), l2=l2, energy=energy,
                                seconds=seconds))
    return records


def _largest_cell(mesh):
    p = mesh.p[:, mesh.t]
    diameters = np.max(np.linalg.norm(p[:, :, None] - p[:, None, :], axis=0),
                       axis=(0, 1))
    return float(diameters.max())


def rates(records, method, key):
    """Observed convergence orders of ``key`` in ``h`` between successive levels."""
    rows = [r for r in records if r["method"] == method]
    return [np.log(a[key] / b[key]) / np.log(a["h"] / b["h"])
            for a, b in zip(rows[:-1], rows[1:])]
