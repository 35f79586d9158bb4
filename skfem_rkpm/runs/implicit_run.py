"""A scene with ``dynamics.scheme = "implicit"``, run with results on disk.

:func:`implicit_scheme` turns a built scene (:class:`~skfem_rkpm.runs.build.Simulation`)
into a :class:`~skfem_rkpm.solvers.time_integration.Newmark` increment
(Eq. 3.38 with the lumped mass of ``material.density``: the trapezoidal
rule for ``integrator = "newmark"``, HHT-α with ``alpha`` for ``"hht"``),
and :func:`run_implicit` drives it with the Newton loop of static runs
(:func:`~skfem_rkpm.solvers.newton.newton_steps`): the same contact,
F-bar, prescribed conditions, tolerance, iterations and step control
(``[steps]``; a step that does not converge is halved, up to
``steps.max_cutbacks`` times, and grows back after easy steps).  The load
factor is ``t = time / duration``: tools reach their motion and the load
its value at the end.  ``duration`` is split into equal steps no longer
than ``dynamics.time_step``.

At ``t = 0``, at every output time (``dynamics.output_interval``, the
first step at or after it) and at the end, a row of ``history.csv`` is
written as explicit runs write it (time, step, step size, Newton
iterations, the energies of :class:`~skfem_rkpm.mechanics.energy.EnergyAccount`,
the tool forces and the followed points), flushed as it is written, with
the fields.  ``status.txt`` says "running" until the run ends, then how
it ended and, for a run that stopped, why (:func:`implicit_stop_report`).
Implicit runs write no checkpoint and do not resume.
"""

import os
import time as clock
from contextlib import ExitStack
from types import SimpleNamespace

import numpy as np

from ..approximation.constraints import ConstraintSet
from ..mechanics.mass import lumped_mass
from ..mechanics.problem import InvertedElementError, NonFiniteError
from ..solvers.linear import make_solver
from ..solvers.newton import newton_steps
from ..solvers.time_integration import Newmark
from .explicit_run import (ExplicitResult, _Progress, console_finish, dynamic_outputs,
                           dynamic_times, initial_velocity, interrupted_text,
                           time_text)
from .folder import status_on_failure
from .runner import _gauges, _Interrupts, _point_probes, final_state_message
from .scene_dynamics import dynamics_of
from .stops import inverted_cause

__all__ = ["implicit_scheme", "implicit_steps", "run_implicit", "implicit_stop_report",
           "summary", "console_run"]

#: HHT-α parameter when a scene gives integrator = "hht" without alpha
DEFAULT_ALPHA = -0.1


def implicit_alpha(scene):
    """α of the scene's integrator: 0 for Newmark's trapezoidal rule."""
    dynamics = dynamics_of(scene)
    if (dynamics["integrator"] or "newmark") == "newmark":
        return 0.0
    return DEFAULT_ALPHA if dynamics["alpha"] is None else float(dynamics["alpha"])


def implicit_steps(scene):
    """The load factors of the time steps: ``ceil(duration / time_step)``
    equal steps (each at most ``time_step``)."""
    dynamics = dynamics_of(scene)
    count = int(np.ceil(dynamics["duration"] / dynamics["time_step"] * (1 - 1e-12)))
    return max(count, 1)


def implicit_scheme(sim):
    """The :class:`Newmark` increment of an implicit scene, at rest at
    ``d = 0`` with ``initial.velocity``; its initial acceleration solves
    ``M a0 = f_ext − f_int`` under the scene's prescribed conditions."""
    if sim.partition is not None:
        raise ValueError("implicit dynamics runs whole on one process (no partitioned "
                         "problem): run without mpiexec")
    if sim.scene["discretization"].get("rereference") is not None:
        raise ValueError("implicit dynamics keeps the RK functions of the initial "
                         "configuration: remove discretization.rereference")
    dynamics = dynamics_of(sim.scene)
    groups = [p.constraint(sim.basis) for p in sim.prescribed]
    constraints = [ConstraintSet(groups, sim.basis.N)] if groups else []
    return Newmark(sim.problem, lumped_mass(sim.problem.assembler,
                                            sim.scene["material"]["density"]),
                   dynamics["duration"], v0=initial_velocity(sim),
                   alpha=implicit_alpha(sim.scene), contributions=sim.contributions,
                   load=sim.load, constraints=constraints)


