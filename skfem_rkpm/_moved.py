"""Old module paths of the flat layout, kept for one release.

Each old module (``skfem_rkpm.basis``, ``skfem_rkpm.linsolve``, ...) is a
two-line file that calls :func:`forward`: importing it warns with a
:class:`DeprecationWarning` naming the new path and hands every attribute
over to the new module, so user scripts keep working unchanged.
"""

import importlib
import warnings


def forward(old, new):
    """``(__getattr__, __all__)`` for the module ``old`` that moved to ``new``."""
    warnings.warn(f"{old} moved to {new}: import from there ({old} goes in the next "
                  f"release)", DeprecationWarning, stacklevel=3)
    module = importlib.import_module(new)

    def __getattr__(name):
        return getattr(module, name)

    return __getattr__, list(getattr(module, "__all__", ()))
