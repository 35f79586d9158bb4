"""A run folder: one run at a time, consistent after a crash, and only its
own files touched.

* :func:`atomic_path` and :func:`write_atomic` write a new file beside the
  target and rename it over the target (``os.replace``): a reader, or a run
  killed at any moment, sees the old file or the new one, never a part;
  a symbolic link at the target is replaced, its target is never written.
* :func:`open_append` opens a file for appending, refusing a symbolic link.
* :class:`RunFolder` takes the folder's lock (``.lock``, an advisory
  ``flock`` that the system releases when the process ends, even on
  SIGKILL, so a lock left by a dead process never blocks) and keeps the
  folder's manifest, :data:`MARKER`: a JSON text (data only, never
  executed) naming the program, the kind of folder (a run, a comparison, a
  sweep) and every file the program wrote there.  Each file is entered
  (:meth:`RunFolder.claim`) before it is first written, so a run killed at
  any moment leaves no file of its own unlisted.

What a folder may be used for (:class:`RunFolder`):

* missing or empty: it becomes a run folder;
* a run folder of the same kind (it holds the manifest): a new run removes
  the files the manifest lists (:meth:`RunFolder.clear`) and nothing else;
* anything else (a user's folder): refused, naming the folder and the way
  out (another ``--out``, or ``--overwrite``).  With ``overwrite=True`` the
  run writes its files beside the ones there, and the folder becomes a run
  folder listing only the run's files;
* never a folder that is a symbolic link, and never over a file the
  program did not write: a file at a name the run writes (``history.csv``,
  ``fields/step-000001.h5``, ...) that the manifest does not list is
  refused, also with ``overwrite=True``.

The guarantees are for a process that is killed; data the operating system
has not yet written to the disk is lost if the machine itself goes down.
"""

import contextlib
import fcntl
import fnmatch
import json
import os
import re
import socket
from pathlib import Path, PurePosixPath

__all__ = ["FolderError", "RunFolder", "atomic_path", "write_atomic", "open_append",
           "read_manifest", "MARKER", "WRITES", "SWEEP_RUN"]

#: the manifest that marks a folder as the program's and lists its files
MARKER = ".skfem-rkpm.json"
LOCK = ".lock"

#: what each kind of folder may write (names and ``fnmatch`` patterns, relative
#: to the folder); the figures are those of
#: :func:`skfem_rkpm.runs.plot.save_run_figures` (a run of a sweep also
#: writes ``result.json``: :data:`SWEEP_RUN`)
WRITES = {
    "run": ("status.txt", "scene.toml", "history.csv", "history.jsonl", "fields.xdmf",
            "fields", "fields/mesh.h5", "fields/step-*.h5", "checkpoint.npz",
            "deformed.png", "forces.png", "calibration.png", "section.png", "energy.png"),
    "compare": ("report.md", "compare.png"),
    "sweep": ("sweep.csv",),
}

#: what a run of a sweep writes
SWEEP_RUN = WRITES["run"] + ("result.json",)

_FORMAT = 1
_MAX_MANIFEST = 1 << 24


class FolderError(ValueError):
    """A run folder that cannot be used (in use, not a folder, not writable,
    a user's folder, a file the run did not write in the way)."""


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; on success rename it to ``path``.

    The temporary name does not exist when yielded (a file or link left
    there by a killed run is removed), so a writer that creates it
    exclusively (``open(..., "x")``, ``h5py.File(..., "x")``) never writes
    through a link.  On an exception the temporary file is removed.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.unlink(missing_ok=True)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path, data):
    """Write ``data`` (str or bytes) to ``path`` through :func:`atomic_path`."""
    with atomic_path(path) as tmp:
        with open(tmp, "xb" if isinstance(data, bytes) else "x",
                  **({} if isinstance(data, bytes) else {"encoding": "utf-8"})) as handle:
            handle.write(data)
    return Path(path)


