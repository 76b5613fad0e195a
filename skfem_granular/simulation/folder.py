"""An output folder belongs to one run.

A run writes ``history.csv``, ``summary.json``, ``checkpoint.npz``, the PVD
indices and their VTU frames into its output folder. Before it writes
anything, :class:`OutputFolder` makes sure that the folder holds no other
run's files (:func:`run_files`), unless the run was told to replace them
(``overwrite``: the old run's files are removed first) or to continue them
(``resume``: the files belong to the checkpoint's run). Files that are not a
run's (a scene file, notes) are left alone and do not count.

While a run writes, the folder holds a lock file, :data:`LOCK_NAME`, with
the holder's process id and host name (JSON). A second run into the same
folder is refused with one line naming the holder while that process is
alive; a lock left by a process that is gone (killed with SIGKILL, say) on
this host is taken over. A lock from another host is never taken over (its
process cannot be seen from here): remove the file by hand once that run is
known to be gone. A lock that cannot be read as JSON (a process killed
between creating the file and writing its two fields) is treated the same
way: refused, never taken over. Left-overs of killed writers (``.partial-*``)
are removed when a run takes the folder.
"""

from __future__ import annotations

import json
import os
import re
import socket
from pathlib import Path

from ..io import remove_partial_files

#: The lock file a running simulation keeps in its output folder.
LOCK_NAME = ".skfem-granular.lock"
#: Files of a run (besides its frames, :data:`FRAME_PATTERN`).
RUN_FILE_NAMES = ("history.csv", "summary.json", "checkpoint.npz", "checkpoint.pkl",
                  "flow.pvd", "particles.pvd")
#: The VTU frames a run writes.
FRAME_PATTERN = re.compile(r"^(flow|particles)_\d{5}\.vtu$")


class FolderInUseError(ValueError):
    """The output folder holds another run's files, or a live run's lock."""


def run_files(directory) -> list[Path]:
    """The files of a run in ``directory`` (history, summary, checkpoint, PVD and frames)."""
    d = Path(directory)
    if not d.is_dir():
        return []
    return sorted(p for p in d.iterdir()
                  if (p.name in RUN_FILE_NAMES or FRAME_PATTERN.match(p.name)) and p.is_file())


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


class OutputFolder:
    """The output folder of one run: ownership checks, the lock, clean-up.

    Parameters
    ----------
    directory : str or Path
    mode : {"new", "overwrite", "resume"}
        ``"new"`` refuses a folder with another run's files; ``"overwrite"``
        removes them when the folder is taken; ``"resume"`` continues them.

    Examples
    --------
    >>> with OutputFolder(tmp, "new"):      # doctest: +SKIP
    ...     write_the_run()
    """

    def __init__(self, directory, mode: str = "new"):
        if mode not in ("new", "overwrite", "resume"):
            raise ValueError(f"mode = {mode!r}: must be 'new', 'overwrite' or 'resume'")
        self.directory = Path(directory)
        self.mode = mode
        self.held = False

    @property
    def lock_path(self) -> Path:
        return self.directory / LOCK_NAME

    def check(self) -> None:
        """Refuse (:class:`FolderInUseError`, one line) a folder this run may not write to."""
        self._check_lock()
        if self.mode != "new":
            return
        found = run_files(self.directory)
        if found:
            names = ", ".join(p.name for p in found[:3]) + (", ..." if len(found) > 3 else "")
            raise FolderInUseError(
                f"output folder {str(self.directory)!r}: holds another run's output ({names}); "
                "use --overwrite (library: overwrite=True) to replace it, --resume DIR to "
                "continue it, or another folder")

    def _holder(self) -> dict | None:
        """The lock's holder (``pid``, ``host``), or None when there is no lock."""
        try:
            text = self.lock_path.read_text()
        except FileNotFoundError:
            return None
        except OSError:
            return {"pid": None, "host": None}
        try:
            info = json.loads(text)
        except ValueError:
            info = None
        return info if isinstance(info, dict) else {"pid": None, "host": None}

    def _check_lock(self) -> None:
        holder = self._holder()
        if holder is None or self._stale(holder):
            return
        raise FolderInUseError(
            f"output folder {str(self.directory)!r}: in use by a running simulation (pid "
            f"{holder.get('pid')} on {holder.get('host')}, lock file {LOCK_NAME}); wait for it "
            "or stop it (remove the lock file only if that run is gone)")

    @staticmethod
    def _stale(holder: dict) -> bool:
        pid = holder.get("pid")
        if holder.get("host") != socket.gethostname() or not isinstance(pid, int):
            return False
        return pid != os.getpid() and not _alive(pid)

    def acquire(self) -> None:
        """Check the folder, take the lock, clean up left-overs (and the old run: overwrite)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        me = json.dumps({"pid": os.getpid(), "host": socket.gethostname()})
        for _ in range(2):
            self.check()
            try:
                fd = os.open(self.lock_path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:  # stale (check() saw its holder gone), or just taken
                self._check_lock()  # by another run starting now: refused
                self.lock_path.unlink(missing_ok=True)
                continue
            with os.fdopen(fd, "w") as f:
                f.write(me)
            self.held = True
            break
        else:
            self._check_lock()
            raise FolderInUseError(f"output folder {str(self.directory)!r}: could not take the "
                              f"lock file {LOCK_NAME}")
        remove_partial_files(self.directory)
        if self.mode == "overwrite":
            remove_run(self.directory)
            self.mode = "resume"  # what is written from now on is this run's

    def release(self) -> None:
        """Remove the lock (if this object holds it)."""
        if self.held:
            self.lock_path.unlink(missing_ok=True)
            self.held = False

    def __enter__(self):
        self.acquire()
        return self

    def __exit__(self, *exc):
        self.release()
        return False


def remove_run(directory) -> list[Path]:
    """Delete a run's files from ``directory`` (what ``overwrite`` does); returns them."""
    found = run_files(directory)
    for p in found:
        p.unlink()
    return found

