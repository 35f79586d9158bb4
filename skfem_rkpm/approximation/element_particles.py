"""Particles where a scikit-fem element has its dofs.

``RKBasis(mesh, element)`` reads what the user asked for from the element,
as ``Basis(mesh, element)`` does: its polynomial degree becomes the RK
order, and for a quadratic element its dof locations (vertices, edge and
face midpoints, cell interiors, as scikit-fem places them) become the
particles.  The particles are numbered as the scalar element's dofs, so
``N``, ``doflocs``, ``get_dofs`` and the nodal/facet/edge/interior dof
arrays of an interpolating basis line up with the FEM basis of the same
element (vector dofs are interleaved, ``ncomp * I + c``, in both).
"""

import re
from dataclasses import dataclass

import numpy as np
from skfem import Basis
from skfem.element import Element, ElementVector

from ..meshes import local_spacing

__all__ = ["scalar_element", "element_degree", "ElementParticles", "element_particles",
           "DEFAULT_SUPPORT", "DEFAULT_INTORDER"]

#: normalized support and Gauss degree of a basis of order 2 on the dof
#: locations of a quadratic element (Poisson on the unit square, P2: support
#: 2.5 with degree 6 was within 1.9x FEM's error, support 2 or degree 4 were
#: 3-22x; the spacing is that of the dofs, half the vertex spacing)
DEFAULT_SUPPORT = {1: 2.0, 2: 2.5}
DEFAULT_INTORDER = {1: 4, 2: 6}


def scalar_element(vector):
    """The scalar scikit-fem element in the second argument of RKBasis (an
    element or ``ElementVector`` of one), or None for a bool."""
    if isinstance(vector, ElementVector):
        return vector.elem
    return vector if isinstance(vector, Element) else None


def element_degree(element):
    """The RK order an element asks for: the degree of the complete
    polynomials it contains (1 for P1, Q1 and the MINI element, 2 for P2,
    Q2 and the serendipity S2; scikit-fem's ``maxdeg`` counts products such
    as Q1's ``xy``, so it is read only where the name carries no degree)."""
    name = type(element).__name__
    digits = re.search(r"(\d+)$", name)
    if "Mini" in name:
        degree = 1
    elif digits is not None:
        degree = int(digits.group(1))
    else:
        degree = int(getattr(element, "maxdeg", 1))
    if degree > 2:
        raise ValueError(
            f"{type(element).__name__} has degree {degree}; RK bases reproduce "
            "polynomials up to order 2: use an element of degree 1 or 2, or pass order=")
    return int(degree)


@dataclass
class ElementParticles:
    """The particles at an element's dofs and what lines them up with FEM."""

    nodes: np.ndarray      # (dim, ndofs) the scalar element's dof locations
    spacing: np.ndarray    # (ndofs,) the spacing of the dofs around each one
    fem: Basis             # the scalar FEM basis whose dofs they are

    def boundary(self, facets):
        """Particle numbers of the dofs on ``facets`` (FEM's ``get_dofs``)."""
        return np.unique(np.asarray(self.fem.get_dofs(facets).flatten()))

    def dof_array(self, name, ncomp):
        """scikit-fem's ``nodal_dofs``/``facet_dofs``/``edge_dofs``/
        ``interior_dofs`` of the vector basis, shape (ncomp * per-entity, n)."""
        scalar = np.asarray(getattr(self.fem, name), dtype=np.int64)
        return (ncomp * scalar[:, None, :] + np.arange(ncomp)[None, :, None]).reshape(
            ncomp * scalar.shape[0], scalar.shape[1])


def element_particles(mesh, element):
    """:class:`ElementParticles` of a quadratic element, or None where the
    particles are the mesh vertices (degree 1 on a linear mesh).

    Each dof gets the spacing of the cells around it, the mean spacing of
    their vertices over the degree, the smallest over those cells.
    """
    if element is None or element_degree(element) < 2:
        return None
    fem = Basis(mesh, element, intorder=1)
    degree = element_degree(element)
    vertex_spacing = local_spacing(mesh)
    cells = np.asarray(mesh.t)
    cell_spacing = vertex_spacing[cells].mean(axis=0) / degree
    spacing = np.full(fem.N, np.inf)
    dofs = fem.element_dofs
    np.minimum.at(spacing, dofs.ravel(),
                  np.broadcast_to(cell_spacing[None, :], dofs.shape).ravel())
    return ElementParticles(np.asarray(fem.doflocs, dtype=float), spacing, fem)


#: the defaults of an RK basis on a 1D mesh (MeshLine), where linear FEM is
#: nodally exact for Poisson problems (its Green's functions are piecewise
#: linear) and an order-1 RK basis is not: scikit-fem's ex15 (-u'' = 1 on 9
#: cells, P1) read u(4/9) 3.8e-4 off the exact 10/81 with order 1 (support
#: 2-3, intorder 4-8, VCI or Gauss), and 3.9e-6 with order 2, support 2.5
#: and Gauss of degree 12; 6.6e-8 with degree 20 (6.1e-7 at the worst vertex).  Order 2 reproduces the
#: quadratic solution, and the Gauss rule is trial and test basis at once
#: (``form.assemble(basis)``), which symmetric VCI is not at order 2.  11
#: points per cell cost nothing in 1D (docs/rk_basis.md, "1D").
LINE_DEFAULTS = {"order": 2, "support": 2.5, "intorder": 20, "integration": "gauss"}


def line_defaults(mesh, degree, order, support, intorder, integration):
    """``(order, support, intorder, integration)`` with the :data:`LINE_DEFAULTS`
    of a 1D mesh filled in where the caller gave None; unchanged (None stays
    None) on other meshes or when ``order``/``integration`` is given (the
    caller chose the scheme)."""
    if mesh.dim() != 1 or order is not None or integration is not None:
        return order, support, intorder, integration
    d = LINE_DEFAULTS
    return (max(degree, d["order"]), d["support"] if support is None else support,
            d["intorder"] if intorder is None else intorder, d["integration"])
