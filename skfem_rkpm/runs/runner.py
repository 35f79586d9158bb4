"""Build a simulation from a scene and run it with results on disk.

:func:`~skfem_rkpm.runs.build.build` turns a scene into library objects;
:func:`run` drives them with :func:`~skfem_rkpm.solvers.newton.newton_steps`.
A run owns its folder (:class:`~skfem_rkpm.runs.folder.RunFolder`: a lock,
a manifest of the files it writes, the files of an earlier run removed and
no other, a folder of someone else refused, ``status.txt`` "running" until
it ends, the resolved scene as ``scene.toml``) and after every converged step
appends to ``history.csv`` and ``history.jsonl``, writes the step's fields
and replaces ``checkpoint.npz``: a run stopped at any moment (Ctrl-C,
SIGTERM, SIGKILL) keeps every step it finished, and ``resume=True``
continues from the last checkpoint exactly as if it had not stopped.
Under ``mpiexec`` every rank runs the same simulation and only rank 0 writes;
with a partitioned problem (:mod:`skfem_rkpm.solvers.partitioned`) every
rank integrates its own cells, and the material state and fields of an
output step are gathered from all ranks before rank 0 writes them.
"""

import contextlib
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..solvers.linear import make_solver
from ..solvers.newton import StepperState, newton_steps
from ..solvers.partitioned import DistributedLU
from ..solvers.petsc import is_root
from .build import Simulation, build
from .checkpoint import load_checkpoint, run_identity, save_checkpoint
from .fold_report import drawn_cells, fold_columns, map_check
from .folder import RunFolder, open_append, status_on_failure
from .io import FieldWriter, HistoryFile, material_fields, record_from_json, record_to_json
from .rereference import rereferencing_of, solve_segments
from .scene_dynamics import is_dynamic
from .stops import stop_report

__all__ = ["Simulation", "build", "run", "scene_step", "steps_finished", "Progress", "scene_text",
           "final_state_message", "blas_threads"]

#: environment variables read by BLAS libraries loaded later (a solver's own)
BLAS_ENV = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: linear solvers that partition the rows by the dof locations
DISTRIBUTED = ("petsc", "petsc-gamg")


def _point_probes(basis, points):
    if not points:
        return None
    X = np.array(list(points.values())).T
    return basis.probes(X)


def _gauges(sim, probes, d):
    """Current positions of the followed material points."""
    if probes is None:
        return {}
    X = np.array(list(sim.points.values())).T
    u = (probes @ d).reshape(X.shape[0], -1)
    out = {}
    for k, name in enumerate(sim.points):
        for c in range(X.shape[0]):
            out[f"{name} {'xyz'[c]}"] = float(X[c, k] + u[c, k])
    return out


def scene_step(t, count):
    """The scene's load step (1..count) that load factor ``t`` belongs to.

    A step that was cut back, or that the step control splits, is solved
    in sub-steps; they all belong to the scene step whose end they
    approach: ``ceil(t count)``.
    """
    return max(1, int(np.ceil(t * count - 1e-9)))


def steps_finished(t, count, completed):
    """How many of the scene's ``count`` steps a run ending at load factor
    ``t`` finished: :func:`scene_step` of ``t`` for a run that completed or
    stopped at a step's end, one fewer when it stopped inside a step."""
    if completed:
        return scene_step(t, count)
    return int(np.floor(t * count + 1e-9))


class Progress:
    """Scene step, load factor, Newton iterations, elapsed time and ETA: one
    updating line on a terminal, a new line every 10 % of the load otherwise
    (log files, pipes).  ``count``: the scene's number of steps; the step
    shown is the scene's (``step 7/100``), also when a step is solved in
    sub-steps; without ``count``, the solver's step counter."""

    def __init__(self, stream=None, enabled=True, count=None):
        # the standard error of now (a default bound at import would keep a
        # stream that may have been replaced and closed since)
        stream = sys.stderr if stream is None else stream
        self.stream, self.enabled, self.count = stream, enabled, count
        self.start = time.perf_counter()
        self.live = bool(getattr(stream, "isatty", lambda: False)())
        self.next_line = 0.1

    def __call__(self, record):
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        eta = elapsed * (1 - record.t) / max(record.t, 1e-12)
        width = 30
        done = int(round(width * record.t))
        step = (f"{scene_step(record.t, self.count)}/{self.count}" if self.count
                else f"{record.step}")
        text = (f"[{'#' * done}{'.' * (width - done)}] step {step} "
                f"t={record.t:.3f} newton={record.iterations} "
                f"elapsed {elapsed:.1f}s eta {eta:.1f}s")
        if self.live:
            self.stream.write(f"\r{text} ")
        elif record.t >= self.next_line - 1e-12:
            self.stream.write(text + "\n")
            self.next_line = np.floor(record.t * 10 + 1e-9) / 10 + 0.1
        self.stream.flush()

    def close(self):
        if self.enabled and self.live:
            self.stream.write("\n")


