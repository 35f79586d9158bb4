"""RKBasis: reproducing kernel shape functions behind scikit-fem's basis face.

A scikit-fem form sees, per background cell, a list of local functions with
their values and gradients at the cell's quadrature points.  For an RK basis
the local functions of a cell are the particles whose supports reach any of
its quadrature points; the lists are padded to a common length with
functions that are zero everywhere.  Particle ``I`` owns the scalar
coefficient ``I`` (scalar fields) or the coefficients ``dim*I + c``
(vector fields, interleaved like scikit-fem's ``ElementVector``).

Coefficients are *generalized* displacements ``d_I`` (Eq. 3.24), not nodal
values: use :meth:`RKBasis.nodal_values` (Eq. 3.32) to read nodal values and
:func:`skfem_rkpm.solve` to prescribe them (the transformation method).
"""

import copy
import warnings

import numpy as np
import scipy.sparse as sp
from skfem.element import Element, ElementH1, ElementVector

from . import cell_layout
from .basis_views import CellViews, FacetViews
from .dofs import RKDofs
from .integration import cell_geometry, facet_geometry, vci_gradients
from .reduction import WHOLE
from .element_particles import (DEFAULT_INTORDER, DEFAULT_SUPPORT, element_degree,
                                element_particles, line_defaults, scalar_element)
from .rk_base import EXACT_ON_DEMAND, RKBase
from ..meshes import local_spacing, mesh_vertices
from .nodal_integration import (NODAL_SCHEMES, SMOOTHING_CELLS, boundary_rule,
                               nodal_quadrature)
from .interpolating import basis_primitive_radius, shape_functions
from .neighbours import group_pointers
from .shape import coordinates
from .visibility import cut_supports

__all__ = ["RKBasis", "RKFacetBasis"]

INTEGRATION_SCHEMES = ("vci", "vci_symmetric", "gauss") + NODAL_SCHEMES


def field_is_vector(vector):
    """``vector`` of :class:`RKBasis` as a bool: given as a bool, or read
    from a scikit-fem element (``ElementVector`` of a continuous element,
    or a continuous scalar element)."""
    if isinstance(vector, (bool, np.bool_)):
        return bool(vector)
    element = vector.elem if isinstance(vector, ElementVector) else vector
    if isinstance(element, ElementH1) and element.maxdeg >= 1:
        return isinstance(vector, ElementVector)
    if isinstance(element, Element):
        raise ValueError(
            f"an RK basis is continuous, one field with values and gradients: it has "
            f"no counterpart of {type(element).__name__}; pair the RK basis with a FEM "
            f"basis on the same points, rk.with_element({type(element).__name__}())")
    raise ValueError(f"the second argument of RKBasis is vector=True/False or a scikit-fem "
                     f"element (ElementTriP1(), ElementVector(ElementQuad1()), ...), not "
                     f"{vector!r}")


def default_integration(interpolating, order, axisymmetric):
    """``"vci_symmetric"`` where it is defined (order 1, not axisymmetric)
    for an interpolating basis, whose users read coefficients as nodal
    values with scikit-fem's own idioms, which take one basis for trial and
    test (``form.assemble(basis)``, conjugate gradients, ``eigsh``); it
    costs no accuracy there (Poisson on 8²-64² squares, uniform and
    distorted: L² and H¹ errors within 1 % of ``"vci"``,
    docs/rk_basis.md).  ``"vci"`` otherwise."""
    if interpolating and order == 1 and not axisymmetric:
        return "vci_symmetric"
    return "vci"


