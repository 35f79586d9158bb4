"""Old module paths of the flat layout, kept for one release.

Each old module (``skfem_rkpm.basis``, ``skfem_rkpm.linsolve``, ...) is a
two-line file that calls :func:`forward`: importing it warns with a
:class:`DeprecationWarning` naming the new path and hands every attribute
over to the new module, so user scripts keep working unchanged.
"""

import importlib
import warnings


def forward(old, *new, renamed=None):
    """``(__getattr__, __all__)`` for the module ``old`` whose names moved to
    the modules ``new`` (looked up in that order); ``renamed`` maps old names
    to their new ones."""
    renamed = renamed or {}
    warnings.warn(f"{old} moved to {' and '.join(new)}: import from there ({old} goes "
                  f"in the next release)", DeprecationWarning, stacklevel=3)
    modules = [importlib.import_module(name) for name in new]

    def __getattr__(name):
        name = renamed.get(name, name)
        for module in modules:
            if hasattr(module, name):
                return getattr(module, name)
        raise AttributeError(f"module {old!r} has no attribute {name!r}")

    return __getattr__, [n for module in modules for n in getattr(module, "__all__", ())]
