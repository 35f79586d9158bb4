"""Frozen contact statuses of grazing nodes within the Newton solves of a step.

The normal law of Eq. (4.5), ``t_n = ⟨λ_n - ω_n ĝ⟩``, switches a node between
open and closed where ``λ_n - ω_n ĝ`` changes sign.  Under exact stick
(``μ = ∞``, Eq. 4.6 without a cone) a node that grazes the tool has no
Newton iterate that settles: its stick shear appears the moment it touches
and pushes it off again, so the line search stops short of the touch point
(the gap shrinks by a fixed fraction per iteration and never closes) or,
when it is taken whole, the node toggles between touching and apart.

:class:`StatusFreeze` fixes the status of such a node for the rest of the
step's Newton solves: a node whose status flipped back and forth
(``flips`` changes between accepted iterates), or that the active-set
prediction of the update (``touching()``) brought into contact ``misses``
iterations in a row without the line search reaching the tool, is held
closed, i.e. bilaterally (its normal traction may turn tensile).  After
each converged solve :meth:`StatusFreeze.review` checks the frozen
statuses against the unilateral law: a frozen-closed node in tension, or a
frozen-open node that penetrates, beyond the tolerance, has its status
corrected and the step is solved again.

A node that contradicts the law in both statuses (closed it pulls, open it
penetrates: released, it loses the stick shear that held it and springs
back into the tool) has no consistent status under ``μ = ∞``.  The limit
``μ → ∞`` of Coulomb's law lets such a node slide at vanishing pressure;
it is therefore released to frictionless unilateral contact (sliding,
shear 0, ``t_n ≥ 0`` by Eq. 4.5) for the rest of the attempt.  The contact
reports the nodes that slide and the largest tension of a frozen node, so
that the departure from exact stick is measured.
"""

import numpy as np

__all__ = ["StatusFreeze"]

FREE, OPEN, CLOSED, SLIDING = -1, 0, 1, 2


class StatusFreeze:
    """Frozen open/closed statuses of contact nodes within one step attempt.

    Parameters
    ----------
    m : int
        Number of contact nodes.
    enabled : bool
        False: nothing is ever frozen (the penalty law and finite ``μ``
        keep their Newton path unchanged).
    flips : int
        Status changes between accepted Newton iterates after which a node
        is frozen closed.
    misses : int
        Consecutive iterations in which the update was predicted to bring
        a node into contact but the accepted iterate left it apart, after
        which it is frozen closed.
    """

    def __init__(self, m, enabled=True, flips=2, misses=3):
        self.m, self.enabled = int(m), bool(enabled)
        self.flips, self.misses = int(flips), int(misses)
        self.reset()

    def reset(self):
        """Forget every frozen status and count (a new step attempt)."""
        self.status = np.full(self.m, FREE, dtype=np.int8)
        self._flips = np.zeros(self.m, dtype=np.int64)
        self._misses = np.zeros(self.m, dtype=np.int64)
        self._last = None
        self._predicted = None

    @property
    def free(self):
        """Nodes under the contact law's own status."""
        return self.status == FREE

    @property
    def closed(self):
        """Nodes frozen closed (held on the tool bilaterally)."""
        return self.status == CLOSED

    @property
    def held(self):
        """Nodes whose open/closed status is frozen (not the law's)."""
        return (self.status == OPEN) | (self.status == CLOSED)

    @property
    def sliding(self):
        """Nodes released to slide without friction."""
        return self.status == SLIDING

    @property
    def count(self):
        """Number of frozen nodes."""
        return int(np.count_nonzero(self.status != FREE))

    def apply(self, active):
        """``active`` (the unilateral law's contact mask) with the frozen
        statuses in place of the law's."""
        return np.where(self.held, self.closed, active)

    def release(self, shear, slip):
        """The Coulomb law's ``shear`` (per node, scalars or vectors) and
        ``slip`` mask with the sliding nodes frictionless: shear 0, slip."""
        sliding = self.sliding
        if not sliding.any():
            return shear, slip
        rows = sliding.reshape((-1,) + (1,) * (np.ndim(shear) - 1))
        return np.where(rows, 0.0, shear), slip | sliding

    def predict(self, touching):
        """Record the nodes that the active-set prediction of the current
        update brings into contact (``touching()``)."""
        self._predicted = np.asarray(touching, bool)

    def observe(self, active):
        """Count status flips and missed predicted contacts at an accepted
        Newton iterate with contact mask ``active``; freeze the nodes that
        reach ``flips`` or ``misses`` closed.  Returns the number of nodes
        newly frozen."""
        if not self.enabled:
            return 0
        active = np.asarray(active, bool)
        free = self.free
        if self._last is not None:
            self._flips += free & (active != self._last)
        if self._predicted is not None:
            missed = free & self._predicted & ~active
            self._misses = np.where(missed, self._misses + 1, 0)
        self._last, self._predicted = active.copy(), None
        freeze = free & ((self._flips >= self.flips) | (self._misses >= self.misses))
        self.status[freeze] = CLOSED
        return int(np.count_nonzero(freeze))

    def review(self, gap, pressure, gap_tolerance, pressure_tolerance):
        """Correct the frozen statuses that contradict the unilateral law
        at a converged solve: closed with ``pressure < -pressure_tolerance``
        (tension) becomes open, open with ``gap < -gap_tolerance``
        (penetration) slides (frictionless unilateral contact; it was closed
        and pulled before, since nodes are only frozen closed).  A sliding node
        is not changed again.  Returns the mask of the nodes changed (the
        step must be solved again if any)."""
        tension = (self.status == CLOSED) & (pressure < -pressure_tolerance)
        penetration = (self.status == OPEN) & (gap < -gap_tolerance)
        self.status[tension] = OPEN
        self.status[penetration] = SLIDING
        return tension | penetration
