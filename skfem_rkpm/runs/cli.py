"""Command line: ``skfem-rkpm run | compare | sweep | scenes``.

    skfem-rkpm scenes
    skfem-rkpm run ring [--method rkpm|fem] [--set key=value ...] [--out DIR] [--resume]
                        [--overwrite] [--solver NAME] [--threads N] [--trust-geo]
    mpiexec -n 2 skfem-rkpm run ring --solver petsc
    skfem-rkpm compare ring [--set key=value ...] [--out DIR] [--overwrite] [--trust-geo]
    skfem-rkpm sweep ring --vary key=v1,v2,... [--vary ...] [--set key=value ...]
               [--method rkpm|fem] [--scheduler ADDRESS] [--workers N] [--out DIR]
               [--overwrite]

A scene is a built-in name (``skfem-rkpm scenes``) or a path to a TOML file.
Every command runs with one BLAS thread (``--threads N`` for more).  An
output folder must be missing, empty or a folder this program wrote (its
manifest ``.skfem-rkpm.json``); a run there removes only the files the
manifest lists.  ``--overwrite`` also writes into a folder of someone else,
beside the files there, and still never replaces a file it did not write
(:class:`~skfem_rkpm.runs.folder.RunFolder`).
"""

import argparse
import contextlib
import hashlib
import shlex
import sys
import warnings
from pathlib import Path

import numpy as np

from ..solvers.petsc import is_root, world
from ..solvers.linear import BACKENDS
from .scene import SceneError, builtin_scenes, load_scene
from .scene_dynamics import is_dynamic

__all__ = ["main"]


def _scene_path(name):
    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        return path
    scenes = builtin_scenes()
    if name not in scenes:
        raise SceneError(f"{name!r} is neither a file nor a built-in scene; built-in: "
                         f"{', '.join(scenes)}")
    return scenes[name]


def _default_out(path, method, settings, suffix=""):
    """``results/SCENE-METHOD``; with ``--set`` a hash of the settings is
    added, so that a changed scene never overwrites the scene's own results."""
    name = f"{path.stem}-{method}{suffix}" if method else f"{path.stem}{suffix}"
    if settings:
        digest = hashlib.sha256("\n".join(settings).encode()).hexdigest()[:8]
        name += f"-set-{digest}"
    return Path("results") / name


def _out(args, path, method, settings, suffix=""):
    if args.out:
        return Path(args.out)
    out = _default_out(path, method, settings, suffix)
    if settings and is_root():
        print(f"note: --set changes the scene, so the results go to {out} (give --out to "
              f"name the folder)")
    return out


def _run_one(path, settings, method, out, resume, quiet, trust_geo=False, overwrite=False):
    from .folder import RunFolder
    from .runner import build, run, steps_finished

    scene = load_scene(path, settings)
    sim = build(scene, method, trust_geo=trust_geo)
    if is_dynamic(scene):  # runs/explicit_run.py, runs/implicit_run.py
        if scene["dynamics"]["scheme"] == "implicit":
            from .implicit_run import console_run
        else:
            from .explicit_run import console_run

        return sim, console_run(sim, out, quiet, resume, overwrite)
    root = is_root()  # under mpiexec only rank 0 writes and prints
    ranks = world()[1]
    if root:
        print(f"{scene['model']['title'] or path.stem}: {sim.method}, {sim.basis.N} dofs, "
              f"{scene['steps']['count']} steps -> {out}")
        if sim.partition is not None:
            counts = np.bincount(sim.partition.cells, minlength=ranks)
            print(f"partitioned over {ranks} MPI ranks: each integrates its own cells "
                  f"({counts.min()}-{counts.max()} of {len(sim.partition.cells)})")
        elif ranks > 1 and scene["steps"]["solver"] == "petsc":
            what = (f"integration = {scene['discretization']['integration']!r}"
                    if sim.method == "rkpm" else "FEM")
            print(f"note: {ranks} MPI ranks, but {what} is not partitioned: every rank "
                  f"assembles the whole model and only the solve is distributed")
        if ranks > 1 and not scene["steps"]["solver"].startswith("petsc"):
            print(f"note: {ranks} MPI ranks, but the solver {scene['steps']['solver']!r} is "
                  f"not distributed: every rank repeats the whole run (use --solver petsc)")
    result = run(sim, out, progress=root and not quiet, resume=resume, overwrite=overwrite)
    if root and scene["output"]["figures"] and result.history:
        from .plot import save_run_figures  # matplotlib: 0.4 s to import

        with RunFolder(out, mode="add") as folder:
            save_run_figures(sim, result, out, folder)
    iterations = sum(r.iterations for r in result.history)
    seconds = sum(r.seconds for r in result.history)
    if root:
        count = sim.scene["steps"]["count"]
        done = (steps_finished(result.history[-1].t, count, result.completed)
                if result.history else 0)
        solved = len(result.history)
        cut = f" (in {solved} sub-steps)" if solved != done else ""
        print(f"{result.message}: {done} of {count} steps{cut}, {iterations} Newton "
              f"iterations, {seconds:.1f} s")
        if getattr(result, "report", ""):
            print(result.report, file=sys.stderr)
    return sim, result


