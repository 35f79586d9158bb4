"""How far each discretization takes the upsetting and a plane-strain block
(docs/large_deformation.md, "Upsetting and the 90 % block").

The paper's upsetting (Sec. 5.4, the built-in ``upsetting``) pressed to
80 % of its height, a plane-strain block between rough platens (μ = 0.3,
``benchmarks/scenes/block_plane.toml``) to 90 %, and the stick ring to
80 % by FEM Q2 (the ring's other methods are in ``reach_study.py``), each
by RKPM Gauss + VCI (the scene's locking choice, and without F-bar), RKPM
SCNI, FEM Q1 and FEM Q2.  Each run goes to its own folder under ``--out``
(a finished one is reused: its ``status.txt`` and ``history.csv`` are
read, nothing else); the script prints where each run stopped and why,
with the CPU seconds of the run, and draws the reduction reached.

    python benchmarks/reach_scenes.py --out results/reach_scenes [--figure docs/figures/large_deformation_reach_scenes.png]
"""

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_study import ending  # noqa: E402

HERE = Path(__file__).resolve().parent
#: scene name -> (scene file or built-in name, settings, platen travel, height) (mm)
SCENES = {
    "upsetting to 80 %": ("upsetting", ["tools.punch.motion=[0.0,-26.88]",
                                        "steps.count=128", "steps.max_iterations=40"],
                          26.88, 33.6),
    "block to 90 %": (str(HERE / "scenes" / "block_plane.toml"), [], 9.0, 10.0),
    "ring stick to 80 %": ("ring", ["tools.platen.friction=stick",
                                    "tools.platen.motion=[0.0,-16.0]", "steps.count=140"],
                           16.0, 20.0),
}
METHODS = {
    "RKPM Gauss+VCI": ("rkpm", []),
    "RKPM Gauss+VCI, no F-bar": ("rkpm", ["discretization.locking=none"]),
    "RKPM SCNI": ("rkpm", ["discretization.integration=scni"]),
    "FEM Q1": ("fem", []),
    "FEM Q2": ("fem", ["discretization.element=quad2"]),
}
#: the ring's other methods are measured by reach_study.py; on the block the
#: scene's choice for RKPM is already no F-bar (2D, a tool slides with friction)
ONLY = {"ring stick to 80 %": ("FEM Q2",),
        "block to 90 %": tuple(m for m in METHODS if m != "RKPM Gauss+VCI, no F-bar")}
COMMON = ["output.fields=false", "output.figures=false"]


def folder(out, scene, method):
    """The run folder of one case."""
    slug = lambda text: "".join(c if c.isalnum() else "_" for c in text).strip("_")
    return out / f"{slug(scene)}-{slug(method)}"


def run_one(out, scene, method):
    """Run one case into ``out`` unless a finished run is there; CPU seconds or None."""
    from skfem_rkpm.runs.runner import build, run
    from skfem_rkpm.runs.scene import builtin_scenes, load_scene

    status = out / "status.txt"
    if status.is_file() and not status.read_text().startswith("running"):
        return None
    source, settings, _, _ = SCENES[scene]
    kind, extra = METHODS[method]
    path = builtin_scenes().get(source, source)
    loaded = load_scene(path, [*settings, *COMMON, *extra])
    load = os.getloadavg()[0]
    clock = time.process_time()
    run(build(loaded, kind), out, progress=False)
    seconds = time.process_time() - clock
    (out.parent / f"{out.name}.cpu.json").write_text(json.dumps(
        {"cpu_s": seconds, "load_start": load, "load_end": os.getloadavg()[0]}))
    return seconds


def reached(out, travel, height):
    """Height reduction reached (%) by a finished or stopped run."""
    rows = list(csv.DictReader(open(out / "history.csv", newline="")))
    t = float(rows[-1]["t"]) if rows else 0.0
    return 100.0 * t * travel / height


def cpu(out):
    """The CPU seconds recorded for a run folder, or None."""
    path = out.parent / f"{out.name}.cpu.json"
    return json.loads(path.read_text())["cpu_s"] if path.is_file() else None


def cases():
    """(scene, method) of every case."""
    return [(s, m) for s in SCENES for m in METHODS if m in ONLY.get(s, METHODS)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/reach_scenes"))
    parser.add_argument("--figure", type=Path)
    parser.add_argument("--scene", action="append", choices=sorted(SCENES))
    parser.add_argument("--no-run", action="store_true",
                        help="only read the finished runs under --out (skip the others)")
    args = parser.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    results = {}
    for scene, method in cases():
        if args.scene and scene not in args.scene:
            continue
        out = folder(args.out, scene, method)
        if args.no_run and not (out / "history.csv").is_file():
            continue
        if not args.no_run:
            seconds = run_one(out, scene, method)
            if seconds is not None:
                print(f"{scene}, {method}: {seconds:.1f} s CPU", file=sys.stderr, flush=True)
        _, _, travel, height = SCENES[scene]
        results[scene, method] = (reached(out, travel, height),
                                  ending((out / "status.txt").read_text().strip()), cpu(out))
    print("| scene | method | reduction reached | how it ended | CPU s |")
    print("|---|---|---|---|---|")
    for (scene, method), (value, text, seconds) in results.items():
        shown = "—" if seconds is None else f"{seconds:.0f}"
        print(f"| {scene} | {method} | {value:.1f} % | {text} | {shown} |")
    if args.figure:
        draw(results, args.figure)


def draw(results, path):
    """Bars of the reduction reached, one group per scene."""
    import matplotlib.pyplot as plt

    names = list(METHODS)
    fig, ax = plt.subplots(figsize=(8.5, 4.4))
    height = 0.8 / len(SCENES)
    for k, scene in enumerate(SCENES):
        values = [results.get((scene, name), (np.nan,))[0] for name in names]
        ax.barh(np.arange(len(names)) + (k - (len(SCENES) - 1) / 2) * height, values,
                height, label=scene)
    ax.set_yticks(np.arange(len(names)), names)
    ax.invert_yaxis()
    ax.set_xlabel("height reduction reached (%)")
    ax.set_xlim(0, 95)
    ax.set_title("Reach per method (target: the scene's end)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