def run(sim, out=None, progress=True, resume=False, log=None, overwrite=False):
    """Run a simulation; with ``out`` write results there step by step.

    Parameters
    ----------
    sim : Simulation
    out : str or Path, optional
        Output folder.  A new run removes the files an earlier run wrote
        there (those its manifest lists) and no others; a folder in use by
        another run, a symbolic link, or a folder that is neither empty nor a
        run folder is refused (a ``FolderError``; see
        :class:`~skfem_rkpm.runs.folder.RunFolder`).
    progress : bool
        Show the progress line.
    resume : bool
        Continue from ``out/checkpoint.npz``: refused (a ``CheckpointError``
        naming what differs) unless the scene and method are the ones of the
        checkpoint; the history and the fields continue the same files.
    log : callable, optional
        Newton's log (one line per iteration and step).
    overwrite : bool
        Also write into a folder that is neither empty nor a run folder: the
        run's files go beside the ones there; a file there at a name the run
        writes is still refused.

    Returns
    -------
    Result
        Of :func:`~skfem_rkpm.solvers.newton.newton_steps`, with the whole
        history (a resumed run's earlier steps included) and ``gauges``.

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C or SIGTERM, after the step being written is complete.
    """
    if is_dynamic(sim.scene):
        raise ValueError(f"this scene has dynamics.scheme = "
                         f"{sim.scene['dynamics']['scheme']!r}: run it with "
                         f"skfem_rkpm.runs.{sim.scene['dynamics']['scheme']}_run."
                         f"run_{sim.scene['dynamics']['scheme']} (skfem-rkpm run does)")
    out = Path(out) if out is not None else None
    solver = _linear_solver(sim)  # a missing solver package stops here, folder untouched
    with contextlib.ExitStack() as stack:
        folder = None
        if out is not None and is_root():  # under mpiexec only rank 0 writes
            folder = stack.enter_context(RunFolder(
                out, mode="resume" if resume else "new", overwrite=overwrite))
            folder.remove_temporaries()
        start = _Start(StepperState(), None, [], [])
        identity = run_identity(sim) if out is not None else None
        if resume and out is not None:  # every MPI rank reads the checkpoint
            d0, stepper, meta = load_checkpoint(out, sim, identity)
            start = _Start(stepper, d0, *_resumed_history(out, meta, folder is not None))
        elif folder is not None:
            folder.clear()
        writer = None
        if folder is not None:
            folder.status(f"running (process {os.getpid()})")
            folder.write("scene.toml", scene_text(sim))
            writer = stack.enter_context(_StepWriter(
                sim, folder, identity, start.stepper.step if resume else None))
        interrupts = stack.enter_context(_Interrupts())
        try:
            return _run_steps(sim, start, writer, folder, interrupts, progress, log, solver,
                              gather=out is not None and sim.partition is not None)
        finally:
            # PETSc objects are destroyed collectively: every rank frees the
            # solver's here, in step, not when its garbage collector runs
            # (rank 0 alone then makes figures, and the ranks would wait
            # for each other)
            solver.reset()


@dataclass
class _Start:
    """Where a run starts: the stepper, coefficients, and the steps done."""

    stepper: StepperState
    d0: np.ndarray
    history: list
    rows: list


class _StepWriter:
    """Writes a converged step whole: a row appended to ``history.csv`` and
    ``history.jsonl``, the step's fields, then ``checkpoint.npz``, the commit
    point (a resume cuts off what a killed run wrote after it).

    ``folder``: the :class:`~skfem_rkpm.runs.folder.RunFolder`, whose
    manifest lists every file before it is written; ``keep_until``: continue
    the files of a resumed run, whose checkpoint is at that step (None:
    start new ones)."""

    def __init__(self, sim, folder, identity, keep_until=None):
        out = folder.path
        self.sim, self.out, self.identity = sim, out, identity
        folder.claim("history.csv", "history.jsonl", "checkpoint.npz")
        self.csv = HistoryFile(out / "history.csv", resume=keep_until is not None)
        self.records = open_append(out / "history.jsonl", encoding="utf-8")
        self.fields = None
        if sim.scene["output"]["fields"]:
            self.fields = FieldWriter(out / "fields.xdmf", sim.problem, keep_until,
                                      owner=folder)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.records.close()

    def write(self, record, gauges, d, evaluation, stepper, steps, gathered=None):
        """``gathered``: the whole domain's material state and fields of a
        partitioned problem (:func:`_gathered`)."""
        self.csv.append(record, gauges)
        self.records.write(record_to_json(record, gauges))
        self.records.flush()
        rereferenced = self.sim.rereferenced
        if self.fields is not None and _field_step(self.sim, record):
            if rereferenced is not None:  # fields on the current reference, in the
                self.fields.problem = self.sim.problem  # initial configuration's frame
                self.fields.offset = rereferenced.offset
            self.fields.write(record.t, d, evaluation, step=record.step,
                              fields=gathered and gathered[1])
        if rereferenced is not None:
            return  # the checkpoint stays at the last step on the initial reference
        save_checkpoint(self.out, self.sim, d, stepper, self.identity,
                        state=gathered and gathered[0], steps=steps,
                        history_bytes=(self.out / "history.csv").stat().st_size,
                        records_bytes=self.records.tell())


