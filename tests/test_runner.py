"""Running scenes: results on disk, interruption keeps finished steps, resume."""

import csv

import numpy as np
import pytest

import skfem_rkpm.runs.runner as runner
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.scene import parse_scene
from conftest import interrupted_at_checkpoint

BLOCK = """
[model]
type = "plane_strain"
title = "block under pressure"

[geometry]
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [4, 4]

[material]
E = 200e3
nu = 0.3
yield = 300.0

[boundary.bottom]
fix = ["y"]
method = "weak"

[boundary.left]
fix = ["x"]
method = "weak"

[boundary.top]
pressure = 320.0

[steps]
count = 4

[output]
points = { corner = [1.0, 1.0] }
"""


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_run_writes_history_fields_and_figures(tmp_path, method):
    from skfem_rkpm.runs.plot import save_run_figures

    sim = runner.build(parse_scene(BLOCK), method)
    result = runner.run(sim, tmp_path, progress=False)
    save_run_figures(sim, result, tmp_path)
    assert result.completed
    for name in ("history.csv", "history.jsonl", "fields.xdmf", "fields/mesh.h5",
                 "fields/step-000004.h5", "deformed.png", "forces.png", "status.txt",
                 "checkpoint.npz", "scene.toml"):
        assert (tmp_path / name).exists(), name
    rows = list(csv.DictReader(open(tmp_path / "history.csv")))
    assert len(rows) == 4
    # dead pressure 320 on a unit top edge, reaction of the bottom support
    assert float(rows[-1]["reaction bottom[1]"]) == pytest.approx(320.0, rel=1e-9)
    assert float(rows[-1]["corner y"]) < 1.0


def test_interrupted_run_resumes_to_the_same_answer(tmp_path, monkeypatch):
    reference = runner.run(runner.build(parse_scene(BLOCK)), tmp_path / "ref",
                           progress=False)
    with interrupted_at_checkpoint(monkeypatch), pytest.raises(KeyboardInterrupt):
        runner.run(runner.build(parse_scene(BLOCK)), tmp_path / "cut", progress=False)
    assert (tmp_path / "cut" / "status.txt").read_text().startswith("interrupted")
    # the third step was appended before its checkpoint failed: resume drops it
    assert len(list(csv.DictReader(open(tmp_path / "cut" / "history.csv")))) == 3
    resumed = runner.run(runner.build(parse_scene(BLOCK)), tmp_path / "cut",
                         progress=False, resume=True)
    assert resumed.completed and len(resumed.history) == 4
    # the predictor and step count are checkpointed: the same operations
    # in the same order, so the same bits
    np.testing.assert_array_equal(resumed.d, reference.d)
    rows = list(csv.DictReader(open(tmp_path / "cut" / "history.csv")))
    assert [int(r["step"]) for r in rows] == [1, 2, 3, 4]


def test_cli_reports_scene_errors(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(BLOCK.replace("nu = 0.3", "nu = 0.7"))
    assert main(["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "bad.toml, line 13: material.nu: must lie in (-1, 0.5)" in capsys.readouterr().err
    assert main(["run", "no-such-scene"]) == 2


def test_cli_runs_a_scene_file(tmp_path, capsys):
    scene = tmp_path / "block.toml"
    scene.write_text(BLOCK)
    assert main(["run", str(scene), "--out", str(tmp_path / "o"), "--quiet",
                 "--set", "steps.count=2", "--method", "fem"]) == 0
    assert "completed: 2 of 2 steps" in capsys.readouterr().out
    assert (tmp_path / "o" / "deformed.png").exists()


def test_progress_prints_one_line_per_tenth_of_the_load_when_not_a_terminal():
    import io
    from types import SimpleNamespace

    from skfem_rkpm.runs.runner import Progress

    stream = io.StringIO()
    bar = Progress(stream)
    for k in range(1, 41):
        bar(SimpleNamespace(step=k, t=k / 40, iterations=2))
    bar.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 10
    assert "\r" not in stream.getvalue()
    assert lines[-1].startswith("[" + "#" * 30 + "] step 40 t=1.000 newton=2")


def test_progress_counts_the_scenes_steps_when_a_step_was_cut():
    """A 100-step scene whose step 3 was cut in two sub-steps ends at "step
    100/100", not "step 101"; the sub-steps show the step they belong to."""
    import io
    from types import SimpleNamespace

    from skfem_rkpm.runs.runner import Progress, scene_step

    loads = [0.01, 0.02, 0.025, 0.03] + [k / 100 for k in range(4, 101)]
    stream = io.StringIO()
    bar = Progress(stream, count=100)
    for k, t in enumerate(loads, start=1):
        bar(SimpleNamespace(step=k, t=t, iterations=2))
    bar.close()
    assert len(loads) == 101
    assert [scene_step(t, 100) for t in loads[:5]] == [1, 2, 3, 3, 4]
    assert "step 100/100 t=1.000" in stream.getvalue().splitlines()[-1]
    assert "step 101" not in stream.getvalue()
    # load factors a hair off the targets (sums of halved steps) stay put
    assert scene_step(0.3 + 1e-12, 10) == 3 and scene_step(0.3 - 1e-12, 10) == 3


def test_the_command_line_runs_blas_with_one_thread_unless_told(tmp_path, monkeypatch):
    """Without OPENBLAS_NUM_THREADS=1 in the shell, BLAS starts with a thread
    per core; the command limits it (to 1, or --threads N) for the run and
    restores it after."""
    import os

    from threadpoolctl import threadpool_info, threadpool_limits

    def blas():
        return {i["filepath"]: i["num_threads"] for i in threadpool_info()
                if i["user_api"] == "blas"}

    seen, real = [], runner.run

    def spy(*args, **kwargs):
        seen.append((blas(), os.environ["OPENBLAS_NUM_THREADS"]))
        return real(*args, **kwargs)

    monkeypatch.setattr(runner, "run", spy)
    small = ["--set=steps.count=1", "--set=geometry.divisions=[6,4]",
             "--set=output.figures=false", "--set=output.fields=false", "--quiet"]
    with threadpool_limits(limits=3, user_api="blas"):  # as in a plain shell
        outside = blas()
        three = [path for path, n in outside.items() if n == 3]  # numpy's, scipy's
        assert three
        assert main(["run", "ring", *small, "--out", str(tmp_path / "a")]) == 0
        assert main(["run", "ring", *small, "--out", str(tmp_path / "b"),
                     "--threads", "2"]) == 0
        assert blas() == outside  # restored
    (one, env1), (two, env2) = seen
    assert set(one.values()) == {1} and env1 == "1"
    assert {two[path] for path in three} == {2} and env2 == "2"
    with pytest.raises(SystemExit):
        main(["run", "ring", "--threads", "0"])
