"""How far a run got and why it stopped.

A run that does not complete says, on the console and in ``status.txt``:

- how far it got: the load factor of its last converged step and, for a
  press, the height reduction reached;
- what failed: the quadrature point or particle whose ``det F`` went
  non-positive (where it started and where it is now), a Newton step that
  did not converge, or contact multipliers that did not settle;
- the folds of the last converged state: the drawn cells with a corner at
  ``det F <= 0`` and whether the deformation map itself folds there
  (:func:`~skfem_rkpm.runs.fold_report.last_state`);
- which option would go further, for that cause and this discretization
  (for a Newton step that did not converge: more iterations a step, with
  the ``steps.max_iterations`` the run allowed, more load steps, cut-backs).

An explicit run (:func:`explicit_stop_report`) says the time it reached
and the explicit step that failed instead of load factors and Newton.
"""

import numpy as np

from ..mechanics.problem import InvertedElementError, NonFiniteError
from .fold_report import last_state

__all__ = ["height_reduction", "stop_report", "explicit_stop_report"]


def _moving_tools(scene):
    """``{name: motion}`` of the tools with a prescribed motion."""
    return {name.split(".", 1)[1]: np.asarray(section["motion"], float)
            for name, section in scene.items()
            if name.startswith("tools.") and section["motion"] and np.any(section["motion"])}


def height_reduction(sim, t):
    """Height reduction in percent at load factors ``t``: the travel of the
    moving tools along the first one's motion over the part's initial height
    in that direction; None for a scene without a moving tool."""
    moving = _moving_tools(sim.scene)
    if not moving:
        return None
    first = next(iter(moving.values()))
    direction = first / np.linalg.norm(first)
    rereferenced = getattr(sim, "rereferenced", None)  # the mesh of the initial state
    mesh = sim.mesh if rereferenced is None else rereferenced.origin_mesh
    height = np.ptp(direction @ mesh.p)
    travel = sum(abs(float(motion @ direction)) for motion in moving.values())
    if travel >= height:  # the tools pass through the part's height: a punch, not a press
        return None
    return 100.0 * np.asarray(t, float) * travel / height


def _reached(sim, result):
    """``reached t = … (…% height reduction), step i of n``."""
    t = result.history[-1].t if result.history else 0.0
    count = sim.scene["steps"]["count"]
    text = f"reached t = {t:.4g} of 1"
    reduction = height_reduction(sim, t)
    if reduction is not None:
        text += f" ({float(reduction):.1f} % height reduction)"
    return text + f" in {len(result.history)} converged steps (the scene has {count})"


def _position_now(sim, d, point):
    """Current position of a flat quadrature point (or particle) index."""
    problem = sim.problem
    X = np.asarray(problem.basis.global_coordinates())
    X = X.reshape(len(X), -1)
    u = np.asarray(problem.basis.interpolate(d)).reshape(len(X), -1)
    return X[:, point] + u[:, point]


def inverted_cause(sim, error, d, state="in the last converged state"):
    """``det F <= 0: <error>`` and where its first point is in the state
    ``d`` (``state`` names that state), for a run stopped by an
    :class:`~skfem_rkpm.mechanics.problem.InvertedElementError`."""
    points = np.atleast_1d(getattr(error, "points", []))
    where = ""
    if points.size and d is not None and not getattr(sim.problem, "partitioned", False):
        x = _position_now(sim, d, int(points[0]))
        where = f"; that point is now at x = ({', '.join(f'{v:.4g}' for v in x)}) {state}"
    return f"det F <= 0: {error}{where}"


def _integration(sim):
    return "fem" if sim.method == "fem" else sim.scene["discretization"]["integration"]


