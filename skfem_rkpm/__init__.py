"""skfem-rkpm: the Lagrangian reproducing kernel particle method on scikit-fem."""

from .assembly import Assembler, isotropic_tangent, layout
from .forms import CorrectedTrialWarning, SlowAssemblyWarning, asm
from .approximation.basis import RKBasis, RKFacetBasis
from .approximation.basis_views import BasisIdiomError, CoefficientsNotNodalError
from .approximation.interior_facet_basis import RKInteriorFacetBasis
from .approximation.constraints import transformation
from .solvers.constrained import linear_solve, solve
from .solvers.idioms import (PartialSolutionWarning, coefficients, condense, eigen, enforce,
                             penalize)
from .approximation.kernels import cubic_spline, quartic_spline
from .meshes import local_spacing
from .approximation.shape import ShapeTable, SingularMomentError, rk_shape_functions
from .indicators import ZeroJumpWarning, recovery_indicator
from .material_interfaces import MaterialInterfaceWarning

__version__ = "0.1.0"

__all__ = [
    "Assembler",
    "BasisIdiomError",
    "CoefficientsNotNodalError",
    "CorrectedTrialWarning",
    "MaterialInterfaceWarning",
    "PartialSolutionWarning",
    "RKBasis",
    "RKFacetBasis",
    "RKInteriorFacetBasis",
    "ShapeTable",
    "SingularMomentError",
    "SlowAssemblyWarning",
    "ZeroJumpWarning",
    "asm",
    "coefficients",
    "condense",
    "cubic_spline",
    "eigen",
    "enforce",
    "isotropic_tangent",
    "layout",
    "linear_solve",
    "local_spacing",
    "penalize",
    "recovery_indicator",
    "quartic_spline",
    "rk_shape_functions",
    "solve",
    "transformation",
]
