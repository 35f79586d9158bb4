"""``basis.elem`` of an RK basis: the element it was built from, guarded.

scikit-fem scripts read ``basis.elem`` to build another basis of "the same
element", most often the same basis on a subdomain (scikit-fem's ex17 and
ex26: ``Basis(mesh, basis.elem, elements=mesh.subdomains['core'])``).  On an
RK basis that call would quietly build an FEM basis, whose dofs are not the
RK coefficients (a load vector of FEM functions beside an RK matrix).  So
``RKBasis.elem`` is the element given to ``RKBasis`` (or the lowest-order
Lagrange element of the mesh, as a vector element for a vector basis), with
every attribute of the element, but building an FEM basis from it raises a
:class:`~.idiom_errors.BasisIdiomError` that names the RK call:
``rk.with_elements(elements)`` for the RK functions on some cells, and
``rk.with_element(rk.elem)`` for an FEM basis of the element on the RK
basis's cells and quadrature (which unwraps the guard).
"""

import copy

from skfem.element import ElementVector

from .idiom_errors import BasisIdiomError

__all__ = ["guarded_element", "plain_element"]

_GUARDS = {}

MESSAGE = (
    "Basis(mesh, rk.elem, ...) would build an FEM basis of {name}, whose dofs are not "
    "the coefficients of the RK basis rk.elem came from; for the RK functions on some "
    "cells (scikit-fem's Basis(mesh, basis.elem, elements=E)) use "
    "rk.with_elements(E); for an FEM basis of this element on the RK basis's cells and "
    "quadrature, rk.with_element(rk.elem)")


def _refuse(self, *args, **kwargs):
    raise BasisIdiomError(MESSAGE.format(name=type(self).__name__))


def _guard_class(cls):
    if cls not in _GUARDS:
        _GUARDS[cls] = type(cls.__name__, (cls,), {
            "gbasis": _refuse, "_rk_guard": True, "__module__": __name__,
            "__doc__": f"{cls.__name__} read from an RK basis (see {__name__})."})
    return _GUARDS[cls]


def guarded_element(element):
    """A copy of ``element`` whose ``gbasis`` (what an FEM basis calls to
    build its functions) raises; an ``ElementVector`` keeps its guarded
    scalar element inside, so that ``ElementVector(rk.elem)`` is refused too."""
    guarded = copy.copy(element)
    if isinstance(element, ElementVector):
        guarded.elem = guarded_element(element.elem)
    guarded.__class__ = _guard_class(type(element))
    return guarded


def plain_element(element):
    """``element`` without the guard (itself if it has none)."""
    if not getattr(element, "_rk_guard", False):
        return element
    plain = copy.copy(element)
    plain.__class__ = type(element).__mro__[1]
    if isinstance(plain, ElementVector):
        plain.elem = plain_element(plain.elem)
    return plain
