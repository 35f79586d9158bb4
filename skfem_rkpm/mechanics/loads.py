"""Boundary loads and their histories in the load factor ``t``.

:class:`History` is a value as a function of ``t`` (0 → 1): a number
reached linearly, or a table of ``(t, value)`` pairs.  :class:`Traction`
(a force per unit reference length, or area for the full ring of an
axisymmetric model) and :class:`Pressure` (normal, on the reference
boundary) are dead loads: they act on the reference boundary with the
reference normal, whatever the deformation.  :class:`BoundaryLoads`
assembles them once and gives ``t -> f_ext`` for
:func:`skfem_rkpm.solvers.newton.newton_steps`.  :class:`FollowerPressure`
acts on the current boundary instead; its force depends on the
displacement, so it enters Newton as a contribution with its tangent.
"""

from dataclasses import dataclass

import numpy as np
from skfem import BilinearForm, LinearForm
from skfem.helpers import dot

from ..assembly import facet_basis
from ..forms import asm

__all__ = ["History", "Traction", "Pressure", "BoundaryLoads", "FollowerPressure"]


class History:
    """A value as a function of the load factor ``t``.

    Parameters
    ----------
    value : float or sequence of (t, value) pairs
        A number ``v``: ``v t`` (a linear ramp from 0 to ``v``).  A table
        ``[[t0, v0], [t1, v1], ...]`` with increasing ``t`` in [0, 1]:
        linear interpolation, constant beyond its first and last ``t``.
    name : str
        Named in error messages.
    """

    def __init__(self, value, name="value"):
        self.name = name
        if np.ndim(value) == 0:
            v = float(value)
            if not np.isfinite(v):
                raise ValueError(f"{name}: must be finite, not {value!r}")
            self.t, self.values = np.array([0.0, 1.0]), np.array([0.0, v])
            return
        table = np.asarray(value, dtype=float)
        if table.ndim != 2 or table.shape[1] != 2 or len(table) < 1:
            raise ValueError(f"{name}: give a number (reached linearly in t) or a table "
                             f"[[t, value], ...], not {value!r}")
        if not np.all(np.isfinite(table)):
            raise ValueError(f"{name}: the table must hold finite numbers")
        t = table[:, 0]
        if np.any(np.diff(t) <= 0) or t[0] < 0 or t[-1] > 1:
            raise ValueError(f"{name}: the load factors t of the table must increase "
                             f"within [0, 1], got {t.tolist()}")
        self.t, self.values = t, table[:, 1]

    def __call__(self, t):
        return float(np.interp(t, self.t, self.values))

    @property
    def final(self):
        """The value at ``t = 1``."""
        return self(1.0)


def _histories(values, ncomp, name):
    """One :class:`History` per component (``None``: no load) from a vector
    ``[v_x, v_y]`` or a dict ``{component: value or table}``."""
    out = [None] * ncomp
    if isinstance(values, dict):
        for comp, value in values.items():
            if not 0 <= comp < ncomp:
                raise ValueError(f"{name}: component {comp} out of range 0..{ncomp - 1}")
            out[comp] = History(value, f"{name}[{comp}]")
        return out
    values = list(values)
    if len(values) != ncomp:
        raise ValueError(f"{name}: needs {ncomp} components, got {len(values)}")
    return [History(v, f"{name}[{c}]") for c, v in enumerate(values)]


@dataclass
class Traction:
    """A dead traction on a named boundary (force per unit reference length;
    axisymmetric: per unit reference area of the full ring).

    ``values``: a vector (each component reached linearly in ``t``) or a
    dict ``{component: number or [[t, value], ...]}``.
    """

    boundary: str
    values: object


@dataclass
class Pressure:
    """A normal pressure on a named boundary (positive pushes inward), on
    the reference boundary: ``value`` a number (reached linearly in ``t``)
    or a table ``[[t, p], ...]``."""

    boundary: str
    value: object


def _weight(model, w):
    """The measure of the full ring (2π r) in an axisymmetric model, else 1."""
    return 2 * np.pi * w.x[0] if model == "axisymmetric" else 1.0


