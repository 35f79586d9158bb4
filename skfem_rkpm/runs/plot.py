"""Figures of a run: deformed particles coloured by plastic strain, force curves."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .io import cell_averages, nodal_displacements  # noqa: E402

__all__ = ["nodal_plastic_strain", "plot_deformed", "plot_history", "save_run_figures"]


def nodal_plastic_strain(problem):
    """Equivalent plastic strain averaged from the cells to the mesh vertices
    (with nodal integration: the values at the particles)."""
    mesh = problem.basis.mesh
    if getattr(problem.basis, "nodal_quadrature", None) is not None:
        return problem.state.alpha
    cells = cell_averages(problem.state.alpha, problem.assembler.layout.dx)
    total = np.bincount(mesh.t.ravel(), np.tile(cells, mesh.t.shape[0]),
                        minlength=mesh.nvertices)
    count = np.bincount(mesh.t.ravel(), minlength=mesh.nvertices)
    return total / np.maximum(count, 1)


def plot_deformed(ax, problem, d, title="", vmax=None, show_cells=True):
    """Particles at their current positions coloured by ε̄ᵖ, over the deformed cells."""
    mesh = problem.basis.mesh
    x = mesh.p + nodal_displacements(problem.basis, d).T
    if show_cells:
        for cell in mesh.t.T:
            ring = np.append(cell, cell[0])
            ax.plot(x[0, ring], x[1, ring], color="0.8", lw=0.5, zorder=1)
    art = ax.scatter(x[0], x[1], c=nodal_plastic_strain(problem), s=14, cmap="viridis",
                     vmin=0.0, vmax=vmax, zorder=2)
    ax.set_aspect("equal")
    ax.set_title(title)
    return art


def plot_history(ax, history, key, label, scale=1.0):
    """A reaction (or gauge) of every step against the load factor."""
    t = [r.t for r in history]
    values = []
    for r in history:
        v = np.atleast_1d(r.reactions[key]) if key in r.reactions else [np.nan]
        values.append(v[-1] * scale)
    ax.plot(t, values, "o-", ms=3, label=label)
    ax.set_xlabel("load factor t")
    ax.grid(True, alpha=0.3)


def save_run_figures(sim, result, out):
    """``deformed.png`` and ``forces.png`` of one run in folder ``out``."""
    fig, ax = plt.subplots(figsize=(6, 5))
    art = plot_deformed(ax, sim.problem, result.d,
                        f"{sim.scene['model']['title'] or 'run'} ({sim.method}), "
                        f"t = {result.history[-1].t if result.history else 0:.3g}")
    fig.colorbar(art, ax=ax, label="equivalent plastic strain")
    fig.tight_layout()
    fig.savefig(out / "deformed.png", dpi=120)
    plt.close(fig)
    keys = sorted({k for r in result.history for k in r.reactions})
    if keys:
        fig, ax = plt.subplots(figsize=(6, 4))
        for key in keys:
            plot_history(ax, result.history, key, key)
        ax.set_ylabel("reaction / tool force")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / "forces.png", dpi=120)
        plt.close(fig)