def _field_step(sim, record):
    """The fields are written at this step."""
    output = sim.scene["output"]
    return bool(output["fields"]) and record.step % output["every"] == 0


def _gathered(sim, record, evaluation):
    """The whole domain's material state and (at a field step) material
    fields of a partitioned problem, gathered on rank 0 (collective; the
    other ranks get Nones)."""
    fields = material_fields(sim.problem, evaluation) if _field_step(sim, record) else None
    return sim.problem.gathered_state(), fields


def _run_steps(sim, start, writer, folder, interrupts, progress, log, solver, gather=False):
    steps = sim.scene["steps"]
    probes = {id(sim.basis): _point_probes(sim.basis, sim.points)}
    history, rows = start.history, start.rows
    bar = Progress(enabled=progress, count=steps["count"])
    rereferencing = rereferencing_of(sim, log)

    def on_step(record, d, evaluation):
        if id(sim.basis) not in probes:  # rebuilt on a later configuration
            probes.clear()
            probes[id(sim.basis)] = _point_probes(sim.basis, sim.points)
        gauges = _gauges(sim, probes[id(sim.basis)], d)
        for tool in sim.tools:
            gauges.update(tool.gauges(record.t))
        gauges.update(fold_columns(sim, d))
        history.append(record)
        rows.append(gauges)
        gathered = _gathered(sim, record, evaluation) if gather else None
        if writer is not None:
            with interrupts.deferred():  # a step is written whole or not at all
                writer.write(record, gauges, d, evaluation, start.stepper, len(history),
                             gathered)
        bar(record)
        if rereferencing is not None:
            rereferencing.after_step(record, d, evaluation)

    def solve(d0):
        return newton_steps(sim.problem, sim.prescribed, load=sim.load,
                            steps=steps["count"], tol=steps["tolerance"],
                            max_iterations=steps["max_iterations"],
                            max_cutbacks=steps["max_cutbacks"], log=log,
                            d0=start.d0 if d0 is None else d0,
                            contributions=sim.contributions, on_step=on_step,
                            linear_solver=solver, stepper=start.stepper)

    def interrupted():
        last = (f"after step {history[-1].step}, t = {history[-1].t:.6g}" if history
                else "before the first step")
        return f"interrupted {last}: continue with --resume"

    try:
        with status_on_failure(folder, interrupted):
            result = (solve(None) if rereferencing is None
                      else solve_segments(rereferencing, solve, start.stepper))
    finally:
        bar.close()
    result.history = history
    result.gauges = rows
    result.report = ""
    if result.completed:
        result.message = final_state_message(sim, result.d)
    else:
        result.report = stop_report(sim, result)
    if rereferencing is not None:
        result.message += f" ({rereferencing.describe()})"
    if folder is not None:
        folder.status("\n".join(filter(None, [result.message, result.report])))
    return result


def final_state_message(sim, d, remedy="more load steps"):
    """"completed", or "completed with inverted cells: …" naming the
    corner with the smallest ``det F`` when a cell of the final state is
    folded (:func:`~skfem_rkpm.runs.io.corner_jacobians`): Newton checks
    ``det F`` at the quadrature points only, so a corner may fold while
    every step converges.  Either says whether the deformation map itself
    folds (:func:`~skfem_rkpm.runs.fold_report.map_check`: sampled in every
    cell) or only the drawn cells do.  ``remedy`` is the first advice for an
    invalid state (a dynamic run's is a smaller time step)."""
    folded, where = drawn_cells(sim, d)
    check = map_check(sim, d)
    if not folded.size and (check is None or check.valid):
        return "completed"
    invalid = (f"the final state is not a valid deformation: use {remedy}, a finer "
               "mesh or another discretization")
    if not folded.size:
        return f"completed with a folded map: {check.describe()}; {invalid}"
    if check is None:
        return f"completed with inverted cells: {where}; {invalid}"
    if check.valid:
        return (f"completed with inverted cells: {where}; {check.describe()}: only the "
                f"drawn cells fold")
    return f"completed with inverted cells: {where}; {check.describe()}; {invalid}"


