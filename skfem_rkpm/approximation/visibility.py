"""Supports cut at material interfaces: the visibility criterion.

A particle's kernel is taken as zero at evaluation points in another
material region than its own: the RK functions (Eq. 3.16-3.19) at a point
of region ``r`` are built from the particles of ``r`` only.  A particle
belongs to every region one of whose cells it is a vertex (or a dof
location, for a quadratic element's particles) of, so the particles on an
interface are shared by the regions on both sides.  Each region then
reproduces the monomials up to the basis order by itself (a field linear in
each region, continuous across the interface, is reproduced exactly), and
the functions of the two sides may kink along the interface as the
solution of a two-material problem does.  With ``interpolating=True`` the
two sides agree at the shared particles; between them the traces differ by
the interpolation error of each side.

:class:`Regions` holds the region of every cell and the particles of every
region, and builds shape tables region by region
(:meth:`Regions.table`).
"""

import numpy as np

from .nodal_integration import NODAL_SCHEMES
from .shape import ShapeTable

__all__ = ["Regions", "cell_regions", "cut_supports"]


def cell_regions(mesh, interfaces):
    """The region of every cell (int array) and the regions' names.

    ``interfaces`` names the materials whose boundaries cut the supports:
    ``True`` or ``"subdomains"`` (every subdomain of ``mesh.subdomains``), a
    sequence of subdomain names or of cell index arrays, or a dict
    name -> cell indices.  Cells in none of them form one more region,
    ``"rest"``.
    """
    subdomains = mesh.subdomains or {}
    if interfaces is True or (isinstance(interfaces, str) and interfaces == "subdomains"):
        if not subdomains:
            raise ValueError("interfaces=True cuts the supports at the boundaries of "
                             "mesh.subdomains, and the mesh has none; give the cells "
                             "of each material, interfaces=[cells_a, cells_b]")
        interfaces = dict(subdomains)
    elif isinstance(interfaces, str):
        interfaces = [interfaces]
    if isinstance(interfaces, dict):
        named = list(interfaces.items())
    else:
        try:
            items = list(interfaces)
        except TypeError:
            raise ValueError(f"interfaces= takes True, subdomain names or cell index "
                             f"arrays, not {interfaces!r}") from None
        named = []
        for k, item in enumerate(items):
            if isinstance(item, str):
                if item not in subdomains:
                    raise ValueError(f"the mesh has no subdomain named {item!r}; it has "
                                     f"{sorted(subdomains)}")
                named.append((item, subdomains[item]))
            else:
                named.append((f"region {k}", item))
    if not named:
        raise ValueError("interfaces= names no region: give at least one subdomain")
    labels = np.full(mesh.nelements, -1, dtype=np.int64)
    names = []
    for k, (name, cells) in enumerate(named):
        cells = np.asarray(mesh.normalize_elements(cells)
                           if not isinstance(cells, np.ndarray) else cells)
        if cells.dtype == bool:
            cells = np.flatnonzero(cells)
        cells = cells.astype(np.int64).ravel()
        if cells.size and (cells.min() < 0 or cells.max() >= mesh.nelements):
            raise ValueError(f"the cells of {name} must be between 0 and "
                             f"{mesh.nelements - 1}")
        twice = cells[labels[cells] >= 0]
        if twice.size:
            raise ValueError(f"cell {twice[0]} is in {names[labels[twice[0]]]} and in "
                             f"{name}: the regions of interfaces= must not overlap")
        labels[cells] = k
        names.append(name)
    if np.any(labels < 0):
        labels[labels < 0] = len(names)
        names.append("rest")
    return labels, names