def cmd_scenes(args):
    for name, path in builtin_scenes().items():
        title = load_scene(path)["model"]["title"]
        print(f"{name:12s} {title}  ({path})")
    return 0


def cmd_run(args):
    path = _scene_path(args.scene)
    method = args.method or load_scene(path, args.set)["model"]["method"]
    out = _out(args, path, method, args.set)
    settings = args.set + ([f"steps.solver={args.solver}"] if args.solver else [])
    if is_root():  # refused before the work, not after the build
        from .folder import RunFolder

        RunFolder(out, mode="resume" if args.resume else "new",
                  overwrite=args.overwrite).check()
    try:
        _, result = _run_one(path, settings, args.method, out, args.resume, args.quiet,
                             args.trust_geo, args.overwrite)
    except KeyboardInterrupt:
        if is_dynamic(load_scene(path, settings)):
            print(f"\ninterrupted: the outputs written so far are in {out}; a dynamic "
                  f"run does not resume, run it again to start over", file=sys.stderr)
            return 130
        again = ["skfem-rkpm", "run", args.scene, *(f"--set={s}" for s in settings),
                 *(["--method", args.method] if args.method else []),
                 *(["--trust-geo"] if args.trust_geo else []), "--out", str(out),
                 "--resume"]
        print(f"\ninterrupted: the finished steps are in {out}; continue with\n  "
              f"{shlex.join(again)}", file=sys.stderr)
        return 130
    return 0 if result.completed else 1


