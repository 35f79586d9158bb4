"""Side-by-side report of RKPM and FEM runs of one scene."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .plot import plot_deformed, plot_history  # noqa: E402

__all__ = ["write_comparison"]


def _summary(sim, result):
    history = result.history
    forces = {k: np.atleast_1d(v) for k, v in (history[-1].reactions.items()
                                               if history else [])}
    return {
        "dofs": sim.basis.N,
        "completed": result.completed,
        "final t": history[-1].t if history else 0.0,
        "steps": len(history),
        "Newton iterations": sum(r.iterations for r in history),
        "iterations/step": (sum(r.iterations for r in history) / len(history)
                            if history else float("nan")),
        "wall time [s]": sum(r.seconds for r in history),
        **{f"force {k}": float(v[-1]) for k, v in forces.items()},
        "message": result.message,
    }


def write_comparison(runs, out):
    """Write ``report.md`` and ``compare.png`` for ``{method: (sim, result)}``."""
    summaries = {m: _summary(*runs[m]) for m in runs}
    keys = list(dict.fromkeys(k for s in summaries.values() for k in s))
    lines = ["# RKPM vs FEM", "", "| | " + " | ".join(runs) + " |",
             "|---|" + "---|" * len(runs)]
    for key in keys:
        cells = []
        for m in runs:
            v = summaries[m].get(key, "")
            cells.append(f"{v:.4g}" if isinstance(v, float) else str(v))
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    lines += ["", "![comparison](compare.png)", ""]
    fig, axes = plt.subplots(1, len(runs) + 1, figsize=(5 * (len(runs) + 1), 4.5))
    vmax = max((runs[m][0].problem.state.alpha.max() for m in runs), default=None)
    for ax, m in zip(axes, runs):
        sim, result = runs[m]
        art = plot_deformed(ax, sim.problem, result.d,
                            f"{m}: t = {summaries[m]['final t']:.3g}", vmax=vmax)
    fig.colorbar(art, ax=axes[:-1], label="equivalent plastic strain")
    ax = axes[-1]
    for m in runs:
        sim, result = runs[m]
        tools = [k for k in (result.history[-1].reactions if result.history else {})
                 if not k.endswith("]")]
        for key in tools:
            plot_history(ax, result.history, key, f"{m} {key}")
    ax.set_ylabel("tool force (last component)")
    ax.legend(fontsize=8)
    fig.savefig(out / "compare.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    report = out / "report.md"
    report.write_text("\n".join(lines))
    return report
