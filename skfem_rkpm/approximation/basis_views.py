"""scikit-fem's basis idioms on RK bases: FEM partners, components, plots, subdomains.

A scikit-fem user's next steps after ``asm`` read a basis in ways that an
RK basis must answer on its own terms, because its coefficients are
generalized displacements (Eq. 3.24), not nodal values:

- ``basis.with_element(elem)``: an FEM ``CellBasis`` (``FacetBasis`` for a
  facet basis) of ``elem`` on the same mesh, cells and quadrature points,
  so that mixed RK x FEM forms assemble (a P0 pressure next to RK
  velocities);
- ``basis.with_elements(elements)``: the same RK functions integrated over
  a subset of the cells (scikit-fem's ``elements=``);
- ``basis.split(x)``: per component, the *nodal values* ``Λᵀx``
  (Eq. 3.32) with a Lagrange FEM basis on the mesh vertices that reads
  them as nodal values;
- ``basis.refinterp(x, nrefs)``: the RK field evaluated from the RK
  functions at the vertices of a refined mesh, and ``basis.plot(x)``,
  ``plot3``, ``draw`` through ``skfem.visuals`` on that mesh;
- ``facet_basis.probes(x)``, ``interpolator``: evaluation anywhere, as on
  the cell basis.

An idiom that cannot be honoured raises :class:`BasisIdiomError`, whose
message says what to use instead.  This module knows the RK bases only by
their attributes (``mesh``, ``nodes``, ``table``, ``nodal_values``,
``probes``, ...), defined in :mod:`skfem_rkpm.approximation.basis`.
"""

import copy
import importlib

import numpy as np
from skfem import CellBasis, FacetBasis
from skfem.element import (ElementHex1, ElementLineP1, ElementQuad1, ElementTetP1,
                           ElementTriP1, ElementVector)
from skfem.mesh import MeshHex1, MeshLine1, MeshQuad1, MeshTet1, MeshTri1
from skfem.refdom import RefHex, RefLine, RefQuad, RefTet, RefTri

from .basis_element import guarded_element, plain_element
from .idiom_errors import BasisIdiomError, CoefficientsNotNodalError


__all__ = ["BasisIdiomError", "CoefficientsNotNodalError", "CellViews", "FacetViews", "lagrange_element",
           "linear_mesh_class"]

_LINEAR = {RefLine: (ElementLineP1, MeshLine1), RefTri: (ElementTriP1, MeshTri1),
           RefQuad: (ElementQuad1, MeshQuad1), RefTet: (ElementTetP1, MeshTet1),
           RefHex: (ElementHex1, MeshHex1)}


def _linear(mesh):
    try:
        return _LINEAR[mesh.refdom]
    except KeyError:
        raise BasisIdiomError(f"no lowest-order Lagrange element is known for "
                              f"{type(mesh).__name__} cells") from None


def lagrange_element(mesh):
    """The lowest-order Lagrange element of the cells of ``mesh`` (P1, Q1):
    one dof per vertex, also on quadratic meshes."""
    return _linear(mesh)[0]()


def linear_mesh_class(mesh):
    """The linear mesh class of the cells of ``mesh`` (MeshTri1 for MeshTri2)."""
    return _linear(mesh)[1]