def _check_distinct(nodes, radius):
    """Raise if two particles coincide (closer than 1e-9 of the smallest
    support, or of the extent of the particles if that is smaller)."""
    from scipy.spatial import cKDTree

    extent = np.ptp(nodes, axis=1).max() if nodes.shape[1] > 1 else 0.0
    tol = 1e-9 * min(np.min(radius, initial=np.inf), extent if extent > 0 else np.inf)
    if not np.isfinite(tol):
        return
    pairs = cKDTree(nodes.T).query_pairs(tol, output_type="ndarray")
    if len(pairs):
        pairs = np.sort(pairs, axis=1)
        i, j = pairs[np.lexsort(pairs.T[::-1])[0]]
        where = ", ".join(f"{c:.6g}" for c in nodes[:, i])
        raise ValueError(
            f"particles {i} and {j} coincide at ({where}) ({len(pairs)} such pairs): "
            "their shape functions would be identical and the stiffness matrix "
            "singular; remove the duplicate vertices or particles")


def _part_cells(mesh, elements, integration, reduction):
    """The cells of a part of a partitioned basis (sorted), or None for a
    basis on all cells (``reduction`` None)."""
    if reduction is None:
        return None
    if elements is None:
        raise ValueError("a part of a partitioned basis (reduction=...) needs its "
                         "cells: give elements=")
    if integration not in ("vci", "gauss"):
        raise ValueError(f"a partitioned basis integrates with 'vci' or 'gauss', not "
                         f"{integration!r}")
    cells = np.unique(np.asarray(mesh.normalize_elements(elements), dtype=np.int64))
    if cells.size == 0 or cells[0] < 0 or cells[-1] >= mesh.nelements:
        raise ValueError(f"the cells of a part must be between 0 and {mesh.nelements - 1} "
                         f"(the mesh's cells), and at least one; got {cells.size} "
                         "cells" + (f" from {cells[0]} to {cells[-1]}" if cells.size else ""))
    return cells


def _part_boundary(mesh, cells):
    """The boundary facets of the cells ``cells`` (None: all of them)."""
    facets = mesh.boundary_facets()
    if cells is None:
        return None
    return facets[np.isin(mesh.f2t[0, facets], cells)]


