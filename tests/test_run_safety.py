"""Run folders you can trust after a crash, and files from others that run nothing.

The small ring (6 × 4 cells, 6 load steps: 11 converged steps, about 1 s)
stands for a scene run.  Its step control is busy: it cuts back twice.
"""

import csv
import os
import pickle
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import skfem_rkpm.runs.runner as runner
from skfem_rkpm.meshes.geo_check import unsafe_geo_commands
from skfem_rkpm.runs.checkpoint import run_identity
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.folder import RunFolder
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

SMALL = ["steps.count=6", "geometry.divisions=[6,4]", "discretization.support=12",
         "output.figures=false"]
RING = builtin_scenes()["ring"]
STEPS = 11


def small_ring(*more):
    return runner.build(load_scene(RING, SMALL + list(more)))


def as_run_folder(out, files):
    """Make ``out`` a run folder whose manifest lists ``files`` (as a run
    that wrote them leaves it; the files are written by the caller)."""
    out.mkdir(parents=True, exist_ok=True)
    with RunFolder(out) as folder:
        folder.claim(*files)


def history_without_time(path):
    """History rows without the wall time (the one column that may differ)."""
    with open(path, newline="") as handle:
        return [{k: v for k, v in row.items() if k != "seconds"}
                for row in csv.DictReader(handle)]


def fields_of(folder):
    """{step: {name: array}} of every step file of the series."""
    out = {}
    for file in sorted((folder / "fields").glob("step-*.h5")):
        with h5py.File(file, "r") as f:
            out[file.name] = {k: f[k][()] for k in f} | {"t": f.attrs["t"]}
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    result = runner.run(small_ring(), out, progress=False)
    assert result.completed and len(result.history) == STEPS
    assert [r.cutbacks for r in result.history] == [1] + [0] * 8 + [1] + [0]
    return out, result


