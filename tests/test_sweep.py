"""Parameter sweeps on dask.distributed and the ring-test calibration chart."""

import csv
import json
import shutil

import numpy as np
import pytest

import skfem_rkpm.runs.sweep as sweep
from skfem_rkpm.runs import runner
from skfem_rkpm.runs.calibration import (ChartError, friction_from_measurement, ring_curve,
                                    sweep_curves)
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

RING = builtin_scenes()["ring"]
# a coarse ring compressed by 10 % in 4 steps: about a second per run
SETTINGS = ["geometry.divisions=[6,4]", "steps.count=4", "tools.platen.motion=[0, -2]",
            "output.fields=false", "output.figures=false"]
FRICTION = "tools.platen.friction"


@pytest.fixture(scope="module")
def client():
    """One local cluster of two single-threaded workers for the whole module."""
    client, cluster = sweep._client(None, 2)
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def fem_sweep(client, tmp_path_factory):
    """A three-value friction sweep with FEM: (folder, records)."""
    out = tmp_path_factory.mktemp("fem_sweep")
    records = sweep.run_sweep(RING, {FRICTION: [0, "0.1", "stick"]}, SETTINGS, "fem", out,
                              progress=False, client=client)
    return out, records


def read_history(path):
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    columns = [c for c in rows[0] if c != "seconds"]  # wall time differs run to run
    return columns, np.array([[float(r[c]) for c in columns] for r in rows])


def one_by_one(tmp_path, overrides, method=None):
    """The same run without the sweep: load_scene, build, run, with one BLAS
    thread as in the sweep's tasks (threads split BLAS sums differently, and
    on some OpenBLAS kernels the round-off then moves a run's cut-backs)."""
    scene = load_scene(RING, SETTINGS + overrides)
    with runner.blas_threads(1):
        result = runner.run(runner.build(scene, method), tmp_path, progress=False)
    return result, read_history(tmp_path / "history.csv")


def test_vary_values_split_and_product():
    assert sweep.split_values("0, 0.05,[6,4],stick") == ["0", "0.05", "[6,4]", "stick"]
    assert sweep.split_values('"a,b",1') == ['"a,b"', "1"]
    key, values = sweep.parse_vary("geometry.divisions=[6,4],[8,6]")
    assert key == "geometry.divisions" and values == ["[6,4]", "[8,6]"]
    combos = sweep.cases({"a.x": [1, 2.5], "b.y": ["stick", [6, 4], True]})
    assert len(combos) == 6
    assert combos[0] == {"a.x": "1", "b.y": "stick"}
    assert combos[-1] == {"a.x": "2.5", "b.y": "true"}
    assert combos[1]["b.y"] == "[6, 4]"
    assert sweep.cases({"a.x": "0,0.1"}) == [{"a.x": "0"}, {"a.x": "0.1"}]
    for bad in ("tools.platen.friction", "tools.platen.friction=0,,1", "=1,2"):
        with pytest.raises(sweep.SweepError, match="--vary"):
            sweep.parse_vary(bad)


def test_scene_key_follows_content_not_spelling():
    text = RING.read_text()
    base = sweep.resolve_text(text, ["tools.platen.friction=0.1"])
    key = sweep.scene_key(base)
    assert key == sweep.scene_key(sweep.resolve_text(text, ["tools.platen.friction=0.10"]))
    assert key == sweep.scene_key("# a comment\n" + base)
    assert key != sweep.scene_key(sweep.resolve_text(text, ["tools.platen.friction=0.2"]))
    assert key != sweep.scene_key(sweep.resolve_text(base, ["model.method=fem"]))
    assert len(key) == 64


def test_workers_use_one_blas_thread(client):
    import os

    env = client.run(lambda: (os.environ.get("OPENBLAS_NUM_THREADS"),
                              os.environ.get("MPLBACKEND")))
    assert len(env) == 2
    assert set(env.values()) == {("1", "Agg")}


