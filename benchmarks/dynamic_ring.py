"""The slow dynamic ring against the quasi-static one, and the trade of
explicit, implicit and quasi-static runs on the ring.

The ring of ``scenes/ring.toml`` (RKPM, 15 x 10 cells, μ = 0.15, to 50 %
height reduction) compressed with inertia (``scenes/ring_dynamic.toml``:
steel, ρ = 7850 kg/m³) at platen speeds v of 10 mm/s, 1 m/s and 10 m/s,
against the quasi-static ring at the same height reductions: the largest
difference of the inner diameter change (points) and of the platen force
(%) over the run (the quasi-static curve interpolated linearly between its
load steps), and at the end (50 %, where the reductions coincide).

Two groups of runs:

- the built-in scenes as they are (``ring``: weak symmetry plane, penalty
  factor 100; ``ring_dynamic``: 10 mm/s, trapezoidal rule, 100 steps,
  smooth start over 5 % of the run), RKPM and FEM, and for RKPM the same
  dynamic scene at 1 m/s and 10 m/s;
- the trade: the scene that the explicit scheme can run too: the symmetry
  plane held on nodal values (``boundary.bottom.method = "nodal"``) and a
  penalty factor of 1 (a stiffer penalty shortens the explicit step as
  its square root), a smooth start over 20 % of the run; quasi-static,
  implicit (trapezoidal and HHT-α, 100 steps) and explicit at 1 m/s and
  10 m/s, implicit alone at 10 mm/s (explicit would take ~4.6 million
  steps there).

CPU seconds are ``time.process_time`` of the run (not the start-up or the
basis; one BLAS thread, as ``skfem-rkpm run``), medians of ``--repeat`` runs where a run is short (under a minute),
single runs otherwise; the machine load is printed.  ``--figure`` draws
the platen force and the inner diameter change against the height
reduction, quasi-static and dynamic.

Run:  python benchmarks/dynamic_ring.py                 (~15 min of CPU)
      python benchmarks/dynamic_ring.py --quick         (the first group, RKPM)
      python benchmarks/dynamic_ring.py --trade         (the trade group)
      python benchmarks/dynamic_ring.py --figure docs/figures/dynamic_ring.png
"""

import argparse
import csv
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from skfem_rkpm.mechanics.mass import largest_eigenvalue, lumped_mass
from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.explicit_run import run_explicit
from skfem_rkpm.runs.implicit_run import run_implicit
from skfem_rkpm.runs.runner import blas_threads, run
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

QUIET = ["output.fields=false", "output.figures=false"]
#: the scene that explicit runs take: nodal symmetry plane, penalty factor 1
TRADE = ['boundary.bottom.method="nodal"', "tools.platen.penalty_factor=1.0"]
HALF_HEIGHT, INNER, STROKE, DENSITY = 20.0, 30.0, 10.0, 7.85e-9


def dynamic(speed, scheme="implicit", steps=100, ramp=None, hht=False):
    """The settings of ring_dynamic at platen ``speed`` (mm/s)."""
    duration = STROKE / speed
    out = [f'dynamics.scheme="{scheme}"', f"dynamics.duration={duration!r}",
           f"dynamics.output_interval={duration / 100!r}"]
    if scheme == "implicit":
        out.append(f"dynamics.time_step={duration / steps!r}")
    if hht:
        out.append('dynamics.integrator="hht"')
    if ramp is not None:
        out.append(f"tools.platen.ramp={ramp!r}")
    return out


def curve(path):
    """Height reduction (%), ID change (%) and platen force (N) of a
    history.csv, from the undeformed ring."""
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    hr = [-float(r["platen dy"]) / HALF_HEIGHT * 100 for r in rows]
    idc = [(float(r["inner_mid x"]) - INNER) / INNER * 100 for r in rows]
    force = [-float(r["reaction platen y"]) for r in rows]
    start = [] if hr[0] == 0.0 else [0.0]
    return tuple(np.array(start + v) for v in (hr, idc, force))


def compare(reference, other, skip=1.0):
    """Largest |ΔID| (points), |ΔF| (%), and both at the end."""
    hr, idc, force = other
    keep = hr > skip
    d_id = idc[keep] - np.interp(hr[keep], reference[0], reference[1])
    d_f = (force[keep] / np.interp(hr[keep], reference[0], reference[2]) - 1) * 100
    return (float(np.abs(d_id).max()), float(np.abs(d_f).max()),
            float(d_id[-1]), float(d_f[-1]))


def one_run(scene, method, settings, folder):
    """Build (untimed) and run once; ``(cpu seconds, steps, iterations,
    completed)`` and the curve."""
    sim = build(load_scene(builtin_scenes()[scene], QUIET + settings), method)
    scheme = sim.scene.get("dynamics", {}).get("scheme", "static")
    start = time.process_time()
    if scheme == "static":
        result = run(sim, folder, progress=False)
        cpu = time.process_time() - start
        steps, iterations = len(result.history), sum(r.iterations for r in result.history)
        completed = result.completed
    else:
        runner = run_explicit if scheme == "explicit" else run_implicit
        result = runner(sim, folder, progress=False)
        cpu = time.process_time() - start
        steps, completed = result.steps, result.completed
        iterations = sum(r.get("newton iterations", 0) for r in result.rows) or None
    return (cpu, steps, iterations, completed), curve(Path(folder) / "history.csv")


