"""``det F`` of the deformation map itself, sampled in every background cell.

Newton checks ``det F`` at the quadrature points, and the drawn cells
(:func:`~skfem_rkpm.runs.io.corner_jacobians`) are the bilinear (trilinear)
maps through the moved particles.  Neither is the map the discretization
stands for between those points: for RK functions ``x = X + Σ_I Ψ_I(X) d_I``
with ``F = I + Σ_I d_I ⊗ ∂Ψ_I/∂X`` (Eq. 3.30), for finite elements the
element interpolation.  A drawn cell may fold while that map stays one to
one (the particles' smooth functions bend where the straight edges cross),
and the map may fold between Gauss points while every one of them is fine.

:class:`MapSampler` samples the map's ``det F`` on a grid of reference points
in every cell of the basis's mesh (its corners, edges and interior; for the
axisymmetric model with the hoop stretch ``F_θθ = 1 + u_r/R``) and
:meth:`MapSampler.check` reports the worst point (:class:`MapValidity`).
For RK functions the shape functions at the samples are built once (they
live in material coordinates), so a check costs a few sparse products; for
a vector finite element the scalar shape functions at the samples are kept
and combined with the coefficients of each component, as scikit-fem's
``interpolate`` does, without its passes over the zero components.
"""

from dataclasses import dataclass

import numpy as np
from skfem.element import ElementVector

from .kinematics import MODELS

__all__ = ["MapSampler", "MapValidity", "reference_samples", "map_validity"]

#: sample points per reference axis by default: 5 x 5 in 2D, 4 x 4 x 4 in 3D
PER_AXIS = {2: 5, 3: 4}
#: samples of a mesh by default at most (fewer per axis on large meshes, the
#: corners always): the shape functions at 1e5 points take ~0.1 GB in 3D
MAX_SAMPLES = 100_000


def reference_samples(mesh, per_axis=None):
    """Sample points of the reference cell of ``mesh``, shape (dim, n): a
    tensor grid of ``per_axis`` points per axis over [0, 1] (quadrilaterals,
    hexahedra), or the points ``i / (per_axis - 1)`` with coordinates
    summing to at most 1 (triangles, tetrahedra); the corners included."""
    dim = mesh.dim()
    per_axis = PER_AXIS.get(dim, 5) if per_axis is None else int(per_axis)
    if per_axis < 2:
        raise ValueError(f"per_axis = {per_axis}: give at least 2 sample points per "
                         f"axis (the corners of the cell)")
    g = np.linspace(0.0, 1.0, per_axis)
    grid = np.array(np.meshgrid(*([g] * dim), indexing="ij")).reshape(dim, -1)
    if mesh.refdom.nnodes == dim + 1:  # a simplex
        grid = grid[:, grid.sum(axis=0) <= 1.0 + 1e-12]
    return grid


@dataclass
class MapValidity:
    """The worst sample of a deformation map (:meth:`MapSampler.check`)."""

    #: the smallest sampled ``det F``
    min_det: float
    #: the cell it is in, its material point and its current position
    cell: int
    X: np.ndarray
    x: np.ndarray
    #: the cells with a sample at ``det F <= 0``
    folded_cells: np.ndarray
    #: the samples at ``det F <= 0``, all samples, all cells
    folded_points: int
    npoints: int
    ncells: int
    #: "RK" or "FEM": whose map
    kind: str = "RK"

    @property
    def valid(self):
        """No sample has ``det F <= 0``."""
        return self.folded_points == 0

    def describe(self):
        """One sentence: valid with its smallest ``det F``, or where it folds."""
        where = (f"X = ({_coords(self.X)}) of cell {self.cell}, now at "
                 f"x = ({_coords(self.x)})")
        per_cell = self.npoints // max(self.ncells, 1)
        if self.valid:
            return (f"the {self.kind} map itself is valid: det F >= {self.min_det:.3g} at "
                    f"all {self.npoints} sample points ({per_cell} in each of "
                    f"{self.ncells} cells; smallest at {where})")
        return (f"the {self.kind} map itself folds: det F <= 0 at {self.folded_points} of "
                f"{self.npoints} sample points in {self.folded_cells.size} of "
                f"{self.ncells} cells (smallest det F = {self.min_det:.3g} at {where})")


def _coords(v):
    return ", ".join(f"{c:.4g}" for c in v)


