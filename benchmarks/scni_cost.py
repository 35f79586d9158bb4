"""What SCNI costs against Gauss+VCI on the forming scenes, whole runs and by part.

Scenes: the ring at μ = 0.15 (``scenes/ring.toml``, 16 x 11 particles, 100
steps), the upsetting (``scenes/upsetting.toml``) and ``billet_3d``, each with
the scene's Gauss+VCI integration and with ``discretization.integration =
"scni"`` (scene default α = 1e-3), fields and figures off.

* *whole run*: CPU seconds (user + sys) of the whole process, median of
  ``--repeat`` fresh processes (:func:`_whole_runs.run_scene`): imports, mesh,
  basis, every Newton attempt, output;
* *by part*: one more run under cProfile, whose cumulative times are split
  into the material update (return map and consistent tangent), the force
  assembly (``F`` from the coefficients and ``∫ ∇̃Ψ · P``), the tangent
  (local products and scatter, stabilization added), the contact (force and
  tangent), the linear solves, and the rest (line search bookkeeping,
  output, setup, imports), in ms per Newton iteration (all attempts).
  cProfile slows the many small calls most: the split is a guide, the whole
  runs are the measurement.

``--source DIR`` runs the ``skfem_rkpm`` package in ``DIR`` instead (e.g.
``git archive COMMIT skfem_rkpm | tar -x -C DIR``), to measure an earlier
version with the same script.

Run:  python benchmarks/scni_cost.py [--cases ring upsetting billet] [--repeat 3]
"""

import argparse
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _whole_runs import history, run_scene

SCENES = {"ring": ("ring", ["tools.platen.friction=0.15"]),
          "upsetting": ("upsetting", []),
          "billet": ("billet_3d", [])}
SCHEMES = {"Gauss+VCI": [], "SCNI": ['discretization.integration="scni"']}
#: the parts of an iteration: (module file, function) whose cumulative times add up
PARTS = {
    "material": [("materials.py", "stress"), ("materials.py", "tangent")],
    "force": [("assembly.py", "gradient"), ("assembly.py", "linear")],
    "tangent": [("problem.py", "_tangent_matrix"), ("stabilization.py", "add_to")],
    "contact": [("rigid_contact.py", "evaluate"), ("surface_contact.py", "evaluate")],
    "solve": [("constrained.py", "solve_constrained")],
}


def profiled(scene, settings, folder, profile):
    """One run of ``scene`` under cProfile into ``profile``."""
    command = [sys.executable, "-m", "cProfile", "-o", str(profile), "-m",
               "skfem_rkpm.runs.cli", "run", scene, "--quiet", "--out", str(folder),
               "--set", "output.fields=false", "--set", "output.figures=false"]
    for setting in settings:
        command += ["--set", setting]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)


def split(profile):
    """Cumulative seconds of every part of :data:`PARTS`, and the total.

    Of several functions of one name in one file (a nested ``stress`` of a
    hardening table inside ``J2Material.stress``) the largest counts."""
    stats = pstats.Stats(str(profile)).stats
    found = {}
    for (path, _, name), (_, _, _, cumulative, _) in stats.items():
        for part, functions in PARTS.items():
            for f, n in functions:
                if path.endswith(os.sep + f) and name == n:
                    found[(f, n)] = max(found.get((f, n), 0.0), cumulative)
    out = {part: sum(found.get(fn, 0.0) for fn in functions)
           for part, functions in PARTS.items()}
    total = max(row[3] for row in stats.values())
    return out, total


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(SCENES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--source", default=None,
                        help="folder holding the skfem_rkpm package to measure")
    parser.add_argument("--limit", type=float, default=1800.0)
    args = parser.parse_args()
    if args.source:
        os.chdir(args.source)  # `python -m` finds the package in the working folder
        os.environ["PYTHONPATH"] = os.path.abspath(args.source)
    print(f"load average at start: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    print("| scene | scheme | steps (cut-backs) | all iterations | whole run CPU s "
          "(median; range) | SCNI / Gauss+VCI | material | force | tangent | contact "
          "| solve | rest | material + force + tangent / Gauss+VCI |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scene, settings = SCENES[case]
            reference = None
            for scheme, extra in SCHEMES.items():
                folder = Path(tmp) / f"{case}-{scheme}".replace("+", "_")
                times = [run_scene(scene, "rkpm", settings + extra, folder, args.limit)[0]
                         for _ in range(args.repeat)]
                _, out = history(folder)
                profile = Path(tmp) / f"{case}-{scheme}.prof".replace("+", "_")
                profiled(scene, settings + extra, folder, profile)
                parts, total = split(profile)
                n = out["all iterations"]
                ms = {k: 1e3 * v / n for k, v in parts.items()}
                ms["rest"] = 1e3 * (total - sum(parts.values())) / n
                core = ms["material"] + ms["force"] + ms["tangent"]
                median = statistics.median(times)
                if reference is None:
                    reference = (median, core)
                print(f"| {case} | {scheme} | {out['steps']} ({out['cut-backs']}) | {n} | "
                      f"{median:.2f} ({min(times):.2f}-{max(times):.2f}) | "
                      f"{median / reference[0]:.2f} | "
                      + " | ".join(f"{ms[k]:.2f}" for k in
                                   ("material", "force", "tangent", "contact", "solve",
                                    "rest"))
                      + f" | {core / reference[1]:.2f} |", flush=True)
    print(f"load average at end: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
