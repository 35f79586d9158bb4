"""Ring-test friction calibration from a friction sweep of the ring scene.

The ring test (Male & Cockcroft) reads the interface friction from two
measurements of a compressed ring: its height reduction and the change of
its inner diameter.  A friction sweep of the ring scene gives one curve per
μ; the chart of those curves turns a measured point back into μ.

For the quarter model of ``scenes/ring.toml`` (axisymmetric, symmetry plane
at mid-height):

* height reduction (%) = −(platen travel) / (half height) · 100, from the
  tool gauge column ``platen dy`` of ``history.csv`` and the half height
  ``geometry.y[1] − geometry.y[0]`` (20 mm);
* inner diameter change (%) = 2 Δr / (2 r₀) · 100 = Δr / r₀ · 100, with Δr
  the radial displacement of the followed point ``inner_mid`` (inner surface
  at mid-height, column ``inner_mid x``) and r₀ its initial radius (30 mm).
  Positive: the hole grows (low friction); negative: it shrinks.  Classic
  charts plot the *decrease*, the negative of this.

Reading μ back (:func:`friction_from_measurement`): at the measured height
reduction every curve is interpolated linearly in the height reduction; the
inner diameter change falls as μ rises, and μ is interpolated linearly
between the two neighbouring curves.  Sticking friction is no value of μ: its
curve is a separate top curve, above the largest μ.  A point on it (within
``tol``) reads ``"stick"``; a point between the largest μ and the sticking
curve has no μ scale and raises :class:`ChartError` unless ``stick_mu`` says
at which μ to place the sticking curve (then it is interpolated like any
other curve; e.g. 1/√3 ≈ 0.577, where μ p reaches the shear yield stress
k = σ_y/√3 for contact pressures p ≥ σ_y).
"""

import csv
import tomllib
from pathlib import Path

import numpy as np

__all__ = ["ChartError", "ring_curve", "sweep_curves", "friction_from_measurement",
           "plot_calibration"]


class ChartError(ValueError):
    """A measured point cannot be read on the calibration chart."""


def _column(rows, name, path):
    if rows and name not in rows[0]:
        raise KeyError(f"{path}: no column {name!r}; columns: {', '.join(rows[0])}")
    return np.array([float(r[name]) for r in rows])


def ring_curve(history, inner_radius=30.0, half_height=20.0, point="inner_mid",
               tool="platen"):
    """Height reduction (%) and inner diameter change (%) of one ring run.

    Parameters
    ----------
    history : str or Path
        A run's ``history.csv`` with the columns ``"{point} x"`` (current
        radius of the inner surface at mid-height) and ``"{tool} dy"``
        (platen displacement).
    inner_radius, half_height : float
        Initial radius of ``point`` and initial height of the quarter model.

    Returns
    -------
    (ndarray, ndarray)
        Height reduction and inner diameter change in percent, starting at
        the undeformed ring (0, 0).
    """
    path = Path(history)
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise ValueError(f"{path}: no steps")
    reduction = -_column(rows, f"{tool} dy", path) / half_height * 100.0
    change = (_column(rows, f"{point} x", path) - inner_radius) / inner_radius * 100.0
    return np.r_[0.0, reduction], np.r_[0.0, change]


def _friction_value(text):
    """A friction column entry of ``sweep.csv``: a number or "stick"."""
    return "stick" if text.strip() == "stick" else float(text)


def sweep_curves(sweep, key="tools.platen.friction", point="inner_mid", tool="platen"):
    """The ring curves of a friction sweep folder: ``{μ or "stick": (hr, idc)}``.

    Reads ``sweep.csv`` and each completed run's ``history.csv``; the initial
    radius of ``point`` and the half height come from the run's
    ``scene.toml`` (written by :func:`skfem_rkpm.runs.sweep.run_case`).  Runs
    that did not complete are left out.
    """
    sweep = Path(sweep)
    table = sweep / "sweep.csv"
    if not table.exists():
        raise FileNotFoundError(f"{table}: not a sweep folder (run skfem-rkpm sweep "
                                f"first)")
    with open(table, newline="") as handle:
        rows = list(csv.DictReader(handle))
    if rows and key not in rows[0]:
        raise KeyError(f"{table}: the sweep does not vary {key!r}; it varies "
                       f"{[k for k in rows[0] if '.' in k]}")
    curves = {}
    for row in rows:
        if row["status"] != "completed":
            continue
        folder = sweep / row["run"]
        scene = tomllib.loads((folder / "scene.toml").read_text())
        r0 = scene["output"]["points"][point][0]
        y0, y1 = scene["geometry"]["y"]
        curves[_friction_value(row[key])] = ring_curve(folder / "history.csv", r0,
                                                       y1 - y0, point, tool)
    if not curves:
        raise ValueError(f"{table}: no completed runs")
    return curves


