"""Parameter sweeps: the Cartesian product of scene overrides, run as tasks on
dask.distributed.

    skfem-rkpm sweep ring --vary tools.platen.friction=0,0.1,stick --workers 2

Every combination of ``vary`` values is one run: the scene text with the
sweep's ``settings`` and the run's own overrides applied (exactly as
:func:`skfem_rkpm.runs.scene.load_scene` does), then :func:`skfem_rkpm.runs.runner.build`
and :func:`skfem_rkpm.runs.runner.run`.  A run's folder is named by a content hash
of the resolved scene (:func:`scene_key`), so re-running a sweep finds the
runs that already finished (their ``result.json``) and skips them.  Results
land as they finish: the run folder (``history.csv``, fields and figures as
the scene says, ``scene.toml``, ``result.json``) and one row of the combined
``sweep.csv``.

Runs go to a ``LocalCluster`` (one single-threaded worker process per core,
one BLAS thread each) unless ``scheduler`` names an existing cluster; with a
remote cluster, ``out`` must be a folder the workers can write to (a shared
file system).  Scripts that start a local cluster need the
``if __name__ == "__main__":`` guard (workers are spawned processes).
"""

import csv
import hashlib
import io
import itertools
import json
import os
import sys
import time
import tomllib
from pathlib import Path

from .folder import SWEEP_RUN, FolderError, RunFolder, read_manifest
from .scene import SceneError, apply_setting, parse_scene, setting_origins

__all__ = ["SweepError", "parse_vary", "split_values", "cases", "resolve_text",
           "scene_key", "run_case", "run_sweep", "SweepProgress", "WORKER_ENV"]

#: Environment of local worker processes: one BLAS thread each (small dense
#: solves are far slower when BLAS threads compete for the cores), no display.
WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "MPLBACKEND": "Agg"}

#: History columns that describe the solver, not the final state.
_BOOKKEEPING = ("step", "iterations", "residual", "cutbacks", "attempts", "all iterations",
                "contact changes", "seconds")


class SweepError(SceneError):
    """A sweep is specified wrongly (``--vary`` syntax, missing Dask)."""


# -- the product of values ---------------------------------------------------------


def split_values(text):
    """Split ``"0,0.05,[6,4],stick"`` at the commas outside brackets and quotes."""
    parts, depth, quote, current = [], 0, None, ""
    for char in text:
        if quote:
            quote = None if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
            continue
        current += char
    parts.append(current.strip())
    if any(p == "" for p in parts):
        raise SweepError(f"--vary values {text!r}: an empty value; separate values "
                         f"by single commas, e.g. 0,0.1,stick")
    return parts


def parse_vary(option):
    """``"tools.platen.friction=0,0.1,stick"`` -> ``("tools.platen.friction",
    ["0", "0.1", "stick"])``; values stay TOML text, read like ``--set`` values."""
    if "=" not in option:
        raise SweepError(f"--vary {option!r}: expected KEY=V1,V2,..., e.g. "
                         f"tools.platen.friction=0,0.1,stick")
    key, values = (s.strip() for s in option.split("=", 1))
    if not key:
        raise SweepError(f"--vary {option!r}: the key is empty")
    return key, split_values(values)


def _toml_text(value):
    """A Python value as the text of a ``--set`` value (strings pass unchanged)."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_text(v) if not isinstance(v, str) else json.dumps(v)
                               for v in value) + "]"
    raise SweepError(f"cannot use {value!r} as a scene value; give a number, a string, "
                     f"a boolean or a list")


def _typed(text):
    """The value a ``--set`` text stands for (TOML, or else the string itself)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def cases(vary):
    """The Cartesian product of ``vary`` (``{key: [values]}``; a value list may
    also be one comma-separated string).  Returns a list of ``{key: text}``
    dicts, the last key varying fastest."""
    if not vary:
        raise SweepError("nothing to vary: give at least one --vary KEY=V1,V2,...")
    keys, lists = [], []
    for key, values in vary.items():
        values = split_values(values) if isinstance(values, str) else list(values)
        if not values:
            raise SweepError(f"--vary {key}: no values")
        keys.append(key)
        lists.append([_toml_text(v) for v in values])
    return [dict(zip(keys, combo)) for combo in itertools.product(*lists)]


# -- one run -----------------------------------------------------------------------


