"""Side-by-side report of RKPM and FEM runs of one scene."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .folder import atomic_path, write_atomic  # noqa: E402
from .plot import (force_axis_label, force_label, friction_text, height_reduction,  # noqa: E402
                   inner_diameter_change, plot_deformed, plot_history)

__all__ = ["write_comparison"]


def _summary(sim, result):
    history = result.history
    forces = {k: np.atleast_1d(v) for k, v in (history[-1].reactions.items()
                                               if history else [])}
    unit = sim.scene["model"]["force_unit"]
    final_t = history[-1].t if history else 0.0
    reduction = height_reduction(sim, final_t)
    change = inner_diameter_change(sim, getattr(result, "gauges", None))
    return {
        "dofs": sim.basis.N,
        "completed": result.completed,
        "final t": final_t,
        **({"height reduction [%]": float(reduction)} if reduction is not None else {}),
        **({"inner diameter change [%]": float(change[-1])} if change is not None else {}),
        "steps": len(history),
        "Newton iterations": sum(r.iterations for r in history),
        "iterations/step": (sum(r.iterations for r in history) / len(history)
                            if history else float("nan")),
        "wall time [s]": sum(r.seconds for r in history),
        **{f"{force_label(k, sim.scene)} [{unit}]": float(v[-1]) for k, v in forces.items()},
        "message": result.message,
    }


def _settings(runs, source, settings):
    """The lines of the report's settings: the scene, every ``--set``, and
    the values that shape the comparison."""
    sim = next(iter(runs.values()))[0]
    scene = sim.scene
    lines = ["## Settings", "", f"- scene: `{source or scene.get('_source')}`"]
    lines += [f"- `--set {s}`" for s in settings] or ["- no `--set`"]
    steps, disc = scene["steps"], scene["discretization"]
    friction = friction_text(scene)
    lines += [f"- model: {scene['model']['type']}, " + (f"{friction}, " if friction else "")
              + f"{steps['count']} load steps, tolerance {steps['tolerance']:g}",
              f"- rkpm: order {disc['order']}, "
              + (f"support {disc['support']:g} {scene['model']['length_unit']}"
                 if disc["support"] is not None else f"dilation {disc['dilation']:g}")
              + f", {disc['integration']} integration, quadrature degree {disc['quadrature']}",
              f"- fem: {disc['element']}; locking control {disc['locking']}",
              "- the resolved scene of each method: `rkpm/scene.toml`, `fem/scene.toml`", ""]
    return lines


def write_comparison(runs, out, settings=(), source=None, folder=None):
    """Write ``report.md`` and ``compare.png`` for ``{method: (sim, result)}``;
    ``settings`` (the ``--set`` strings) and ``source`` (the scene) go into
    the report's settings.  Both are written atomically; ``folder``: the
    :class:`~skfem_rkpm.runs.folder.RunFolder` of ``out`` (kind
    ``compare``), whose manifest lists them before they are written."""
    out = Path(out)
    if folder is not None:
        folder.claim("report.md", "compare.png")
    summaries = {m: _summary(*runs[m]) for m in runs}
    keys = list(dict.fromkeys(k for s in summaries.values() for k in s))
    lines = ["# RKPM vs FEM", "", *_settings(runs, source, settings), "## Results", "",
             "| | " + " | ".join(runs) + " |", "|---|" + "---|" * len(runs)]
    for key in keys:
        cells = []
        for m in runs:
            v = summaries[m].get(key, "")
            cells.append(f"{v:.4g}" if isinstance(v, float) else str(v))
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    lines += ["", "![comparison](compare.png)", ""]
    fig, axes = plt.subplots(1, len(runs) + 1, figsize=(5 * (len(runs) + 1), 4.5))
    # a partitioned problem's own state is its rank's: rank 0 keeps the whole one
    vmax = max(((runs[m][0].problem.whole_state or runs[m][0].problem.state)
                .alpha.max() for m in runs), default=None)
    for ax, m in zip(axes, runs):
        sim, result = runs[m]
        art = plot_deformed(ax, sim.problem, result.d,
                            f"{m}: t = {summaries[m]['final t']:.3g}", vmax=vmax,
                            scene=sim.scene)
    fig.colorbar(art, ax=axes[:-1], label="equivalent plastic strain")
    ax = axes[-1]
    for m in runs:
        sim, result = runs[m]
        reactions = result.history[-1].reactions if result.history else {}
        # the tools' forces; without tools the reactions of the boundaries
        tools = [k for k in reactions if not k.endswith("]")] or list(reactions)
        reduction = height_reduction(sim, [r.t for r in result.history])
        for key in tools:
            plot_history(ax, result.history, key, f"{m}: {force_label(key, sim.scene)}",
                         x=reduction)
        if reduction is not None:
            ax.set_xlabel("height reduction (%)")
    ax.set_ylabel(force_axis_label(sim.scene))
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4), useMathText=True)
    ax.legend(fontsize=8)
    with atomic_path(out / "compare.png") as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return write_atomic(out / "report.md", "\n".join(lines))
