"""Moved to :mod:`skfem_rkpm.verification.elasticity` (this path goes in the next release)."""

from ._moved import forward

__getattr__, __all__ = forward(__name__, "skfem_rkpm.verification.elasticity")