def _ordered(curves, stick_mu):
    """Curves sorted by μ; sticking last (at ``stick_mu``, or +inf)."""
    numbers = sorted(k for k in curves if k != "stick")
    keys = numbers + (["stick"] if "stick" in curves else [])
    if stick_mu is not None and numbers and stick_mu <= numbers[-1]:
        raise ValueError(f"stick_mu={stick_mu} must exceed the largest μ of the chart "
                         f"({numbers[-1]})")
    mus = np.array([np.inf if k == "stick" and stick_mu is None else
                    (stick_mu if k == "stick" else k) for k in keys], float)
    return keys, mus


def friction_from_measurement(curves, height_reduction, id_change, stick_mu=None,
                              tol=1e-9):
    """The friction coefficient of a measured ring, read on the chart.

    Parameters
    ----------
    curves : dict
        ``{μ: (height_reduction, id_change)}`` in percent (e.g. from
        :func:`sweep_curves`); the key ``"stick"`` marks the sticking curve.
    height_reduction, id_change : float
        The measurement, in percent (id_change > 0: the hole grew).
    stick_mu : float, optional
        Place the sticking curve at this μ (above every other μ) to read
        points between the largest μ and sticking; by default they raise.
    tol : float
        Distance in percent within which a point counts as on a curve.

    Returns
    -------
    float or "stick"
        μ, linear between the two curves around the point; ``"stick"`` for a
        point on the sticking curve (when ``stick_mu`` is None).

    Raises
    ------
    ChartError
        The point lies outside the chart: beyond the height reduction some
        curve reaches, above the frictionless curve, below the sticking (or
        largest-μ) curve, or between the largest μ and sticking without
        ``stick_mu``.
    """
    if len(curves) < 2:
        raise ChartError("a chart needs at least two friction curves")
    keys, mus = _ordered(curves, stick_mu)
    reach = min(float(np.max(curves[k][0])) for k in keys)
    if not 0.0 <= height_reduction <= reach:
        raise ChartError(f"height reduction {height_reduction}% lies outside the chart: "
                         f"all curves cover 0% to {reach:.4g}%")
    values = np.array([np.interp(height_reduction, *curves[k]) for k in keys])
    if np.any(np.diff(values) > tol):
        raise ChartError(f"at {height_reduction}% height reduction the curves are not "
                         f"ordered by μ (inner diameter change {np.round(values, 4)} for "
                         f"μ = {keys}); the chart cannot be read there")
    label = {k: f"μ={k}" if k != "stick" else "sticking" for k in keys}
    if id_change > values[0] + tol:
        hint = ("no friction lets the hole grow more: check the measurement"
                if keys[0] == 0 else "add smaller μ to the sweep")
        raise ChartError(f"inner diameter change {id_change}% lies above the {label[keys[0]]} "
                         f"curve ({values[0]:.4g}% at {height_reduction}% height "
                         f"reduction): outside the chart; {hint}")
    if id_change < values[-1] - tol:
        raise ChartError(f"inner diameter change {id_change}% lies below the "
                         f"{label[keys[-1]]} curve ({values[-1]:.4g}% at "
                         f"{height_reduction}% height reduction): outside the chart")
    on = np.flatnonzero(np.abs(values - id_change) <= tol)
    if on.size:
        k = keys[on[0]]
        return k if k == "stick" and stick_mu is None else float(mus[on[0]])
    upper = int(np.flatnonzero(values < id_change)[0])  # first curve below the point
    if np.isinf(mus[upper]):
        raise ChartError(f"the point lies between the μ={keys[upper - 1]} and the sticking "
                         f"curve: μ > {keys[upper - 1]}, but sticking has no μ scale; add "
                         f"larger μ to the sweep or pass stick_mu")
    lo, hi = upper - 1, upper
    weight = (values[lo] - id_change) / (values[lo] - values[hi])
    return float(mus[lo] + weight * (mus[hi] - mus[lo]))


def plot_calibration(curves, path=None, measurement=None, ax=None, title=None):
    """The calibration chart: inner diameter change (%) vs height reduction (%),
    one curve per μ; ``measurement=(hr, idc, mu)`` marks a read-back point.
    Saves to ``path`` when given; returns the axes."""
    import matplotlib.pyplot as plt

    keys, _ = _ordered(curves, None)
    if ax is None:
        _, ax = plt.subplots(figsize=(6.0, 4.5))
    colors = plt.cm.viridis(np.linspace(0.0, 0.9, len(keys)))
    for key, color in zip(keys, colors):
        hr, idc = curves[key]
        ax.plot(hr, idc, color="k" if key == "stick" else color, lw=1.6,
                ls="--" if key == "stick" else "-",
                label="sticking" if key == "stick" else f"μ = {key:g}")
    if measurement is not None:
        hr, idc, mu = measurement
        text = mu if isinstance(mu, str) else f"μ ≈ {mu:.3f}"
        ax.plot([hr], [idc], "o", color="crimson", ms=7, label=f"measured: {text}")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("inner diameter change (%)")
    ax.set_title(title or "Ring-test calibration chart")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    if path is not None:
        ax.figure.tight_layout()
        ax.figure.savefig(path, dpi=120)
    return ax
