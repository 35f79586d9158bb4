"""What SCNI costs against Gauss+VCI on the forming scenes, whole runs and by part.

Scenes: the ring at μ = 0.15 (``scenes/ring.toml``, 16 x 11 particles, 100
steps), the upsetting (``scenes/upsetting.toml``) and ``billet_3d``, each with
the scene's Gauss+VCI integration and with ``discretization.integration =
"scni"`` (scene default α = 1e-3), fields and figures off.

* *whole run*: CPU seconds (user + sys) of the whole process, median of
  ``--repeat`` fresh processes (:func:`_whole_runs.run_scene`): imports, mesh,
  basis, every Newton attempt, output;
* *by part*: one more run with CPU timers around the functions of
  :data:`PARTS`: the material update (return map and consistent tangent),
  the force assembly (``F`` from the coefficients and ``∫ ∇̃Ψ · P``), the
  tangent (local products and scatter, stabilization added), the contact
  (force and tangent), the linear solves, the start-up (interpreter and
  imports, until the run starts), the setup (scene, mesh, basis:
  ``runner.build``), the output after every step (checkpoint, fold
  columns, history row) and the rest of the process (kinematics, the
  rest of Newton and the line search, the folder), in ms per Newton
  iteration (all attempts).

``--source DIR`` runs the ``skfem_rkpm`` package in ``DIR`` instead (e.g.
``git archive COMMIT skfem_rkpm | tar -x -C DIR``), to measure an earlier
version with the same script.

Run:  python benchmarks/scni_cost.py [--cases ring upsetting billet] [--repeat 3]
"""

import argparse
import os
import json
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
#: the parts of an iteration: (module, class or None, function) timed in them
PARTS = {
    "material": [("mechanics.materials", "J2Material", "stress"),
                 ("mechanics.materials", "J2Material", "tangent")],
    "force": [("assembly", "Assembler", "gradient"), ("assembly", "Assembler", "linear")],
    "tangent": [("mechanics.problem", "SolidProblem", "_tangent_matrix"),
                ("mechanics.stabilization", "Stabilization", "add_to")],
    "contact": [("mechanics.rigid_contact", "RigidContact", "evaluate"),
                ("mechanics.surface_contact", "SurfaceContact", "evaluate")],
    "solve": [("solvers.newton", None, "solve_constrained")],
    "setup": [("runs.runner", None, "build")],
    "output": [("runs.runner", None, "save_checkpoint"), ("runs.runner", None, "fold_columns"),
               ("runs.io", "HistoryFile", "append")],
}
#: the columns of the table, in ms per iteration (start-up: measured apart)
COLUMNS = ("material", "force", "tangent", "contact", "solve", "start-up", "setup", "output",
           "rest")

#: runs ``skfem-rkpm`` (the arguments after the output path) with the
#: functions of PARTS wrapped in CPU timers (only the outermost of nested
#: timed calls counts), and writes the seconds of each part, the whole
#: process's CPU seconds and the tangents formed as JSON to the output path
_TIMED = """
import importlib, json, runpy, sys, time
parts, path = json.loads(sys.argv[1]), sys.argv[2]
sys.argv = ['skfem-rkpm'] + sys.argv[3:]
seconds = {part: 0.0 for part in parts}
active = [False]
calls = {'tangents': 0}

def timed(part, fn, count):
    def wrapper(*args, **kwargs):
        if active[0]:
            return fn(*args, **kwargs)
        active[0] = True
        start = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            seconds[part] += time.process_time() - start
            active[0] = False
            calls['tangents'] += count
    return wrapper

for part, functions in parts.items():
    for module, owner, name in functions:
        m = importlib.import_module('skfem_rkpm.' + module)
        target = m if owner is None else getattr(m, owner)
        if name in vars(target):
            setattr(target, name, timed(part, vars(target)[name], name == '_tangent_matrix'))
seconds['start-up'] = time.process_time()  # the interpreter and the imports above
try:
    runpy.run_module('skfem_rkpm.runs.cli', run_name='__main__')
except SystemExit:
    pass
json.dump({'parts': seconds, 'total': time.process_time(), **calls}, open(path, 'w'))
"""


def timed_run(scene, settings, folder, output):
    """One run of ``scene`` with its parts timed (:data:`_TIMED`): the CPU
    seconds of each part of :data:`PARTS`, of the whole process, and the
    number of tangents formed."""
    command = [sys.executable, "-c", _TIMED, json.dumps(PARTS), str(output), "run", scene,
               "--quiet", "--out", str(folder), "--set", "output.fields=false",
               "--set", "output.figures=false"]
    for setting in settings:
        command += ["--set", setting]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return json.loads(Path(output).read_text())


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
          "(median; range) | SCNI / Gauss+VCI | " + " | ".join(COLUMNS)
          + " | material + force + tangent / Gauss+VCI |")
    print("|---|---|---|---:|---:|---:|" + "---:|" * (len(COLUMNS) + 1))
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            scene, settings = SCENES[case]
            reference = None
            for scheme, extra in SCHEMES.items():
                folder = Path(tmp) / f"{case}-{scheme}".replace("+", "_")
                times = [run_scene(scene, "rkpm", settings + extra, folder, args.limit)[0]
                         for _ in range(args.repeat)]
                _, out = history(folder)
                timing = timed_run(scene, settings + extra, folder,
                                   Path(tmp) / f"{case}-{scheme}.json".replace("+", "_"))
                parts, total = timing["parts"], timing["total"]
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
                      + " | ".join(f"{ms[k]:.2f}" for k in COLUMNS)
                      + f" | {core / reference[1]:.2f} |", flush=True)
    print(f"load average at end: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