def resolve_text(text, settings):
    """Scene text with ``"key=value"`` settings applied in order, as in
    :func:`skfem_rkpm.runs.scene.load_scene`."""
    for setting in settings:
        text = apply_setting(text, setting)
    return text


def scene_key(text, source="<scene>", base=None):
    """Content hash (sha256 hex) of a resolved scene.

    The hash is taken over the validated scene (every default filled in, so
    formatting, comments and ``0.1`` vs ``0.10`` do not matter) plus the bytes
    of a gmsh geometry file it references; a scene that does not validate is
    hashed by its text (its run fails and is recorded).
    """
    digest = hashlib.sha256()
    try:
        scene = parse_scene(text, source, base)
    except SceneError:
        digest.update(b"text\n" + text.encode())
        return digest.hexdigest()
    content = {k: v for k, v in scene.items() if not k.startswith("_")}
    digest.update(json.dumps(content, sort_keys=True, default=str).encode())
    geometry = scene["geometry"]
    if geometry["kind"] == "gmsh":
        path = Path(geometry["file"])
        if base is not None and not path.is_absolute():
            path = Path(base) / path
        if path.exists():
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _final_row(path):
    """The last row of a ``history.csv`` as floats, without solver bookkeeping."""
    if not path.exists():
        return {}
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        return {}
    return {k: float(v) for k, v in rows[-1].items() if k not in _BOOKKEEPING and v != ""}


def run_case(text, source, base, run_dir, params, origins=None, threads=1):
    """Run one scene (its resolved TOML ``text``) into ``run_dir``; never raises.

    This is the task a worker executes.  Writes ``scene.toml``, the runner's
    output and ``result.json`` into a run folder
    (:class:`~skfem_rkpm.runs.folder.RunFolder`: a folder of someone else at
    that name is refused, and the run recorded as failed); returns the record
    of ``sweep.csv``: the parameters, ``status`` (completed, incomplete or
    failed), ``completed``, ``steps``, ``newton iterations``, ``wall time``,
    ``message``, ``error`` and the last row of the history (tool forces,
    gauges).  ``origins``: where a scene value came from (``{key: "--vary
    key=value"}``, for the error messages); ``threads``: BLAS threads of the
    run, in whatever process it runs.
    """
    from .folder import RunFolder
    from .plot import save_run_figures
    from .runner import blas_threads, build, run

    run_dir = Path(run_dir)
    record = dict(params, run=run_dir.name, status="failed", completed=False, steps=0,
                  **{"newton iterations": 0, "wall time": 0.0}, message="", error="")
    start = time.perf_counter()
    ours = False
    try:
        with RunFolder(run_dir, writes=SWEEP_RUN) as folder:  # kept if the build fails
            folder.clear()
            folder.write("scene.toml", text)
        ours = True
        scene = parse_scene(text, source, base, origins)
        with blas_threads(threads):
            sim = build(scene)
            result = run(sim, run_dir, progress=False)
        if scene["output"]["figures"] and result.history:
            with RunFolder(run_dir, mode="add", writes=SWEEP_RUN) as folder:
                save_run_figures(sim, result, run_dir, folder)
        record.update(status="completed" if result.completed else "incomplete",
                      completed=bool(result.completed), steps=len(result.history),
                      message=result.message)
        record["newton iterations"] = sum(r.iterations for r in result.history)
        if not result.completed:
            record["error"] = result.message
    except Exception as err:  # a failed run is a result of the sweep
        record["error"] = f"{type(err).__name__}: {err}"
    record["wall time"] = time.perf_counter() - start
    if not ours:  # a folder of someone else: nothing of it is read or written
        return record
    record.update(_final_row(run_dir / "history.csv"))
    try:
        with RunFolder(run_dir, mode="add", writes=SWEEP_RUN) as folder:
            folder.write("result.json", json.dumps(record, indent=1))
    except Exception as err:  # a result that cannot be kept is still a result
        record["error"] = record["error"] or f"{type(err).__name__}: {err}"
    return record


# -- progress ----------------------------------------------------------------------