def open_append(path, **kwargs):
    """Open a text file for appending (created if missing), never through a link."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError:
        if Path(path).is_symlink():
            raise FolderError(f"{path} is a symbolic link: a run writes only its own "
                              f"files; remove the link") from None
        raise
    return os.fdopen(fd, "a", **kwargs)


def _describe(err):
    return err.strerror.lower() if getattr(err, "strerror", None) else str(err)


def _is_own_lock(path):
    """``path`` is a lock file this program writes (empty, or ``process ...``)."""
    if path.is_symlink() or not path.is_file() or path.stat().st_size > 200:
        return False
    text = path.read_bytes()
    return text == b"" or text.startswith(b"process ")


def read_manifest(folder):
    """The manifest of ``folder`` (a dict), or None without one.

    Raises
    ------
    FolderError
        When the manifest is a link, too big, not JSON or not of this program.
    """
    path = Path(folder) / MARKER
    if not path.exists() and not path.is_symlink():
        return None
    problem = None
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
        with os.fdopen(fd, "rb") as handle:
            data = handle.read(_MAX_MANIFEST + 1)
        manifest = json.loads(data.decode("utf-8")) if len(data) <= _MAX_MANIFEST else None
    except (OSError, UnicodeDecodeError, ValueError) as err:
        problem, manifest = _describe(err), None
    if problem is None and not (
            isinstance(manifest, dict) and manifest.get("program") == "skfem-rkpm"
            and manifest.get("kind") in WRITES and isinstance(manifest.get("files"), list)
            and all(isinstance(f, str) and _relative(f) is not None
                    for f in manifest["files"])):
        problem = "not a manifest of skfem-rkpm"
    if problem is not None:
        raise FolderError(f"--out {folder}: its {MARKER} cannot be read ({problem}); "
                          f"choose another --out, or remove {MARKER} if the folder is yours")
    return manifest


def _relative(name):
    """``name`` as a clean relative POSIX path inside a folder, or None."""
    path = PurePosixPath(name.rstrip("/"))
    if path.is_absolute() or not path.parts or ".." in path.parts or "." in path.parts:
        return None
    return str(path) + ("/" if name.endswith("/") else "")


def _looks_like_an_old_run(path):
    scene = path / "scene.toml"
    try:
        return (path / "status.txt").is_file() and scene.is_file() and \
            scene.read_text(encoding="utf-8", errors="replace").startswith("# resolved scene")
    except OSError:
        return False


class RunFolder:
    """The output folder of one run (use as a context manager: holds the lock).

    Parameters
    ----------
    path : str or Path
        The folder; created if missing.
    kind : {"run", "compare", "sweep"}
        What the folder holds; a folder of another kind is refused.
    mode : {"new", "resume", "add"}
        ``new``: a run starts (call :meth:`clear` to remove an earlier run's
        files); ``resume``: continue the run there (a folder that is not
        empty must be a run folder); ``add``: write more files into a run
        folder (figures after the run).
    overwrite : bool
        Also write into a folder that is not empty and not the program's
        (mode ``new``): the program's files go beside the ones there; a file
        at a name it writes is still refused.
    writes : sequence of str, optional
        The names and patterns the run may write (default :data:`WRITES`
        of ``kind``).
    """

    def __init__(self, path, kind="run", mode="new", overwrite=False, writes=None):
        if kind not in WRITES or mode not in ("new", "resume", "add"):
            raise ValueError(f"kind {kind!r} or mode {mode!r} unknown")
        self.path = Path(path)
        self.kind, self.mode, self.overwrite = kind, mode, overwrite
        self.writes = tuple(WRITES[kind] if writes is None else writes)
        self.files = []
        self._lock = None

    # -- taking the folder ------------------------------------------------------

    def _refuse(self, why, out=True):
        raise FolderError(f"--out {self.path}: {why}" if out else why)

    def check(self):
        """What the folder holds (None: nothing yet; else its manifest); raises
        FolderError when it may not be used.  Writes nothing (a command
        checks its folder so before the work starts)."""
        path = self.path
        if path.is_symlink():
            self._refuse(f"is a symbolic link (to {os.readlink(path)}); a run writes "
                         f"only into a real folder: give the folder itself or choose "
                         f"another --out")
        if not path.exists():
            if self.mode == "add":
                self._refuse("does not exist; nothing to add to")
            return None
        if not path.is_dir():
            self._refuse("is a file, not a folder; choose another --out")
        manifest = read_manifest(path)
        if manifest is not None:
            if manifest["kind"] != self.kind:
                self._refuse(f"is the {manifest['kind']} folder of skfem-rkpm, not a "
                             f"{self.kind} folder; choose another --out")
            self._conflicts(set(manifest["files"]))
            return manifest
        try:
            entries = [e for e in os.listdir(path)
                       if not (e == LOCK and _is_own_lock(path / LOCK))]
        except OSError as err:
            self._refuse(f"cannot be read ({_describe(err)}); choose another --out")
        if not entries:
            if self.mode == "add":
                self._refuse(f"is not a {self.kind} folder of skfem-rkpm")
            return None
        hint = (" (it looks like a run folder of an earlier skfem-rkpm, which did not "
                "list its files: delete it to run there again)"
                if _looks_like_an_old_run(path) else "")
        if self.mode == "resume":
            self._refuse(f"is not a run folder of skfem-rkpm (it has no {MARKER}), so "
                         f"there is nothing to resume{hint}; run without --resume into "
                         f"another --out")
        if self.mode == "add" or not self.overwrite:
            self._refuse(f"is not empty and not a {self.kind} folder of skfem-rkpm (it "
                         f"has no {MARKER}){hint}; its files are left alone: choose "
                         f"another --out, or pass --overwrite to write the run's files "
                         f"beside them")
        self._conflicts(set())
        return None

    def _conflicts(self, listed):
        """FolderError naming the files at names the run writes that the
        program did not write (not in ``listed``)."""
        found = []
        for pattern in self.writes:
            parent, _, name = pattern.rpartition("/")
            folder = self.path / parent if parent else self.path
            if not folder.is_dir() or folder.is_symlink():
                continue
            for entry in sorted(os.listdir(folder)):
                rel = f"{parent}/{entry}" if parent else entry
                if not fnmatch.fnmatchcase(entry, name) or rel in listed:
                    continue
                if (folder / entry).is_dir() and not (folder / entry).is_symlink() \
                        and any(p.startswith(rel + "/") for p in self.writes):
                    continue  # a real folder the run writes into (fields/)
                found.append(rel)
        if found:
            shown = ", ".join(found[:5]) + (f" and {len(found) - 5} more"
                                            if len(found) > 5 else "")
            many = len(found) > 1
            self._refuse(f"holds {shown}, not written by skfem-rkpm, at "
                         f"{'names' if many else 'a name'} the run writes; "
                         f"{'they are' if many else 'it is'} never replaced (not even "
                         f"with --overwrite): move or rename {'them' if many else 'it'}, "
                         f"or choose another --out")

    def __enter__(self):
        existed = self.path.exists()
        self.check()
        lock = self.path / LOCK
        had_lock = lock.exists() or lock.is_symlink()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        except OSError as err:
            self._refuse(f"cannot write there ({_describe(err)}); choose another --out")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
            os.close(fd)
            self._refuse(f"{self.path} is in use by another run ({owner or 'unknown'}); "
                         f"wait for it to finish or choose another --out", out=False)
        try:
            manifest = self.check()  # again, now that no other run can change it
        except FolderError:
            os.close(fd)
            if not had_lock:
                lock.unlink(missing_ok=True)
            if not existed:
                with contextlib.suppress(OSError):
                    self.path.rmdir()
            raise
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
        self._lock = fd
        self.files = list(manifest["files"]) if manifest is not None else []
        self.claim(LOCK)
        return self

    def __exit__(self, *exc):
        if self._lock is not None:
            os.close(self._lock)  # releases the flock; the file stays (harmless)
            self._lock = None

    # -- the files of the program -----------------------------------------------

    def _name(self, path):
        path = Path(path)
        if path.is_absolute() or path.parts[:len(self.path.parts)] == self.path.parts:
            path = Path(os.path.relpath(path, self.path))
        name = _relative(path.as_posix())
        if name is None:
            raise ValueError(f"{path} is not inside the run folder {self.path}")
        return name

    def claim(self, *paths, folder=False):
        """Enter ``paths`` (inside the folder) in the manifest before they are
        written; ``folder=True``: they are folders the program creates."""
        new = [self._name(p) + ("/" if folder else "") for p in paths]
        new = [n for n in new if n not in self.files]
        if new:
            self.files += new
            self._write_manifest()

    def owns(self, path):
        """``path`` is a file the program wrote here (the manifest lists it)."""
        return self._name(path) in self.files

    def _write_manifest(self):
        write_atomic(self.path / MARKER, json.dumps(
            {"program": "skfem-rkpm", "format": _FORMAT, "kind": self.kind,
             "files": self.files}, indent=0) + "\n")

    def _inside(self, name):
        """The path of a listed name if every folder above it is a real folder
        of the run (never through a link), else None."""
        path = self.path
        for part in PurePosixPath(name.rstrip("/")).parts[:-1]:
            path = path / part
            if path.is_symlink() or not path.is_dir():
                return None
        return self.path / name.rstrip("/")

    def clear(self):
        """Remove what an earlier run wrote here (the files the manifest lists;
        its folders when they are empty) and nothing else."""
        kept = [LOCK]
        for name in self.files:
            path = self._inside(name)
            if name == LOCK or name.endswith("/") or path is None:
                continue
            if path.is_symlink() or path.is_file():
                path.unlink()
            elif path.exists():  # a folder now at a file's name: not the run's
                continue
        for name in sorted((n for n in self.files if n.endswith("/")), key=len,
                           reverse=True):
            path = self._inside(name)
            if path is not None and path.is_dir() and not path.is_symlink():
                try:
                    path.rmdir()
                except OSError:  # holds files of someone else: it stays
                    kept.append(name)
        self.files = kept
        self._write_manifest()

    def remove_temporaries(self):
        """Remove the temporary files a killed run left (``.NAME.PID.tmp`` of
        the files the manifest lists, and of the manifest); the lock
        guarantees no one writes them."""
        for name in [MARKER, *self.files]:
            path = self._inside(name)
            if path is None or name.endswith("/") or not path.parent.is_dir():
                continue
            pattern = re.compile(rf"\.{re.escape(path.name)}\.\d+\.tmp")
            for tmp in path.parent.glob(f".{path.name}.*.tmp"):
                if pattern.fullmatch(tmp.name) and not tmp.is_dir():
                    tmp.unlink(missing_ok=True)

    def write(self, name, data):
        """Claim ``name`` and write ``data`` (str or bytes) to it atomically."""
        self.claim(name)
        return write_atomic(self.path / name, data)

    def status(self, text):
        """Replace ``status.txt``."""
        self.write("status.txt", text.rstrip("\n") + "\n")


@contextlib.contextmanager
def status_on_failure(folder, interrupted):
    """Write ``status.txt`` of ``folder`` (a :class:`RunFolder`, or ``None``
    for no folder) when the block ends by an exception, then re-raise it:
    ``interrupted()`` (called then, so it can name how far the run got) on
    Ctrl-C or SIGTERM (``KeyboardInterrupt``), ``failed: <type>: <text>``
    on any other exception."""
    try:
        yield
    except KeyboardInterrupt:
        if folder is not None:
            folder.status(interrupted())
        raise
    except BaseException as err:
        if folder is not None:
            folder.status(f"failed: {type(err).__name__}: {err}")
        raise