class Regions:
    """The regions of a basis with supports cut at material interfaces.

    Parameters
    ----------
    mesh : skfem.Mesh
    interfaces
        As :func:`cell_regions` takes it.
    cell_particles : ndarray, shape (nlocal, nelements)
        The particles of every cell (``mesh.t`` for vertex particles, a
        quadratic element's ``element_dofs``).
    nnodes : int
    """

    def __init__(self, mesh, interfaces, cell_particles, nnodes):
        self.mesh = mesh
        self.cells, self.names = cell_regions(mesh, interfaces)
        n = len(self.names)
        self.members = np.zeros((n, nnodes), dtype=bool)
        cell_particles = np.asarray(cell_particles)
        for r in range(n):
            self.members[r, cell_particles[:, self.cells == r].ravel()] = True
        # one region per particle, for tables at the particles themselves
        self.particle_region = np.argmax(self.members, axis=0)
        self._centroids = None

    @property
    def shared(self):
        """The particles that belong to more than one region."""
        return np.flatnonzero(self.members.sum(axis=0) > 1)

    def points_of_cells(self, cells, npoints):
        """The region of ``npoints`` points per cell of ``cells`` (None: all
        cells), cell-major."""
        return np.repeat(self.cells if cells is None else self.cells[np.asarray(cells)],
                         npoints)

    def locate(self, x):
        """The region of arbitrary points ``x`` (dim, n): that of the cell
        containing each point (the nearest cell centroid if the mesh's
        point location fails, e.g. for a point just outside)."""
        from scipy.spatial import cKDTree  # 0.1-0.15 s CPU to import: not on FEM runs

        x = np.atleast_2d(np.asarray(x, dtype=float))
        try:
            cells = np.asarray(self.mesh.element_finder()(*x), dtype=np.int64)
            if cells.shape != (x.shape[1],) or np.any(cells < 0):
                raise ValueError
        except Exception:  # noqa: BLE001 - any failure of skfem's finder
            if self._centroids is None:
                self._centroids = cKDTree(self.mesh.p[:, self.mesh.t].mean(axis=1).T)
            cells = self._centroids.query(x.T)[1]
        return self.cells[cells]

    def table(self, x, labels, build):
        """Shape table at ``x`` with the particles of each point's region.

        ``build(x, members)`` returns the table at points ``x`` of the
        particles ``members`` (sorted global indices), numbered locally.
        The pairs of each point keep the order of the particles.
        """
        labels = np.asarray(labels)
        npoints = x.shape[1]
        parts = []
        for r in np.unique(labels):
            points = np.flatnonzero(labels == r)
            members = np.flatnonzero(self.members[r])
            t = build(x[:, points], members)
            parts.append((points[t.rows], members[t.indices], t))
        rows = np.concatenate([p[0] for p in parts])
        order = np.argsort(rows, kind="stable")
        indices = np.concatenate([p[1] for p in parts])[order]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=npoints))])

        def joined(name, axis=-1):
            arrays = [getattr(p[2], name) for p in parts]
            if any(a is None for a in arrays):
                return None
            return np.take(np.concatenate(arrays, axis=axis), order, axis=axis)

        return ShapeTable(indptr, indices, joined("values"), joined("grads"),
                          self.members.shape[1], joined("kernel"))


def cut_supports(mesh, interfaces, particles, nodes, integration):
    """The :class:`Regions` of ``RKBasis(..., interfaces=...)``: the
    particles are the mesh vertices, or a quadratic element's dofs
    (``particles``, :class:`.element_particles.ElementParticles`)."""
    if integration in NODAL_SCHEMES:
        raise ValueError(f"interfaces= cuts the supports at the cells of the materials, "
                         f"and integration={integration!r} has no cells: use "
                         "integration='vci' or 'gauss'")
    if particles is not None:
        cell_particles = particles.fem.element_dofs
    elif mesh.t.max() < nodes.shape[1] <= mesh.p.shape[1] and np.array_equal(
            nodes, mesh.p[:, :nodes.shape[1]]):
        cell_particles = mesh.t
    else:
        raise ValueError("interfaces= assigns the particles to materials through the "
                         "cells they are vertices of: leave nodes=None (the particles "
                         "are the mesh vertices or the element's dofs)")
    return Regions(mesh, interfaces, cell_particles, nodes.shape[1])
