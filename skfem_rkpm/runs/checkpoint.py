"""Checkpoints of a run: arrays and JSON metadata in one ``.npz`` file.

A checkpoint holds plain arrays only (it is read with
``allow_pickle=False``: a file from someone else cannot run code): the
coefficients ``d``, the material state (``Cp_inv``, ``alpha``), each
contact's state, the step predictor of
:class:`~skfem_rkpm.solvers.newton.StepperState`, and a JSON text with the
load factor, the step count, the step size control, how far ``history.csv`` and ``history.jsonl``
had grown, and the run's identity (:func:`run_identity`: the resolved
scene, the method, the number of dofs, a hash of them).  Resuming refuses
a checkpoint of another scene or method and names what differs.
"""

import dataclasses
import hashlib
import json
import zipfile
from pathlib import Path

import numpy as np

from ..mechanics.materials import MaterialState
from ..solvers.newton import StepperState
from ..solvers.step_control import StepControl
from .folder import atomic_path

__all__ = ["CheckpointError", "run_identity", "save_checkpoint", "load_checkpoint",
           "NAME", "FORMAT"]

NAME = "checkpoint.npz"
FORMAT = 1
#: scene keys that may change between a run and its resumption: they change
#: neither the model nor the steps (the linear solver only the round-off)
MAY_CHANGE = ("steps.solver", "steps.reuse_factorization", "output.figures")


class CheckpointError(ValueError):
    """A checkpoint that cannot be resumed (missing, unreadable, another run)."""


def _flatten(scene):
    flat = {}
    for section, values in scene.items():
        if section.startswith("_"):
            continue
        for key, value in values.items():
            if f"{section}.{key}" not in MAY_CHANGE:
                flat[f"{section}.{key}"] = value
    return flat


def run_identity(sim):
    """What a resumed run must share with its checkpoint: the resolved scene
    (with the SHA-256 of a gmsh geometry file), the method, the number of
    dofs, and a SHA-256 hash of them all."""
    scene = _flatten(sim.scene)
    geometry = sim.scene.get("geometry", {})
    if geometry.get("kind") == "gmsh":
        path = Path(geometry["file"])
        if sim.scene.get("_base") and not path.is_absolute():
            path = Path(sim.scene["_base"]) / path
        scene["geometry.file contents (sha256)"] = hashlib.sha256(
            path.read_bytes()).hexdigest()
    identity = {"scene": json.loads(json.dumps(scene, default=str)), "method": sim.method,
                "dofs": int(sim.problem.N)}
    text = json.dumps(identity, sort_keys=True)
    identity["hash"] = hashlib.sha256(text.encode()).hexdigest()
    return identity


def _differences(old, new):
    found = []
    if old["method"] != new["method"]:
        found.append(f"method {old['method']} there, {new['method']} now")
    for key in sorted(set(old["scene"]) | set(new["scene"])):
        a, b = old["scene"].get(key, "(unset)"), new["scene"].get(key, "(unset)")
        if a != b:
            found.append(f"{key} = {json.dumps(a)} there, {json.dumps(b)} now")
    if not found and old["dofs"] != new["dofs"]:
        found.append(f"{old['dofs']} dofs there, {new['dofs']} now")
    return found


def save_checkpoint(folder, sim, d, stepper, identity, state=None, **meta):
    """Write ``folder/checkpoint.npz`` atomically; ``meta`` (JSON values) is
    stored with the step state and the identity.  ``state``: the material
    state of the whole domain (default the problem's; a partitioned problem
    passes its ``gathered_state()``)."""
    state = sim.problem.state if state is None else state
    arrays = {"d": np.asarray(d, float), "Cp_inv": state.Cp_inv, "alpha": state.alpha}
    if stepper.rate is not None:
        arrays["rate"] = np.asarray(stepper.rate, float)
    if sim.problem.stabilization is not None:  # an incremental SCNI stabilization
        for name, value in sim.problem.stabilization.get_state().items():
            arrays[f"stabilization.{name}"] = np.asarray(value)
    for k, tool in enumerate(sim.tools):
        for f in dataclasses.fields(tool.get_state()):
            arrays[f"tool{k}.{f.name}"] = np.asarray(getattr(tool.get_state(), f.name))
    control = (None if stepper.control is None
               else {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in dataclasses.asdict(stepper.control).items()})
    info = dict(meta, format=FORMAT, t=float(stepper.t), step=int(stepper.step),
                control=control, identity=identity)
    arrays["meta"] = np.frombuffer(json.dumps(info).encode(), np.uint8)
    with atomic_path(Path(folder) / NAME) as tmp:
        with open(tmp, "xb") as handle:
            np.savez(handle, **arrays)


