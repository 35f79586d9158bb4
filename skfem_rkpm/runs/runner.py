"""Build a simulation from a scene and run it with results on disk.

:func:`~skfem_rkpm.runs.build.build` turns a scene into library objects;
:func:`run` drives them with :func:`~skfem_rkpm.solvers.newton.newton_steps`
and writes, after every converged step, ``history.csv``, ``fields.xdmf``
and a checkpoint, so an interrupted run keeps everything it finished and
``resume=True`` continues from the last step.  Under ``mpiexec`` every rank
runs the same simulation and only rank 0 writes.
"""

import sys
import time
from pathlib import Path

import numpy as np

from ..solvers.linear import make_solver
from ..solvers.newton import newton_steps
from ..solvers.petsc import is_root
from .build import Simulation, build
from .io import FieldWriter, write_history

__all__ = ["Simulation", "build", "run", "scene_step", "Progress"]

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


class Progress:
    """Scene step, load factor, Newton iterations, elapsed time and ETA: one
    updating line on a terminal, a new line every 10 % of the load otherwise
    (log files, pipes).  ``count``: the scene's number of steps; the step
    shown is the scene's (``step 7/100``), also when a step is solved in
    sub-steps; without ``count``, the solver's step counter."""

    def __init__(self, stream=sys.stderr, enabled=True, count=None):
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


def run(sim, out=None, progress=True, resume=False, log=None):
    """Run a simulation; with ``out`` write results there step by step.

    Returns the :class:`~skfem_rkpm.solvers.newton.Result` (history, solutions,
    completed flag and message).
    """
    steps = sim.scene["steps"]
    output = sim.scene["output"]
    out = Path(out) if out is not None else None
    probes = _point_probes(sim.basis, sim.points)
    d0, start, history_rows, past = None, 0.0, [], []
    if out is not None:
        checkpoint = out / "checkpoint.pkl"
        if resume:  # every MPI rank reads the checkpoint
            if not checkpoint.exists():
                raise FileNotFoundError(f"{checkpoint}: nothing to resume")
            d0, start, past, history_rows = _load_checkpoint(sim, checkpoint)
    if not is_root():  # under mpiexec only rank 0 writes
        out = None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    fields = None
    if out is not None and output["fields"]:
        name = "fields.xdmf" if start == 0 else f"fields-from-t{start:.4f}.xdmf"
        fields = FieldWriter(out / name, sim.problem).__enter__()
    bar = Progress(enabled=progress, count=steps["count"])
    history = list(past)

    def on_step(record, d, evaluation):
        history.append(record)
        gauges = _gauges(sim, probes, d)
        for tool in sim.tools:
            gauges.update(tool.gauges(record.t))
        history_rows.append(gauges)
        if out is not None:
            write_history(out / "history.csv", history, history_rows)
            if fields is not None and record.step % output["every"] == 0:
                fields.write(record.t, d, evaluation)
            _save_checkpoint(sim, out / "checkpoint.pkl", d, record.t, history,
                             history_rows)
        bar(record)

    try:
        result = newton_steps(sim.problem, sim.prescribed, load=sim.load,
                              steps=steps["count"], tol=steps["tolerance"],
                              max_iterations=steps["max_iterations"],
                              max_cutbacks=steps["max_cutbacks"], log=log, d0=d0,
                              contributions=sim.contributions, start=start, on_step=on_step,
                              linear_solver=_linear_solver(sim))
    finally:
        bar.close()
        if fields is not None:
            fields.__exit__(None, None, None)
    result.history = history
    result.gauges = history_rows
    if out is not None:
        (out / "status.txt").write_text(result.message + "\n")
    return result


def _linear_solver(sim):
    """The scene's solver; the distributed ones get the dof locations to
    partition the particles among the MPI ranks."""
    name = sim.scene["steps"]["solver"]
    if name in DISTRIBUTED:
        return make_solver(name, points=sim.basis.doflocs)
    return name


def _save_checkpoint(sim, path, d, t, history, rows):
    import pickle

    state = sim.problem.state
    tools = [tool.get_state() for tool in sim.tools]
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as handle:
        pickle.dump(dict(d=d, t=t, Cp_inv=state.Cp_inv, alpha=state.alpha, tools=tools,
                         history=history, rows=rows), handle)
    tmp.replace(path)


def _load_checkpoint(sim, path):
    import pickle

    from ..mechanics.materials import MaterialState

    with open(path, "rb") as handle:
        data = pickle.load(handle)
    if data["d"].shape != (sim.problem.N,):
        raise ValueError(f"{path} belongs to a different discretization "
                         f"({data['d'].shape[0]} dofs, this run has {sim.problem.N})")
    sim.problem.state = MaterialState(data["Cp_inv"], data["alpha"])
    for tool, state in zip(sim.tools, data["tools"]):
        tool.set_state(state)
    return data["d"], data["t"], data["history"], data["rows"]