def _row(sim, probes, state, step, dt, iterations, reactions, d, first, tools):
    """One row of ``history.csv``: the columns of an explicit run's, with
    the Newton iterations and the elastic and plastic parts of the internal
    work; ``tools``: the tools' gauges."""
    balance = state.balance
    row = {"time": state.time, "step": step, "dt": dt, "newton iterations": iterations,
           "kinetic": state.kinetic, "internal": state.internal, "elastic": state.elastic,
           "plastic": state.plastic, "contact": state.contact,
           "external work": state.external, "balance": balance,
           "balance error": balance - (balance if first is None else first)}
    dim = sim.mesh.dim()
    for name, force in reactions.items():
        for c, value in enumerate(np.atleast_1d(force)[:dim]):
            row[f"reaction {name} {'xyz'[c]}"] = float(value)
    row.update(tools)
    row.update(_gauges(sim, probes, d))
    return row


def run_implicit(sim, out=None, progress=True, resume=False, overwrite=False, log=None):
    """Run an implicit scene; with ``out`` write its results there.

    The folder is taken as :func:`skfem_rkpm.runs.runner.run` takes it;
    ``resume`` is refused (an implicit run writes no checkpoint).  Returns
    an :class:`~skfem_rkpm.runs.explicit_run.ExplicitResult` (``steps``:
    the time steps done, ``records``: the energy states of the rows); a
    step that fails after its cut-backs ends the run with
    ``completed=False`` and a stop report, in ``status.txt`` too.

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C or SIGTERM, after the row being written is complete.
    """
    dynamics, duration, interval = dynamic_times(sim, resume, "implicit")
    steps = sim.scene["steps"]
    count = implicit_steps(sim.scene)
    solver = make_solver(steps["solver"], reuse_factorization=steps["reuse_factorization"])
    scheme = implicit_scheme(sim)
    probes = _point_probes(sim.basis, sim.points)
    records, rows = [], []
    result = ExplicitResult(np.zeros(sim.basis.N), records, rows, False, duration=duration)
    with ExitStack() as stack:
        folder, history, fields = dynamic_outputs(stack, sim, out, overwrite)
        interrupts = stack.enter_context(_Interrupts())
        bar = _Progress(duration, progress)
        every = sim.scene["output"]["every"]
        state = dict(next=0.0, t=0.0, iterations=0, keys=None)

        initial_tools = {}  # the gauges at rest, before a step moves the tools
        for tool in sim.tools:
            initial_tools.update(tool.gauges(0.0))

        def emit(energy, step, dt, iterations, reactions, d, evaluation, tools=None):
            first = records[0].balance if records else None
            if tools is None:
                tools = {}
                for tool in sim.tools:
                    tools.update(tool.gauges(energy.time / duration))
            row = _row(sim, probes, energy, step, dt, iterations, reactions, d, first, tools)
            records.append(energy)
            rows.append(row)
            result.d, result.steps, result.time = d, step, energy.time
            if history is not None:
                with interrupts.deferred():  # a row and its fields whole or not at all
                    history.append(row)
                    if fields is not None and (len(records) - 1) % every == 0:
                        fields.write(energy.time, d, evaluation, step=step)
            bar(SimpleNamespace(time=energy.time, step=step, dt=dt))
            state["next"] = (np.floor(energy.time / interval * (1 + 1e-9)) + 1) * interval

        def on_step(record, d, evaluation):
            energy, dt = scheme.records[-1], (record.t - state["t"]) * duration
            state["t"], state["iterations"] = record.t, state["iterations"] + record.iterations
            result.d, result.steps, result.time = d, record.step, energy.time
            if not records:  # the initial state, with the columns of the first step
                emit(scheme.records[0], 0, 0.0, 0,
                     {k: np.zeros_like(np.atleast_1d(v), dtype=float)
                      for k, v in record.reactions.items()}, np.zeros_like(d), None,
                     initial_tools)
            if energy.time >= state["next"] * (1 - 1e-9) or record.t >= 1 - 1e-12:
                emit(energy, record.step, dt, state["iterations"], record.reactions, d,
                     evaluation)
                state["iterations"] = 0

        start = clock.process_time()
        with status_on_failure(folder, lambda: interrupted_text(result, "implicit")):
            try:
                outcome = newton_steps(sim.problem, sim.prescribed, load=sim.load, steps=count,
                                       tol=steps["tolerance"],
                                       max_iterations=steps["max_iterations"],
                                       max_cutbacks=steps["max_cutbacks"], log=log,
                                       contributions=sim.contributions, on_step=on_step,
                                       linear_solver=solver, increment=scheme)
            finally:
                bar.close()
                solver.reset()
                result.cpu_seconds = clock.process_time() - start
        result.completed = outcome.completed
        if outcome.completed:
            result.message = final_state_message(sim, outcome.d, "a smaller dynamics.time_step")
        else:
            result.d, result.error = outcome.d, outcome.error
            result.message = "stopped"
            result.report = implicit_stop_report(sim, result, outcome.message)
        if folder is not None:
            folder.status(result.report or result.message)
    return result