def _cause(sim, result):
    """(what failed, what would go further) for the last error of a run."""
    error = getattr(result, "error", None)
    scheme = _integration(sim)
    more_steps = (f"more load steps (--set steps.count={2 * sim.scene['steps']['count']}) "
                  f"or more cut-backs (--set steps.max_cutbacks="
                  f"{sim.scene['steps']['max_cutbacks'] + 4})")
    if isinstance(error, InvertedElementError):
        failed = inverted_cause(sim, error, result.d)
        if scheme == "fem":
            return failed, ("the elements fold: try --method rkpm (particles with smooth "
                            "functions over several cells) or " + more_steps)
        if scheme in ("scni", "dni"):
            return failed, ("a particle's smoothing cell inverts: try a larger support "
                            "(--set discretization.dilation=3) or " + more_steps)
        return failed, ("the background cells that carry the quadrature fold: try "
                        "--set discretization.integration=scni (nodal integration, no "
                        "background cells), " + _rereferencing(sim) + more_steps)
    if isinstance(error, NonFiniteError):
        return f"a non-finite value: {error}", "check the scene's values; then " + more_steps
    text = str(error) if error is not None else result.message
    if "augmented Lagrangian" in text:
        return (f"the contact multipliers did not settle: {text}",
                "try a larger penalty (--set tools.NAME.penalty_factor=100) or "
                "--set tools.NAME.enforcement=penalty, or " + more_steps)
    if scheme != "fem":
        more_steps = _rereferencing(sim) + more_steps
    return f"Newton did not converge: {text}", _more_iterations(sim) + more_steps


def _more_iterations(sim):
    """More Newton iterations a step, with the number this run allowed."""
    used = sim.scene["steps"]["max_iterations"]
    return (f"more Newton iterations a step (--set steps.max_iterations={2 * used}; "
            f"this run allowed {used}), ")


def _rereferencing(sim):
    """The re-referencing option for an RKPM run without it; for one whose
    rebuild was refused, what would let it rebuild."""
    if sim.method == "fem":
        return ""
    disc = sim.scene["discretization"]
    if disc.get("rereference") is None:
        return ("re-referencing (--set discretization.rereference=0.5: rebuild the RK "
                "functions on the current configuration, docs/large_deformation.md) or ")
    chain = getattr(sim, "rereferenced", None)
    if chain is None or chain.refused is None:
        return ""
    spacing = ("supports re-dilated with the current spacing (--set "
               "discretization.rereference_supports=spacing), "
               if (disc.get("rereference_supports") or "keep") == "keep" else "")
    return (f"a rebuild that is not refused: {spacing}a larger threshold (--set "
            f"discretization.rereference={min(0.9, disc['rereference'] + 0.2):.2g}: "
            f"rebuild before the cells distort as far), or ")


def stop_report(sim, result):
    """The lines a run that stopped writes to the console and ``status.txt``."""
    failed, advice = _cause(sim, result)
    lines = [f"stopped: {_reached(sim, result)}", f"cause: {failed}"]
    if result.d is not None and not getattr(sim.problem, "partitioned", False):
        lines.append(f"last converged state: {last_state(sim, result.d)}")
    return "\n".join([*lines, f"to go further: {advice}"])


def explicit_stop_report(sim, result):
    """The stop report of an explicit run (:class:`~skfem_rkpm.runs.explicit_run.ExplicitResult`):
    the time and steps reached, the failed step's cause (the point whose
    ``det F`` went non-positive, where it started and where it is at the
    last finished step) and what would go further."""
    error = result.error
    reached = (f"reached t = {result.time:.4g} s of {result.duration:.4g} s in "
               f"{result.steps} explicit steps")
    if isinstance(error, InvertedElementError):
        cause = inverted_cause(sim, error, result.d, "after the last finished step")
        advice = ("the cells fold faster than one step resolves: a smaller step "
                  "(--set dynamics.safety=0.5), a finer mesh, or "
                  + ("--method rkpm" if sim.method == "fem" else
                     "--set discretization.integration=scni (no background cells)"))
    else:
        cause = f"a non-finite value: {error}"
        advice = ("the step is above the stable one or a value is out of range: a smaller "
                  "step (--set dynamics.safety=0.5, or remove dynamics.time_step) and "
                  "check the scene's values")
    return "\n".join([f"stopped: {reached}", f"cause: {cause}", f"to go further: {advice}"])
