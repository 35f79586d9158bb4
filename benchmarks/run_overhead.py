"""Whole-process CPU of the runs whose per-iteration overhead is targeted,
this version against another one, run in turn.

Runs (fields and figures off, as in :func:`_whole_runs.run_scene`):

* ``ring``: the ring at μ = 0.15, RKPM, Gauss+VCI (``scenes/ring.toml``);
* ``ring scni``: the same with ``discretization.integration = "scni"``;
* ``stick ring``: ``tools.platen.friction = "stick"``;
* ``billet fem``: ``billet_3d --method fem`` (Hex1, 945 unknowns).

Each run is repeated ``--repeat`` times; with ``--source DIR`` (another
version's ``skfem_rkpm`` package, e.g. ``git archive COMMIT skfem_rkpm |
tar -x -C DIR``) the two versions alternate run by run, so that both see
the same load.  Reported: the Newton iterations (all attempts), the median
whole-process CPU seconds (range), the CPU per iteration, the SCNI / Gauss+VCI
ratio of the medians, and whether the other version's ``history.csv`` is the
same (every column but the wall-clock ``seconds``: identical, or the largest
relative difference).

Run:  python benchmarks/run_overhead.py [--cases ring "ring scni" ...] [--repeat 3]
                                        [--source DIR]
"""

import argparse
import csv
import os
import statistics
import tempfile
from pathlib import Path

from _whole_runs import history, run_scene

CASES = {
    "ring": ("ring", "rkpm", ["tools.platen.friction=0.15"]),
    "ring scni": ("ring", "rkpm", ["tools.platen.friction=0.15",
                                   'discretization.integration="scni"']),
    "stick ring": ("ring", "rkpm", ['tools.platen.friction="stick"']),
    "billet fem": ("billet_3d", "fem", []),
}


def difference(a, b):
    """"identical", or the largest relative difference of two history.csv files
    (the wall-clock column left out), or why they cannot be compared."""
    rows_a = list(csv.DictReader(open(Path(a) / "history.csv")))
    rows_b = list(csv.DictReader(open(Path(b) / "history.csv")))
    if len(rows_a) != len(rows_b):
        return f"{len(rows_a)} against {len(rows_b)} steps"
    worst = 0.0
    for ra, rb in zip(rows_a, rows_b):
        for key in ra:
            if key == "seconds" or ra[key] == rb.get(key):
                continue
            x, y = float(ra[key]), float(rb[key])
            worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-300))
    return "identical" if worst == 0.0 else f"{worst:.1e}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(CASES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--source", default=None,
                        help="folder holding the other version's skfem_rkpm package")
    args = parser.parse_args()
    versions = {"this": None} | ({"other": args.source} if args.source else {})
    print(f"load average at start: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    print("| run | version | all iterations | whole run CPU s (median; range) | ms per "
          "iteration | history.csv of the other version |")
    print("|---|---|---:|---:|---:|---|")
    medians = {}
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scene, method, settings = CASES[case]
            times = {v: [] for v in versions}
            folders = {v: Path(tmp) / f"{case}-{v}".replace(" ", "_") for v in versions}
            for _ in range(args.repeat):
                for version, source in versions.items():
                    times[version].append(run_scene(scene, method, settings,
                                                    folders[version], source=source)[0])
            for version in versions:
                n = history(folders[version])[1]["all iterations"]
                median = medians[case, version] = statistics.median(times[version])
                same = (difference(folders["this"], folders["other"])
                        if args.source and version == "this" else "")
                print(f"| {case} | {version} | {n} | {median:.2f} "
                      f"({min(times[version]):.2f}-{max(times[version]):.2f}) | "
                      f"{1e3 * median / n:.1f} | {same} |", flush=True)
    for version in versions:
        if ("ring", version) in medians and ("ring scni", version) in medians:
            print(f"\nSCNI / Gauss+VCI ({version}): "
                  f"{medians['ring scni', version] / medians['ring', version]:.2f}")
    print(f"load average at end: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