def test_sweep_gives_the_numbers_of_runs_one_by_one(fem_sweep, tmp_path):
    out, records = fem_sweep
    assert [r[FRICTION] for r in records] == [0, 0.1, "stick"]
    assert all(r["status"] == "completed" and not r["skipped"] for r in records)
    table = list(csv.DictReader(open(out / "sweep.csv", newline="")))
    assert [row[FRICTION] for row in table] == ["0", "0.1", "stick"]
    for record, row in zip(records, table):
        value = record[FRICTION]
        result, (columns, reference) = one_by_one(tmp_path / str(value),
                                                  [f"{FRICTION}={value}"], "fem")
        got_columns, got = read_history(out / record["run"] / "history.csv")
        assert got_columns == columns
        np.testing.assert_allclose(got, reference, rtol=1e-12, atol=1e-12)
        # sweep.csv: counts and the last history row of this run
        assert int(row["steps"]) == len(result.history) == record["steps"]
        assert int(row["newton iterations"]) == sum(r.iterations for r in result.history)
        last = result.gauges[-1]
        for name in ("inner_mid x", "outer_mid x", "platen dy"):
            assert float(row[name]) == pytest.approx(last[name], rel=1e-12, abs=1e-12)
        assert float(row["platen dy"]) == pytest.approx(-2.0, rel=1e-12)
        assert json.loads((out / record["run"] / "result.json").read_text())["steps"] \
            == len(result.history)
    # friction holds the hole back: the inner radius at mid-height falls with μ
    radii = [float(row["inner_mid x"]) for row in table]
    assert radii[0] > 30.0 > radii[2] and radii[0] > radii[1] > radii[2]


def test_a_failing_run_is_recorded_and_the_others_finish(client, tmp_path):
    vary = {"discretization.support": ["6.0", "1.0"], FRICTION: ["0.1", "-1"]}
    records = sweep.run_sweep(RING, vary, SETTINGS, None, tmp_path, progress=False,
                              client=client)
    status = {(r["discretization.support"], r[FRICTION]): r for r in records}
    assert len(status) == 4
    ok = status[(6.0, 0.1)]
    assert ok["status"] == "completed" and ok["error"] == ""
    assert "SingularMomentError" in status[(1.0, 0.1)]["error"]
    # the bad value is named by the --vary that gave it, not by a line of ring.toml
    assert "SceneError: --vary tools.platen.friction=-1: must be a number >= 0" \
        in status[(6.0, -1)]["error"]
    assert all(status[k]["status"] == "failed" and not status[k]["completed"]
               for k in [(1.0, 0.1), (6.0, -1), (1.0, -1)])
    # the RKPM run of the sweep equals the same run done directly
    _, (columns, reference) = one_by_one(tmp_path / "ref", ["discretization.support=6.0",
                                                            f"{FRICTION}=0.1"])
    got_columns, got = read_history(tmp_path / ok["run"] / "history.csv")
    assert got_columns == columns
    np.testing.assert_allclose(got, reference, rtol=1e-12, atol=1e-12)
    # a second pass skips the finished run and tries the failed ones again
    again = sweep.run_sweep(RING, vary, SETTINGS, None, tmp_path, progress=False,
                            client=client)
    assert [r["skipped"] for r in again] == [True, False, False, False]
    assert [r["status"] for r in again] == [r["status"] for r in records]


def test_rerun_skips_finished_runs(fem_sweep, client, tmp_path):
    source, records = fem_sweep
    out = tmp_path / "copy"
    shutil.copytree(source, out)
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("run-*/*")}
    vary = {FRICTION: ["0", "0.05", "0.1", "stick"]}
    again = sweep.run_sweep(RING, vary, SETTINGS, "fem", out, progress=False, client=client)
    assert [r["skipped"] for r in again] == [True, False, True, True]
    assert stamps == {p: p.stat().st_mtime_ns for p in stamps}  # nothing rewritten
    assert len(list(out.glob("run-*"))) == 4
    done = {r[FRICTION]: r for r in again}
    for record in records:
        assert done[record[FRICTION]]["run"] == record["run"]
        assert done[record[FRICTION]]["inner_mid x"] == record["inner_mid x"]
    rows = list(csv.DictReader(open(out / "sweep.csv", newline="")))
    assert [row[FRICTION] for row in rows] == ["0", "0.05", "0.1", "stick"]
    assert float(rows[0]["inner_mid x"]) > float(rows[1]["inner_mid x"]) \
        > float(rows[2]["inner_mid x"])


def test_cli_sweep_on_an_existing_scheduler(fem_sweep, client, tmp_path, capsys):
    source, records = fem_sweep
    out = tmp_path / "cli"
    shutil.copytree(source, out)
    args = ["sweep", "ring", "--vary", f"{FRICTION}=0,0.2", "--method", "fem",
            "--scheduler", client.scheduler.address, "--out", str(out)]
    for setting in SETTINGS:
        args += ["--set", setting]
    assert main(args) == 0
    assert client.status == "running"  # the cluster is left as it was
    captured = capsys.readouterr()
    assert "2 of 2 runs completed" in captured.out
    assert "done earlier" in captured.err and "[2/2]" in captured.err
    assert "2 runs: completed 2, failed 0, running 0, pending 0" in captured.err
    rows = list(csv.DictReader(open(out / "sweep.csv", newline="")))
    assert [row[FRICTION] for row in rows] == ["0", "0.2"]
    assert rows[0]["run"] == records[0]["run"]
    _, history = read_history(out / rows[1]["run"] / "history.csv")
    assert len(history) == int(rows[1]["steps"])


