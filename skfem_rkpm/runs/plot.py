"""Figures of a run: deformed particles coloured by plastic strain
(``deformed.png``; 3D: the deformed surface and ``section.png``, see
:mod:`skfem_rkpm.runs.plot3d`), tool forces and reactions (``forces.png``)
and, for a ring scene, the inner-diameter change against the height
reduction (``calibration.png``).  Axes carry the scene's units
(``model.length_unit``, ``model.force_unit``)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .folder import atomic_path  # noqa: E402
from .io import nodal_displacements, nodal_plastic_strain  # noqa: E402
from .plot3d import figures_3d, plot_section  # noqa: E402
from .stops import _moving_tools, height_reduction  # noqa: E402

__all__ = ["nodal_plastic_strain", "plot_deformed", "plot_history", "save_run_figures",
           "run_figures", "height_reduction", "inner_diameter_change", "friction_text",
           "force_label", "force_axis_label", "calibration_figure"]


def _axis_names(scene):
    return {"axisymmetric": ("r", "z"), "3d": ("x", "y", "z")}.get(scene["model"]["type"],
                                                                  ("x", "y"))


def plot_deformed(ax, problem, d, title="", vmax=None, show_cells=True, scene=None):
    """Particles at their current positions coloured by ε̄ᵖ, over the deformed
    cells; with ``scene`` the axes are labelled in its length unit.  In 3D
    the section through the middle (:func:`skfem_rkpm.runs.plot3d.plot_section`)."""
    mesh = problem.basis.mesh
    if mesh.dim() == 3:
        return plot_section(ax, problem, d, title, vmax, scene)
    x = mesh.p + nodal_displacements(problem.basis, d).T
    if show_cells:
        for cell in mesh.t.T:
            ring = np.append(cell, cell[0])
            ax.plot(x[0, ring], x[1, ring], color="0.8", lw=0.5, zorder=1)
    art = ax.scatter(x[0], x[1], c=nodal_plastic_strain(problem), s=14, cmap="viridis",
                     vmin=0.0, vmax=vmax, zorder=2)
    ax.set_aspect("equal")
    ax.set_title(title)
    if scene is not None:
        unit = scene["model"]["length_unit"]
        names = _axis_names(scene)
        ax.set_xlabel(f"{names[0]} ({unit})")
        ax.set_ylabel(f"{names[1]} ({unit})")
    return art


def tool_travel(sim, t):
    """``(name, travel)``: the first moving tool and its distance travelled
    at load factors ``t`` (length units); None without a moving tool."""
    moving = _moving_tools(sim.scene)
    if not moving:
        return None
    name, motion = next(iter(moving.items()))
    return name, np.asarray(t, float) * float(np.linalg.norm(motion))


def inner_diameter_change(sim, gauges, point="inner_mid"):
    """Change of the inner diameter in percent, ``(r - R) / R · 100``, of the
    followed point ``point`` (the ring scenes' inner surface at mid-height)
    at every row of ``gauges``; None if the scene does not follow it."""
    if point not in sim.points or not gauges:
        return None
    R = float(sim.points[point][0])
    return 100.0 * (np.array([g[f"{point} x"] for g in gauges]) - R) / R


def friction_text(scene):
    """``μ = 0.15`` (one tool), ``platen μ = 0.1, die sticking`` (several)."""
    tools = {name.split(".", 1)[1]: section["friction"] for name, section in scene.items()
             if name.startswith("tools.")}
    words = {name: "sticking" if mu == "stick" else f"μ = {mu:g}" for name, mu in tools.items()}
    if len(words) == 1:
        return next(iter(words.values()))
    return ", ".join(f"{name} {text}" for name, text in words.items())


def force_label(key, scene):
    """A reaction key of the history as a legend label: ``platen, force z``
    for a tool, ``boundary bottom, reaction z`` for ``bottom[1]``."""
    names = _axis_names(scene)
    if key.endswith("]"):
        boundary, component = key[:-1].split("[", 1)
        if not component.isdigit():  # a skew condition: along its direction n=(...)
            return f"boundary {boundary}, reaction along {component}"
        return f"boundary {boundary}, reaction {names[int(component)]}"
    return f"{key}, force {names[-1]}"


def plot_history(ax, history, key, label, scale=1.0, x=None):
    """A reaction (or gauge) of every step (its last component) against the
    load factor, or against ``x`` (one value per step) when given."""
    t = [r.t for r in history] if x is None else x
    values = []
    for r in history:
        v = np.atleast_1d(r.reactions[key]) if key in r.reactions else [np.nan]
        values.append(v[-1] * scale)
    ax.plot(t, values, "o-", ms=3, label=label)
    if x is None:
        ax.set_xlabel("load factor t")
    ax.grid(True, alpha=0.3)


def force_axis_label(scene):
    full = {"axisymmetric": ", full ring", "3d": ""}.get(scene["model"]["type"],
                                                        ", per unit thickness")
    return f"force on the part ({scene['model']['force_unit']}{full})"


def save_run_figures(sim, result, out, folder=None):
    """``deformed.png``, ``forces.png`` and, for a scene that follows the
    point ``inner_mid`` with a moving tool (the ring), ``calibration.png``
    of one run in folder ``out`` (:func:`run_figures`), each written
    atomically; ``folder``: the :class:`~skfem_rkpm.runs.folder.RunFolder`
    of ``out``, whose manifest lists them before they are written."""
    for name, fig in run_figures(sim, result).items():
        if folder is not None:
            folder.claim(name)
        with atomic_path(Path(out) / name) as tmp:
            fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")
        plt.close(fig)


def run_figures(sim, result):
    """The figures of :func:`save_run_figures`, ``{file name: Figure}``."""
    figures = {}
    scene, history = sim.scene, result.history
    t = np.array([r.t for r in history])
    reduction = height_reduction(sim, t)
    travel = tool_travel(sim, t)
    unit = scene["model"]["length_unit"]
    if reduction is not None and len(t):
        progress, x, xlabel = (f"height reduction {reduction[-1]:.3g} %", reduction,
                               "height reduction (%)")
    elif travel is not None and len(t):
        progress, x, xlabel = (f"{travel[0]} travel {travel[1][-1]:.3g} {unit}", travel[1],
                               f"{travel[0]} travel ({unit})")
    else:
        progress, x, xlabel = f"t = {t[-1] if len(t) else 0:.3g}", None, None
    title = f"{_run_title(sim)}\n{progress}"
    if sim.mesh.dim() == 3:
        figures.update(figures_3d(sim, result, title))
    else:
        figures["deformed.png"] = _deformed_figure(sim, result, title)
    keys = sorted({k for r in history for k in r.reactions},
                  key=lambda k: (k.endswith("]"), k))  # tools first
    if keys:
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        for key in keys:
            plot_history(ax, history, key, force_label(key, scene), x=x)
        if xlabel is not None:
            ax.set_xlabel(xlabel)
        ax.set_ylabel(force_axis_label(scene))
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4), useMathText=True)
        ax.set_title(_run_title(sim))
        ax.legend(fontsize=8)
        fig.tight_layout()
        figures["forces.png"] = fig
    change = inner_diameter_change(sim, result.gauges)
    if change is not None and reduction is not None:
        figures["calibration.png"] = calibration_figure(sim, np.r_[0.0, reduction],
                                                        np.r_[0.0, change])
    return figures


def _run_title(sim):
    """``ring (RKPM), μ = 0.15``; without tools no friction."""
    friction = friction_text(sim.scene)
    return (f"{sim.scene['model']['title'] or 'run'} ({sim.method.upper()})"
            + (f", {friction}" if friction else ""))


def _deformed_figure(sim, result, title):
    """``deformed.png`` of a 2D run, sized to the part's aspect ratio."""
    x = sim.mesh.p + nodal_displacements(sim.basis, result.d).T
    aspect = np.ptp(x[1]) / max(np.ptp(x[0]), 1e-300)
    wide = aspect < 0.8  # a flat part: the colour bar below it
    fig, ax = plt.subplots(figsize=(7.0, float(np.clip(6.0 * aspect + 2.4, 3.6, 7.5))))
    art = plot_deformed(ax, sim.problem, result.d, title, scene=sim.scene)
    fig.colorbar(art, ax=ax, label="equivalent plastic strain",
                 orientation="horizontal" if wide else "vertical",
                 fraction=0.08 if wide else 0.05, pad=0.18 if wide else 0.04)
    return fig


def calibration_figure(sim, reduction, change):
    """The run's inner-diameter change against height reduction, drawn as
    one curve of the friction calibration chart
    (:func:`skfem_rkpm.runs.calibration.plot_calibration`)."""
    from .calibration import plot_calibration

    scene = sim.scene
    tools = [s["friction"] for n, s in scene.items() if n.startswith("tools.")]
    key = tools[0] if len(tools) == 1 else friction_text(scene)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    if isinstance(key, str) and key != "stick":  # several tools: one labelled curve
        ax.plot(reduction, change, lw=1.6, label=key)
        ax.set_xlabel("height reduction (%)")
        ax.set_ylabel("inner diameter change (%)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    else:
        plot_calibration({key: (reduction, change)}, ax=ax,
                         title=f"{scene['model']['title'] or 'run'} "
                               f"({sim.method.upper()}): inner diameter at mid-height")
    fig.tight_layout()
    return fig