class _DofIdioms:
    """Dof idioms of both RK bases: component indices, and loud errors where
    scikit-fem would hand out dofs that read coefficients as nodal values."""

    def _dof_array(self, name):
        """scikit-fem's dof arrays: on an interpolating basis (coefficients
        are nodal values) ``nodal_dofs`` (ncomp, nparticles) and empty facet,
        edge and interior dofs (on a quadratic element's particles, those of
        its FEM basis); a :class:`CoefficientsNotNodalError` otherwise."""
        interpolating = getattr(getattr(self, "parent", self), "interpolating", False)
        if interpolating and name == "dofs":
            raise CoefficientsNotNodalError(
                "an RK basis has no scikit-fem Dofs object (basis.dofs); its dof numbers "
                "come from basis.get_dofs(facets) (x[basis.get_dofs(facets)] = g sets "
                "nodal values on this interpolating basis), basis.nodal_dofs and "
                "basis.split_indices()")
        if interpolating:
            particles = getattr(getattr(self, "parent", self), "_element_particles", None)
            if particles is not None:
                return particles.dof_array(name, self.ncomp)
            if name == "nodal_dofs":
                return np.arange(self.N).reshape(-1, self.ncomp).T
            return np.zeros((self.ncomp, 0), dtype=np.int64)
        raise CoefficientsNotNodalError(
            f"an RK basis has no {name}: its coefficients are not nodal values, and "
            f"x[basis.{name}[c]] would read coefficients; the nodal values of component "
            f"c are basis.nodal_values(x)[c::{self.ncomp}] (or basis.split(x) on the "
            "cell basis); dof numbers come from basis.get_dofs(...) and "
            "basis.split_indices()")

    nodal_dofs = property(lambda self: self._dof_array("nodal_dofs"))
    facet_dofs = property(lambda self: self._dof_array("facet_dofs"))
    edge_dofs = property(lambda self: self._dof_array("edge_dofs"))
    interior_dofs = property(lambda self: self._dof_array("interior_dofs"))
    dofs = property(lambda self: self._dof_array("dofs"))

    @property
    def elem(self):
        """The element the RK basis was built from (the mesh's lowest-order
        Lagrange element, vector-valued for a vector basis, if none was given),
        with scikit-fem's attributes; ``Basis(mesh, rk.elem, ...)`` raises a
        :class:`BasisIdiomError` that names ``rk.with_elements(E)`` and
        ``rk.with_element(rk.elem)`` (:mod:`.basis_element`)."""
        cell = getattr(self, "parent", self)
        element = getattr(cell, "_element", None)
        if element is None:
            element = lagrange_element(self.mesh)
            if self.ncomp > 1:
                element = ElementVector(element)
        return guarded_element(element)

    def split_indices(self):
        """Coefficient numbers of each component: ``[arange(c, N, ncomp)]``.

        ``x[ix]`` are the coefficients of that component (for the scalar
        bases of :meth:`split_bases`), not its nodal values.
        """
        return [np.arange(c, self.N, self.ncomp) for c in range(self.ncomp)]