def _read(path):
    with open(path, "rb") as handle:
        head = handle.read(4)
    if head != b"PK\x03\x04":  # every .npz is a zip archive
        what = ("empty" if not head else "a pickle, which is never loaded (it could run "
                "code)" if head[:1] == b"\x80" else "not an .npz archive")
        raise CheckpointError(f"{path} cannot be resumed: it is {what}; start the run "
                              f"afresh (without --resume)")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
        info = json.loads(arrays.pop("meta").tobytes().decode())
        return arrays, info
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile,
            UnicodeDecodeError) as err:
        reason = str(err) or type(err).__name__
        if "pickle" in reason:
            reason = "it holds object arrays, which are never loaded (they could run code)"
        raise CheckpointError(f"{path} cannot be resumed: {reason}; start the run "
                              f"afresh (without --resume)") from None


def load_checkpoint(folder, sim, identity):
    """Restore the material and contact states of ``sim`` from
    ``folder/checkpoint.npz``; return ``(d, stepper, meta)``.

    Raises
    ------
    CheckpointError
        No checkpoint, an unreadable one, or one of another scene or method
        (the message names what differs).
    """
    folder = Path(folder)
    path = folder / NAME
    if not path.is_file():
        old = (" (it holds checkpoint.pkl of an older version: a pickle, which is "
               "never loaded)" if (folder / "checkpoint.pkl").exists() else "")
        raise CheckpointError(f"--resume: {folder} has no {NAME}, nothing to resume{old}; "
                              f"run without --resume")
    arrays, info = _read(path)
    if info.get("format") != FORMAT or "identity" not in info:
        raise CheckpointError(f"{path}: unknown checkpoint format {info.get('format')!r}; "
                              f"start the run afresh (without --resume)")
    if info["identity"].get("hash") != identity["hash"]:
        what = "; ".join(_differences(info["identity"], identity)) or "the scene hash"
        raise CheckpointError(f"--resume: {path} belongs to another run: {what}. Resume "
                              f"with the same scene, --set and --method, or start afresh "
                              f"in another --out")
    N = sim.problem.N
    nqp = sim.problem.whole_points
    expected = {"d": (N,), "Cp_inv": (nqp, 3, 3), "alpha": (nqp,)}
    if "rate" in arrays:
        expected["rate"] = (N,)
    for name, shape in expected.items():
        if name not in arrays or arrays[name].shape != shape:
            raise CheckpointError(f"{path}: array {name!r} is missing or has the wrong "
                                  f"shape; start the run afresh (without --resume)")
    state = MaterialState(arrays["Cp_inv"].astype(float), arrays["alpha"].astype(float))
    sim.problem.restore_state(state)  # partitioned: this rank's points
    stabilization = sim.problem.stabilization
    if stabilization is not None and stabilization.get_state():
        try:
            stabilization.set_state({name: arrays[f"stabilization.{name}"]
                                     for name in stabilization.get_state()})
        except (KeyError, ValueError) as err:
            raise CheckpointError(f"{path}: the stabilization state does not fit ({err}); "
                                  f"start the run afresh (without --resume)") from None
    for k, tool in enumerate(sim.tools):
        cls = type(tool.get_state())
        try:
            # a field with a default may be missing (a checkpoint written
            # before the field existed: the contact rates start at 0)
            state = cls(**{f.name: arrays[f"tool{k}.{f.name}"]
                           for f in dataclasses.fields(cls)
                           if f"tool{k}.{f.name}" in arrays
                           or f.default is dataclasses.MISSING})
            tool.set_state(state)
        except (KeyError, ValueError) as err:
            raise CheckpointError(f"{path}: the state of tool {k} does not fit ({err}); "
                                  f"start the run afresh (without --resume)") from None
    try:
        control = StepControl(**info["control"]) if info.get("control") else None
    except (TypeError, ValueError) as err:
        raise CheckpointError(f"{path}: the step control does not fit ({err}); start the "
                              f"run afresh (without --resume)") from None
    stepper = StepperState(float(info["t"]), int(info["step"]), arrays.get("rate"), control)
    return arrays["d"].astype(float), stepper, info