def scene_text(sim):
    """The resolved scene as TOML text (the scene file with every ``--set``
    applied; a relative gmsh file made absolute), with the method."""
    from .scene import apply_setting

    text = sim.scene.get("_text")
    if text is None:
        return f"# scene of {sim.scene.get('_source')} (its text is not known)\n"
    geometry = sim.scene["geometry"]
    if geometry.get("kind") == "gmsh" and sim.scene.get("_base"):
        path = Path(sim.scene["_base"]) / geometry["file"]
        text = apply_setting(text, f'geometry.file="{path.resolve()}"')
    text = apply_setting(text, f'model.method="{sim.method}"')
    return f"# resolved scene of {sim.scene.get('_source')}\n" + text


def _resumed_history(out, meta, root):
    """The records and gauges of the checkpoint's steps from ``history.jsonl``;
    on rank 0, cut ``history.csv`` and ``history.jsonl`` back to their size at
    the checkpoint (a kill may have left a step written after it)."""
    records_path, csv_path = out / "history.jsonl", out / "history.csv"
    for path, size in ((records_path, meta["records_bytes"]),
                       (csv_path, meta["history_bytes"])):
        if not path.is_file() or path.is_symlink() or path.stat().st_size < size:
            from .checkpoint import CheckpointError

            raise CheckpointError(f"--resume: {path} is missing or shorter than at the "
                                  f"checkpoint (changed after the run?); start the run "
                                  f"afresh (without --resume)")
    with open(records_path, "rb") as handle:
        lines = handle.read(meta["records_bytes"]).decode("utf-8").splitlines()
    if root:
        for path, size in ((records_path, meta["records_bytes"]),
                           (csv_path, meta["history_bytes"])):
            with open(path, "r+b") as handle:
                handle.truncate(size)
    pairs = [record_from_json(line) for line in lines]
    return [p[0] for p in pairs], [p[1] for p in pairs]


class _Interrupts:
    """SIGTERM handled like Ctrl-C (a ``KeyboardInterrupt``), and both held
    back while a step is being written (:meth:`deferred`).  Installed only in
    the main thread (signal handlers cannot be set elsewhere)."""

    def __init__(self):
        self.critical, self.pending, self.saved = False, None, {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.saved[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, handler in self.saved.items():
            signal.signal(sig, handler)

    def _handler(self, signum, frame):
        if self.critical:
            self.pending = signum
            return
        raise KeyboardInterrupt(signal.Signals(signum).name)

    @contextlib.contextmanager
    def deferred(self):
        self.critical = True
        try:
            yield
        finally:
            self.critical = False
        if self.pending is not None:
            signum, self.pending = self.pending, None
            raise KeyboardInterrupt(signal.Signals(signum).name)


def _linear_solver(sim):
    """The scene's solver; the distributed ones get the dof locations to
    partition the particles among the MPI ranks, a partitioned problem the
    solver of its ranks' shares."""
    name = sim.scene["steps"]["solver"]
    if sim.partition is not None:
        return DistributedLU(sim.partition, sim.problem.reduction)
    if name in DISTRIBUTED:
        return make_solver(name, points=sim.basis.doflocs)
    return make_solver(name, reuse_factorization=sim.scene["steps"]["reuse_factorization"])


@contextlib.contextmanager
def blas_threads(count=1):
    """Limit the BLAS libraries to ``count`` threads for the block.

    A run solves many small dense systems (the moment matrices, Eq. 2.33);
    threads that spin on them cost CPU time and gain none (``skfem-rkpm run
    ring`` on 2 shared cores, load 5-7: 28.5 s CPU with two threads,
    OpenBLAS's default there, 8.4 s with one; medians of 3).
    The loaded libraries are limited with threadpoolctl; a library loaded
    inside the block (the MKL of PARDISO, cvxopt's OpenBLAS) reads
    ``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS``, set for the block.
    """
    from threadpoolctl import threadpool_limits

    if int(count) < 1:
        raise ValueError(f"--threads {count}: give a number of threads >= 1")
    saved = {name: os.environ.get(name) for name in BLAS_ENV}
    os.environ.update({name: str(int(count)) for name in BLAS_ENV})
    try:
        with threadpool_limits(limits=int(count), user_api="blas"):
            yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
