"""Closed-form solutions (:mod:`.exact`), the small-strain elasticity driver
(:mod:`.elasticity`) and convergence studies (:mod:`.studies`).

The names of :mod:`.studies` are importable from here, as they were from the
former module ``skfem_rkpm.verification``.
"""

from .studies import (Problem, convergence_study, plate_with_hole, rates,
                      rigid_motion_dofs, solve_problem, timoshenko_beam)

__all__ = ["Problem", "timoshenko_beam", "plate_with_hole", "solve_problem",
           "rigid_motion_dofs", "convergence_study", "rates"]
