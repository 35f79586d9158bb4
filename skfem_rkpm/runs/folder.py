"""A run folder: one run at a time, consistent after a crash.

* :func:`atomic_path` and :func:`write_atomic` write a new file beside the
  target and rename it over the target (``os.replace``): a reader, or a run
  killed at any moment, sees the old file or the new one, never a part;
  a symbolic link at the target is replaced, its target is never written.
* :func:`open_append` opens a file for appending, refusing a symbolic link.
* :class:`RunFolder` takes the folder's lock (``.lock``, an advisory
  ``flock`` that the system releases when the process ends, even on
  SIGKILL, so a lock left by a dead process never blocks), removes the
  outputs of an earlier run and keeps ``status.txt``.

The guarantees are for a process that is killed; data the operating system
has not yet written to the disk is lost if the machine itself goes down.
"""

import contextlib
import fcntl
import os
import shutil
import socket
from pathlib import Path

__all__ = ["FolderError", "RunFolder", "atomic_path", "write_atomic", "open_append",
           "OUTPUTS"]

#: what a run writes (removed when a new run starts in the folder); the
#: figures are those of :func:`skfem_rkpm.runs.plot.save_run_figures`
OUTPUTS = ("history.csv", "history.jsonl", "fields.xdmf", "fields", "fields.h5",
           "checkpoint.npz", "checkpoint.pkl", "status.txt", "deformed.png", "forces.png",
           "calibration.png")


class FolderError(ValueError):
    """A run folder that cannot be used (in use, not a folder, not writable)."""


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


class RunFolder:
    """The output folder of one run (use as a context manager: holds the lock).

    Parameters
    ----------
    path : str or Path
        The folder; created if missing.
    """

    def __init__(self, path):
        self.path = Path(path)
        self._lock = None

    def __enter__(self):
        if self.path.exists() and not self.path.is_dir():
            raise FolderError(f"--out {self.path}: is a file, not a folder; choose "
                              f"another --out")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        except OSError as err:
            raise FolderError(f"--out {self.path}: cannot write there ({_describe(err)}); "
                              f"choose another --out") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
            os.close(fd)
            raise FolderError(f"{self.path} is in use by another run ({owner or 'unknown'}"
                              f"); wait for it to finish or choose another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
        self._lock = fd
        return self

    def __exit__(self, *exc):
        if self._lock is not None:
            os.close(self._lock)  # releases the flock; the file stays (harmless)
            self._lock = None

    def clear(self):
        """Remove what an earlier run wrote (see :data:`OUTPUTS`)."""
        for name in OUTPUTS:
            path = self.path / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            else:
                path.unlink(missing_ok=True)

    def remove_temporaries(self):
        """Remove the temporary files a killed run left (``.NAME.PID.tmp``,
        here and in ``fields/``); the lock guarantees no one writes them."""
        for folder in (self.path, self.path / "fields"):
            if folder.is_dir() and not folder.is_symlink():
                for tmp in folder.glob(".*.tmp"):
                    tmp.unlink(missing_ok=True)

    def status(self, text):
        """Replace ``status.txt``."""
        write_atomic(self.path / "status.txt", text.rstrip("\n") + "\n")