class CellViews(_DofIdioms):
    """scikit-fem's idioms on :class:`~skfem_rkpm.RKBasis` (mixed in there)."""

    def _require_cells(self, idiom):
        if getattr(self, "nodal_quadrature", None) is not None:
            raise BasisIdiomError(
                f"{idiom} needs the Gauss points of the mesh cells, but "
                f"integration={self.integration!r} integrates at the particles (one "
                "point per particle, no cells); build the RK basis with a cell scheme "
                "(integration='vci', 'vci_symmetric' or 'gauss') for mixed RK x FEM "
                "forms and subdomains, or an FEM basis on its own: skfem.Basis(mesh, elem)")

    @property
    def particles_are_vertices(self):
        """Whether the particles are the mesh vertices (the default), so that
        nodal values live on the vertices (``split``, ``get_dofs`` by name)."""
        p, nv = self.mesh.p, self.mesh.nvertices
        if self.nodes.shape != (p.shape[0], nv):
            return False  # also all nodes of a quadratic mesh as particles
        return self.nodes is p or np.array_equal(self.nodes, p[:, :nv])

    def with_element(self, elem):
        """An FEM basis of ``elem`` on the same mesh, cells and quadrature points.

        As scikit-fem's ``CellBasis.with_element``: the result shares the
        quadrature (``X``, ``W``, ``dx``) and the cells (``elements=``) of this
        basis, so forms that mix RK and FEM functions assemble with
        ``asm(form, ubasis, vbasis)``, e.g. a P0 pressure against RK
        velocities: ``asm(div_form, rk, rk.with_element(ElementQuad0()))``.

        Parameters
        ----------
        elem : skfem.element.Element
            Any scikit-fem element of the mesh's reference cell.

        Returns
        -------
        skfem.CellBasis
            An FEM basis; its coefficients are FEM dofs (nodal values for
            Lagrange elements), the RK basis's are RK coefficients.
        """
        self._require_cells("with_element")
        return CellBasis(self.mesh, plain_element(elem), mapping=self.mapping,
                         quadrature=self.quadrature, elements=self.tind)

    def with_elements(self, elements=None):
        """The same RK functions, integrated over a subset of the cells.

        scikit-fem's ``Basis(mesh, e, elements=...)`` and
        ``basis.with_elements(...)``: forms assembled on the result integrate
        over the cells ``elements`` only, with the dof numbering of the whole
        basis (``N`` unchanged), so matrices of disjoint subdomains add up to
        the matrix of their union.  The functions, and with VCI their
        corrected gradients, are those of the whole basis (the correction is
        built for the whole domain, not for the subdomain).

        Parameters
        ----------
        elements : array of int, callable, str or None
            Anything ``mesh.normalize_elements`` accepts (cell indices, a
            callable of the cell centres, a subdomain name); None: all cells.

        Returns
        -------
        RKBasis
            ``tind`` holds the cell indices.
        """
        self._require_cells("with_elements")
        if getattr(self, "_part_of_partition", False):
            raise BasisIdiomError("with_elements: this basis is one part of a partitioned "
                                  "basis (RKBasis(..., reduction=...)), built on its own "
                                  "cells only; build the part on the cells wanted instead")
        whole = getattr(self, "_whole", None) or self
        if elements is None:
            return whole
        tind = np.asarray(self.mesh.normalize_elements(elements), dtype=np.int64)
        if tind.ndim != 1 or tind.size == 0 or tind.min() < 0 or \
                tind.max() >= self.mesh.nelements:
            raise ValueError(f"elements must select cells 0..{self.mesh.nelements - 1} "
                             f"of the mesh, at least one; got {elements!r}")
        nqp = whole.X.shape[-1]
        rows = (tind[:, None] * nqp + np.arange(nqp)).ravel()
        table = whole._pair_table(test=True, rows=rows)
        geometry = CellBasis(self.mesh, whole.geometry.elem, mapping=whole.mapping,
                             quadrature=whole.quadrature, elements=tind)
        sub = copy.copy(whole)
        sub._basis = sub._trial = None
        sub._setup(self.mesh, geometry, table, whole.nodes, whole.vector, release=True)
        sub.tind = tind
        sub._whole = whole
        return sub

    def _restrict(self, elements):
        """``RKBasis(..., elements=...)``: become ``with_elements(elements)``
        of the basis just built (nothing if ``elements`` is None)."""
        if elements is not None:
            self.__dict__.update(copy.copy(self).with_elements(elements).__dict__)

    def scalar_basis(self):
        """The scalar RK basis of the same particles, cells and quadrature
        (this basis itself if it is scalar): the basis of one component."""
        if self.ncomp == 1:
            return self
        scalar = copy.copy(self)
        scalar.ncomp, scalar.Nbfun = 1, self.element_nodes.shape[0]
        scalar._basis = scalar._trial = None
        scalar._nodal_matrix = self._nodal_matrix[::self.ncomp, ::self.ncomp]
        whole = getattr(self, "_whole", None)
        scalar._whole = None if whole is None else whole.scalar_basis()
        return scalar

    def split_bases(self):
        """The basis of each component's coefficients (``split_indices``):
        :meth:`scalar_basis`, once per component."""
        return [self.scalar_basis()] * self.ncomp

    def point_source(self, x):
        """Load vector of a unit point source at ``x`` (shape (dim,)).

        The test functions at ``x``, ``Ψ_I(x)``, as scikit-fem's
        ``CellBasis.point_source`` (first component of a vector basis).
        """
        return self.probes(np.asarray(x, dtype=float)[:, None]).toarray()[0]

    def __mul__(self, other):
        return self._composite(other, equal_dofnum=False)

    def __matmul__(self, other):
        return self._composite(other, equal_dofnum=True)

    def _composite(self, other, equal_dofnum):
        """scikit-fem's ``vbasis * pbasis`` with an RK basis in it.

        scikit-fem's ``CompositeBasis`` asks its bases for ``elem``, which an
        RK basis has not; the same object is built here after the same
        checks.  A composite basis is trial and test basis at once, so the
        RK basis must have one set of gradients for both: not
        ``integration="vci"``.
        """
        from skfem.assembly.basis.composite_basis import CompositeBasis

        bases = (self, other)
        for b in bases:
            if getattr(b, "integration", None) == "vci":
                raise BasisIdiomError(
                    "a composite basis serves as trial and test basis at once, but an "
                    "integration='vci' basis has other gradients on the trial side "
                    "(basis.trial); build it with integration='vci_symmetric' (or "
                    "'gauss'), or assemble the blocks, asm(a, rk.trial, rk), "
                    "asm(b, rk.trial, p), ..., and join them with scipy.sparse.bmat")
        if not isinstance(other, (CellBasis, CellViews)):
            raise BasisIdiomError(f"an RK basis composes with cell bases (RKBasis, "
                                  f"skfem.CellBasis), not with {type(other).__name__}")
        if len(other.W) != len(self.W) or other.nelems != self.nelems:
            raise ValueError(
                f"the bases of a composite basis need the same cells and quadrature: "
                f"{self.nelems} x {len(self.W)} and {other.nelems} x {len(other.W)}; "
                "take the FEM basis from the RK basis, rk.with_element(elem)")
        composite = CompositeBasis.__new__(CompositeBasis)
        composite.bases, composite.equal_dofnum = bases, equal_dofnum
        composite._element_dofs = composite._basis = None
        return composite

    def _nodal_partner(self):
        """The Lagrange FEM basis on the mesh vertices that reads nodal values."""
        if not self.particles_are_vertices:
            raise BasisIdiomError(
                "split(x) pairs nodal values with a basis on the mesh vertices, but the "
                "particles are not the mesh vertices; read the values at the particles "
                "with basis.nodal_values(x) (one per particle and component, "
                "interleaved) or anywhere with basis.probes(points) @ x")
        elem = lagrange_element(self.mesh)
        if getattr(self, "nodal_quadrature", None) is not None:
            return CellBasis(self.mesh, elem, intorder=self.intorder)
        return self.with_element(elem)

    def split(self, x):
        """Per component: its NODAL values and a basis that reads them as such.

        scikit-fem's ``basis.split(x)`` returns ``(x[dofs of component c],
        component basis)``.  RK coefficients are not nodal values, so here
        the first entry of each pair is the component's nodal values ``Λᵀx``
        (:meth:`nodal_values`, Eq. 3.32), one per particle, and the second
        the lowest-order Lagrange FEM basis on the mesh vertices (P1, Q1,
        :meth:`with_element`, same quadrature), whose dofs are exactly those
        nodal values.  ``b.plot(u)``, ``mesh.save(point_data={"u": u})`` and
        ``b.interpolate(u)`` then read them right; ``b.interpolate(u)`` is the
        piecewise linear interpolant of the RK field through its nodal
        values, not the RK field: evaluate that from the coefficients with
        :meth:`interpolate`, :meth:`probes` or :meth:`refinterp`.

        Parameters
        ----------
        x : ndarray, shape (N,)
            RK coefficients.

        Returns
        -------
        list of (ndarray, skfem.CellBasis)
            One pair per component (one for a scalar basis).

        Raises
        ------
        BasisIdiomError
            If the particles are not the mesh vertices.
        """
        self._components(x)  # checks the length
        values = np.asarray(self.nodal_values(x))
        partner = self._nodal_partner()
        return [(values[c::self.ncomp], partner) for c in range(self.ncomp)]

    def refinterp(self, x, nrefs=1, Nrefs=None):
        """The RK field on a refined mesh, evaluated from the RK functions.

        As scikit-fem's ``CellBasis.refinterp``: every cell is split ``nrefs``
        times and the field is evaluated (``probes``, not read from
        coefficients or nodal values) at the vertices of the pieces, which are
        repeated per cell.  With ``nrefs=0`` the values are the nodal values
        at the cell vertices.

        Parameters
        ----------
        x : ndarray, shape (N,)
            RK coefficients.
        nrefs : int
            Refinements of each cell.
        Nrefs : int, optional
            Old name of ``nrefs``.

        Returns
        -------
        mesh : skfem.Mesh
            A linear mesh of the pieces (MeshTri1, MeshQuad1, ...), curved
            cells of quadratic meshes mapped with their own mapping.
        values : ndarray
            Field values at ``mesh.p``, shape (npoints,), or component-major
            (all first components, then all second, ...), shape
            (ncomp*npoints,), as scikit-fem's ``refinterp`` of vector elements
            (``skfem.visuals.matplotlib.plot`` draws 2D vectors as arrows).
        """
        if Nrefs is not None:
            nrefs = Nrefs
        self._components(x)  # checks the length
        meshclass = linear_mesh_class(self.mesh)
        ref = meshclass.init_refdom().refined(nrefs)
        X = ref.p
        if self.mesh.dim() == 1:  # keeps duplicate points in order, as scikit-fem
            X = (1.0 - 1e-10) * ref.p + 5e-11
        tind = None if getattr(self, "nodal_quadrature", None) is not None else self.tind
        points = self.mesh._mapping().F(X, tind=tind)  # (dim, ncells, nv)
        ncells, nv = points.shape[1], points.shape[2]
        t = (np.tile(ref.t, (1, ncells))
             + nv * np.repeat(np.arange(ncells), ref.t.shape[1])[None, :])
        p = points.reshape(self.mesh.dim(), -1)
        return meshclass(p, t), self.probes(p) @ np.asarray(x)

    def _visuals(self, visuals):
        return importlib.import_module(f"skfem.visuals.{visuals}")

    def plot(self, x, visuals="matplotlib", **kwargs):
        """Plot the RK field of coefficients ``x`` through ``skfem.visuals``.

        The field is evaluated on a refined mesh (:meth:`refinterp`,
        ``nrefs=1`` unless given) and drawn by ``skfem.visuals.<visuals>.plot``
        with the other keyword arguments (``ax``, ``colorbar``, ``shading``,
        ...).  2D vector fields come out as arrows.
        """
        nrefs = kwargs.pop("nrefs", kwargs.pop("Nrefs", 1))
        return self._visuals(visuals).plot(*self.refinterp(x, nrefs=nrefs), **kwargs)

    def plot3(self, x, visuals="matplotlib", **kwargs):
        """As :meth:`plot`, as a surface ``z = u(x, y)`` (scalar 2D fields)."""
        nrefs = kwargs.pop("nrefs", kwargs.pop("Nrefs", 1))
        return self._visuals(visuals).plot3(*self.refinterp(x, nrefs=nrefs), **kwargs)

    def draw(self, visuals="matplotlib", **kwargs):
        """Draw the background mesh (cells of this basis) through ``skfem.visuals``."""
        return self._visuals(visuals).draw(self.mesh, **kwargs)


