"""Whole-run cost and results of the 3D forming scenes, RKPM against FEM.

Every case runs ``skfem-rkpm run SCENE`` in a fresh process and reports:
unknowns and Gauss points, the load steps, the Newton iterations of all
attempts (failed ones and cut-backs included), the CPU time of the whole
process (user + system: imports, mesh, basis, every attempt, the history;
fields and figures are not written), the
CPU time per iteration (whole process over all iterations: an upper
bound), the peak memory (maximum resident set of the process), and the
scene's result: the inner-diameter change and full-ring force of the ring
sector, the force and corner bulge of the billet, the punch force and the
thinning at the pole of the stretched sheet.  ``--repeat N`` runs each case
N times and reports the median CPU time.

Run:  python benchmarks/forming_3d.py                 (~1 hour, one core per case)
      python benchmarks/forming_3d.py --quick         (coarse meshes, ~1 minute)
      python benchmarks/forming_3d.py --cases billet
"""

import argparse
import os
import statistics
import tempfile
from pathlib import Path

from _whole_runs import history, ring_id_change, run_scene

CASES = {
    # name: (scene, method, settings)
    "ring_sector rkpm": ("ring_sector", "rkpm", []),
    "ring_sector fem": ("ring_sector", "fem", []),
    "billet_3d rkpm": ("billet_3d", "rkpm", []),
    "billet_3d fem": ("billet_3d", "fem", []),
    "stretch_3d rkpm": ("stretch_3d", "rkpm", []),
    "stretch_3d fem": ("stretch_3d", "fem", []),
}

QUICK = {"ring_sector": ["geometry.divisions=[5, 2, 4]", "steps.count=20"],
         "billet_3d": ["geometry.divisions=[4, 2, 3]", "steps.count=20"],
         "stretch_3d": ["geometry.divisions=[8, 8, 1]", "steps.count=10"]}

def result(scene, last, status):
    """The scene's own numbers from the last row of its history."""
    if scene == "ring_sector":
        change = ring_id_change(last)
        return f"ID {change:+.2f} %, F {-24e-3 * float(last['reaction platen z']):.0f} kN"
    if scene == "billet_3d":
        folded = "; cells folded" if "inverted" in status else ""
        return (f"F {-4e-3 * float(last['reaction platen z']):.1f} kN, corner "
                f"({float(last['corner x']):.2f}, {float(last['corner y']):.2f}) mm{folded}")
    if scene == "stretch_3d":
        pole = float(last["pole z"]) - (15.0 * float(last["t"]) - 1.0)
        return (f"F {4e-3 * float(last['reaction punch z']):.2f} kN, pole thickness "
                f"{pole:.3f} mm")
    return ""


def summary(folder, scene):
    rows, out = history(folder)
    status = (Path(folder) / "status.txt").read_text().strip()
    out["result"] = result(scene, rows[-1], status)
    return out


def size(scene, method, settings):
    """Unknowns and Gauss points of a case (built in this process)."""
    from skfem_rkpm.runs.build import build
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    sim = build(load_scene(builtin_scenes()[scene], settings), method)
    return sim.problem.N, sim.problem.assembler.layout.dx.size


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=[],
                        help="run only cases whose name contains one of these words")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="the coarse meshes")
    args = parser.parse_args()
    names = [n for n in CASES if not args.cases or any(w in n for w in args.cases)]
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    print("| case | unknowns | Gauss points | status | t | steps | all iterations | "
          "cut-backs | CPU s (median) | CPU s / iteration | peak MB | result |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        scene, method, settings = CASES[name]
        settings = settings + (QUICK[scene] if args.quick else [])
        unknowns, points = size(scene, method, settings)
        times, peaks = [], []
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.repeat):
                seconds, peak, code = run_scene(scene, method, settings, Path(tmp) / f"r{k}")
                times.append(seconds)
                peaks.append(peak)
            s = summary(Path(tmp) / "r0", scene)
        cpu = statistics.median(times)
        status = "completed" if code == 0 else f"stopped ({code})"
        print(f"| {name} | {unknowns} | {points} | {status} | {s['t']:.3f} | {s['steps']} | "
              f"{s['all iterations']} | {s['cut-backs']} | {cpu:.1f} | "
              f"{cpu / max(s['all iterations'], 1):.2f} | {max(peaks):.0f} | "
              f"{s['result']} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
