"""Material interfaces meet smooth RK functions: say so.

RK shape functions are smooth across cell edges.  The solution of a problem
with a coefficient that jumps (two materials) has a kink along the
interface, which FEM functions follow along the edges of the cells and RK
functions cannot: the error then converges as ``h`` instead of ``h²``.
Measured on scikit-fem's published examples with the swap
``RKBasis(mesh, element, interpolating=True)``: ex17 (insulated wire,
conductivities 101 and 11, Q1 on a disk of 289 and 1089 vertices) T(0)
errors 6x and 11x FEM's; ex35 (coaxial cable, subdomain matrices with
permittivities 2.1 ε₀ and ε₀, P1) the capacitance 12x and 26x FEM's
(tests/test_published_examples.py, docs/rk_basis.md).  Supports cut at the
interfaces, ``RKBasis(..., interfaces=True)`` (the visibility criterion,
:mod:`skfem_rkpm.approximation.visibility`), bring them to 0.7x FEM's (ex17)
and 1.8-1.9x (ex35's capacitance), second order again.

:func:`check_interfaces` warns with :class:`MaterialInterfaceWarning` when
a form on an RK basis meets

- a coefficient (a ``DiscreteField`` in the form's keyword arguments, e.g.
  ``basis0.interpolate(conductivity)`` of a P0 field) whose cell values jump
  across interior facets while varying little inside the cells, or
- a bilinear form integrated over part of the cells (``with_elements``,
  ``RKBasis(..., elements=...)``), the way matrices of subdomains with
  different coefficients are summed.

unless the basis cuts its supports there already (``interfaces=``: the jumps
lie between its regions, the part is a union of them).  The warning names
what to do: supports cut at the interfaces, or an FEM basis.
"""

import warnings

import numpy as np
from skfem.element import DiscreteField

__all__ = ["MaterialInterfaceWarning", "check_interfaces", "jumping_coefficients",
           "JUMP_FACTOR", "advice"]

#: a coefficient jumps where the difference of its means in two neighbouring
#: cells exceeds this many times its variation inside them (a smooth field
#: differs by about its variation inside a cell; a P0 field does not vary)
JUMP_FACTOR = 10.0

def advice(basis):
    """What to do, for the mesh of ``basis``: ``interfaces=True`` if it has
    subdomains, else the cells of each material."""
    mesh = basis.mesh
    cut = ("interfaces=True" if mesh.subdomains else
           "interfaces=[E1, E2, ...] with the cells of each material")
    where = (f"cuts the supports at the boundaries of mesh.subdomains "
             f"{sorted(mesh.subdomains)}" if mesh.subdomains else
             "cuts the supports at the boundaries of those cell sets")
    return ("smooth RK functions cannot follow the kink of the solution along a material "
            "interface: the error converges as h, not h² (scikit-fem's ex17 and ex35 with "
            "RKBasis(mesh, element, interpolating=True): 6-26x FEM's error); build the "
            f"basis as RKBasis(mesh, element, interpolating=True, {cut}), which {where} "
            "(ex17 and ex35: 0.7-1.9x FEM's error), or use FEM, "
            "skfem.Basis(mesh, element)")


def _regions(basis):
    """The region of every cell if ``basis`` cuts its supports, else None."""
    for b in (basis, getattr(basis, "_whole", None)):
        regions = getattr(b, "_regions", None)
        if regions is not None:
            return regions.cells
    return None


class MaterialInterfaceWarning(UserWarning):
    """A form on an RK basis has a coefficient that jumps between cells, or
    is integrated over a subdomain: the accuracy drops to first order."""


def _cell_rows(basis):
    """The interior facets between two cells of ``basis``, as pairs of its
    rows (positions in its list of cells)."""
    mesh = basis.mesh
    cells = np.arange(mesh.nelements) if basis.tind is None else np.asarray(basis.tind)
    row = np.full(mesh.nelements, -1)
    row[cells] = np.arange(cells.size)
    left, right = mesh.f2t
    inner = right >= 0
    a, b = row[left[inner]], row[right[inner]]
    keep = (a >= 0) & (b >= 0)
    return a[keep], b[keep]


def jumping_coefficients(basis, fields):
    """Names of the fields (``DiscreteField`` or arrays at the quadrature
    points of ``basis``, shape (..., nelems, nqp)) that jump across an
    interior facet: ``{name: (number of facets, smallest, largest value)}``."""
    out = {}
    if getattr(basis, "nodal_quadrature", None) is not None or not hasattr(basis, "mesh") \
            or hasattr(basis, "parent"):  # nodal schemes and facet bases: no cells
        return out
    pairs = None
    regions = _regions(basis)
    cells = np.arange(basis.mesh.nelements) if basis.tind is None else np.asarray(basis.tind)
    for name, field in fields.items():
        value = np.asarray(field) if isinstance(field, DiscreteField) else field
        if not isinstance(value, np.ndarray) or value.ndim < 2 or \
                value.shape[-2:] != (basis.nelems, basis.X.shape[-1]) or \
                not np.isrealobj(value):
            continue
        value = value.reshape((-1,) + value.shape[-2:])
        if pairs is None:
            pairs = _cell_rows(basis)
        a, b = pairs
        if regions is not None:  # jumps between regions are cut already
            inside = regions[cells[a]] == regions[cells[b]]
            a, b = a[inside], b[inside]
        mean = value.mean(axis=-1)
        spread = np.ptp(value, axis=-1)
        scale = np.abs(value).max()
        jump = np.abs(mean[:, a] - mean[:, b])
        within = np.maximum(spread[:, a], spread[:, b])
        jumps = (jump > JUMP_FACTOR * within) & (jump > 1e-8 * scale)
        if jumps.any():
            out[name] = (int(jumps.any(axis=0).sum()), float(value.min()), float(value.max()))
    return out


def check_interfaces(bilinear, basis, fields, stacklevel=3):
    """Warn (:class:`MaterialInterfaceWarning`) if ``fields`` hold a jumping
    coefficient, or a ``bilinear`` form is integrated over part of the cells
    of the RK ``basis``."""
    found = jumping_coefficients(basis, fields)
    for name, (facets, low, high) in found.items():
        warnings.warn(f"the coefficient {name!r} jumps between cells ({low:.4g} to "
                      f"{high:.4g}, across {facets} interior facets): {advice(basis)}",
                      MaterialInterfaceWarning, stacklevel=stacklevel + 1)
    if bilinear and getattr(basis, "_whole", None) is not None and not _union_of_regions(
            basis):
        warnings.warn(f"a bilinear form over {basis.nelems} of the "
                      f"{basis.mesh.nelements} cells (with_elements): if the parts of a "
                      f"matrix summed from subdomains have different coefficients, {advice(basis)}",
                      MaterialInterfaceWarning, stacklevel=stacklevel + 1)


def _union_of_regions(basis):
    """True if the cells of the part ``basis`` are whole regions of the
    supports it cuts (no region partly inside)."""
    regions = _regions(basis)
    if regions is None:
        return False
    inside = np.zeros(basis.mesh.nelements, dtype=bool)
    inside[np.asarray(basis.tind)] = True
    return all(np.all(inside[regions == r]) or not np.any(inside[regions == r])
               for r in np.unique(regions))