def implicit_stop_report(sim, result, message=""):
    """The stop report of an implicit run: the time and time steps reached,
    the cause (the point whose ``det F`` went non-positive, where it is in
    the last converged state; or Newton's message) and what would go further."""
    dynamics, steps = dynamics_of(sim.scene), sim.scene["steps"]
    error = result.error
    reached = (f"reached t = {result.time:.4g} s of {result.duration:.4g} s in "
               f"{result.steps} converged time steps (dynamics.time_step = "
               f"{dynamics['time_step']:.4g} s)")
    if isinstance(error, InvertedElementError):
        cause = inverted_cause(sim, error, result.d)
    elif isinstance(error, NonFiniteError):
        cause = f"a non-finite value: {error}"
    else:
        cause = f"Newton did not converge: {message or error}"
    advice = (f"a shorter step (--set dynamics.time_step={dynamics['time_step'] / 2:.3g}), "
              f"more cut-backs (--set steps.max_cutbacks={steps['max_cutbacks'] + 4}), "
              f"more iterations (--set steps.max_iterations={2 * steps['max_iterations']})")
    if implicit_alpha(sim.scene) == 0.0:
        advice += (", or damping of the high modes (--set dynamics.integrator=\"hht\", "
                   "alpha -0.1)")
    return "\n".join([f"stopped: {reached}", f"cause: {cause}", f"to go further: {advice}"])


def summary(result):
    """The console line of a finished run."""
    return (f"{result.message}: t = {time_text(result.time)} of "
            f"{time_text(result.duration)} in {result.steps} implicit time steps, "
            f"{result.cpu_seconds:.1f} s CPU")


def console_run(sim, out, quiet=False, resume=False, overwrite=False):
    """``skfem-rkpm run`` of an implicit scene: the head line, the run, the
    figures, the summary line (and the stop report on the standard error)."""
    scene = sim.scene
    dynamics = dynamics_of(scene)
    title = scene["model"]["title"] or os.path.basename(str(scene.get("_source")))
    alpha = implicit_alpha(scene)
    method = "trapezoidal rule" if alpha == 0.0 else f"HHT-α (α = {alpha:g})"
    print(f"{title}: {sim.method}, {sim.basis.N} dofs, implicit ({method}) over "
          f"{time_text(dynamics['duration'])} in {implicit_steps(scene)} steps -> {out}")
    result = run_implicit(sim, out, progress=not quiet, resume=resume, overwrite=overwrite)
    return console_finish(sim, out, result, summary(result))
