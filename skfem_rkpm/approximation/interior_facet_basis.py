"""The particles of an RK basis seen from interior facets.

scikit-fem's ``InteriorFacetBasis(mesh, elem, side=0|1)`` evaluates the
functions of the cell on either side of every interior facet, for jump
terms (error estimators, interior penalty and DG methods).  RK functions
are continuous across facets (as smooth as the kernel), so both sides give
the same values and gradients; ``side`` matters for what the basis is mixed
with: ``with_element(elem)`` is the FEM ``InteriorFacetBasis`` of that side
on the same facets and quadrature points, and ``w.n`` is scikit-fem's
normal of the facet (the outward normal of side 0, on both sides).
Interpolating a field here warns (:class:`~skfem_rkpm.indicators.ZeroJumpWarning`,
once per basis): its jumps are zero, and an error indicator built on them
reads nothing; :func:`skfem_rkpm.recovery_indicator` works on RK fields.
"""

import warnings

from skfem import InteriorFacetBasis

from .basis import RKFacetBasis
from .basis_views import BasisIdiomError
from .integration import _lagrange_element
from ..indicators import ZERO_JUMP_MESSAGE, ZeroJumpWarning

__all__ = ["RKInteriorFacetBasis"]


class RKInteriorFacetBasis(RKFacetBasis):
    """RK functions of a cell basis at the quadrature points of interior facets.

    Parameters
    ----------
    basis : RKBasis
        The cell basis whose particles and supports are used.
    facets : optional
        Interior facets (indices or anything ``mesh.normalize_facets``
        takes); default all facets with a cell on both sides.
    side : {0, 1}
        The cell of each facet the basis belongs to (``w.n`` points out of
        side 0), as in scikit-fem.
    intorder : int, optional
        Quadrature degree on the facets; default that of ``basis``.
    """

    def __init__(self, basis, facets=None, side=0, intorder=None):
        if side not in (0, 1):
            raise ValueError(f"side must be 0 or 1 (the cell on either side of a "
                             f"facet), not {side!r}")
        self.parent = basis
        self.side = side
        mesh = basis.mesh
        if facets is not None:
            facets = mesh.normalize_facets(facets)
            outer = facets[mesh.f2t[1, facets] < 0]
            if outer.size:
                raise ValueError(f"facet {outer[0]} ({outer.size} in all) is on the "
                                 "boundary: it has a cell on one side only; give "
                                 "interior facets, or use basis.boundary(facets)")
        geometry = InteriorFacetBasis(mesh, _lagrange_element(mesh), facets=facets,
                                      side=side, intorder=basis.intorder
                                      if intorder is None else intorder)
        table = basis._shape_table(geometry.global_coordinates().reshape(mesh.dim(), -1))
        self.radius = basis.radius
        self._setup(mesh, geometry, table, basis.nodes, basis.vector, release=True)

    def interpolate(self, w):
        """The field on the facets, as on a cell basis; warns once
        (:class:`~skfem_rkpm.indicators.ZeroJumpWarning`) that both sides
        give the same values and gradients."""
        if not getattr(self, "_jump_warned", False):
            self._jump_warned = True
            warnings.warn(ZERO_JUMP_MESSAGE, ZeroJumpWarning, stacklevel=2)
        return super().interpolate(w)

    def with_element(self, elem):
        """The FEM ``InteriorFacetBasis`` of ``elem`` on the same side, facets
        and quadrature points, for mixed RK x FEM jump terms."""
        return InteriorFacetBasis(self.mesh, elem, mapping=self.mapping,
                                  quadrature=self.quadrature, facets=self.find,
                                  side=self.side)

    def boundary(self, *args, **kwargs):
        raise BasisIdiomError("an interior facet basis has no boundary; take it "
                              "from the cell basis, basis.boundary(facets)")
