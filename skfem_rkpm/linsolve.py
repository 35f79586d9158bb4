"""Moved to :mod:`skfem_rkpm.solvers.linear` and :mod:`skfem_rkpm.solvers.backend` and :mod:`skfem_rkpm.solvers.constrained` (this path goes in the next release)."""

from ._moved import forward

__getattr__, __all__ = forward(__name__, "skfem_rkpm.solvers.linear", "skfem_rkpm.solvers.backend", "skfem_rkpm.solvers.constrained")
