"""Which backend builds the RK shape functions: numpy or the compiled kernel.

:func:`~skfem_rkpm.approximation.shape.rk_shape_functions` takes
``backend`` ("auto", "numpy", "numba"), or the environment variable
``SKFEM_RKPM_SHAPE_BACKEND``; "auto" loads the compiled kernel
(:mod:`skfem_rkpm.approximation._shape_numba`, needs numba) for large calls
only, and uses it for every call once loaded.
"""

import importlib
import os

from .kernels import KERNELS

__all__ = ["BackendUnavailableError", "compiled_backend", "kernel_name"]

#: environment variable with the default backend ("auto", "numpy", "numba")
BACKEND_VARIABLE = "SKFEM_RKPM_SHAPE_BACKEND"
#: "auto" loads the compiled kernel only for a call with at least this many
#: evaluation points: loading numba and the cached machine code takes
#: 0.3-0.4 s of CPU, which the compiled kernel saves back (1-3 µs per point)
#: on about this many points (docs/benchmarks/shape_and_assembly.md,
#: "Compiled kernel (optional)"); once loaded, it is used for every call
AUTO_MIN_POINTS = 200_000


class BackendUnavailableError(ImportError):
    """The requested shape-function backend cannot be imported."""


def _load_compiled():
    """The compiled kernel module; ImportError if numba is missing."""
    return importlib.import_module("skfem_rkpm.approximation._shape_numba")


#: the compiled kernel once a call has used it (then "auto" uses it always)
_loaded = None


def compiled_backend(backend, window, dim, npoints):
    """The compiled kernel module if ``backend`` selects it, else None."""
    global _loaded
    if backend is None:
        backend = os.environ.get(BACKEND_VARIABLE, "").strip() or "auto"
    if backend not in ("auto", "numpy", "numba"):
        raise ValueError(f"backend must be 'auto', 'numpy' or 'numba', not "
                         f"{backend!r} (from the argument or {BACKEND_VARIABLE})")
    if backend == "numpy":
        return None
    covered = 1 <= dim <= 3 and kernel_name(window) is not None
    if backend == "numba":
        try:
            module = _load_compiled()
        except ImportError as err:
            raise BackendUnavailableError(
                "the 'numba' backend of rk_shape_functions needs numba: "
                "pip install skfem-rkpm[fast] (or pip install numba), or use "
                f"backend='numpy' ({err})") from err
        if not covered:
            raise ValueError(
                f"the 'numba' backend covers the kernels {sorted(KERNELS)} in 1 to "
                f"3 dimensions, not kernel {window!r} in {dim}D; use "
                "backend='numpy' or 'auto'")
        _loaded = module
        return module
    if not covered:
        return None
    if _loaded is None and npoints >= AUTO_MIN_POINTS:
        try:
            _loaded = _load_compiled()
        except ImportError:
            _loaded = False  # numba is not installed: numpy from now on
    return _loaded or None


def kernel_name(window):
    """Name of a built-in kernel function, None for any other callable."""
    for name, function in KERNELS.items():
        if window is function:
            return name
    return None
