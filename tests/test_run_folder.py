"""Output folders: a run changes no file it did not write.

A folder is the program's when it holds the manifest ``.skfem-rkpm.json``
listing the files the program wrote there.  A user's folder is refused
(with ``--overwrite`` the run writes beside its files, but never over a
file at a name the run writes), a symbolic link is refused, and a run into
an earlier run's folder removes that run's files and only those.  The
small ring (6 x 4 cells, 6 load steps: 11 converged steps, about 1 s).
"""

import csv
import json
import os
from pathlib import Path

import pytest

from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.folder import MARKER, FolderError, RunFolder, status_on_failure

SMALL = ["steps.count=6", "geometry.divisions=[6,4]", "discretization.support=12",
         "output.figures=false"]
STEPS = 11  # converged steps of SMALL (cut-backs included)


def run_args(out, *more, settings=SMALL):
    return ["run", "ring", *(f"--set={s}" for s in settings), "--out", str(out), "--quiet",
            *more]


def snapshot(folder):
    """{relative path: (bytes, mtime_ns)} of every file below ``folder``."""
    return {str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def users_folder(tmp_path):
    """A folder of a user's own files, one of them at a name a run writes."""
    out = tmp_path / "mine"
    (out / "fields").mkdir(parents=True)
    (out / "history.csv").write_text("my own measurements\n1,2,3\n")
    (out / "notes.txt").write_text("notes\n")
    (out / "fields" / "keep.h5").write_bytes(b"not an HDF5 file, but mine")
    return out


def manifest(folder):
    return json.loads((folder / MARKER).read_text())


def rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: ") and "Traceback" not in err
    return err


def test_a_users_folder_is_refused_and_left_as_it_was(tmp_path, capsys):
    out = users_folder(tmp_path)
    before = snapshot(out)
    assert main(run_args(out)) == 2
    err = one_line_error(capsys)
    assert f"--out {out}: is not empty and not a run folder of skfem-rkpm" in err
    assert "choose another --out, or pass --overwrite" in err
    assert snapshot(out) == before  # content and times
    assert sorted(p.name for p in out.rglob("*")) == ["fields", "history.csv", "keep.h5",
                                                       "notes.txt"]  # no lock, no marker
    # --resume finds nothing of the program's there either
    assert main(run_args(out, "--resume")) == 2
    assert "nothing to resume" in one_line_error(capsys)
    assert snapshot(out) == before


def test_overwrite_writes_beside_a_users_files_never_over_them(tmp_path, capsys):
    out = users_folder(tmp_path)
    before = snapshot(out)
    # the user's history.csv has the name of the run's history: refused even so
    assert main(run_args(out, "--overwrite")) == 2
    err = one_line_error(capsys)
    assert "holds history.csv, not written by skfem-rkpm, at a name the run writes" in err
    assert "not even with --overwrite" in err
    assert snapshot(out) == before
    assert not (out / MARKER).exists() and not (out / ".lock").exists()
    # moved out of the way, the run writes beside the user's files
    os.replace(out / "history.csv", out / "my-history.csv")
    before = snapshot(out)
    assert main(run_args(out, "--overwrite")) == 0
    after = snapshot(out)
    assert {k: after[k] for k in before} == before
    assert len(rows(out / "history.csv")) == STEPS
    listed = manifest(out)["files"]
    assert {"history.csv", "checkpoint.npz", "scene.toml", "fields/mesh.h5",
            f"fields/step-{STEPS:06d}.h5"} <= set(listed)
    assert not set(before) & set(listed)  # the user's files are not the run's
    assert "fields/" not in listed  # the folder was the user's: never removed
    # now a run folder: run again without --overwrite; the user's files stay
    assert main(run_args(out)) == 0
    after = snapshot(out)
    assert {k: after[k] for k in before} == before
    assert len(rows(out / "history.csv")) == STEPS


def test_a_symlinked_folder_is_refused(tmp_path, capsys):
    real = tmp_path / "real"
    assert main(run_args(real)) == 0  # a run folder of the program, even
    before = snapshot(real)
    link = tmp_path / "link"
    link.symlink_to(real)
    for more in ([], ["--overwrite"], ["--resume"]):
        assert main(run_args(link, *more)) == 2
        err = one_line_error(capsys)
        assert f"--out {link}: is a symbolic link (to {real})" in err
        assert "give the folder itself or choose another --out" in err
    assert snapshot(real) == before


def test_an_earlier_run_is_replaced_and_a_users_file_in_it_survives(tmp_path, capsys):
    out = tmp_path / "run"
    # the earlier run: 15 steps with figures
    assert main(run_args(out, settings=SMALL[:-1] + ["output.figures=true"])) == 0
    first = set(manifest(out)["files"])
    assert {"deformed.png", "forces.png", "calibration.png",
            f"fields/step-{STEPS:06d}.h5"} <= first
    assert all((out / name).exists() for name in first)
    (out / "notes.txt").write_text("what I saw\n")
    (out / "fields" / "keep.h5").write_bytes(b"mine")
    mine = {k: v for k, v in snapshot(out).items() if k in ("notes.txt", "fields/keep.h5")}
    # the new run: 2 steps, no figures
    assert main(run_args(out, settings=["steps.count=2", *SMALL[1:]])) == 0
    history = rows(out / "history.csv")
    assert 2 <= len(history) < STEPS
    # the earlier run's files that the new run did not write again are gone
    for name in ("deformed.png", "forces.png", "calibration.png",
                 f"fields/step-{STEPS:06d}.h5"):
        assert not (out / name).exists(), name
    steps = sorted(p.name for p in (out / "fields").glob("step-*.h5"))
    assert steps == [f"step-{k:06d}.h5" for k in range(1, len(history) + 1)]
    # the user's files are untouched, and on disk is exactly what the manifest says
    now = snapshot(out)
    assert {k: now[k] for k in mine} == mine
    listed = {name for name in manifest(out)["files"] if not name.endswith("/")}
    assert set(now) == listed | set(mine) | {MARKER}
    assert (out / "status.txt").read_text() == "completed\n"


def test_the_marker_is_written_and_is_data(tmp_path):
    out = tmp_path / "run"
    assert main(run_args(out)) == 0
    data = manifest(out)
    assert data["program"] == "skfem-rkpm" and data["kind"] == "run"
    # every listed file exists, and the run wrote nothing it did not list
    files = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    listed = {name for name in data["files"] if not name.endswith("/")}
    assert files == listed | {MARKER} and "fields/" in data["files"]


@pytest.mark.parametrize("files, why", [
    (["../precious.txt"], "not a manifest of skfem-rkpm"),
    ([str(Path("/") / "tmp" / "precious.txt")], "not a manifest of skfem-rkpm"),
    ("history.csv", "not a manifest of skfem-rkpm"),
    (None, "expecting property name"),
])
def test_a_hostile_or_broken_manifest_deletes_nothing(tmp_path, capsys, files, why):
    precious = tmp_path / "precious.txt"
    precious.write_text("keep me\n")
    out = tmp_path / "run"
    out.mkdir()
    text = ("{not json" if files is None else
            json.dumps({"program": "skfem-rkpm", "format": 1, "kind": "run",
                        "files": files}))
    (out / MARKER).write_text(text)
    before = snapshot(tmp_path)
    assert main(run_args(out)) == 2
    err = one_line_error(capsys)
    assert f"its {MARKER} cannot be read (" in err and why in err.lower(), err
    assert snapshot(tmp_path) == before


def test_a_listed_file_behind_a_linked_folder_is_not_followed(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(run_args(out)) == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "step-000001.h5").write_bytes(b"someone else's")
    for p in (out / "fields").iterdir():
        p.unlink()
    (out / "fields").rmdir()
    (out / "fields").symlink_to(elsewhere)  # fields/step-000001.h5 is listed
    assert main(run_args(out)) == 2
    assert "holds fields, not written by skfem-rkpm" in one_line_error(capsys)
    assert (elsewhere / "step-000001.h5").read_bytes() == b"someone else's"


def test_compare_and_sweep_folders_follow_the_same_rules(tmp_path, capsys):
    out = users_folder(tmp_path)
    before = snapshot(out)
    assert main(["compare", "ring", *(f"--set={s}" for s in SMALL), "--out", str(out),
                 "--quiet"]) == 2
    assert "is not empty and not a compare folder" in one_line_error(capsys)
    assert snapshot(out) == before
    pytest.importorskip("distributed")
    # refused before a cluster is started
    assert main(["sweep", "ring", "--vary", "tools.platen.friction=0,0.1",
                 *(f"--set={s}" for s in SMALL), "--out", str(out), "--quiet"]) == 2
    assert "is not empty and not a sweep folder" in one_line_error(capsys)
    assert snapshot(out) == before
    # a run folder is not a compare folder (nor the other way round)
    run = tmp_path / "run"
    assert main(run_args(run)) == 0
    assert main(["compare", "ring", *(f"--set={s}" for s in SMALL), "--out", str(run),
                 "--quiet"]) == 2
    assert f"--out {run}: is the run folder of skfem-rkpm, not a compare folder" in \
        one_line_error(capsys)


def test_compare_replaces_its_own_report_and_keeps_a_users_file(tmp_path, capsys):
    out = tmp_path / "cmp"
    args = ["compare", "ring", *(f"--set={s}" for s in ["steps.count=1", *SMALL[1:]]),
            "--out", str(out), "--quiet"]
    assert main(args) == 0
    assert set(manifest(out)["files"]) == {".lock", "report.md", "compare.png"}
    assert manifest(out / "rkpm")["kind"] == manifest(out / "fem")["kind"] == "run"
    (out / "notes.txt").write_text("mine\n")
    mine = snapshot(out)["notes.txt"]
    old = (out / "report.md").stat().st_mtime_ns
    assert main(args) == 0
    assert snapshot(out)["notes.txt"] == mine
    assert (out / "report.md").stat().st_mtime_ns >= old
    assert "# RKPM vs FEM" in (out / "report.md").read_text()


def test_a_folder_of_another_run_in_progress_is_not_cleared(tmp_path):
    """The checks run again under the lock: the folder seen before it is the
    one used."""
    out = tmp_path / "run"
    with RunFolder(out) as folder:
        folder.write("history.csv", "in progress\n")
        with pytest.raises(FolderError, match="is in use by another run"):
            with RunFolder(out):
                pass
    assert (out / "history.csv").read_text() == "in progress\n"


def test_temporaries_of_a_killed_run_go_and_a_users_look_alike_stays(tmp_path):
    out = tmp_path / "run"
    assert main(run_args(out)) == 0
    left = [out / ".history.csv.4242.tmp", out / "fields" / ".step-000003.h5.4242.tmp",
            out / f".{MARKER}.4242.tmp"]  # what a kill during a write leaves
    for path in left:
        path.write_bytes(b"part")
    mine = [out / ".notes.txt.4242.tmp", out / ".history.csv.draft.tmp"]
    for path in mine:
        path.write_bytes(b"mine")
    assert main(run_args(out)) == 0
    assert not any(path.exists() for path in left)
    assert all(path.read_bytes() == b"mine" for path in mine)


def test_a_sweep_trusts_only_the_result_its_run_wrote(tmp_path):
    from skfem_rkpm.runs.folder import SWEEP_RUN
    from skfem_rkpm.runs.sweep import _finished

    record = {"status": "completed", "steps": 3}
    planted = tmp_path / "run-planted"  # a result.json put there by someone else
    planted.mkdir()
    (planted / "result.json").write_text(json.dumps(record))
    assert _finished(planted) is None
    ours = tmp_path / "run-ours"
    with RunFolder(ours, writes=SWEEP_RUN) as folder:
        folder.write("result.json", json.dumps(record))
    assert _finished(ours) == record
    (ours / "result.json").write_text(json.dumps(dict(record, status="failed")))
    assert _finished(ours) is None  # a failed run is tried again


def test_a_failing_block_leaves_its_status_and_raises_on(tmp_path):
    """An interrupt writes the caller's message, any other exception its type
    and text; both propagate, and a block that ends normally writes none."""
    with RunFolder(tmp_path / "run") as folder:
        with status_on_failure(folder, lambda: "interrupted after step 3"):
            pass
        assert not (folder.path / "status.txt").exists()
        with pytest.raises(KeyboardInterrupt):
            with status_on_failure(folder, lambda: "interrupted after step 3"):
                raise KeyboardInterrupt("SIGTERM")
        assert (folder.path / "status.txt").read_text() == "interrupted after step 3\n"
        with pytest.raises(ZeroDivisionError):
            with status_on_failure(folder, lambda: "never used"):
                1 / 0
        assert (folder.path / "status.txt").read_text() == (
            "failed: ZeroDivisionError: division by zero\n")
    with pytest.raises(ValueError):
        with status_on_failure(None, lambda: "no folder"):
            raise ValueError("nothing is written without a folder")
