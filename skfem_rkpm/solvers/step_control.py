"""Load-step size control: cut on failure, grow again when steps come easily.

A failed attempt halves the size of the load step.  After a converged step
the size grows with the Newton iterations ``n`` it took (Crisfield's rule):
by ``sqrt(n_target / n)``, at most by ``growth``, never beyond ``max_step``
and only after ``patience`` steps in a row converged without a cut-back.
Steps that take more than ``n_target`` iterations do not shrink the next
one: only a failure does.  The size is
remembered from step to step, so that a run that needed small steps at a
hard stage does not try the full step (and fail) again at every step after
it.  While the contact status of more than ``max_changes`` nodes changes in
a step (nodes touching, leaving, starting or stopping to slip), the step does
not grow: those are the steps whose Newton iterations are the least
predictable.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["StepControl"]


@dataclass
class StepControl:
    """The size of the next load step.

    Parameters
    ----------
    max_step : float
        Largest step of the load factor (default in :func:`newton_steps`:
        the spacing of its targets, so that a run without difficulties takes
        exactly the steps asked for).
    min_step : float
        Smallest step; a failure below it ends the run.
    target_iterations : int
        Newton iterations per step that the size aims at.
    growth : float
        Largest factor between two consecutive step sizes.
    max_changes : int
        A step that changes the contact status of more nodes does not grow.
    patience : int
        Steps in a row without a cut-back before the size grows again.
    """

    max_step: float
    min_step: float
    target_iterations: int = 6
    growth: float = 2.0
    max_changes: int = 2
    patience: int = 3
    size: float = None
    streak: int = 0

    def __post_init__(self):
        if not 0 < self.min_step <= self.max_step:
            raise ValueError(f"need 0 < min_step <= max_step, not {self.min_step:g} and "
                             f"{self.max_step:g}")
        if self.size is None:
            self.size = self.max_step

    def next(self, t_done, target):
        """The step to take from ``t_done`` toward ``target``: the remaining
        part split into equal steps no larger than the current size."""
        remaining = target - t_done
        count = np.ceil(remaining / min(self.size, self.max_step) * (1 - 1e-9))
        return remaining / max(count, 1.0)

    def failed(self, dt):
        """Halve after a failed attempt of size ``dt``; False once below ``min_step``."""
        self.size = 0.5 * dt
        return self.size >= self.min_step * (1 - 1e-12)

    def converged(self, dt, iterations, changes=0, cut=False):
        """Adapt after a converged step of size ``dt`` (``cut``: it needed a cut-back)."""
        self.streak = 0 if cut else self.streak + 1
        factor = np.sqrt(self.target_iterations / max(iterations, 1))
        factor = min(max(factor, 1.0), self.growth)
        if self.streak < self.patience or changes > self.max_changes:
            factor = 1.0
        # a step shortened to land on a target leaves the size as it was
        self.size = min(max(dt, self.size) * factor, self.max_step)
