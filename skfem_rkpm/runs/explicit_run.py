"""A scene with ``dynamics.scheme = "explicit"``, run with results on disk.

:func:`explicit_scheme` turns a built scene (:class:`~skfem_rkpm.runs.build.Simulation`)
into a :class:`~skfem_rkpm.solvers.explicit.CentralDifference` scheme: the
lumped mass of ``material.density``, the scene's rigid tools as penalty
contacts (moving with ``t = time / duration``), its fixes and symmetry
planes as kinematic conditions held by projection, its dead pressures and
tractions as the external force, and ``initial.velocity`` as the initial
velocity of every coefficient (the RK functions reproduce constants, so
the coefficients of a uniform field are its value).

:func:`run_explicit` integrates over ``dynamics.duration`` and writes, at
every output time (``dynamics.output_interval``) and at the end, a row of
``history.csv`` (time, step, step size, the energies, the tool forces and
the followed points), flushed as it is written, and the fields
(``fields.xdmf``, one HDF5 file per output).  ``status.txt`` says
"running" until the run ends, then how it ended; a run that fails or is
killed keeps every row and field written before.  Explicit runs write no
checkpoint and do not resume.
"""

import csv
import io
import os
import sys
import time as clock
from contextlib import ExitStack
from dataclasses import dataclass

import numpy as np

from ..approximation.constraints import nodal_constraint
from ..mechanics.problem import InvertedElementError, NonFiniteError
from ..solvers.explicit import CentralDifference
from .folder import RunFolder, open_append, status_on_failure, write_atomic
from .io import FieldWriter
from .runner import _gauges, _Interrupts, _point_probes, final_state_message, scene_text
from .scene_dynamics import dynamics_of, initial_of
from .stops import explicit_stop_report

__all__ = ["ExplicitResult", "explicit_scheme", "initial_velocity", "run_explicit",
           "history_row", "dynamic_outputs", "time_text", "summary", "save_explicit_figures",
           "console_run", "console_finish"]


@dataclass
class ExplicitResult:
    """Outcome of :func:`run_explicit`."""

    d: np.ndarray
    #: the :class:`~skfem_rkpm.solvers.explicit.EnergyRecord` of every output
    records: list
    #: the rows of ``history.csv``, one dict per output
    rows: list
    completed: bool
    message: str = ""
    report: str = ""
    error: BaseException = None
    #: explicit steps done and the time reached
    steps: int = 0
    time: float = 0.0
    duration: float = 0.0
    cpu_seconds: float = 0.0


def dynamic_times(sim, resume, scheme):
    """``(dynamics, duration, output interval)`` of a dynamic scene run by
    ``scheme`` ("explicit" or "implicit"); ``resume`` is refused, as a
    dynamic run writes no checkpoint."""
    if resume:
        raise ValueError(f"--resume: an {scheme} run writes no checkpoint and cannot "
                         f"resume; run it again without --resume")
    dynamics = dynamics_of(sim.scene)
    return dynamics, dynamics["duration"], dynamics["output_interval"] or dynamics["duration"] / 10


def interrupted_text(result, scheme):
    """The status of a dynamic run stopped by Ctrl-C or SIGTERM: how far it
    got, and that it does not resume."""
    return (f"interrupted after t = {time_text(result.time)} (step {result.steps}): the "
            f"rows and fields written so far are kept; an {scheme} run does not resume, "
            f"run it again")


