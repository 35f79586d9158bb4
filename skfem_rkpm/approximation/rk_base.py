"""What cell and facet RK bases share: dofs, local functions, fields.

:class:`RKBase` is scikit-fem's ``AbstractBasis`` face of an RK shape table:
per background cell (or facet) the particles whose supports reach its
quadrature points, padded to a common number of local functions
(:mod:`.cell_layout`), the interleaved dof numbering of vector fields, and
``interpolate``.  :class:`~.basis.RKBasis` and :class:`~.basis.RKFacetBasis`
build the tables.
"""

import warnings

import numpy as np
from skfem.assembly.basis import AbstractBasis
from skfem.element import DiscreteField

from . import cell_layout
from ..forms import PairwiseLoopWarning, pairwise_loop_message, scikit_fem_caller

__all__ = ["RKBase", "EXACT_ON_DEMAND"]

#: ``_exact_grads`` of a basis that keeps only its corrected gradients
#: (``"vci_symmetric"``): the exact ones are computed again when a pair table
#: with them is asked for (:meth:`RKBase._exact_pairs`)
class _ExactOnDemand:
    """The one value of :data:`EXACT_ON_DEMAND`, the same after copies."""

    def __repr__(self):
        return "EXACT_ON_DEMAND"

    def __reduce__(self):
        return "EXACT_ON_DEMAND"  # copies and pickles are the module's object


EXACT_ON_DEMAND = _ExactOnDemand()