class Bomb:
    """A pickle that, when loaded, creates a marker file."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


@pytest.mark.parametrize("name", ["checkpoint.pkl", "checkpoint.npz"])
def test_a_malicious_pickle_in_a_run_folder_is_never_loaded(tmp_path, capsys, name):
    marker = tmp_path / "pwned"
    out = tmp_path / "run"
    as_run_folder(out, [name])  # the manifest is someone else's too
    (out / name).write_bytes(pickle.dumps(Bomb(marker)))
    pickle.loads(pickle.dumps(Bomb(tmp_path / "works")))  # the bomb does go off
    assert (tmp_path / "works").exists()
    code = main(["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                 "--quiet", "--resume"])
    assert code == 2 and not marker.exists()
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: ")
    assert ("pickle" in err) and ("never loaded" in err)


@pytest.mark.parametrize("content, expected", [
    (None, "nothing to resume"),
    (b"", "cannot be resumed"),
    (b"PK\x03\x04garbage", "cannot be resumed"),
])
def test_missing_empty_or_corrupt_checkpoint_gives_one_line(tmp_path, capsys, content,
                                                            expected):
    out = tmp_path / "run"
    out.mkdir()
    if content is not None:
        as_run_folder(out, ["checkpoint.npz"])
        (out / "checkpoint.npz").write_bytes(content)
    assert main(["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                 "--quiet", "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and expected in err, err


def test_a_truncated_checkpoint_of_a_real_run_is_refused(tmp_path, capsys, reference):
    out = tmp_path / "run"
    runner.run(small_ring(), out, progress=False)
    data = (out / "checkpoint.npz").read_bytes()
    (out / "checkpoint.npz").write_bytes(data[: len(data) // 2])
    assert main(["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                 "--quiet", "--resume"]) == 2
    assert "cannot be resumed" in capsys.readouterr().err


GEO = """// a square
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5};
Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3};
Physical Curve("left") = {4}; Physical Surface("body") = {1};
"""

GEO_SCENE = """
[model]
type = "plane_strain"
method = "fem"
[geometry]
kind = "gmsh"
file = "square.geo"
[discretization]
element = "tri1"
[material]
E = 200e3
nu = 0.3
yield = 300.0
[boundary.bottom]
fix = ["y"]
[boundary.left]
fix = ["x"]
[boundary.top]
pressure = 1.0
[steps]
count = 1
[output]
fields = false
figures = false
"""


def test_a_geo_file_with_a_system_call_is_refused_and_runs_nothing(tmp_path, capsys):
    marker = tmp_path / "marker"
    (tmp_path / "square.geo").write_text(GEO + f'SystemCall "touch {marker}";\n')
    (tmp_path / "scene.toml").write_text(GEO_SCENE)
    args = ["run", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "o"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"square.geo', line {GEO.count(chr(10)) + 1}: SystemCall runs a program" in err and "--trust-geo" in err
    assert not marker.exists()
    # the check is what stops it: trusted, gmsh runs the command
    assert main(args + ["--trust-geo"]) == 0
    assert marker.exists()


@pytest.mark.parametrize("line, command", [
    ('Include "other.geo";', "Include"), ('Merge "x.msh";', "Merge"),
    ('NonBlockingSystemCall "ls";', "NonBlockingSystemCall"),
    ('OnelabRun("a", "b");', "OnelabRun"), ('v() = ShapeFromFile("a.brep");', "ShapeFromFile"),
    ('Save "out.msh";', "Save"), ('Printf("x") > "file.txt";', "Printf > file"),
    ('Field[1] = ExternalProcess;', "ExternalProcess"), ("Exit;", "Exit"),
    ('Solver.Executable0 = "evil";', "Solver.Executable0"),
    ('General.BackgroundImageFileName = "/etc/passwd";', "General.BackgroundImageFileName"),
    ('Plugin(Remove).Run;', "Plugin"), ('CreateDir "d";', "CreateDir"),
])
def test_every_command_that_reaches_outside_is_found(line, command):
    found = unsafe_geo_commands(GEO + line + "\n")
    assert [(where, what) for where, what, _ in found] == [(GEO.count("\n") + 1, command)]


def test_comments_strings_and_plain_geometry_pass():
    text = GEO + ('// SystemCall "rm" in a comment\n/* Include "x" */\n'
                  'Printf("Merge %g", 1);\nMesh.RecombineAll = 1;\n')
    assert unsafe_geo_commands(text) == []
    for path in Path(RING).parent.glob("*.geo"):
        assert unsafe_geo_commands(path.read_text()) == [], path


def test_outputs_never_write_through_a_symlink(tmp_path):
    out = tmp_path / "run"
    names = ("history.csv", "status.txt", "fields.xdmf", "checkpoint.npz")
    as_run_folder(out, names)  # a run folder whose outputs became links
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    for name in names:
        (out / name).symlink_to(target)
    result = runner.run(small_ring(), out, progress=False)
    assert result.completed and target.read_text() == "keep me\n"
    assert not (out / "history.csv").is_symlink()
    assert len(history_without_time(out / "history.csv")) == STEPS
    # resuming into a folder whose history became a link is refused
    (out / "history.csv").unlink()
    (out / "history.csv").symlink_to(target)
    with pytest.raises(ValueError, match="history.csv is missing or shorter"):
        runner.run(small_ring(), out, progress=False, resume=True)
    assert target.read_text() == "keep me\n"


@pytest.mark.parametrize("stop_at", [1, 2, 5, 10])
def test_resumed_run_equals_the_uninterrupted_one(tmp_path, monkeypatch, reference,
                                                  stop_at):
    """Stopped after step 1 or 10 (each needed cut-backs: the next steps
    start from the halved size), 2 or 5 (the size grows again after 3 steps
    without a cut-back); the stop falls after the step's history rows and
    fields are written but before its checkpoint, the worst moment."""
    ref_out, ref = reference
    out = tmp_path / "run"
    save = runner.save_checkpoint
    calls = {"n": 0}

    def stopping(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == stop_at + 1:
            raise KeyboardInterrupt
        return save(*args, **kwargs)

    monkeypatch.setattr(runner, "save_checkpoint", stopping)
    with pytest.raises(KeyboardInterrupt):
        runner.run(small_ring(), out, progress=False)
    monkeypatch.setattr(runner, "save_checkpoint", save)
    assert (out / "status.txt").read_text().startswith(
        f"interrupted after step {stop_at + 1}")
    resumed = runner.run(small_ring(), out, progress=False, resume=True)
    assert resumed.completed and len(resumed.history) == STEPS
    # the predictor, the step count, the step control and the states are
    # checkpointed exactly:
    # the resumed run repeats the same operations, so the same bits
    np.testing.assert_array_equal(resumed.d, ref.d)
    assert history_without_time(out / "history.csv") == history_without_time(
        ref_out / "history.csv")
    mine, theirs = fields_of(out), fields_of(ref_out)
    assert list(mine) == list(theirs) and len(mine) == STEPS
    for step in theirs:
        for key in theirs[step]:
            np.testing.assert_array_equal(mine[step][key], theirs[step][key])
    with open(out / "fields.xdmf") as handle:
        assert handle.read().count("<Time ") == STEPS


def test_resume_refuses_another_scene_or_method_and_names_it(tmp_path, capsys):
    out = tmp_path / "run"
    runner.run(small_ring(), out, progress=False)
    base = ["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out), "--quiet",
            "--resume"]
    assert main(base + ["--set", "tools.platen.friction=0"]) == 2
    assert "tools.platen.friction = 0.15 there, 0 now" in capsys.readouterr().err
    assert main(base + ["--method", "fem"]) == 2
    assert "method rkpm there, fem now" in capsys.readouterr().err
    # the linear solver changes only the round-off: allowed
    assert main(base + ["--solver", "superlu"]) == 0


def test_a_locked_folder_is_refused_and_a_dead_lock_is_not(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out), "--quiet"]
    with RunFolder(out):
        assert main(args) == 2
        err = capsys.readouterr().err
        assert f"{out} is in use by another run (process {os.getpid()}" in err
    # a lock file left by a process that died (its pid no longer runs)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    (out / ".lock").write_text(f"process {dead} on this host\n")
    assert main(args) == 0


def test_a_new_run_clears_the_folder_and_keeps_its_scene(tmp_path, monkeypatch):
    out = tmp_path / "run"
    earlier = ("deformed.png", "forces.png", "fields.xdmf", "history.csv", "status.txt")
    as_run_folder(out, earlier)
    for name in earlier:
        (out / name).write_text("an earlier run")
    (out / "status.txt").write_text("completed\n")
    (out / "notes.txt").write_text("mine")
    seen = {}

    def stop(*args, **kwargs):
        seen["status"] = (out / "status.txt").read_text()
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "save_checkpoint", stop)
    with pytest.raises(KeyboardInterrupt):
        runner.run(small_ring(), out, progress=False)
    assert seen["status"].startswith("running")
    assert (out / "status.txt").read_text().startswith("interrupted after step 1")
    assert not (out / "deformed.png").exists() and not (out / "forces.png").exists()
    assert (out / "notes.txt").read_text() == "mine"
    assert len(history_without_time(out / "history.csv")) == 1
    # scene.toml is the resolved scene: read back, it is the same run
    again = runner.build(load_scene(out / "scene.toml"))
    assert run_identity(again)["hash"] == run_identity(small_ring())["hash"]


def test_out_that_is_a_file_or_not_writable_gives_one_line(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    for out in (afile, afile / "below"):
        assert main(["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                     "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err.startswith(f"error: --out {out}"), err


def test_default_folder_names_the_method_and_the_settings(tmp_path, monkeypatch, capsys):
    from skfem_rkpm.runs.cli import _default_out

    assert _default_out(Path("ring.toml"), "fem", []) == Path("results/ring-fem")
    a = _default_out(Path("ring.toml"), "rkpm", ["tools.platen.friction=0"])
    b = _default_out(Path("ring.toml"), "rkpm", ["tools.platen.friction=stick"])
    assert a != b and a.name.startswith("ring-rkpm-set-")
    monkeypatch.chdir(tmp_path)
    assert main(["run", "ring", *(f"--set={s}" for s in SMALL), "--quiet",
                 "--method", "fem"]) == 0
    out = capsys.readouterr().out
    assert "note: --set changes the scene, so the results go to results/ring-fem-set-" in out
    assert len(list((tmp_path / "results").glob("ring-fem-set-*/history.csv"))) == 1


def test_version(capsys):
    from skfem_rkpm import __version__

    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.strip() == f"skfem-rkpm {__version__}"


def test_missing_solver_package_is_one_line_and_leaves_the_folder(tmp_path, capsys,
                                                                  monkeypatch):
    import skfem_rkpm.solvers.linear as linear

    monkeypatch.setattr(linear, "available", lambda: ["dense", "superlu"])
    out = tmp_path / "run"
    as_run_folder(out, ["status.txt"])  # an earlier run's folder
    (out / "status.txt").write_text("completed\n")
    code = main(["run", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                 "--quiet", "--solver", "pardiso"])
    err = capsys.readouterr().err.strip()
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        assert code == 2 and err.count("\n") == 0 and "pypardiso" in err, err
        assert (out / "status.txt").read_text() == "completed\n"
    else:
        assert code == 0


def test_memory_estimate_is_close_and_refuses_what_does_not_fit(tmp_path, capsys,
                                                                 monkeypatch):
    import skfem_rkpm.runs.memory as memory
    from skfem_rkpm.runs.scene import spacing_radius

    sim = small_ring()
    disc = sim.scene["discretization"]
    pairs, need, _ = memory.estimate_rk_bytes(sim.mesh, spacing_radius(sim.mesh, disc),
                                           disc["order"], disc["support_shape"],
                                           disc["quadrature"])
    actual = sim.basis.npairs
    # the estimate may only be a little high (supports at the boundary are
    # clipped by the bounding box only): measured 9-11 % on finer rings
    assert actual <= pairs <= 1.25 * actual, (pairs, actual)
    monkeypatch.setattr(memory, "available_bytes", lambda: need / 2)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "ring", *(f"--set={s}" for s in SMALL), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "the RK basis would need about" in err
    assert "geometry.divisions" in err and "--method fem" in err
    assert not (tmp_path / "results").exists()  # refused before anything was written


def test_a_geo_file_without_physical_groups_says_so(tmp_path, capsys):
    plain = "\n".join(line for line in GEO.splitlines() if "Physical" not in line)
    (tmp_path / "square.geo").write_text(plain + "\n")
    (tmp_path / "scene.toml").write_text(GEO_SCENE)
    assert main(["run", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "o"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the file square.geo defines no named boundaries" in err
    assert 'Physical Curve("name")' in err


def test_warnings_print_as_one_line(tmp_path, capsys):
    # the platen starts 20 mm above the ring and moves 10 mm: it never touches
    args = ["run", "ring", *(f"--set={s}" for s in SMALL), "--set",
            "tools.platen.point=[0.0, 40.0]", "--out", str(tmp_path / "o"), "--quiet"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "warning: tool 'platen' does not reach the part" in err
    assert "UserWarning" not in err and "warn(" not in err