def time_text(seconds):
    """A time in the unit that suits it: ``80 µs``, ``1.5 ms``, ``2 s``."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if abs(seconds) >= scale or unit == "ns" or seconds == 0:
            return f"{seconds / scale:.4g} {unit}"
    raise AssertionError(seconds)


def initial_velocity(sim):
    """The coefficients of the uniform ``initial.velocity`` (zero without it)."""
    v = np.zeros(sim.basis.N)
    velocity = initial_of(sim.scene)["velocity"]
    if velocity is not None:
        for c, index in enumerate(sim.basis.split_indices()):
            v[index] = velocity[c]
    return v


def _constraints(sim):
    """The nodal conditions ``C d = 0`` of the scene's fixes and symmetry
    planes: one per component (the boundaries that fix it joined, so that a
    corner on two of them is held once), one per skew symmetry plane."""
    mesh, by_component, skew = sim.basis.mesh, {}, []
    for p in sim.prescribed:
        if p.method != "nodal" or callable(p.values) or p.values != 0.0:
            raise ValueError(f"explicit dynamics holds zero nodal displacements only, not "
                             f"{p.values!r} ({p.method}) on {p.boundary!r}")
        if isinstance(p.component, (int, np.integer)):
            by_component.setdefault(int(p.component), []).append(p.boundary)
        else:
            skew.append(p)
    out = [nodal_constraint(sim.basis, boundaries[0] if len(boundaries) == 1 else np.unique(
        np.concatenate([mesh.boundaries[b] for b in boundaries])), component)
        for component, boundaries in sorted(by_component.items())]
    return out + [nodal_constraint(sim.basis, p.boundary, p.component) for p in skew]


def explicit_scheme(sim):
    """The :class:`CentralDifference` scheme of an explicit scene."""
    if sim.partition is not None or sim.follower_loads:
        raise ValueError("explicit dynamics runs whole on one process and takes dead "
                         "loads only (no partitioned problem, no follower pressure)")
    for tool in sim.tools:
        if not hasattr(tool, "omega_n"):
            raise ValueError(f"explicit dynamics needs tools with a prescribed motion and "
                             f"penalty contact, not a {type(tool).__name__}")
    dynamics = dynamics_of(sim.scene)
    return CentralDifference(sim.problem, sim.scene["material"]["density"],
                             contacts=sim.tools, safety=dynamics["safety"],
                             estimate_every=dynamics["estimate_every"],
                             constraints=_constraints(sim))


class _HistoryWriter:
    """``history.csv`` of an explicit run: the header and first row written
    atomically, every later row appended and flushed (O(1) a row)."""

    def __init__(self, path):
        self.path, self.columns = path, None

    def append(self, row):
        text = io.StringIO()
        if self.columns is None:
            self.columns = list(row)
            writer = csv.DictWriter(text, fieldnames=self.columns, lineterminator="\n")
            writer.writeheader()
            writer.writerow(row)
            write_atomic(self.path, text.getvalue())
            return
        csv.DictWriter(text, fieldnames=self.columns, lineterminator="\n").writerow(row)
        with open_append(self.path, newline="", encoding="utf-8") as handle:
            handle.write(text.getvalue())
            handle.flush()
            os.fsync(handle.fileno())


def dynamic_outputs(stack, sim, out, overwrite=False):
    """``(folder, history, fields)`` of a dynamic run into ``out`` (Nones
    without it): the :class:`RunFolder` entered on ``stack``, the files of
    an earlier run removed, ``status.txt`` "running", ``scene.toml``, the
    ``history.csv`` writer and the field writer (with ``output.fields``)."""
    if out is None:
        return None, None, None
    folder = stack.enter_context(RunFolder(out, overwrite=overwrite))
    folder.remove_temporaries()
    folder.clear()
    folder.status(f"running (process {os.getpid()})")
    folder.write("scene.toml", scene_text(sim))
    folder.claim("history.csv")
    history = _HistoryWriter(folder.path / "history.csv")
    fields = None
    if sim.scene["output"]["fields"]:
        fields = FieldWriter(folder.path / "fields.xdmf", sim.problem, owner=folder)
    return folder, history, fields


def history_row(sim, probes, record, first):
    """One row of ``history.csv``: time, step, step size, energies, the tool
    forces (``reaction NAME x``, as static runs), tool gauges, followed points."""
    balance = record.balance
    row = {"time": record.time, "step": record.step, "dt": record.dt,
           "kinetic": record.kinetic, "leapfrog kinetic": record.leapfrog_kinetic,
           "internal": record.internal, "contact": record.contact,
           "external work": record.external, "balance": balance,
           "balance error": balance - (balance if first is None else first.balance)}
    dim = sim.mesh.dim()
    for name, force in record.forces.items():
        for c, value in enumerate(np.atleast_1d(force)[:dim]):
            row[f"reaction {name} {'xyz'[c]}"] = float(value)
    duration = dynamics_of(sim.scene)["duration"]
    for tool in sim.tools:
        row.update(tool.gauges(record.time / duration))
    row.update(_gauges(sim, probes, record.d))
    return row


class _Progress:
    """A line per output time (on a terminal: one updating line)."""

    def __init__(self, duration, enabled, stream=None):
        self.duration, self.enabled = duration, enabled
        self.stream = sys.stderr if stream is None else stream
        self.live = bool(getattr(self.stream, "isatty", lambda: False)())
        self.start = clock.perf_counter()

    def __call__(self, record):
        if not self.enabled:
            return
        done = record.time / self.duration
        elapsed = clock.perf_counter() - self.start
        eta = f" eta {elapsed * (1 - done) / done:.1f}s" if done > 0 else ""
        bar = "#" * int(round(30 * done))
        text = (f"[{bar:.<30}] t = {time_text(record.time)} of {time_text(self.duration)}, "
                f"step {record.step}, dt {record.dt:.3g} s, elapsed {elapsed:.1f}s{eta}")
        self.stream.write(f"\r{text} " if self.live else text + "\n")
        self.stream.flush()

    def close(self):
        if self.enabled and self.live:
            self.stream.write("\n")


def run_explicit(sim, out=None, progress=True, resume=False, overwrite=False):
    """Run an explicit scene; with ``out`` write its results there.

    The folder is taken as :func:`skfem_rkpm.runs.runner.run` takes it (a
    :class:`~skfem_rkpm.runs.folder.RunFolder`: only the files its manifest
    lists are removed, a folder of someone else refused).  ``resume`` is
    refused: an explicit run writes no checkpoint.

    Returns an :class:`ExplicitResult`; a step that fails (``det F <= 0``,
    a non-finite force) ends the run with ``completed=False`` and a stop
    report (:func:`~skfem_rkpm.runs.stops.explicit_stop_report`), in
    ``status.txt`` too.

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C or SIGTERM, after the row being written is complete.
    """
    dynamics, duration, interval = dynamic_times(sim, resume, "explicit")
    scheme = explicit_scheme(sim)
    probes = _point_probes(sim.basis, sim.points)
    d0, v0 = np.zeros(sim.basis.N), initial_velocity(sim)
    external = None
    if sim.load is not None:
        external = lambda t: sim.load(t / duration)  # noqa: E731
    records, rows = [], []
    result = ExplicitResult(d0, records, rows, False, duration=duration)
    with ExitStack() as stack:
        folder, history, fields = dynamic_outputs(stack, sim, out, overwrite)
        interrupts = stack.enter_context(_Interrupts())
        bar = _Progress(duration, progress)
        every = sim.scene["output"]["every"]

        def on_output(record):
            row = history_row(sim, probes, record, records[0] if records else None)
            records.append(record)
            rows.append(row)
            result.d, result.steps, result.time = record.d, record.step, record.time
            if history is not None:
                with interrupts.deferred():  # a row and its fields whole or not at all
                    history.append(row)
                    if fields is not None and (len(records) - 1) % every == 0:
                        fields.write(record.time, record.d, step=record.step)
            bar(record)

        start = clock.process_time()
        with status_on_failure(folder, lambda: interrupted_text(result, "explicit")):
            try:
                scheme.run(d0, v0, duration=duration, dt=dynamics["time_step"],
                           output_interval=interval, external=external, on_output=on_output)
            except (InvertedElementError, NonFiniteError) as error:
                result.error = error
                result.steps = getattr(error, "step", result.steps)
                result.time = getattr(error, "time", result.time)
                if getattr(error, "d", None) is not None:
                    result.d = error.d
            finally:
                bar.close()
                result.cpu_seconds = clock.process_time() - start
        if result.error is None:
            result.completed = True
            result.message = final_state_message(
                sim, result.d, "a smaller dynamics.safety (a shorter time step)")
        else:
            result.message = "stopped"
            result.report = explicit_stop_report(sim, result)
        if folder is not None:
            folder.status(result.report or result.message)
    return result


def summary(result):
    """The console line of a finished run."""
    return (f"{result.message}: t = {time_text(result.time)} of "
            f"{time_text(result.duration)} in {result.steps} explicit steps, "
            f"{result.cpu_seconds:.1f} s CPU")


def save_explicit_figures(sim, result, out, folder=None):
    """``deformed.png`` (the last state coloured by ε̄ᵖ; in 3D its surface,
    and ``section.png``), ``energy.png`` (the
    energies against time) and, with tools, ``forces.png`` (their forces
    against time), each written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .folder import atomic_path
    from .plot import force_axis_label, plot_deformed

    title = (f"{sim.scene['model']['title'] or 'run'} ({sim.method.upper()}, "
             f"{dynamics_of(sim.scene)['scheme']})\n"
             f"t = {time_text(result.time)}")
    figures = {}
    if sim.mesh.dim() == 2:
        fig, ax = plt.subplots(figsize=(6.0, 6.5))
        art = plot_deformed(ax, sim.problem, result.d, title, scene=sim.scene)
        fig.colorbar(art, ax=ax, label="equivalent plastic strain")
        figures["deformed.png"] = fig
    else:  # the deformed surface and a section, coloured by ε̄ᵖ
        from .plot3d import figures_3d

        figures.update(figures_3d(sim, result, title))
    t = np.array([r["time"] for r in result.rows]) * 1e6
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for key in ("kinetic", "internal", "contact", "external work", "balance error"):
        ax.plot(t, [r[key] for r in result.rows], "o-", ms=3, label=key)
    ax.set_xlabel("time (µs)")
    ax.set_ylabel(f"energy ({sim.scene['model']['force_unit']} "
                  f"{sim.scene['model']['length_unit']})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    figures["energy.png"] = fig
    keys = [k for k in (result.rows[0] if result.rows else {}) if k.startswith("reaction ")]
    if keys:
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        for key in keys:
            ax.plot(t, [r[key] for r in result.rows], "o-", ms=3, label=key[9:])
        ax.set_xlabel("time (µs)")
        ax.set_ylabel(force_axis_label(sim.scene))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title(title)
        figures["forces.png"] = fig
    for name, fig in figures.items():
        if folder is not None:
            folder.claim(name)
        with atomic_path(out / name) as tmp:
            fig.savefig(tmp, format="png", dpi=120, bbox_inches="tight")
        plt.close(fig)


def console_run(sim, out, quiet=False, resume=False, overwrite=False):
    """``skfem-rkpm run`` of an explicit scene: the head line, the run, the
    figures, the summary line (and the stop report on the standard error)."""
    scene = sim.scene
    title = scene["model"]["title"] or os.path.basename(str(scene.get("_source")))
    print(f"{title}: {sim.method}, {sim.basis.N} dofs, explicit over "
          f"{time_text(dynamics_of(scene)['duration'])} -> {out}")
    result = run_explicit(sim, out, progress=not quiet, resume=resume, overwrite=overwrite)
    return console_finish(sim, out, result, summary(result))


def console_finish(sim, out, result, line):
    """After a dynamic run on the console: its figures (with
    ``output.figures``), the summary ``line`` and the stop report (on the
    standard error)."""
    if sim.scene["output"]["figures"] and result.rows and out is not None:
        with RunFolder(out, mode="add") as folder:
            save_explicit_figures(sim, result, folder.path, folder)
    print(line)
    if result.report:
        print(result.report, file=sys.stderr)
    return result
