"""Runs killed at random moments, then resumed, end as an uninterrupted run.

``skfem-rkpm run`` on the small ring (6 load steps, 11 converged steps with
cut-backs) in a subprocess is killed with SIGKILL and SIGTERM alternately
after a random delay (seeded), then started again with ``--resume`` (or
afresh when it died before its first checkpoint), until it completes.  The
history (every column but the wall time) and every field file must equal
those of an uninterrupted run bit for bit: the checkpoint holds the exact
state, and a step written after the last checkpoint is cut off on resume.
The default suite kills 2 times; ``-m slow`` kills 24 times.
"""

import csv
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

SETTINGS = ["steps.count=6", "geometry.divisions=[6,4]", "discretization.support=12",
            "output.figures=false"]
ROOT = Path(__file__).resolve().parent.parent


def command(out, resume=False):
    return [sys.executable, "-m", "skfem_rkpm.runs.cli", "run", "ring",
            *(f"--set={s}" for s in SETTINGS), "--out", str(out), "--quiet",
            *(["--resume"] if resume else [])]


def environment():
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return env


def history(out):
    with open(out / "history.csv", newline="") as handle:
        return [{k: v for k, v in row.items() if k != "seconds"}
                for row in csv.DictReader(handle)]


def fields(out):
    found = {}
    for file in sorted((out / "fields").glob("step-*.h5")):
        with h5py.File(file, "r") as f:
            found[file.name] = {k: f[k][()] for k in f} | {"t": f.attrs["t"]}
    return found


def kill_and_resume(tmp_path, kills, seed):
    env = environment()
    reference = tmp_path / "reference"
    start = time.perf_counter()
    subprocess.run(command(reference), env=env, check=True, capture_output=True)
    duration = time.perf_counter() - start
    rng = random.Random(seed)
    out = tmp_path / "run"
    sent = {signal.SIGKILL: 0, signal.SIGTERM: 0}
    finished, during_steps = False, 0
    for _ in range(4 * kills + 10):
        resume = (out / "checkpoint.npz").exists() and not finished
        proc = subprocess.Popen(command(out, resume), env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        done = sum(sent.values())
        if done < kills:
            try:  # most of a run is the start-up (imports, basis): aim at the steps too
                proc.wait(timeout=rng.uniform(0.2, duration))
            except subprocess.TimeoutExpired:
                sig = signal.SIGKILL if done % 2 == 0 else signal.SIGTERM
                status = out / "status.txt"
                during_steps += status.exists() and status.read_text().startswith("running")
                proc.send_signal(sig)
                code = proc.wait(timeout=120)
                error = proc.stderr.read()
                if code == 0:  # it had just finished: the signal came too late
                    assert (out / "status.txt").read_text().strip() == "completed"
                    finished = True
                    continue
                sent[sig] += 1
                finished = False
                # SIGTERM during the steps: the run stops cleanly and says how to go on
                assert code in (-sig, 130), (code, error)
                if code == 130:
                    assert "--resume" in error and "Traceback" not in error, error
                continue
        code = proc.wait(timeout=600)
        error = proc.stderr.read()
        assert code == 0, error
        if sum(sent.values()) >= kills:
            break
        # finished before its kill: start afresh (the new run clears the folder)
        assert (out / "status.txt").read_text().strip() == "completed"
        finished = True
    assert sum(sent.values()) >= kills
    assert (out / "status.txt").read_text().strip() == "completed"
    assert history(out) == history(reference)
    mine, theirs = fields(out), fields(reference)
    assert list(mine) == list(theirs)
    for step in theirs:
        for key in theirs[step]:
            np.testing.assert_array_equal(mine[step][key], theirs[step][key])
    assert (out / "fields.xdmf").read_text().count("<Time ") == len(theirs)
    assert len((out / "history.jsonl").read_text().splitlines()) == len(history(out))
    return sent, during_steps


def test_killed_runs_resume_to_the_uninterrupted_result(tmp_path):
    sent, _ = kill_and_resume(tmp_path, kills=2, seed=1)
    assert sent[signal.SIGKILL] == 1 and sent[signal.SIGTERM] == 1


@pytest.mark.slow
def test_twenty_four_kills(tmp_path):
    sent, during_steps = kill_and_resume(tmp_path, kills=24, seed=2)
    assert sent[signal.SIGKILL] == 12 and sent[signal.SIGTERM] == 12
    # the others hit the start-up (imports, building the basis) or the resume
    assert during_steps >= 8, during_steps
    print(f"{during_steps} of 24 kills during the steps")
