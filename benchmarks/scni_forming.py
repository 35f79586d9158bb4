"""Nodal integration (SCNI) on the forming scenes against Gauss+VCI.

The ring (``scenes/ring.toml``, 16 x 11 particles, μ = 0.15, 0.3 and stick)
and the upsetting scene (``scenes/upsetting.toml``), each run to the end with
the scene's Gauss+VCI integration and with SCNI and its stabilization
variants at the same particles, in fresh processes
(:func:`_whole_runs.run_scene`).  Reports the result (ring: inner-diameter
change and platen force; upsetting: punch force and rim radius at mid-height),
its difference from the Gauss+VCI run of the same case, the steps, cut-backs,
Newton iterations, the run's end status (the smallest ``det F`` at a cell
corner of the drawn cells when it is <= 0, see ``runner.final_state_message``)
and its CPU time.

Run:  python benchmarks/scni_forming.py                       (~15 minutes)
      python benchmarks/scni_forming.py --fine --cases ring    (31 x 21 particles)
      python benchmarks/scni_forming.py --cases "mu=0.3" --variants shear
"""

import argparse
import os
import re
import tempfile
from pathlib import Path

from _whole_runs import history, ring_id_change, run_scene

SCENES = {
    "ring mu=0.15": ("ring", ["tools.platen.friction=0.15"]),
    "ring mu=0.3": ("ring", ["tools.platen.friction=0.3"]),
    "ring stick": ("ring", ['tools.platen.friction="stick"']),
    "upsetting": ("upsetting", []),
}


def scni(alpha, moduli=None):
    out = ['discretization.integration="scni"', f"discretization.stabilization={alpha}"]
    if moduli is not None:
        out.append(f'discretization.stabilization_moduli="{moduli}"')
    return out


VARIANTS = {
    "gauss+vci": [],
    "scni a=0": scni(0.0),
    "scni a=1e-3 elastic": scni(1e-3),
    "scni a=1e-3 shear": scni(1e-3, "shear"),
    "scni a=3e-3 shear": scni(3e-3, "shear"),
    "scni a=1e-2 shear": scni(1e-2, "shear"),
    "scni a=1e-3 tangent": scni(1e-3, "tangent"),
    "scni a=3e-3 tangent": scni(3e-3, "tangent"),
    "scni a=1e-2 tangent": scni(1e-2, "tangent"),
}


def result(folder):
    """(diameter or radius, force) at the end of a run, and the totals."""
    rows, out = history(folder)
    last = rows[-1]
    if "inner_mid x" in last:
        size = ring_id_change(last)  # ID change, %
        force = -float(last["reaction platen y"]) / 1e3  # kN
    else:
        size = float(last["rim_mid x"])  # mm
        force = -float(last["reaction punch y"]) / 1e3  # kN
    status = (Path(folder) / "status.txt").read_text().strip()
    return size, force, out, status


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(SCENES))
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS))
    parser.add_argument("--keep", default=None, help="folder to keep the runs in")
    parser.add_argument("--limit", type=float, default=1800.0)
    parser.add_argument("--fine", action="store_true",
                        help="the ring at 31 x 21 particles (supports of 3 spacings)")
    parser.add_argument("--set", nargs="*", default=[], dest="settings",
                        help="more scene settings for every run (e.g. steps.count=200)")
    args = parser.parse_args()
    fine = ["geometry.divisions=[30, 20]", "discretization.support=3.0"] if args.fine else []
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    print("| case | variant | ID change % (rim mm) | Δ | force kN | Δ % | steps "
          "| cut-backs | iterations | all iterations | end | CPU s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        for case in [c for c in SCENES if any(w in c for w in args.cases)]:
            scene, settings = SCENES[case]
            settings = settings + (fine if scene == "ring" else []) + args.settings
            reference = None
            names = [v for v in VARIANTS if v == "gauss+vci" or any(w in v for w in args.variants)]
            for name in names:
                folder = root / f"{case}-{name}".replace(" ", "_")
                seconds, _, code = run_scene(scene, "rkpm", settings + VARIANTS[name],
                                             folder, args.limit)
                try:
                    size, force, out, status = result(folder)
                except (FileNotFoundError, IndexError, KeyError):
                    print(f"| {case} | {name} | failed ({code}) |", flush=True)
                    continue
                if name == "gauss+vci":
                    reference = (size, force)
                dsize = size - reference[0] if reference else float("nan")
                dforce = 100 * (force / reference[1] - 1) if reference else float("nan")
                folded = re.search(r"det F = (\S+) <= 0 at the corner (X = \([^)]*\))", status)
                end = (f"corner det F {float(folded[1]):.1e} at {folded[2]}" if folded else
                       "completed" if out["t"] >= 1 - 1e-9 else f"stopped at t={out['t']:.3f}")
                print(f"| {case} | {name} | {size:.2f} | {dsize:+.2f} | {force:.1f} | "
                      f"{dforce:+.1f} | {out['steps']} | {out['cut-backs']} | "
                      f"{out['iterations']} | {out['all iterations']} | {end} | "
                      f"{seconds:.1f} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