class MapSampler:
    """``det F`` of the deformation map of ``basis`` on sample points in
    every cell of its mesh.

    Parameters
    ----------
    basis : RKBasis or skfem CellBasis
        A vector basis (``d`` interleaved per component, as both use).
    model : {"plane_strain", "axisymmetric", "3d"}
        ``axisymmetric``: ``x`` is the radius ``R`` and the hoop stretch
        ``1 + u_r/R`` multiplies the in-plane ``det F`` (on the axis, where
        ``u_r/R`` has the limit ``∂u_r/∂R``, that one).
    per_axis : int, optional
        Sample points per reference axis (:func:`reference_samples`); by
        default :data:`PER_AXIS`, fewer where the mesh would have more than
        :data:`MAX_SAMPLES` (2, the corners, at the least).
    """

    def __init__(self, basis, model="plane_strain", per_axis=None):
        if model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, not {model!r}")
        mesh = basis.mesh
        self.dim = mesh.dim()
        if (model == "3d") != (self.dim == 3):
            raise ValueError(f"model {model!r} on a {self.dim}D mesh: use \"3d\" for 3D "
                             f"meshes and \"plane_strain\" or \"axisymmetric\" for 2D ones")
        self.basis, self.model = basis, model
        self.ncells = mesh.t.shape[1]
        if per_axis is None:
            fit = int(np.floor((MAX_SAMPLES / self.ncells) ** (1.0 / self.dim) + 1e-9))
            per_axis = max(2, min(PER_AXIS.get(self.dim, 5), fit))
        ref = reference_samples(mesh, per_axis)
        self.per_cell = ref.shape[1]
        self.X = mesh.mapping().F(ref)  # (dim, ncells, n)
        self.kind = "RK" if hasattr(basis, "_shape_table") else "FEM"
        if self.kind == "RK":
            table = basis._shape_table(self.X.reshape(self.dim, -1))
            self._values = table.matrix().tocsr()
            self._grads = [table.gradient_matrix(k).tocsr() for k in range(self.dim)]
        else:  # the element's own interpolation at the samples
            weights = np.full(self.per_cell, 1.0 / self.per_cell)
            self._scalar = None
            if isinstance(basis.elem, ElementVector) and basis.elem.dim == self.dim:
                scalar = type(basis)(mesh, basis.elem.elem, quadrature=(ref, weights))
                self._scalar = [(np.array(scalar.basis[j][0]), np.array(scalar.basis[j][0].grad))
                                for j in range(scalar.Nbfun)]  # values, gradients
                # the vector dof of scalar function j, component i: row dim * j + i
                # (ElementVector numbers them so); the vector basis of all cells
                self._dofs = type(basis)(mesh, basis.elem, quadrature=(
                    ref[:, :1], weights[:1])).element_dofs
            else:
                self._fem = type(basis)(mesh, basis.elem, quadrature=(ref, weights))

    def _fields(self, d):
        """``u`` (dim, n) and ``∂u_i/∂X_k`` (dim, dim, n) at the samples."""
        d = np.asarray(d, float)
        c = self.dim
        if self.kind == "RK":
            u = np.array([self._values @ d[i::c] for i in range(c)])
            grad = np.array([[G @ d[i::c] for G in self._grads] for i in range(c)])
            return u, grad
        if self._scalar is not None:  # Σ_j d_(j, i) φ_j, φ_j in the order of interpolate
            n = self.X[0].size
            u, grad = np.zeros((c,) + self.X.shape[1:]), np.zeros((c, c) + self.X.shape[1:])
            for j, (phi, dphi) in enumerate(self._scalar):
                for i in range(c):
                    values = d[self._dofs[c * j + i]][:, None]
                    u[i] += values * phi
                    grad[i] += values * dphi
            return u.reshape(c, n), grad.reshape(c, c, n)
        field = self._fem.interpolate(d)
        return (np.asarray(field).reshape(c, -1),
                np.asarray(field.grad).reshape(c, c, -1))

    def jacobians(self, d):
        """``det F`` at the samples, shape (ncells, samples per cell), and
        the displacements there (dim, ncells, samples per cell)."""
        u, grad = self._fields(d)
        # F = I + ∂u/∂X entry by entry, each entry an array over the samples
        F = np.zeros((3, 3, u.shape[1]))
        F[:self.dim, :self.dim] = grad
        for i in range(3):
            F[i, i] += 1.0
        if self.model == "axisymmetric":
            R = self.X[0].ravel()
            on_axis = np.abs(R) <= 1e-12 * max(np.abs(R).max(), 1.0)
            with np.errstate(divide="ignore", invalid="ignore"):
                F[2, 2] = np.where(on_axis, F[0, 0], 1.0 + u[0] / R)
        J = _determinant(F)
        return J.reshape(self.ncells, self.per_cell), u.reshape(self.X.shape)

    def check(self, d):
        """The worst sample of the map of coefficients ``d`` (:class:`MapValidity`)."""
        J, u = self.jacobians(d)
        cell, k = np.unravel_index(np.argmin(J), J.shape)
        bad = J <= 0
        X = self.X[:, cell, k]
        return MapValidity(min_det=float(J[cell, k]), cell=int(cell), X=X.copy(),
                           x=X + u[:, cell, k], folded_cells=np.flatnonzero(bad.any(axis=1)),
                           folded_points=int(bad.sum()), npoints=J.size, ncells=self.ncells,
                           kind=self.kind)


def _determinant(f):
    """``det F`` of 3x3 matrices ``f`` (3, 3, n), expanded along the first row
    with the cofactors of :func:`~skfem_rkpm.mechanics.kinematics.inverse_and_determinant`
    (the same operations, so the same values), without the inverse."""
    return (f[0, 0] * (f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1])
            + f[0, 1] * (f[1, 2] * f[2, 0] - f[1, 0] * f[2, 2])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0]))


def map_validity(basis, d, model="plane_strain", per_axis=None):
    """:meth:`MapSampler.check` of a new sampler: the worst sampled ``det F``
    of the deformation map of ``basis`` with coefficients ``d``."""
    return MapSampler(basis, model, per_axis).check(d)