class SweepProgress:
    """A line per finished run and a status line: done, failed, running,
    pending, elapsed and an ETA from the throughput so far."""

    def __init__(self, total, keys=(), stream=None, enabled=True):
        self.total, self.keys = total, tuple(keys)
        self.stream, self.enabled = stream or sys.stderr, enabled
        self.start = time.perf_counter()
        self.done = self.failed = self.skipped = self.new = 0
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()

    def finished(self, record, skipped=False):
        """Count a finished (or skipped) run and print its line."""
        self.done += 1
        self.skipped += skipped
        self.new += not skipped
        self.failed += record["status"] != "completed"
        if not self.enabled:
            return
        params = " ".join(f"{k}={v}" for k, v in record.items() if k in self.keys)
        if skipped:
            what = "done earlier"
        else:
            what = (f"{record['status']}, {record['steps']} steps, "
                    f"{record['wall time']:.1f} s")
            if record["error"] and record["status"] == "failed":
                what += f": {record['error']}"
        self._clear()
        self.stream.write(f"[{self.done}/{self.total}] {params}: {what} "
                          f"({record['run']})\n")
        self.stream.flush()

    def status(self, running):
        """Print the status line (in place on a terminal)."""
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        left = self.total - self.done
        eta = f"{elapsed * left / self.new:.0f} s" if self.new else "?"
        line = (f"{self.total} runs: completed {self.done - self.failed}, failed "
                f"{self.failed}, running {running}, pending {max(left - running, 0)}, "
                f"elapsed {elapsed:.0f} s, eta {eta}")
        if self.tty:
            self.stream.write(f"\r{line} ")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def _clear(self):
        if self.tty:
            self.stream.write("\r\033[K")

    def close(self):
        """End the status line."""
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()


# -- the sweep ---------------------------------------------------------------------


def _require_dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SweepError("parameter sweeps run on dask.distributed, which is not "
                         "installed; install it with: pip install skfem-rkpm[dask]") from None