class RKBase(AbstractBasis):
    """What cell and facet RK bases share: dofs, local functions, fields."""

    def _setup(self, mesh, geometry, table, nodes, vector, release=False, cells=None):
        """Lay out ``table`` per cell (:func:`.cell_layout.padded`), with
        its ``test_grads`` where it has them (VCI).

        The basis keeps the padded arrays (and, with VCI, the exact gradients
        as pairs until :meth:`_exact_layout` lays them out for the trial
        basis); :attr:`table` and :attr:`test_grads` gather the pair layout
        from them when asked.  ``release``: the table's pair arrays may be
        dropped while they are laid out (the caller keeps no use for them).
        ``cells``: :func:`.cell_layout.cell_particles` of ``table`` if known.
        """
        self.mesh = mesh
        self.geometry = geometry
        self.X, self.W = geometry.X, geometry.W
        self.dx = geometry.dx
        self.nelems = geometry.nelems
        self.nodes = nodes
        self.ncomp = nodes.shape[0] if vector else 1
        self.tind = None
        self.mapping = geometry.mapping
        nqp = self.X.shape[-1]
        self._pairs = table.indptr
        self._cells = cells or cell_layout.cell_particles(table, self.nelems, nqp)
        self.element_nodes, self.values, self.grads, self._exact_grads = cell_layout.padded(
            table, self.nelems, nqp, self._cells, release=release)
        self.Nbfun = self.ncomp * self.element_nodes.shape[0]

    @property
    def npairs(self):
        """Pairs of a particle and a quadrature point its support reaches."""
        return int(self._pairs[-1])

    @property
    def table(self):
        """The shape functions and their exact gradients in pair (CSR) layout,
        a :class:`~.shape.ShapeTable` gathered from the padded arrays at every
        call (the basis keeps one copy of each value: the per-cell layout)."""
        return self._pair_table()

    def _pair_table(self, test=False, rows=None):
        """:attr:`table` (of the quadrature points ``rows`` only, if given),
        with its ``test_grads`` if ``test`` and the basis has corrected ones
        (VCI)."""
        entries, exact = self._entries(rows), self._exact_grads
        laid_out = exact is None or (exact is not EXACT_ON_DEMAND and exact.ndim == 4)
        table = cell_layout.pair_table(
            entries, self.nodes.shape[1], self._cells, self.element_nodes, self.values,
            (self.grads if exact is None else exact) if laid_out else None,
            self.grads if test and exact is not None else None)
        if exact is EXACT_ON_DEMAND:
            again = self._exact_pairs(rows)
            if not (np.array_equal(again.indptr, table.indptr)
                    and np.array_equal(again.indices, table.indices)):
                raise RuntimeError("the shape functions computed again have other pairs "
                                   "than the basis: its particles or supports changed")
            table.grads = again.grads
            if rows is None:  # kept from now on, as the exact gradients of a VCI basis
                self._exact_grads = again.grads
        elif not laid_out:  # the exact gradients, still pairs
            table.grads = exact[:, entries[1]]
        return table

    def _exact_pairs(self, rows=None):
        """The shape table at the quadrature points ``rows`` (default all)
        computed again, for :data:`EXACT_ON_DEMAND`."""
        raise NotImplementedError(f"{type(self).__name__} keeps its exact gradients")

    def _exact_layout(self):
        """The exact gradients of a VCI basis in the padded layout (dim, nloc,
        nelems, nqp), laid out from their pairs at the first call."""
        if self._exact_grads.ndim == 2:
            self._exact_grads = cell_layout.scattered(self._exact_grads,
                                                      self._entries()[-1], self.values.shape)
        return self._exact_grads

    @property
    def test_grads(self):
        """The test functions' gradients in the pair order of :attr:`table`,
        shape (dim, npairs): the VCI-corrected ones where they differ from
        the exact gradients, gathered from the padded arrays."""
        if self.grads is None:
            return None
        return cell_layout.gathered(self.grads, self._entries()[-1])

    def _entries(self, rows=None):
        """:func:`.cell_layout.pair_entries` of the pairs of the quadrature
        points ``rows`` (default all)."""
        return cell_layout.pair_entries(self._pairs, self._cells, self.nelems,
                                        self.X.shape[-1], rows)

    # -- dof numbering -----------------------------------------------------
    @property
    def N(self):
        return self.ncomp * self.nodes.shape[1]

    @property
    def nnodes(self):
        return self.nodes.shape[1]

    @property
    def element_dofs(self):
        c = self.ncomp
        dofs = c * self.element_nodes[:, None, :] + np.arange(c)[None, :, None]
        return dofs.reshape(-1, self.nelems)

    @property
    def doflocs(self):
        """Location of every coefficient: its particle, shape (dim, N).

        Unless ``interpolating=True``, the coefficients are not the field's
        values there (they are generalized displacements): ``f(basis.doflocs)``
        is not the coefficient vector of ``f``; use :meth:`RKBasis.project`,
        and :meth:`RKBasis.nodal_values` to read values at the particles.
        """
        return np.repeat(self.nodes, self.ncomp, axis=1)

    @property
    def vector(self):
        return self.ncomp > 1

    # -- local functions for scikit-fem forms -----------------------------
    @property
    def basis(self):
        """Per local function a tuple ``(DiscreteField,)`` as in scikit-fem,
        read by scikit-fem's loop over local functions
        (``form.assemble(basis)``, ``skfem.asm``): warns with
        :class:`~skfem_rkpm.forms.PairwiseLoopWarning`, at the line that made
        the call, with the fast replacement of that call (see
        :func:`~skfem_rkpm.forms.pairwise_loop_message`), once per basis.  Without
        the warning: :attr:`local_fields`."""
        if not getattr(self, "_loop_warned", False):
            self._loop_warned = True
            call, level = scikit_fem_caller()
            warnings.warn(pairwise_loop_message(self, call), PairwiseLoopWarning,
                          stacklevel=level)
        return self.local_fields

    @property
    def local_fields(self):
        """Per local function a tuple ``(DiscreteField,)`` (test gradients)."""
        if getattr(self, "_basis", None) is None:
            self._basis = self._local_functions(self.values, self.grads)
        return self._basis

    def _local_functions(self, values, grads):
        out = []
        c = self.ncomp
        for k in range(self.element_nodes.shape[0]):
            g = None if grads is None else grads[:, k]
            if c == 1:
                out.append((DiscreteField(values[k], g),))
                continue
            for comp in range(c):
                v = np.zeros((c,) + values[k].shape)
                v[comp] = values[k]
                gv = None
                if g is not None:
                    gv = np.zeros((c,) + g.shape)
                    gv[comp] = g
                out.append((DiscreteField(v, gv),))
        return out

    def default_parameters(self):
        return self.geometry.default_parameters()

    def global_coordinates(self):
        return self.geometry.global_coordinates()

    def mesh_parameters(self):
        return self.geometry.mesh_parameters()

    # -- fields -------------------------------------------------------------
    def _components(self, w):
        w = np.asarray(w)
        if w.shape[0] != self.N:
            raise ValueError(
                f"coefficient vector has length {w.shape[0]}, the basis has "
                f"{self.N} dofs ({self.nnodes} particles x {self.ncomp} components)"
            )
        return w.reshape(self.nnodes, self.ncomp).T

    def _shape_of(self, a):
        return a.reshape(a.shape[:-1] + (self.nelems, -1))

    def interpolate(self, w):
        """Field and its exact gradient at the quadrature points.

        Returns a ``DiscreteField`` of shape (nelems, nqp) for scalar bases
        or (dim, nelems, nqp) for vector bases, with ``.grad``.
        """
        comps = self._components(w)
        table = self.table
        value = self._shape_of(comps @ table.matrix().T)
        grad = None
        if table.grads is not None:
            grad = np.stack([comps @ table.gradient_matrix(k).T
                             for k in range(self.nodes.shape[0])], axis=-2)
            grad = self._shape_of(grad)
        if self.ncomp == 1:
            value = value[0]
            grad = None if grad is None else grad[0]
        return DiscreteField(value, grad)

    def zeros(self, dtype=None):
        return np.zeros(self.N, dtype=dtype)

    def __repr__(self):
        return (f"<skfem_rkpm {type(self).__name__}: {self.nnodes} particles, "
                f"{self.N} dofs, {self.nelems} cells x {self.X.shape[-1]} "
                f"quadrature points, up to {self.element_nodes.shape[0]} "
                "particles per cell>")
