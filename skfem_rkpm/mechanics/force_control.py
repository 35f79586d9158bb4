"""Force-driven rigid tools: the tool moves so that its reaction follows a
prescribed force history (a blank holder at constant force).

The tool's position along a fixed direction ``e`` is an extra unknown
``s`` with the extra equation ``R(d, s) = F(t)``, ``R = e · F_tool`` the
force of the tool on the body along ``e``.  Newton's bordered system

    [ K_b + K_c    ∂f/∂s ] [δd]   [ r     ]
    [ ∂R/∂d        ∂R/∂s ] [δs] = [ F - R ]

is solved by eliminating ``s`` exactly: at every evaluation ``s`` solves
the scalar equation ``R(d, s) = F(t)`` for the given ``d`` (the contact
force is monotone in ``s``), and the tangent is the Schur complement

    K = K_c - (K_c T)(Tᵀ K_c) / (Tᵀ K_c T),

where ``T`` is the coefficient vector of the uniform displacement ``e``
(the RK and FEM bases reproduce constants, so ``T`` tiles ``e`` over the
nodes): the contact force depends on ``x - s e``, hence ``∂f/∂s = -K_c T``,
``R = -Tᵀ f`` and ``∂R/∂s = Tᵀ K_c T``.  The result is the same Newton
iteration as with ``s`` in the unknowns, with the solver and the step
controller left as they are.
"""

from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse as sp

from .friction import ContactState
from .loads import History
from .rigid_contact import RigidContact

__all__ = ["ForceDrivenContact", "DrivenContactState"]


@dataclass
class DrivenContactState(ContactState):
    """The contact state of a force-driven tool and its ``travel`` along
    its direction (plain arrays, for checkpoints)."""

    travel: np.ndarray = 0.0


class ForceDrivenContact:
    """A :class:`RigidContact` (or 3D
    :class:`~skfem_rkpm.mechanics.surface_contact.SurfaceContact`) whose tool
    is driven by a force history.

    Parameters
    ----------
    contact : RigidContact or SurfaceContact
        The tool and its contact; the tool's own ``motion`` is added to
        the force-driven travel (usually zero).
    direction : array_like (2,) or (3,)
        Direction ``e`` of the travel (normalized here); the force is the
        tool's push on the body along ``e``.
    force : float or table
        ``F(t)`` as a :class:`~skfem_rkpm.mechanics.loads.History` (a
        number: reached linearly); must not be negative (a tool can only
        push).
    reach : float
        Largest travel searched for, in length units (default: 10 × the
        span of the slave points).
    """

    def __init__(self, contact, direction, force, reach=None):
        if not isinstance(contact, RigidContact):
            raise TypeError("contact must be a RigidContact")
        dim = contact.points.dim
        e = np.asarray(direction, dtype=float)
        if e.shape != (dim,) or not np.all(np.isfinite(e)) or not np.linalg.norm(e) > 0:
            raise ValueError(f"tool {contact.name!r}: the force direction must be a "
                             f"non-zero vector of {dim} components, not {direction!r}")
        self.contact, self.name = contact, contact.name
        self.e = e / np.linalg.norm(e)
        self.history = History(force, f"tool {contact.name!r} force")
        if np.min(self.history.values) < 0:
            raise ValueError(f"tool {contact.name!r}: a force history must not be "
                             "negative (a tool can only push)")
        self.T = np.tile(self.e, contact.problem.basis.N // dim)
        span = np.ptp(contact.points.X, axis=1).max()
        self.reach = 10.0 * span if reach is None else float(reach)
        self.s = self.s_trial = 0.0
        base = contact.tool.motion
        contact.tool.motion = lambda t: np.asarray(base(t), float) + self.s_trial * self.e

    def _push(self, d, t, s):
        """Contact force, tangent and the push ``R`` with the tool at ``s``."""
        self.s_trial = s
        f, K = self.contact.evaluate(d, t)
        return f, K, -self.T @ f

    def _travel(self, d, t, target):
        """The travel ``s`` at which the push equals ``target``."""
        f, K, push = self._push(d, t, self.s)
        if abs(push - target) <= 1e-12 * max(target, 1e-300):
            return self.s
        lo, hi = self.s, self.s
        step = max(1e-6 * self.reach, abs(self.s) * 1e-3)
        if push < target:  # advance until the push exceeds the target
            while push < target:
                lo, hi = hi, hi + step
                if hi - self.s > self.reach:
                    raise RuntimeError(
                        f"tool {self.name!r}: no travel up to {self.reach:g} along "
                        f"{self.e.tolist()} pushes with {target:g}; check the "
                        "direction and the slave boundaries")
                push = self._push(d, t, hi)[2]
                step *= 2.0
        else:  # retreat until the push falls below the target
            while push > target:
                hi, lo = lo, lo - step
                push = self._push(d, t, lo)[2]
                step *= 2.0
            if target == 0.0:
                return lo  # apart: any travel without contact will do
        from scipy.optimize import brentq  # 0.2 s to import: only force-driven runs need it

        return brentq(lambda s: self._push(d, t, s)[2] - target, lo, hi,
                      xtol=1e-14 * max(abs(lo), abs(hi), self.reach * 1e-6), rtol=1e-15)

    def evaluate(self, d, t):
        """Contact force and the tangent with the travel eliminated, with
        the tool where its push equals ``F(t)``."""
        target = self.history(t)
        s = self._travel(d, t, target)
        f, K, _ = self._push(d, t, s)
        KT = K @ self.T
        TK = K.T @ self.T
        stiffness = self.T @ KT
        if stiffness > 0:
            a, b = sp.csr_matrix(KT), sp.csr_matrix(TK)
            K = (K - (a.T @ b) / stiffness).tocsr()
        return f, K

    #: hooks of the wrapped contact that Newton calls when they exist
    #: (augmented Lagrangian enforcement, contact status counts)
    FORWARDED = ("touching", "restart", "augment", "violation", "status_changes", "tool",
                 "points", "watch_status", "review_status")

    def __getattr__(self, name):
        if name in ForceDrivenContact.FORWARDED:
            return getattr(self.contact, name)
        raise AttributeError(name)

    def commit(self):
        self.s = self.s_trial
        self.contact.commit()

    def resultants(self):
        return self.contact.resultants()

    def gauges(self, t):
        out = self.contact.gauges(t)
        out[f"{self.name} travel"] = float(self.s)
        return out

    def get_state(self):
        """The committed contact state with the committed travel."""
        state = self.contact.get_state()
        return DrivenContactState(**{f.name: getattr(state, f.name)
                                     for f in fields(ContactState)},
                                  travel=np.float64(self.s))

    def set_state(self, state):
        """Restore a state returned by :meth:`get_state`."""
        self.contact.set_state(ContactState(**{f.name: getattr(state, f.name)
                                               for f in fields(ContactState)}))
        self.s = self.s_trial = float(state.travel)
