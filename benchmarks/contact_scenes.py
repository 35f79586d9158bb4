"""Whole-run cost of the paper's contact scenes with penalty and augmented contact.

Every case runs ``skfem-rkpm run SCENE --set ...`` in a fresh process and
reports the CPU time of that whole process (user + system of the child,
from ``getrusage``:
imports, mesh, basis, every Newton attempt, output), the load steps, the
Newton iterations of the converged attempts and of all attempts (failed ones
and cut-backs included), the penetration at the end and the scene's result
(punch force, inner-diameter change of the ring).  ``--repeat N`` runs each
case N times and reports the median CPU time.

Run:  python benchmarks/contact_scenes.py                  (~10 minutes, one core)
      python benchmarks/contact_scenes.py --cases ring      (the ring cases only)
      python benchmarks/contact_scenes.py --repeat 3
      python benchmarks/contact_scenes.py --penalty-sweep  (the ring's penalty factor)
"""

import argparse
import os
import statistics
import tempfile
from pathlib import Path

from _whole_runs import history, ring_id_change, run_scene


def augmented(*tools, factor=10):
    return [s for tool in tools for s in (f'tools.{tool}.enforcement="augmented"',
                                          f"tools.{tool}.penalty_factor={factor}")]


def penalty(*tools, factor=1000):
    """The paper's penalty law (the sheet scenes choose augmented contact)."""
    return [s for tool in tools for s in (f'tools.{tool}.enforcement="penalty"',
                                          f"tools.{tool}.penalty_factor={factor}")]


CASES = {
    # name: (scene, method, settings)
    "ring mu=0.15 rkpm penalty": ("ring", "rkpm", []),
    "ring mu=0.15 rkpm augmented": ("ring", "rkpm", augmented("platen")),
    "ring mu=0.15 fem penalty": ("ring", "fem", []),
    "ring mu=0.15 fem augmented": ("ring", "fem", augmented("platen")),
    "ring stick rkpm penalty": ("ring", "rkpm", ['tools.platen.friction="stick"']),
    "ring stick fem penalty": ("ring", "fem", ['tools.platen.friction="stick"']),
    "ring stick rkpm augmented": ("ring", "rkpm", ['tools.platen.friction="stick"']
                                  + augmented("platen")),
    "ring stick fem augmented": ("ring", "fem", ['tools.platen.friction="stick"']
                                 + augmented("platen")),
    "ring_refined stick rkpm penalty": ("ring_refined", "rkpm",
                                        ['tools.platen.friction="stick"']),
    "ring_refined stick rkpm augmented": ("ring_refined", "rkpm",
                                          ['tools.platen.friction="stick"']
                                          + augmented("platen")),
    "ring_refined stick fem augmented": ("ring_refined", "fem",
                                         ['tools.platen.friction="stick"']
                                         + augmented("platen")),
    "punch rkpm penalty": ("punch", "rkpm", penalty("punch", "die")),
    "punch rkpm augmented": ("punch", "rkpm", augmented("punch", "die")),
    "punch fem augmented": ("punch", "fem", augmented("punch", "die")),
    "hemisphere mu=0 rkpm augmented": ("hemisphere", "rkpm", augmented("punch", "die")),
    "hemisphere mu=0.3 rkpm augmented": ("hemisphere", "rkpm",
                                         ["tools.punch.friction=0.3"]
                                         + augmented("punch", "die")),
    "hemisphere mu=0 fem augmented": ("hemisphere", "fem", augmented("punch", "die")),
    "hemisphere mu=0.3 fem augmented": ("hemisphere", "fem",
                                        ["tools.punch.friction=0.3"]
                                        + augmented("punch", "die")),
}

#: the ring's penalty law against its penalty factor (``--penalty-sweep``)
PENALTY_SWEEP = {}
for _friction, _setting in (("mu=0.15", "0.15"), ("stick", '"stick"')):
    for _method in ("rkpm", "fem"):
        for _factor in (30, 100, 300, 1000, 3000):
            PENALTY_SWEEP[f"ring {_friction} {_method} penalty factor {_factor}"] = (
                "ring", _method, [f"tools.platen.friction={_setting}"]
                + penalty("platen", factor=_factor))


def summary(folder):
    rows, out = history(folder)
    last = rows[-1]
    out["penetration"] = max(float(v) for k, v in last.items() if k.endswith("penetration"))
    if "inner_mid x" in last:
        out["result"] = (f"ID {ring_id_change(last):+.3f} %, "
                         f"F {-float(last['reaction platen y']) / 1e3:.1f} kN")
    elif "reaction punch y" in last:
        out["result"] = f"F {-float(last['reaction punch y']):.1f} N"
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=[],
                        help="run only cases whose name contains one of these words")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--penalty-sweep", action="store_true",
                        help="the ring with penalty factors 30-3000 instead of the scenes")
    parser.add_argument("--limit", type=float, default=1800.0,
                        help="seconds after which a run is stopped")
    args = parser.parse_args()
    cases = PENALTY_SWEEP if args.penalty_sweep else CASES
    names = [n for n in cases if not args.cases or any(w in n for w in args.cases)]
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    print("| case | status | t | steps | iterations/step | all iterations | cut-backs "
          "| penetration (mm) | result | CPU s (median) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        scene, method, settings = cases[name]
        times = []
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.repeat):
                seconds, _, code = run_scene(scene, method, settings, Path(tmp) / f"r{k}",
                                             args.limit)
                times.append(seconds)
            s = summary(Path(tmp) / "r0")
        status = "completed" if code == 0 else f"stopped ({code})"
        print(f"| {name} | {status} | {s['t']:.3f} | {s['steps']} | "
              f"{s['iterations'] / s['steps']:.2f} | {s['all iterations']} | "
              f"{s['cut-backs']} | {s['penetration']:.1e} | {s.get('result', '')} | "
              f"{statistics.median(times):.1f} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