def measure(scene, method, settings, repeat, tmp):
    times, out = [], None
    for i in range(repeat):
        folder = Path(tempfile.mkdtemp(dir=tmp))
        out = one_run(scene, method, settings, folder)
        times.append(out[0][0])
        if out[0][0] > 60:  # long runs once
            break
    (cpu, steps, iterations, completed), data = out
    return dict(cpu=float(np.median(times)), runs=len(times), steps=steps,
                iterations=iterations, completed=completed), data


def stable_steps(settings):
    """``2/ω_max`` of the lumped mass at rest, RKPM and FEM, on the ring's
    particle spacing (2 mm): the body alone, and the explicit scheme's
    first estimate with the penalty contact."""
    from skfem_rkpm.runs.explicit_run import explicit_scheme

    out = {}
    for method in ("rkpm", "fem"):
        sim = build(load_scene(builtin_scenes()["ring_dynamic"], QUIET + settings), method)
        d = np.zeros(sim.basis.N)
        K = sim.problem.evaluate(d, tangent=True).K
        m = lumped_mass(sim.problem.assembler, sim.scene["material"]["density"])
        body = 2 / np.sqrt(largest_eigenvalue(0.5 * (K + K.T), m))
        scheme = explicit_scheme(sim)
        out[method] = (body, float(scheme.stable_step(d)))
    return out


def table(rows):
    print("| run | v | CPU s | runs | steps | Newton iterations | max ΔID (points) "
          "| max ΔF (%) | ΔID at 50 % | ΔF at 50 % |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, speed, stats, diff in rows:
        its = "—" if stats["iterations"] is None else f"{stats['iterations']:,}"
        d = ("—",) * 4 if diff is None else (f"{diff[0]:.4f}", f"{diff[1]:.3f}",
                                              f"{diff[2]:+.4f}", f"{diff[3]:+.3f}")
        done = "" if stats["completed"] else " (stopped)"
        print(f"| {label}{done} | {speed} | {stats['cpu']:.1f} | {stats['runs']} | "
              f"{stats['steps']:,} | {its} | " + " | ".join(d) + " |")


def figure(path, static, curves):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
    ax.plot(static[0], static[2] / 1e6, "k-", lw=2.5, label="quasi-static (100 steps)")
    bx.plot(static[0], static[1], "k-", lw=2.5, label="quasi-static")
    styles = ["o", "s", "^", "v", "D"]
    for (label, data), style in zip(curves, styles):
        ax.plot(data[0], data[2] / 1e6, style, ms=3.5, mfc="none", label=label)
        bx.plot(data[0], data[1], style, ms=3.5, mfc="none", label=label)
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("platen force, full ring (MN)")
    bx.set_xlabel("height reduction (%)")
    bx.set_ylabel("inner diameter change (%)")
    for a in (ax, bx):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    ax.set_title("RKPM ring, μ = 0.15: platen force")
    bx.set_title("inner diameter change")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="the first group, RKPM only")
    parser.add_argument("--trade", action="store_true", help="the trade group only")
    parser.add_argument("--figure", help="write the force and ID change figure here")
    args = parser.parse_args()
    print(f"load: {os.getloadavg()}")
    tmp = tempfile.mkdtemp(prefix="dynamic_ring-")
    rows, curves = [], []
    for method in () if args.trade else ("rkpm",) if args.quick else ("rkpm", "fem"):
        stats, static = measure("ring", method, [], args.repeat, tmp)
        rows.append((f"{method} quasi-static (ring)", "—", stats, None))
        speeds = ((10.0, "10 mm/s"), (1e3, "1 m/s"), (1e4, "10 m/s"))
        for speed, text in speeds if method == "rkpm" else speeds[:1]:
            settings = [] if speed == 10.0 else dynamic(speed)
            stats, data = measure("ring_dynamic", method, settings, args.repeat, tmp)
            rows.append((f"{method} trapezoidal (ring_dynamic)", text, stats,
                         compare(static, data)))
            if method == "rkpm":
                curves.append((f"trapezoidal, {text}", data))
        if method == "rkpm":
            rk_static = static
    if rows:
        table(rows)
    if args.figure and rows:
        figure(args.figure, rk_static, curves)
    if args.quick:
        return
    rows = []
    stats, static = measure("ring", "rkpm", TRADE, args.repeat, tmp)
    rows.append(("quasi-static", "—", stats, None))
    for speed, text in ((10.0, "10 mm/s"), (1e3, "1 m/s"), (1e4, "10 m/s")):
        for label, settings in (
                ("trapezoidal", dynamic(speed, ramp=0.2)),
                ("HHT-α −0.1", dynamic(speed, ramp=0.2, hht=True)),
                ("explicit", dynamic(speed, "explicit", ramp=0.2))):
            if label == "explicit" and speed < 1e3:
                continue
            # ring_dynamic's time_step would be the explicit scheme's fixed step:
            # the explicit runs start from ring.toml with the density instead
            scene = "ring" if label == "explicit" else "ring_dynamic"
            extra = [f"material.density={DENSITY!r}"] if label == "explicit" else []
            stats, data = measure(scene, "rkpm", TRADE + extra + settings, args.repeat, tmp)
            rows.append((label, text, stats, compare(static, data)))
    table(rows)
    steps = stable_steps(TRADE)
    print("| basis | 2/ω_max, body (µs) | explicit estimate with contact (µs) |")
    print("|---|---:|---:|")
    for method, (body, estimate) in steps.items():
        print(f"| {method} | {body * 1e6:.3f} | {estimate * 1e6:.3f} |")
    print(f"load: {os.getloadavg()}")


if __name__ == "__main__":
    with blas_threads(1):
        main()