class RKBasis(CellViews, RKBase):
    """Reproducing kernel basis on the background cells of a scikit-fem mesh.

    Parameters
    ----------
    mesh : skfem.Mesh
        Background mesh; its cells supply quadrature, its vertices are the
        particles unless ``nodes`` is given.
    vector : bool or skfem element
        Vector field with ``mesh.dim()`` components (displacements).  A
        scikit-fem element may stand here, as in ``Basis(mesh, element)``:
        ``ElementVector(...)`` gives a vector field, a scalar element a
        scalar one.  The element's degree is the default ``order``, and a
        quadratic element (P2, Q2, S2) puts the particles at its dof
        locations, numbered as its dofs, so that ``N``, ``doflocs`` and
        ``get_dofs`` equal those of ``Basis(mesh, element)``
        (:mod:`.element_particles`).
    support : float
        Normalized support ``c``: particle I gets radius ``a_I = c h_I``
        with ``h_I`` the local nodal spacing (:func:`local_spacing`; for the
        particles of a quadratic element, the spacing of its dofs).
        Default 2, and 2.5 on a quadratic element's dofs (measured:
        :data:`.element_particles.DEFAULT_SUPPORT`).
    order : int
        Basis order ``N`` of Eq. (3.18): 0, 1 or 2.  Default: the degree of
        the element given as ``vector``, else 1.  On a 1D mesh, unless
        ``order`` or ``integration`` is given: order 2, support 2.5 and
        Gauss of degree 20 (:data:`.element_particles.LINE_DEFAULTS`).
    kernel : str or callable
        Window function, ``"cubic"`` (Eq. 3.12, default) or ``"quartic"``.
    support_shape : {"radial", "box"}
        Circular/spherical or tensor-product supports.
    intorder : int
        Degree of the Gauss rule on each background cell; default 4, and 6
        on a quadratic element's dofs.
    integration : {"vci", "vci_symmetric", "gauss", "scni", "dni"}
        Default ``"vci"``, and ``"vci_symmetric"`` for an interpolating
        basis of order 1 that is not axisymmetric (:func:`default_integration`).
        ``"gauss"``: plain Gauss quadrature, the paper's scheme.
        ``"vci"``: variationally consistent test-function gradients (see
        :mod:`skfem_rkpm.approximation.integration`); ``basis.basis`` then holds the
        corrected test functions and ``basis.trial`` the exact ones, and
        ``asm(form, basis.trial, basis)`` is the consistent Petrov-Galerkin
        matrix (not symmetric).
        ``"vci_symmetric"``: corrected gradients that also reproduce linear
        fields, used for trial and test functions alike (``basis.trial`` is
        the basis itself): symmetric matrices, patch test to round-off.
        Order 1, not axisymmetric.
        ``"scni"``: stabilized conforming nodal integration, one point per
        particle with gradients smoothed over its median dual cell;
        ``"dni"``: direct nodal integration (exact gradients at the
        particles, fails the patch test).  See
        :mod:`skfem_rkpm.approximation.nodal_integration`; both need the
        particles to be the vertices of a linear triangle, quadrilateral,
        tetrahedron or hexahedron mesh, and the "cells" of the basis are
        then the particles (``nelems = nnodes``, one point each).
    nodes : ndarray, shape (dim, nnodes), optional
        Particle positions; default the mesh vertices.
    radius : float or ndarray, optional
        Support radii given explicitly (overrides ``support``).
    axisymmetric : bool
        The problem is axisymmetric with ``x`` the radius: VCI then imposes
        its constraints in the measure ``R dR dZ``.  The basis itself (and
        ``dx`` for scikit-fem forms) is unchanged.  With ``"scni"`` the
        smoothing is done in that measure (points at the cell centroids).
    stabilization : float
        ``α`` of the modified SCNI stabilization (``"scni"`` only): the
        solid adds ``α Σ_k A_k (B_k - B_L)ᵀ C (B_k - B_L)`` with the piece
        gradients of the smoothing cells and the elastic moduli ``C``
        (:class:`skfem_rkpm.mechanics.problem.SolidProblem`).  0 for plain SCNI.
    smoothing : {"median_dual", "voronoi"}
        The smoothing cells of ``"scni"`` (and the weights of ``"dni"``):
        the median dual cells of the mesh (2D and 3D), or the Voronoi cells
        of the particles clipped to the mesh (2D;
        :mod:`skfem_rkpm.approximation.voronoi_cells`).
    elements : optional
        Integrate over these cells only (scikit-fem's ``elements=``), the
        same as ``RKBasis(mesh, ...).with_elements(elements)``.
    interpolating : bool
        ``Ψ_I(X_J) = δ_IJ`` (:mod:`skfem_rkpm.approximation.interpolating`):
        coefficients are nodal values, ``nodal_matrix`` is the identity.
    reduction : optional
        Build a *part* of a partitioned basis (:mod:`.reduction`, e.g. one
        MPI rank's, :mod:`skfem_rkpm.solvers.partitioned`): the shape
        functions are computed only at the quadrature points of the cells
        ``elements`` (and of the boundary facets of those cells), and the
        VCI sums over the points are added up over the parts by
        ``reduction``, so that the gradients equal those of the whole basis
        restricted to ``elements``.  Needs ``elements`` and
        ``integration="vci"`` or ``"gauss"``.
    interfaces : optional
        Cut the supports at material interfaces (the visibility criterion,
        :mod:`.visibility`): ``True`` for the boundaries of every subdomain
        of ``mesh.subdomains``, or subdomain names or cell index arrays of
        the materials.  The RK functions at a point are built from the
        particles of its material only, the particles on an interface
        shared: the functions kink there, as a two-material solution does.
    """

    def __init__(self, mesh, vector=False, support=None, order=None, kernel="cubic",
                 support_shape="radial", intorder=None, integration=None,
                 nodes=None, radius=None, axisymmetric=False, stabilization=0.0,
                 elements=None, interpolating=False, smoothing="median_dual",
                 reduction=None, interfaces=None):
        element = scalar_element(vector)
        self._element = vector if element is not None else None  # RKBasis.elem
        vector = field_is_vector(vector)
        particles = (element_particles(mesh, element)
                     if nodes is None and integration not in NODAL_SCHEMES else None)
        degree = 1 if element is None else element_degree(element)
        if particles is not None or nodes is None:
            order, support, intorder, integration = line_defaults(
                mesh, degree, order, support, intorder, integration)
        order = degree if order is None else order
        support = DEFAULT_SUPPORT[degree if particles is not None else 1] \
            if support is None else support
        intorder = DEFAULT_INTORDER[degree if particles is not None else 1] \
            if intorder is None else intorder
        if integration is None:
            integration = default_integration(interpolating, order, axisymmetric)
        if integration not in INTEGRATION_SCHEMES:
            raise ValueError(f"integration must be one of {INTEGRATION_SCHEMES}, "
                             f"not {integration!r}")
        if isinstance(order, (bool, np.bool_)) or order not in (0, 1, 2):
            raise ValueError(f"basis order must be 0, 1 or 2, not {order!r}")
        if isinstance(intorder, (bool, np.bool_)) or not isinstance(
                intorder, (int, np.integer)) or intorder < 1:
            raise ValueError(f"intorder (the Gauss rule degree) must be an integer >= 1, "
                             f"not {intorder!r}")
        if integration in NODAL_SCHEMES and nodes is not None and not (
                np.shape(nodes) == mesh.p.shape and np.array_equal(nodes, mesh.p)):
            raise ValueError(f"integration={integration!r} integrates at the mesh "
                             "vertices: leave nodes=None (the particles are the vertices)")
        if isinstance(stabilization, (bool, np.bool_)) or not isinstance(
                stabilization, (int, float, np.integer, np.floating)) or not (
                np.isfinite(stabilization) and stabilization >= 0):
            raise ValueError(f"stabilization must be a number >= 0, not {stabilization!r}")
        if smoothing not in SMOOTHING_CELLS:
            raise ValueError(f"smoothing must be one of {SMOOTHING_CELLS}, not {smoothing!r}")
        if smoothing != "median_dual" and integration not in NODAL_SCHEMES:
            raise ValueError(f"smoothing={smoothing!r} chooses the cells of nodal "
                             f"integration: it needs integration='scni' or 'dni' "
                             f"(not {integration!r})")
        if stabilization and integration != "scni":
            raise ValueError(f"stabilization={stabilization} needs integration='scni' "
                             f"(not {integration!r})")
        part = _part_cells(mesh, elements, integration, reduction)
        self._element_particles = particles
        if particles is not None:
            nodes, spacing = particles.nodes, particles.spacing
        elif nodes is None:
            nodes = coordinates(mesh_vertices(mesh), "mesh vertex")
            spacing = local_spacing(mesh)[:nodes.shape[1]]
        else:
            nodes = coordinates(nodes, "particle")
            spacing = None
        if nodes.shape[1] == 0:
            raise ValueError("there are no particles; give at least one")
        from_spacing = radius is None
        if radius is None:
            if spacing is None:
                raise ValueError("with custom nodes give the support radii "
                                 "explicitly: RKBasis(..., radius=...)")
            if isinstance(support, (bool, np.bool_)) or not isinstance(
                    support, (int, float, np.integer, np.floating)) or not (
                    np.isfinite(support) and support > 0):
                raise ValueError("normalized support must be positive and finite, "
                                 f"not {support!r}")
            radius = support * spacing
        try:
            self.radius = np.broadcast_to(np.asarray(radius, float),
                                          (nodes.shape[1],)).copy()
        except (TypeError, ValueError):
            raise ValueError(f"radius must be one number or one per particle "
                             f"({nodes.shape[1]}), not {radius!r}") from None
        bad = np.flatnonzero(~(np.isfinite(self.radius) & (self.radius > 0)))
        if bad.size:
            where = ", ".join(f"{c:.6g}" for c in nodes[:, bad[0]])
            raise ValueError(f"support radius of particle {bad[0]} at ({where}) is "
                             f"{self.radius[bad[0]]}; radii must be positive and finite"
                             + (" (a mesh vertex without cells has no spacing: remove "
                                "unused vertices)" if from_spacing else ""))
        _check_distinct(nodes, self.radius)
        self._regions = None if interfaces is None else cut_supports(
            mesh, interfaces, particles, nodes, integration)
        self._primitive = basis_primitive_radius(interpolating, nodes, self.radius)
        self.interpolating = self._primitive is not None
        if self.interpolating and order == 2 and particles is not None and mesh.dim() > 1:
            warnings.warn(
                "interpolating RK functions of order 2 converge more slowly than the "
                "plain ones: on P2 meshes of the unit square (Poisson) their L2 error "
                "was 2.9-11x FEM's, against 0.4-0.8x without interpolating=True; drop "
                "it and prescribe nodal values with skfem_rkpm.condense(..., basis=rk)",
                stacklevel=2)
        # a too small support is reported as a normalized support only when
        # the radii come from it; explicit radii get a growth factor
        self.dilation = support if from_spacing else None
        self.order, self.kernel = order, kernel
        self.support_shape, self.intorder = support_shape, intorder
        self.integration = integration
        self.axisymmetric = axisymmetric
        self.stabilization = float(stabilization)
        self.smoothing = smoothing
        self.nodal_quadrature = None
        if integration in NODAL_SCHEMES:
            self._setup_nodal(mesh, nodes, vector)
            self._restrict(elements)
            return

        try:
            geometry = cell_geometry(mesh, intorder, part)
            boundary = facet_geometry(mesh, intorder, _part_boundary(mesh, part))
        except NotImplementedError:
            raise ValueError(f"scikit-fem has no Gauss rule of degree {intorder} for "
                             f"{type(mesh).__name__} cells; use a lower intorder") from None
        xq = geometry.global_coordinates().reshape(mesh.dim(), -1)
        xb = boundary.global_coordinates().reshape(mesh.dim(), -1)
        # one build for every point the basis will need (cell and boundary
        # quadrature, particles), so that a too small support is reported
        # once, for all of them, with a dilation that works everywhere
        sizes = np.cumsum([0, xq.shape[1], xb.shape[1], nodes.shape[1]])
        labels = None if self._regions is None else np.concatenate([
            self._regions.points_of_cells(geometry.tind, geometry.X.shape[-1]),
            self._regions.points_of_cells(mesh.f2t[0, boundary.find], boundary.X.shape[-1]),
            self._regions.particle_region])
        # the pair search runs once per cell and facet (and particle)
        groups = group_pointers((geometry.nelems, geometry.X.shape[-1]),
                                (boundary.nelems, boundary.X.shape[-1]), (nodes.shape[1], 1))
        everything = self._shape_table(np.hstack([xq, xb, nodes]), nodes, labels=labels,
                                       groups=groups)
        # the cell rows stay views: laying them out below frees them array by array
        table, btable, ntable = (cell_layout.table_rows(everything, a, b, copy=a > 0)
                                 for a, b in zip(sizes[:-1], sizes[1:]))
        del everything
        self._nodal_matrix = sp.kron(ntable.matrix(), sp.identity(
            nodes.shape[0] if vector else 1), format="csr")
        del ntable
        cells = cell_layout.cell_particles(table, geometry.nelems, geometry.X.shape[-1])
        # symmetric VCI: the corrected gradients serve trial and test functions;
        # they are written over the exact ones, which are computed again if
        # asked for (basis.table, interpolate)
        on_demand = integration == "vci_symmetric" and order >= 1
        if integration in ("vci", "vci_symmetric"):
            corrected = vci_gradients(
                table, xq, geometry.dx.ravel(), btable, xb,
                boundary.dx.ravel(), boundary.normals.reshape(mesh.dim(), -1),
                nodes, self.radius, order, kernel, support_shape, axisymmetric,
                symmetric=integration == "vci_symmetric", reduction=reduction or WHOLE,
                cells=(geometry.X.shape[-1], cells), overwrite=on_demand)
            if on_demand:
                table.test_grads, table.grads = corrected, None
            elif corrected is not table.grads:  # order 0: nothing to correct
                table.test_grads = corrected
            del corrected
        del btable
        table.kernel = None  # only VCI reads it: 8 bytes per pair
        self._setup(mesh, geometry, table, nodes, vector, release=True, cells=cells)
        if on_demand:
            self._exact_grads = EXACT_ON_DEMAND
        if part is None:
            self._restrict(elements)
        else:
            self.tind = part
            self._part_of_partition = True

    @property
    def segment_points(self):
        """Gauss points per segment of the smoothing cells (nodal schemes).

        2D: ``max(2, (intorder + 2) // 2)`` Gauss points per segment (3 for
        the default ``intorder=4``).  3D: ``max(2, intorder // 2)``, selecting
        the rule on the cells' triangles
        (:func:`~.median_dual_3d.triangle_rule`: 3 points of degree 2 for
        ``intorder <= 5``, 6 points of degree 4 for 6 and 7).
        """
        if self.nodes.shape[0] == 3:
            return max(2, self.intorder // 2)
        return max(2, (self.intorder + 2) // 2)

    def _setup_nodal(self, mesh, nodes, vector):
        """One point per particle (see :mod:`.nodal_integration`)."""
        self.nodes = nodes  # the dimension selects segment_points
        ntable = self._shape_table(nodes, nodes)
        self._nodal_matrix = sp.kron(ntable.matrix(), sp.identity(
            nodes.shape[0] if vector else 1), format="csr")
        q = nodal_quadrature(mesh, self.integration,
                             lambda x: self._shape_table(x, nodes, gradients=False), ntable,
                             self.segment_points, self.axisymmetric,
                             pieces=bool(self.stabilization), smoothing=self.smoothing)
        self.nodal_quadrature = q
        self._setup(mesh, q.geometry, q.table, nodes, vector)

    def _exact_pairs(self, rows=None):
        """The shape table at the quadrature points ``rows`` (default all, in
        the order of the basis's table) computed again: the exact gradients
        of a ``"vci_symmetric"`` basis, which keeps only the corrected ones
        (the same functions, the same arithmetic per point)."""
        nqp = self.X.shape[-1]
        points = np.arange(self.nelems * nqp) if rows is None else np.asarray(rows)
        x = self.geometry.global_coordinates().reshape(self.nodes.shape[0], -1)[:, points]
        cells = points[::nqp] // nqp
        whole = len(points) % nqp == 0 and np.array_equal(
            points, (cells[:, None] * nqp + np.arange(nqp)).ravel())
        labels = None if self._regions is None else self._regions.points_of_cells(
            self.geometry.tind, nqp)[points]
        return self._shape_table(x, labels=labels, groups=group_pointers(
            (len(cells), nqp)) if whole else None)

    def _shape_table(self, x, nodes=None, gradients=True, labels=None, groups=None):
        nodes = self.nodes if nodes is None else nodes
        regions = getattr(self, "_regions", None)
        if regions is None:
            return shape_functions(
                x, nodes, self.radius, self.order, self.kernel, self.support_shape,
                gradients=gradients, dilation=self.dilation, primitive=self._primitive,
                groups=groups)
        primitive = self._primitive
        return regions.table(x, regions.locate(x) if labels is None else labels,
                             lambda y, m: shape_functions(
                                 y, nodes[:, m], self.radius[m], self.order, self.kernel,
                                 self.support_shape, gradients=gradients,
                                 dilation=self.dilation,
                                 primitive=None if primitive is None else primitive[m]))

    @property
    def trial(self):
        """The same basis with the trial gradients: the exact (uncorrected)
        ones for ``integration="vci"``.

        With ``integration="gauss"`` or ``"vci_symmetric"`` this is the basis
        itself.
        """
        if self._exact_grads is None or self.integration == "vci_symmetric":
            return self
        if getattr(self, "_trial", None) is None:
            trial = copy.copy(self)
            trial.grads, trial._exact_grads = self._exact_layout(), None
            trial._basis = None
            trial._trial = trial
            self._trial = trial
        return self._trial

    # -- the transformation method, Eq. (3.32)-(3.34) ------------------------
    @property
    def nodal_matrix(self):
        """Λᵀ of Eq. (3.33): maps coefficients d to nodal values d̂ = Λᵀ d.

        Scalar entries ``L_IJ = Ψ_I(X_J)`` (Eq. 3.34), interleaved per
        component for vector bases; sparse, shape (N, N).
        """
        return self._nodal_matrix

    def nodal_values(self, d):
        """Nodal values ``û = Λᵀ d`` (Eq. 3.32) of coefficients ``d``."""
        return self.nodal_matrix @ np.asarray(d)

    # -- evaluation anywhere -------------------------------------------------
    def probes(self, x):
        """Sparse matrix that maps coefficients to field values at points ``x``.

        ``x`` has shape (dim, npoints).  Rows are ordered component-major
        (all points of component 0, then component 1, ...), as in scikit-fem.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        T = self._shape_table(x, gradients=False).matrix()
        c = self.ncomp
        blocks = [sp.kron(T, sp.csr_matrix(([1.0], ([0], [comp])), shape=(1, c)))
                  for comp in range(c)]
        return sp.vstack(blocks, format="csr")

    def interpolator(self, w):
        """Function ``x -> field values at x`` for coefficients ``w``."""
        def interpolate_at(x):
            out = self.probes(x) @ w
            return out if self.ncomp == 1 else out.reshape(self.ncomp, -1)
        return interpolate_at

    def project(self, interp):
        """L² projection of a function onto the basis; returns coefficients.

        ``interp`` is a callable of the global quadrature coordinates
        (shape (dim, nelems, nqp)) or an array of values at the quadrature
        points, shaped like :meth:`interpolate` returns.  Particles whose
        supports miss every cell of the basis (``elements=``) get 0.
        """
        from scipy.sparse.linalg import splu

        if callable(interp):
            interp = interp(self.global_coordinates())
        values = np.broadcast_to(np.asarray(interp, dtype=float),
                                 ((self.ncomp,) if self.ncomp > 1 else ())
                                 + (self.nelems, self.X.shape[-1]))
        A = self.table.matrix()
        w = self.dx.ravel()
        M = (A.T @ sp.diags(w) @ A).tocsc()
        rhs = A.T @ (values.reshape(self.ncomp, -1) * w).T
        seen, coeffs = np.flatnonzero(M.diagonal() > 0), np.zeros(rhs.shape)
        coeffs[seen] = splu(M[seen][:, seen], permc_spec="MMD_AT_PLUS_A").solve(
            np.asarray(rhs)[seen])
        return coeffs.reshape(-1)

    # -- dofs ---------------------------------------------------------------
    def get_dofs(self, facets=None, component=None, nodes=None):
        """Coefficient numbers of the particles on a boundary.

        Parameters
        ----------
        facets : str, callable, set of str or array, optional
            A boundary name of ``mesh.boundaries`` (or several), facet
            indices, or a callable ``x -> bool`` evaluated at the particle
            positions.  Default: the whole boundary.
        component : int or sequence of int, optional
            Keep these components of a vector basis (default all).
        nodes : array of int, optional
            Particle indices, instead of ``facets``.

        Returns
        -------
        RKDofs
            Sorted dof numbers, interleaved ``dim*I + c``: an integer array
            with scikit-fem's ``DofsView`` methods (``.all()``,
            ``.nodal["u^1"]``, ``.keep``, ``.drop``).
        """
        if nodes is None:
            nodes = self._boundary_particles(facets)
        nodes = np.asarray(nodes, dtype=np.int64)
        comps = range(self.ncomp) if component is None else np.atleast_1d(component)
        bad = [c for c in comps if not 0 <= c < self.ncomp]
        if bad:
            raise ValueError(f"component {bad[0]} does not exist: the basis "
                             f"has {self.ncomp} component(s)")
        dofs = (self.ncomp * nodes[:, None] + np.asarray(list(comps))[None, :])
        return RKDofs(np.unique(dofs.ravel()), self.ncomp)

    def _boundary_particles(self, facets):
        if callable(facets):
            return np.flatnonzero(facets(self.nodes))
        if getattr(self, "_element_particles", None) is not None:
            return self._element_particles.boundary(facets)
        if not self.particles_are_vertices:
            raise ValueError("particles are not the mesh vertices: select them "
                             "with a callable get_dofs(lambda x: ...) or nodes=")
        if facets is None:
            facets = self.mesh.boundary_facets()
        elif isinstance(facets, str):
            facets = self._named_boundary(facets)
        elif isinstance(facets, (set, list, tuple)) and all(
                isinstance(f, str) for f in facets):
            facets = np.concatenate([self._named_boundary(f) for f in facets])
        return np.unique(self.mesh.facets[:, np.asarray(facets)])

    def _named_boundary(self, name):
        boundaries = self.mesh.boundaries or {}
        if name not in boundaries:
            raise ValueError(f"the mesh has no boundary named {name!r}; it has "
                             f"{sorted(boundaries)}")
        return np.asarray(boundaries[name])

    def boundary(self, facets=None, intorder=None):
        """The RK facet basis on (part of) the boundary, for traction loads."""
        return RKFacetBasis(self, facets, intorder)


class RKFacetBasis(FacetViews, RKBase):
    """The particles of an :class:`RKBasis` seen from boundary facets.

    Used for boundary integrals (pressure and traction loads) with
    scikit-fem forms; ``w.n`` holds the outward unit normal.

    Parameters
    ----------
    basis : RKBasis
        The cell basis whose particles and supports are used.
    facets : str, set of str or array, optional
        Named boundary (boundaries) or facet indices; default all.
    intorder : int, optional
        Quadrature degree on the facets; default that of ``basis``.  Keep the
        default for loads in a VCI patch test: the correction is built with
        that boundary quadrature.  For nodal schemes the default is the
        composite rule of the smoothing cells' boundary segments.
    """

    def __init__(self, basis, facets=None, intorder=None):
        self.parent = basis
        mesh = basis.mesh
        if isinstance(facets, str):
            facets = basis._named_boundary(facets)
        elif isinstance(facets, (set, list, tuple)) and all(
                isinstance(f, str) for f in facets):
            facets = np.concatenate([basis._named_boundary(f) for f in facets])
        quadrature = None
        if intorder is None and basis.integration in NODAL_SCHEMES:
            # the points of the smoothing cells' boundary segments
            quadrature = boundary_rule(basis.segment_points, mesh)
        geometry = facet_geometry(mesh, basis.intorder if intorder is None
                                  else intorder, facets, quadrature)
        xb = geometry.global_coordinates().reshape(mesh.dim(), -1)
        regions = getattr(basis, "_regions", None)
        table = basis._shape_table(xb, labels=None if regions is None else
                                   regions.points_of_cells(mesh.f2t[0, geometry.find],
                                                           geometry.X.shape[-1]))
        self.radius = basis.radius
        self._setup(mesh, geometry, table, basis.nodes, basis.vector, release=True)

    def default_parameters(self):
        return self.geometry.default_parameters()