class BoundaryLoads:
    """``t -> f_ext`` of dead tractions and pressures on a basis.

    Each load component is assembled once (a unit vector times its
    :class:`History`), so a call costs a few vector additions.
    """

    def __init__(self, basis, loads, model="plane_strain"):
        self.N = basis.N
        self.parts = []  # (History, vector)
        ncomp = basis.mesh.dim()
        for load in loads:
            fb = facet_basis(basis, load.boundary)
            if isinstance(load, Pressure):

                @LinearForm
                def normal(v, w):
                    return -dot(w.n, v) * _weight(model, w)

                self.parts.append((History(load.value, f"{load.boundary} pressure"),
                                   asm(normal, fb)))
                continue
            for comp, history in enumerate(_histories(load.values, ncomp,
                                                      f"{load.boundary} traction")):
                if history is None:
                    continue

                @LinearForm
                def unit(v, w, comp=comp):
                    return v[comp] * _weight(model, w)

                self.parts.append((history, asm(unit, fb)))

    def __call__(self, t):
        f = np.zeros(self.N)
        for history, vector in self.parts:
            f += history(t) * vector
        return f


def _apply(A, b):
    """``A b`` per point: A (2, 2, ...) and b (2, ...)."""
    return np.einsum("ij...,j...->i...", A, b)


class FollowerPressure:
    """A normal pressure on the current (deformed) boundary, for Newton.

    A pressure ``p`` on the current boundary exerts ``f = -∫ p n da``.  In
    2D, with the reference unit tangent ``t₀`` (the boundary run with the
    body on its left, so that ``n₀ = (t₀_y, -t₀_x)``), the current line
    element is ``dx = F t₀ ds`` and ``n da = (dx_y, -dx_x) ds``, linear in
    the displacement gradient; the axisymmetric ring adds the current
    circumference ``2π (X_r + u_r)``:

        f_ext(d) = -∫ p(t) v · (dx_y, -dx_x) w ds,   w = 1 or 2π (X_r + u_r),

    and its derivative in ``d`` is exact.  It is not symmetric: a follower
    load is not conservative in general.

    As a contribution of :func:`~skfem_rkpm.solvers.newton.newton_steps`
    (``evaluate(d, t) -> (f, K)`` is added to the internal force) it
    returns ``-f_ext`` and ``-∂f_ext/∂d``.

    Parameters
    ----------
    basis : RKBasis or skfem vector basis
    boundary : str
        Named boundary.
    value : float or table
        The pressure as a :class:`History` of the load factor.
    model : {"plane_strain", "axisymmetric"}
    """

    def __init__(self, basis, boundary, value, model="plane_strain"):
        if basis.mesh.dim() != 2:
            raise ValueError("a follower pressure needs a 2D model (plane strain or "
                             "axisymmetric)")
        self.boundary, self.model = boundary, model
        self.history = History(value, f"{boundary} pressure")
        self.fb = facet_basis(basis, boundary)

    def _forms(self, p):
        axisymmetric = self.model == "axisymmetric"

        def current(w):
            n0 = w.n
            t0 = np.array([-n0[1], n0[0]])
            dx = t0 + _apply(w.u.grad, t0)
            return t0, np.array([dx[1], -dx[0]])

        @LinearForm
        def force(v, w):
            _, nda = current(w)
            ring = 2 * np.pi * (w.x[0] + w.u[0]) if axisymmetric else 1.0
            return -p * dot(v, nda) * ring

        @BilinearForm
        def stiffness(du, v, w):
            t0, nda = current(w)
            ddx = _apply(du.grad, t0)
            dnda = np.array([ddx[1], -ddx[0]])
            if not axisymmetric:
                return -p * dot(v, dnda)
            ring = 2 * np.pi * (w.x[0] + w.u[0])
            return -p * (dot(v, dnda) * ring + dot(v, nda) * 2 * np.pi * du[0])

        return force, stiffness

    def evaluate(self, d, t):
        """``(-f_ext, -∂f_ext/∂d)`` at coefficients ``d`` and load factor ``t``."""
        force, stiffness = self._forms(self.history(t))
        u = self.fb.interpolate(d)
        return -asm(force, self.fb, u=u), -asm(stiffness, self.fb, u=u)

    def commit(self):
        """Nothing to keep: the load has no history of its own."""

    def resultants(self):
        return {}