class FacetViews(_DofIdioms):
    """scikit-fem's idioms on :class:`~skfem_rkpm.RKFacetBasis` (mixed in there)."""

    @property
    def normals(self):
        """Outward unit normals at the quadrature points, (dim, nfacets, nqp),
        as scikit-fem's ``FacetBasis.normals``."""
        return self.geometry.normals

    @property
    def find(self):
        """Indices of the facets of this basis, as scikit-fem's ``FacetBasis.find``."""
        return self.geometry.find

    def with_element(self, elem):
        """An FEM ``FacetBasis`` of ``elem`` on the same facets and quadrature
        points (outward normals alike), for mixed RK x FEM boundary forms."""
        return FacetBasis(self.mesh, plain_element(elem), mapping=self.mapping,
                          quadrature=self.quadrature, facets=self.find)

    def probes(self, x):
        """Sparse matrix mapping coefficients to field values at points ``x``
        (shape (dim, npoints)), the same as the cell basis's :meth:`probes`:
        the facet basis has the particles of its cell basis."""
        return self.parent.probes(x)

    def interpolator(self, w):
        """Function ``x -> field values at x`` for coefficients ``w``."""
        return self.parent.interpolator(w)

    def nodal_values(self, d):
        """Nodal values ``Λᵀd`` (Eq. 3.32), as on the cell basis."""
        return self.parent.nodal_values(d)

    def split(self, x):
        """Refused: split the coefficients with the cell basis."""
        raise BasisIdiomError("split the coefficients with the cell basis, "
                              "basis.split(x) (nodal values per component)")

    def project(self, interp, facets=None, dtype=None):
        """Boundary values on the facets of this basis, as scikit-fem's
        ``FacetBasis.project`` is used: a vector that holds ``interp`` at
        the dofs on the facets (here the particles on them) and zero
        elsewhere, ready for ``condense(K, f, x=x, D=D)``.

        On an interpolating basis the coefficients are nodal values, so the
        values at the particles are taken as they are (``interp`` a number
        or a callable of the coordinates, evaluated at the particles); for a
        linear FEM trace this is what scikit-fem's L² projection on the
        boundary gives for constant and linear ``interp``.  A basis without
        ``interpolating=True`` has no boundary coefficients to set: a
        :class:`BasisIdiomError` names the call that prescribes values there.
        """
        cell = self.parent
        if dtype is not None and not np.issubdtype(dtype, np.floating):
            raise BasisIdiomError(f"RK bases are real: project with dtype={dtype!r} "
                                  "is not supported")
        if not getattr(cell, "interpolating", False):
            raise BasisIdiomError(
                "an RK facet basis without interpolating=True has no boundary-only "
                "coefficients to project on (its coefficients are not nodal values); "
                "prescribe nodal values instead: x = basis.zeros(); "
                "D = basis.get_dofs(facets); x[D] = value; then "
                "skfem_rkpm.condense(K, f, x=x, D=D, basis=basis), or build the basis "
                "with RKBasis(mesh, element, interpolating=True), on which "
                "facet_basis.project(value) works as in scikit-fem")
        dofs = np.asarray(cell.get_dofs(self.find if facets is None else facets))
        x = cell.zeros()
        if callable(interp):
            locations = cell.doflocs[:, dofs]
            values = np.asarray(interp(locations), dtype=float)
            if cell.ncomp > 1 and values.ndim == 2:  # (ncomp, ndofs): the own component
                values = values[dofs % cell.ncomp, np.arange(dofs.size)]
        elif np.ndim(interp) == 0:
            values = float(interp)
        else:
            raise BasisIdiomError(
                "facet_basis.project on an RK basis takes a number or a callable of the "
                "coordinates (evaluated at the boundary particles), not values at "
                "quadrature points; for those, project(lambda x: ...) with the function "
                "that gave them")
        x[dofs] = values
        return x

    def trace(self, *args, **kwargs):
        """Refused: evaluate the RK field on the boundary instead."""
        raise BasisIdiomError(
            "an RK field has no trace in a boundary finite element space; evaluate it "
            "on the facets with facet_basis.interpolate(x) (quadrature points) or "
            "facet_basis.probes(points) @ x")
