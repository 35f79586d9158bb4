"""Moved to :mod:`skfem_rkpm.approximation.constraints` and :mod:`skfem_rkpm.solvers.constrained` (this path goes in the next release)."""

from ._moved import forward

__getattr__, __all__ = forward(__name__, "skfem_rkpm.approximation.constraints", "skfem_rkpm.solvers.constrained")