def test_missing_dask_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)
    with pytest.raises(sweep.SweepError, match=r"pip install skfem-rkpm\[dask\]"):
        sweep.run_sweep(RING, {FRICTION: [0.1]}, progress=False)
    assert main(["sweep", "ring", "--vary", f"{FRICTION}=0.1"]) == 2
    assert "pip install skfem-rkpm[dask]" in capsys.readouterr().err


# -- calibration chart ---------------------------------------------------------


def linear_chart():
    """Curves with id_change = hr (0.2 - 2 μ), sticking at hr (-0.5)."""
    hr = np.linspace(0.0, 50.0, 11)
    curves = {mu: (hr, hr * (0.2 - 2 * mu)) for mu in (0.0, 0.1, 0.2)}
    curves["stick"] = (hr, -0.5 * hr)
    return curves


def test_friction_read_back_on_and_between_curves():
    curves = linear_chart()
    for mu in (0.0, 0.1, 0.2):
        assert friction_from_measurement(curves, 33.0, 33.0 * (0.2 - 2 * mu)) \
            == pytest.approx(mu, abs=1e-12)
    # the chart is linear in μ: any point between curves reads its exact μ
    for mu in (0.03, 0.05, 0.17):
        assert friction_from_measurement(curves, 27.0, 27.0 * (0.2 - 2 * mu)) \
            == pytest.approx(mu, rel=1e-12)
    assert friction_from_measurement(curves, 20.0, -10.0) == "stick"
    # sticking placed at μ = 0.6: halfway between μ = 0.2 (-4 %) and sticking (-10 %)
    assert friction_from_measurement(curves, 20.0, -7.0, stick_mu=0.6) \
        == pytest.approx(0.4, rel=1e-12)
    assert friction_from_measurement(curves, 20.0, -10.0, stick_mu=0.6) == 0.6


@pytest.mark.parametrize("hr, idc, message", [
    (55.0, 0.0, "outside the chart: all curves cover 0% to 50%"),
    (-1.0, 0.0, "outside the chart"),
    (20.0, 4.5, "above the μ=0.0 curve"),
    (20.0, -10.5, "below the sticking curve"),
    (20.0, -7.0, "between the μ=0.2 and the sticking curve"),
])
def test_points_off_the_chart_raise(hr, idc, message):
    with pytest.raises(ChartError, match=message):
        friction_from_measurement(linear_chart(), hr, idc)


def test_chart_from_a_friction_sweep(fem_sweep, tmp_path):
    out, records = fem_sweep
    curves = sweep_curves(out)
    assert set(curves) == {0.0, 0.1, "stick"}
    for record in records:
        mu = 0.0 if record[FRICTION] == 0 else record[FRICTION]
        hr, idc = curves[mu]
        # independent: final platen travel 2 mm of 20 mm, inner radius 30 mm
        assert hr[0] == idc[0] == 0.0 and hr[-1] == pytest.approx(10.0, rel=1e-12)
        assert idc[-1] == pytest.approx((record["inner_mid x"] - 30.0) / 30.0 * 100,
                                        rel=1e-12)
        assert len(hr) == record["steps"] + 1
        read = friction_from_measurement(curves, hr[-1], idc[-1])
        assert read == ("stick" if mu == "stick" else pytest.approx(mu, abs=1e-9))
    # halfway between the μ = 0 and μ = 0.1 curves at 8 % height reduction
    middle = 0.5 * (np.interp(8.0, *curves[0.0]) + np.interp(8.0, *curves[0.1]))
    mu = friction_from_measurement(curves, 8.0, middle)
    assert 0.0 < mu < 0.1
    assert mu == pytest.approx(0.05, abs=1e-12)  # linear in μ between two curves
    direct = ring_curve(out / records[1]["run"] / "history.csv")
    np.testing.assert_array_equal(direct[1], curves[0.1][1])
    with pytest.raises(ChartError, match="outside the chart"):
        friction_from_measurement(curves, 12.0, 0.0)