def _client(scheduler, workers, threads=1):
    """A client of the cluster at ``scheduler``, or of a new LocalCluster
    (its workers' BLAS libraries start with ``threads`` threads)."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler is not None:
        return Client(scheduler), None
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           dashboard_address=":0",
                           env=dict(WORKER_ENV, **{k: str(threads) for k in WORKER_ENV
                                                   if k.endswith("_NUM_THREADS")}),
                           silence_logs=logging.ERROR)
    return Client(cluster), cluster


def _write_table(folder, records):
    """Write ``sweep.csv`` of the sweep's ``folder`` (a RunFolder), atomically:
    one row per record, columns in first-seen order."""
    columns = list(dict.fromkeys(k for r in records for k in r))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns)
    writer.writeheader()
    writer.writerows(records)
    folder.write("sweep.csv", text.getvalue())


def _finished(folder):
    """The record of a run folder's ``result.json``, if the run wrote it and
    completed (a folder or file of someone else is never read)."""
    try:
        manifest = read_manifest(folder)
    except FolderError:
        return None
    path = folder / "result.json"
    if manifest is None or manifest["kind"] != "run" or "result.json" not in \
            manifest["files"] or path.is_symlink() or not path.is_file():
        return None
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("status") == "completed" \
        else None


def _running(client, futures):
    """How many of ``futures`` are running: those assigned to workers, at most
    one per worker thread (a worker may hold queued tasks too)."""
    try:
        keys = {f.key for f in futures}
        assigned = sum(len(keys.intersection(v)) for v in client.processing().values())
        return min(assigned, sum(client.nthreads().values()))
    except Exception:  # a status line must not stop the sweep
        return 0


def run_sweep(scene_path, vary, settings=(), method=None, out=None, scheduler=None,
              workers=None, progress=True, stream=None, client=None, overwrite=False,
              threads=1):
    """Run every combination of ``vary`` on dask.distributed; return the records.

    Parameters
    ----------
    scene_path : str or Path
        A scene file.
    vary : dict
        ``{key: values}``; values are ``--set`` texts (``"0.1"``, ``"stick"``,
        ``"[6, 4]"``) or Python numbers, booleans and lists.
    settings : sequence of str
        ``"key=value"`` overrides for every run (applied before ``vary``).
    method : {"rkpm", "fem"}, optional
        Overrides ``model.method`` (becomes part of the resolved scene).
    out : str or Path
        Sweep folder (default ``results/SCENE-sweep``): ``sweep.csv`` and one
        folder ``run-HASH`` per run.
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:port``); used unchanged.
    workers : int, optional
        Worker processes of the local cluster (default: one per core).
    progress : bool
        Print a line per finished run and a status line to ``stream``
        (default standard error).
    client : distributed.Client, optional
        Use this client (its cluster is left running).
    overwrite : bool
        Also use an ``out`` that is neither empty nor a sweep folder (the
        sweep's files go beside the ones there; a ``sweep.csv`` of someone
        else is refused even so).  A sweep folder is used again as it is:
        its finished runs are kept.
    threads : int
        BLAS threads of every run (also in the worker processes).

    Returns
    -------
    list of dict
        One record per run in product order (see :func:`run_case`), each with
        ``skipped`` True when it had finished in an earlier sweep.
    """
    _require_dask()
    scene_path = Path(scene_path)
    if not scene_path.exists():
        raise SweepError(f"{scene_path}: no such scene file")
    out = Path(out or f"results/{scene_path.stem}-sweep")
    base_settings = list(settings) + ([f"model.method={method}"] if method else [])
    source, base = str(scene_path), str(scene_path.parent.resolve())
    text = scene_path.read_text()
    common = setting_origins(list(settings), "--set")

    plan, jobs = [], {}
    for params in cases(vary):
        resolved = resolve_text(text, base_settings + [f"{k}={v}" for k, v in params.items()])
        name = "run-" + scene_key(resolved, source, base)[:16]
        plan.append(({k: _typed(v) for k, v in params.items()}, name))
        jobs.setdefault(name, (resolved, params))
    with RunFolder(out, kind="sweep", overwrite=overwrite) as folder:
        return _sweep(folder, plan, jobs, common, source, base, vary, scheduler, workers,
                      progress, stream, client, threads)


def _sweep(folder, plan, jobs, common, source, base, vary, scheduler, workers, progress,
           stream, client, threads):
    """The runs of :func:`run_sweep` in its sweep ``folder`` (held)."""
    from distributed import as_completed

    out = folder.path
    records, todo = {}, []
    for name in jobs:
        record = _finished(out / name)
        if record is not None:
            records[name] = dict(record, skipped=True)
            continue
        todo.append(name)

    bar = SweepProgress(len(plan), vary, stream, progress)

    def table():
        rows = [dict(params, **{k: v for k, v in records[name].items() if k not in params})
                for params, name in plan if name in records]
        _write_table(folder, rows)
        return rows

    for params, name in plan:
        if name in records:
            bar.finished(dict(records[name], **params), skipped=True)
    table()
    if todo:
        own = client is None
        if own:
            client, cluster = _client(scheduler, workers, threads)
        try:
            futures = {client.submit(run_case, jobs[name][0], source, base,
                                     str((out / name).resolve()),
                                     {k: _typed(v) for k, v in jobs[name][1].items()},
                                     dict(common, **setting_origins(
                                         [f"{k}={v}" for k, v in jobs[name][1].items()],
                                         "--vary")),
                                     threads, pure=False): name for name in todo}
            bar.status(_running(client, futures))
            pending = as_completed(futures)
            last = time.perf_counter()
            while not pending.is_empty():
                batch = pending.next_batch(block=False)
                if not batch:
                    time.sleep(0.2)
                    if bar.tty and time.perf_counter() - last > 2.0:
                        bar.status(_running(client, futures))
                        last = time.perf_counter()
                    continue
                for future in batch:
                    name = futures.pop(future)
                    records[name] = _collect(future, name, jobs[name][1])
                    bar.finished(records[name])
                table()
                bar.status(_running(client, futures))
                last = time.perf_counter()
        finally:
            bar.close()
            if own:
                client.close()
                if cluster is not None:
                    cluster.close()
    rows = table()
    return [dict(row, skipped=records[name].get("skipped", False))
            for row, (_, name) in zip(rows, plan)]


def _collect(future, name, params):
    """The record of a finished future; a lost task (worker died) is a failure."""
    if future.status == "finished":
        return dict(future.result(), skipped=False)
    try:
        error = future.exception()
        error = f"{type(error).__name__}: {error}"
    except Exception as err:
        error = f"{type(err).__name__}: {err}"
    return dict({k: _typed(v) for k, v in params.items()}, run=name, status="failed",
                completed=False, steps=0, message="", error=error, skipped=False,
                **{"newton iterations": 0, "wall time": float("nan")})
