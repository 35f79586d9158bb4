"""Moved to :mod:`skfem_rkpm.mechanics.tools`, :mod:`.slave_points`, :mod:`.friction`,
:mod:`.rigid_contact` and :mod:`.deformable_contact` (this path goes in the next release)."""

from .._moved import forward

__getattr__, __all__ = forward(__name__, "skfem_rkpm.mechanics.tools",
                               "skfem_rkpm.mechanics.slave_points",
                               "skfem_rkpm.mechanics.friction",
                               "skfem_rkpm.mechanics.rigid_contact",
                               "skfem_rkpm.mechanics.deformable_contact",
                               "skfem_rkpm.runs.build",
                               renamed={"from_scene": "tool_from_scene"})