def cmd_compare(args):
    from .report import write_comparison

    from .folder import RunFolder

    path = _scene_path(args.scene)
    if is_dynamic(load_scene(path, args.set)):
        raise SceneError(f"compare runs static scenes; {path.stem} is dynamic: run "
                         f"skfem-rkpm run {args.scene} --method rkpm and --method fem")
    out = _out(args, path, None, args.set, "-compare")
    runs = {}
    with contextlib.ExitStack() as stack:
        top = None
        if is_root():  # under mpiexec only rank 0 writes and prints
            # the report's folder, held for the whole comparison: its own
            # files (report.md, compare.png) go, each run clears its own
            top = stack.enter_context(RunFolder(out, kind="compare",
                                                overwrite=args.overwrite))
            for method in ("rkpm", "fem"):  # refused before the work
                RunFolder(out / method, overwrite=args.overwrite).check()
            top.clear()
        try:
            for method in ("rkpm", "fem"):
                runs[method] = _run_one(path, args.set, method, out / method, False,
                                        args.quiet, args.trust_geo, args.overwrite)
        except KeyboardInterrupt:
            print(f"\ninterrupted: the finished steps are in {out}; compare cannot "
                  f"resume, run it again to start over", file=sys.stderr)
            return 130
        failed = [m for m, (_, result) in runs.items() if not result.completed]
        if top is None:
            return 1 if failed else 0
        report = write_comparison(runs, out, args.set, str(path), folder=top)
    print(f"report: {report}")
    if failed:
        print(f"not completed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


def cmd_sweep(args):
    from .sweep import parse_vary, run_sweep

    path = _scene_path(args.scene)
    vary = dict(parse_vary(option) for option in args.vary)
    out = _out(args, path, None, args.set, "-sweep")
    records = run_sweep(path, vary, args.set, args.method, out, args.scheduler,
                        args.workers, progress=not args.quiet, overwrite=args.overwrite,
                        threads=args.threads)
    bad = [r for r in records if r["status"] != "completed"]
    print(f"{len(records) - len(bad)} of {len(records)} runs completed -> {out / 'sweep.csv'}")
    return 1 if bad else 0


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give a whole number >= 1")
    return value


def _folder_options(p, kind):
    """``--overwrite`` and ``--threads`` of run, compare and sweep."""
    names = {"run": "history.csv, scene.toml, fields/step-*.h5, the figures",
             "compare": "report.md, compare.png; the runs' files in rkpm/ and fem/",
             "sweep": "sweep.csv"}[kind]
    p.add_argument("--overwrite", action="store_true",
                   help="write into a folder that is neither empty nor one skfem-rkpm "
                        "wrote: the program's files go beside the files there, which "
                        "are never changed or removed; a file there at a name the "
                        f"program writes ({names}) is refused even so.  A folder "
                        "skfem-rkpm wrote needs no --overwrite: its .skfem-rkpm.json "
                        "lists the program's files, and only those are replaced")
    p.add_argument("--threads", type=_positive_int, default=1, metavar="N",
                   help="BLAS threads" + (" of every run" if kind == "sweep" else "")
                        + " (default 1: the many small dense solves of a run are "
                          "slower spread over threads)")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Warnings as one line, ``warning: ...``, without the source line."""
    print(f"warning: {message}", file=file or sys.stderr)


def main(argv=None):
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="skfem-rkpm", description="Run RKPM and FEM scenes: run, compare, sweep, scenes.")
    parser.add_argument("--version", action="version", version=f"skfem-rkpm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=cmd_scenes)
    for name, helptext, func in (("run", "run a scene", cmd_run),
                                 ("compare", "run RKPM and FEM on the same scene",
                                  cmd_compare)):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("scene", help="built-in scene name or TOML file")
        p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                       help="override a scene value, e.g. tools.platen.friction=0.3")
        p.add_argument("--out", help=("output folder (default results/SCENE-METHOD)"
                                      if name == "run" else
                                      "output folder (default results/SCENE-compare)")
                       + "; with --set a hash of the settings is added")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        _folder_options(p, name)
        p.add_argument("--trust-geo", action="store_true",
                       help="let the scene's gmsh .geo file run programs or read and "
                            "write other files (refused otherwise)")
        if name == "run":
            p.add_argument("--method", choices=("rkpm", "fem"),
                           help="discretization (default: the scene's model.method)")
            p.add_argument("--resume", action="store_true",
                           help="continue from the last finished step in --out")
            p.add_argument("--solver", choices=("auto", *BACKENDS),
                           help="linear solver (default: the scene's steps.solver, auto); "
                                "petsc and petsc-gamg distribute the solve over the ranks "
                                "of mpiexec -n P skfem-rkpm run ...")
        p.set_defaults(func=func)
    p = sub.add_parser("sweep", help="run every combination of scene values on "
                                     "dask.distributed (pip install skfem-rkpm[dask])")
    p.add_argument("scene", help="built-in scene name or TOML file")
    p.add_argument("--vary", action="append", required=True, metavar="KEY=V1,V2,...",
                   help="values of one key, e.g. tools.platen.friction=0,0.1,stick; "
                        "several --vary give the Cartesian product")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value in every run")
    p.add_argument("--method", choices=("rkpm", "fem"),
                   help="discretization (default: the scene's model.method)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="existing dask scheduler, e.g. tcp://host:8786 (default: a "
                        "local cluster)")
    p.add_argument("--workers", type=int, help="local worker processes (default: one "
                                                "per core)")
    p.add_argument("--out", help="sweep folder (default results/SCENE-sweep; with --set a "
                                 "hash of the settings is added)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    _folder_options(p, "sweep")
    p.set_defaults(func=cmd_sweep)
    args = parser.parse_args(argv)
    shown, warnings.showwarning = warnings.showwarning, _show_warning
    try:
        if not hasattr(args, "threads"):  # skfem-rkpm scenes
            return args.func(args)
        from .runner import blas_threads

        with blas_threads(args.threads):
            return args.func(args)
    except (ValueError, ImportError) as err:
        # SceneError, the library's checks of the input, the run folder and
        # checkpoint checks, a linear solver whose package is missing
        print(f"error: {err}", file=sys.stderr)
        return 2
    except MemoryError as err:
        print(f"error: out of memory ({err or 'MemoryError'}); use a coarser mesh or a "
              f"smaller support", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # sweep: running it again skips the finished runs
        print("\ninterrupted: the finished runs are kept; run the same command again to "
              "do the others", file=sys.stderr)
        return 130
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":
    sys.exit(main())
