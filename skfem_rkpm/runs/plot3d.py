"""Figures of a 3D run: the deformed surface coloured by the equivalent
plastic strain (``deformed.png``, matplotlib's 3D axes) and a section
through the middle of the part (``section.png``: the particles of the
layer nearest to the middle plane in y, at their current x and z).  Axes
carry the scene's length unit."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.cm import ScalarMappable  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from ..meshes import local_spacing  # noqa: E402
from .io import nodal_displacements, nodal_plastic_strain  # noqa: E402

__all__ = ["plot_surface", "plot_section", "section_layer", "figures_3d"]

#: the axis across the section and the two drawn in it (x horizontal, z up)
SECTION_AXIS, SECTION_PLANE = 1, (0, 2)


def _unit(scene):
    return scene["model"]["length_unit"] if scene is not None else None


def _label(name, scene):
    unit = _unit(scene)
    return f"{name} ({unit})" if unit else name


def plot_surface(ax, problem, d, title="", vmax=None, scene=None):
    """The boundary faces of the deformed mesh on the 3D axes ``ax``, each
    coloured by the mean equivalent plastic strain of its vertices.

    Returns the :class:`~matplotlib.cm.ScalarMappable` for a colour bar.
    """
    mesh = problem.basis.mesh
    x = mesh.p + nodal_displacements(problem.basis, d).T
    faces = mesh.facets[:, mesh.boundary_facets()]  # scikit-fem orders them around
    alpha = nodal_plastic_strain(problem)
    vmax = vmax if vmax is not None else max(float(alpha.max()), 1e-12)
    colours = ScalarMappable(Normalize(0.0, vmax), "viridis")
    polygons = np.moveaxis(x[:, faces], 0, -1).transpose(1, 0, 2)  # (faces, corners, 3)
    surface = Poly3DCollection(polygons, facecolors=colours.to_rgba(alpha[faces].mean(axis=0)),
                               edgecolors="0.25", linewidths=0.3)
    ax.add_collection3d(surface)
    low, high = x.min(axis=1), x.max(axis=1)
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    ax.set_box_aspect(np.maximum(high - low, 1e-3 * np.max(high - low)))
    for axis, name in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), "xyz"):
        axis(_label(name, scene))
    ax.set_title(title)
    colours.set_array(alpha)
    return colours


def section_layer(mesh):
    """``(vertices, Y)``: the vertices of the layer nearest to the middle plane
    of the mesh in y (within a quarter of the median spacing of the nearest
    vertex's reference y; of two as near, the lower), and that y."""
    Y = mesh.p[SECTION_AXIS]
    distance = np.abs(Y - 0.5 * (Y.min() + Y.max()))
    # of two layers as near (an odd number of cells), the lower one
    nearest = Y[distance <= distance.min() + 1e-9 * np.ptp(Y)].min()
    width = 0.25 * np.nanmedian(local_spacing(mesh))
    return np.flatnonzero(np.abs(Y - nearest) <= width), float(nearest)


def plot_section(ax, problem, d, title="", vmax=None, scene=None):
    """The particles of :func:`section_layer` at their current positions in
    the x-z plane, coloured by ε̄ᵖ, over the deformed faces of the cells that
    lie in that layer (structured meshes).  Returns the scatter artist."""
    mesh = problem.basis.mesh
    x = mesh.p + nodal_displacements(problem.basis, d).T
    layer, Y = section_layer(mesh)
    inside = np.zeros(mesh.nvertices, bool)
    inside[layer] = True
    h, v = SECTION_PLANE
    faces = mesh.facets[:, np.all(inside[mesh.facets], axis=0)]
    for face in faces.T:
        ring = np.append(face, face[0])
        ax.plot(x[h, ring], x[v, ring], color="0.8", lw=0.5, zorder=1)
    art = ax.scatter(x[h, layer], x[v, layer], c=nodal_plastic_strain(problem)[layer], s=14,
                     cmap="viridis", vmin=0.0, vmax=vmax, zorder=2)
    ax.set_aspect("equal")
    unit = _unit(scene)
    where = f"section Y = {Y:.4g}" + (f" {unit}" if unit else "")
    ax.set_title(f"{title}\n{where}" if title else where)
    ax.set_xlabel(_label("x", scene))
    ax.set_ylabel(_label("z", scene))
    return art


def figures_3d(sim, result, title):
    """``{"deformed.png": surface, "section.png": section}`` of a 3D run."""
    scene = sim.scene
    fig = plt.figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot(projection="3d")
    colours = plot_surface(ax, sim.problem, result.d, title, scene=scene)
    fig.colorbar(colours, ax=ax, label="equivalent plastic strain", shrink=0.7, pad=0.1)
    figures = {"deformed.png": fig}
    fig, ax = plt.subplots(figsize=(7.0, 6.0))
    art = plot_section(ax, sim.problem, result.d, title, scene=scene)
    fig.colorbar(art, ax=ax, label="equivalent plastic strain")
    figures["section.png"] = fig
    return figures
