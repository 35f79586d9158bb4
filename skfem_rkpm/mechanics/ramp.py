"""A tool motion that starts smoothly: the speed rises from zero, then stays.

A tool driven at constant speed from ``t = 0`` starts with a jump of its
velocity.  In a dynamic run that jump sends an elastic wave of stress
``ρ c v`` into the body and, under the trapezoidal rule, leaves an
undamped oscillation of period ``2 Δt`` in the velocities of the nodes in
contact (``v_1 = 2 v``, ``v_2 = 0``, ...): the inertia force of it,
about ``m v / Δt``, grows as the step shrinks.  :class:`SmoothStart`
removes the jump: over the first fraction ``ramp`` of the run the speed
follows the smooth step ``3τ² − 2τ³`` of ``τ = t / ramp`` from zero to its
final value (the acceleration is continuous, zero at both ends of the
ramp), then stays constant; the tool still reaches its whole motion at
``t = 1``.  The fraction of the motion travelled is

    s(t) = V ramp (τ³ − τ⁴/2)      for t < ramp,
    s(t) = V (t − ramp/2)           after it,

with the constant speed ``V = 1 / (1 − ramp/2)``.
"""

import numpy as np

__all__ = ["SmoothStart", "ramped"]


class SmoothStart:
    """``t -> s``: the fraction of a tool's motion travelled at load factor
    ``t`` (in dynamic runs ``t = time / duration``) with a smooth start over
    the first ``ramp`` of the run; ``ramp = 0`` is ``s = t``."""

    def __init__(self, ramp):
        ramp = float(ramp)
        if not 0.0 <= ramp <= 1.0:
            raise ValueError(f"ramp must be a fraction of the run in [0, 1], not {ramp!r}")
        self.ramp = ramp
        self.speed = 1.0 / (1.0 - 0.5 * ramp)

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        r, V = self.ramp, self.speed
        if r == 0.0:
            return t
        tau = np.clip(t / r, 0.0, 1.0)
        return np.where(t < r, V * r * (tau ** 3 - 0.5 * tau ** 4), V * (t - 0.5 * r))

    def rate(self, t):
        """``ds/dt``: the speed as a fraction of the motion per unit ``t``."""
        t = np.asarray(t, dtype=float)
        if self.ramp == 0.0:
            return np.ones_like(t)
        tau = np.clip(t / self.ramp, 0.0, 1.0)
        return self.speed * (3 * tau ** 2 - 2 * tau ** 3)


def ramped(final, ramp):
    """``t -> s(t) · final``: the motion ``final`` (a displacement vector)
    travelled with a :class:`SmoothStart` of ``ramp``."""
    final = np.asarray(final, dtype=float)
    profile = SmoothStart(ramp)
    return lambda t: float(profile(t)) * final
