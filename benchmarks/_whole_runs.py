"""Whole runs of ``skfem-rkpm run`` in fresh processes, for the benchmarks of
whole scenes (``contact_scenes.py``, ``forming_3d.py``; the leading underscore keeps
``run_all.py`` from running it as a benchmark).

Each run is started by a small measuring process, so that the CPU time
(user + system) and the peak memory (maximum resident set) reported are
those of the run alone: imports, mesh, basis, every Newton attempt, output.
"""

import csv
import os
import subprocess
import sys
from pathlib import Path

#: runs a command (after the time limit in seconds) and prints the CPU
#: seconds and peak memory (kB) of it and its exit status (-9: stopped)
_MEASURE = ("import resource, subprocess, sys; "
            "limit = float(sys.argv[1]) or None\n"
            "try:\n"
            "    code = subprocess.run(sys.argv[2:], stdout=subprocess.DEVNULL, "
            "stderr=subprocess.DEVNULL, timeout=limit).returncode\n"
            "except subprocess.TimeoutExpired:\n"
            "    code = -9\n"
            "r = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
            "print(r.ru_utime + r.ru_stime, r.ru_maxrss, code)")


def run_scene(scene, method, settings, folder, limit=0.0, source=None):
    """CPU seconds, peak memory (MB) and exit status of one whole run of
    ``scene`` (fields and figures not written) with ``--set`` ``settings``;
    ``limit``: seconds after which the run is stopped (0: none); ``source``:
    a folder holding another version's ``skfem_rkpm`` package to run instead
    (e.g. ``git archive COMMIT skfem_rkpm | tar -x -C DIR``)."""
    command = [sys.executable, "-m", "skfem_rkpm.runs.cli", "run", scene, "--quiet",
               "--method", method, "--out", str(Path(folder).resolve()),
               "--set", "output.fields=false", "--set", "output.figures=false"]
    for setting in settings:
        command += ["--set", setting]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    cwd = None
    if source is not None:  # `python -m` finds the package in the working folder
        cwd = env["PYTHONPATH"] = str(Path(source).resolve())
    out = subprocess.run([sys.executable, "-c", _MEASURE, str(limit), *command], env=env,
                         cwd=cwd, capture_output=True, text=True,
                         check=True).stdout.split()
    return float(out[0]), float(out[1]) / 1024.0, int(out[2])


def history(folder):
    """The rows of a run's ``history.csv`` and their totals: the load factor
    reached, the steps, the Newton iterations of the converged attempts and
    of all attempts, and the cut-backs."""
    rows = list(csv.DictReader(open(Path(folder) / "history.csv")))
    return rows, {"t": float(rows[-1]["t"]), "steps": len(rows),
                  "iterations": sum(int(r["iterations"]) for r in rows),
                  "all iterations": sum(int(r["all iterations"]) for r in rows),
                  "cut-backs": sum(int(r["cutbacks"]) for r in rows)}


#: the ring's inner radius before compression, mm (scenes ring, ring_refined)
RING_INNER_RADIUS = 30.0


def ring_id_change(gauges):
    """Inner-diameter change of the ring in %, from a row of its gauges (the
    ``inner_mid x`` gauge: the inner surface at mid-height)."""
    return 100.0 * (float(gauges["inner_mid x"]) / RING_INNER_RADIUS - 1.0)
