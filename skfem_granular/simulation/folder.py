"""An output folder belongs to one run.

A run writes ``history.csv``, ``summary.json``, ``checkpoint.npz`` (and the
one before it, ``checkpoint.prev.npz``), the PVD indices and their VTU frames
into its output folder. Before it writes
anything, :class:`OutputFolder` makes sure that the folder holds no other
run's files (:func:`run_files`), unless the run was told to replace them
(``overwrite``: the old run's files are removed first) or to continue them
(``resume``: the files belong to the checkpoint's run). Files that are not a
run's (a scene file, notes) are left alone and do not count. A study's folder
(marked by :data:`STUDY_MARKER`) is never a run's, nor a run's folder a
study's.

While a run (or a study, :mod:`skfem_granular.studies`) writes, its folder
holds a lock file, :data:`LOCK_NAME`, with the holder's process id and host
name (JSON), :class:`FolderLock`. The lock file is always complete or absent:
it is written whole under a temporary name and hard-linked onto
:data:`LOCK_NAME` (which fails when a lock is there), so a process killed
at any moment leaves no half-written lock. A second writer into the same
folder is refused with one line naming the holder while that process is
alive. A stale lock is taken over: one whose process is gone (killed with
SIGKILL, say) on this host, and one that cannot be read as a lock (empty or
garbled, as an earlier version of this package could leave it when killed
between creating and writing it). A lock from another host is never taken
over (its process cannot be seen from here): remove the file by hand once
that run is known to be gone. Left-overs of killed writers (``.partial-*``,
and the lock's own temporary files) are removed when a run takes the folder.
"""

from __future__ import annotations

import errno
import json
import os
import re
import secrets
import socket
from pathlib import Path

from ..io import remove_partial_files

#: The lock file a running simulation (or study) keeps in its output folder.
LOCK_NAME = ".skfem-granular.lock"
#: Files of a run (besides its frames, :data:`FRAME_PATTERN`).
RUN_FILE_NAMES = ("history.csv", "summary.json", "checkpoint.npz", "checkpoint.prev.npz",
                  "checkpoint.pkl", "flow.pvd", "particles.pvd")
#: The VTU frames a run writes.
FRAME_PATTERN = re.compile(r"^(flow|particles)_\d{5}\.vtu$")
#: The file that marks a study's folder (:mod:`skfem_granular.studies`), and its format.
STUDY_MARKER = "study.json"
STUDY_FORMAT = "skfem-granular study"
#: The lock's temporary files: ``<LOCK_NAME>.<host>.<pid>.<random>.tmp`` (a lock being
#: written) and ``.stale`` (a stale lock being taken over).
LOCK_TEMP_PATTERN = re.compile(re.escape(LOCK_NAME)
                               + r"\.(?P<host>.+)\.(?P<pid>\d+)\.[0-9a-f]+\.(tmp|stale)$")
#: The tokens of the locks this process holds (a lock with this process's id and another
#: token was left by an earlier process that had the same id: a restarted container).
_HELD: set[str] = set()
#: errno values of file systems that cannot make hard links.
_NO_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS, errno.EMLINK,
             errno.EXDEV}


class FolderInUseError(ValueError):
    """The output folder holds another run's files, or a live run's lock."""


def run_files(directory) -> list[Path]:
    """The files of a run in ``directory`` (history, summary, checkpoint, PVD and frames)."""
    d = Path(directory)
    if not d.is_dir():
        return []
    return sorted(p for p in d.iterdir()
                  if (p.name in RUN_FILE_NAMES or FRAME_PATTERN.match(p.name)) and p.is_file())


def study_in(directory) -> dict | None:
    """The study whose output ``directory`` holds (its :data:`STUDY_MARKER`), or ``None``."""
    try:
        info = json.loads((Path(directory) / STUDY_MARKER).read_text())
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) and info.get("format") == STUDY_FORMAT else None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


class FolderLock:
    """The lock file of a folder: one live writer at a time.

    Parameters
    ----------
    directory : str or Path
    what : str
        What holds the lock, named in a refusal (``"simulation"``, ``"study"``).

    Examples
    --------
    >>> lock = FolderLock(tmp, "study")      # doctest: +SKIP
    >>> lock.acquire()                       # FolderInUseError when a live process holds it
    >>> lock.release()
    """

    def __init__(self, directory, what: str = "simulation"):
        self.directory = Path(directory)
        self.what = what
        self.token: str | None = None  # ours, while held

    @property
    def path(self) -> Path:
        return self.directory / LOCK_NAME

    @property
    def held(self) -> bool:
        return self.token is not None

    def _read(self, path=None):
        """``(holder, identity)`` of the lock at ``path`` (default: the lock), or ``None``.

        ``holder`` is its JSON (``pid``, ``host``, ...) or ``None`` when it cannot be read
        as a lock; ``identity`` (device, inode, bytes) tells one lock file from another.
        """
        try:
            with open(path or self.path, "rb") as f:
                st = os.fstat(f.fileno())
                data = f.read(4096)
        except FileNotFoundError:
            return None
        except (PermissionError, IsADirectoryError) as exc:
            raise FolderInUseError(
                f"output folder {str(self.directory)!r}: its lock file {LOCK_NAME} cannot be "
                f"read ({exc.strerror}); remove it only if no run is writing there") from None
        try:
            info = json.loads(data.decode())
        except ValueError:
            info = None
        ok = (isinstance(info, dict) and isinstance(info.get("pid"), int)
              and isinstance(info.get("host"), str))
        return (info if ok else None), (st.st_dev, st.st_ino, data)

    def _stale(self, holder: dict | None) -> bool:
        if holder is None:  # empty or garbled: no process to wait for
            return True
        if holder["host"] != socket.gethostname():
            return False
        pid = holder["pid"]
        if pid == os.getpid():
            return holder.get("token") not in _HELD
        return not _alive(pid)

    def check(self) -> None:
        """Refuse (:class:`FolderInUseError`, one line naming the process) a live lock."""
        found = self._read()
        if found is not None and not self._stale(found[0]):
            self._refuse(found[0])

    def _refuse(self, holder: dict):
        what = holder.get("what", "simulation")
        raise FolderInUseError(
            f"output folder {str(self.directory)!r}: in use by a running {what} (pid "
            f"{holder['pid']} on {holder['host']}, lock file {LOCK_NAME}); wait for it "
            "or stop it (remove the lock file only if that process is gone)")

    def acquire(self) -> None:
        """Take the lock: a stale one is taken over, a live one refused (one line, its pid).

        Raises
        ------
        FolderInUseError
            A live process holds the lock (or it cannot be read: permissions).
        OSError
            The lock cannot be written (a full disk).
        """
        self.directory.mkdir(parents=True, exist_ok=True)
        token = secrets.token_hex(8)
        mine = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                           "what": self.what, "token": token}).encode()
        for _ in range(8):  # each round: a lock was placed or removed by another process
            found = self._read()
            if found is not None:
                if not self._stale(found[0]):
                    self._refuse(found[0])
                self._remove_stale(found[1])
                continue
            if self._place(mine):
                self.token = token
                _HELD.add(token)
                self._remove_temps()
                return
        found = self._read()
        if found is not None and found[0] is not None:
            self._refuse(found[0])
        raise FolderInUseError(f"output folder {str(self.directory)!r}: could not take the "
                               f"lock file {LOCK_NAME} (other processes keep changing it)")

    def _temp_name(self, kind: str) -> Path:
        return self.directory / (f"{LOCK_NAME}.{socket.gethostname()}.{os.getpid()}."
                                 f"{secrets.token_hex(4)}.{kind}")

    def _place(self, content: bytes) -> bool:
        """Put a lock holding ``content`` in place if there is none; whether it is ours."""
        tmp = self._temp_name("tmp")
        fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        try:
            try:
                _write_all(fd, content)
            finally:
                os.close(fd)
            try:
                os.link(tmp, self.path)  # the whole file appears at once, or not at all
            except FileExistsError:
                return False
            except OSError as exc:
                if exc.errno not in _NO_LINKS:
                    raise
                return self._place_without_links(content)
        finally:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        return self._is_mine(content)

    def _place_without_links(self, content: bytes) -> bool:
        """Where hard links cannot be made: create the lock and write it in one call (a kill
        in between leaves an empty lock, which the next run takes over)."""
        try:
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        try:
            _write_all(fd, content)
        finally:
            os.close(fd)
        return self._is_mine(content)

    def _is_mine(self, content: bytes) -> bool:
        found = self._read()
        return found is not None and found[1][2] == content

    def _remove_stale(self, identity) -> None:
        """Take the stale lock ``identity`` away: renamed aside first, so that a lock placed
        meanwhile by another process is recognised and put back, never deleted."""
        grave = self._temp_name("stale")
        try:
            os.rename(self.path, grave)
        except FileNotFoundError:  # removed by another process meanwhile
            return
        try:
            try:
                found = self._read(grave)
                other = found is not None and found[1] != identity
            except FolderInUseError:  # cannot be read: not the one judged stale
                other = True
            if other:  # a lock placed meanwhile: put it back
                try:
                    os.link(grave, self.path)
                except OSError:  # a third process holds the folder by now
                    pass
        finally:
            try:
                os.unlink(grave)
            except FileNotFoundError:
                pass

    def _remove_temps(self) -> None:
        """Remove the lock's temporary files left by killed processes on this host."""
        host = socket.gethostname()
        for name in os.listdir(self.directory):
            m = LOCK_TEMP_PATTERN.match(name)
            if m and m["host"] == host and not _alive(int(m["pid"])):
                try:
                    os.unlink(self.directory / name)
                except FileNotFoundError:
                    pass

    def release(self) -> None:
        """Remove the lock if this object holds it (and it is still its own)."""
        if self.token is None:
            return
        found = self._read()
        if found is not None and found[0] is not None and found[0].get("token") == self.token:
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass
        _HELD.discard(self.token)
        self.token = None


def _write_all(fd: int, data: bytes) -> None:
    while data:
        data = data[os.write(fd, data):]


class HeldFolder:
    """A folder held through its :attr:`lock` while a ``with`` block is open (subclasses take
    it in :meth:`acquire`)."""

    lock: FolderLock

    def acquire(self) -> None:
        raise NotImplementedError

    def release(self) -> None:
        """Remove the lock (if this object holds it)."""
        self.lock.release()

    def __enter__(self):
        self.acquire()
        return self

    def __exit__(self, *exc):
        self.release()
        return False


class OutputFolder(HeldFolder):
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
        self.lock = FolderLock(self.directory, "simulation")

    @property
    def lock_path(self) -> Path:
        return self.lock.path

    @property
    def held(self) -> bool:
        return self.lock.held

    def check(self) -> None:
        """Refuse (:class:`FolderInUseError`, one line) a folder this run may not write to."""
        self.lock.check()
        self._check_files()

    def _check_files(self) -> None:
        if self.mode == "resume":
            return
        study = study_in(self.directory)
        if study is not None:
            raise FolderInUseError(
                f"output folder {str(self.directory)!r}: holds the output of the study "
                f"{study.get('study')!r} ({STUDY_MARKER}); a run needs a folder of its own")
        if self.mode != "new":
            return
        found = run_files(self.directory)
        if found:
            names = ", ".join(p.name for p in found[:3]) + (", ..." if len(found) > 3 else "")
            raise FolderInUseError(
                f"output folder {str(self.directory)!r}: holds another run's output ({names}); "
                "use --overwrite (library: overwrite=True) to replace it, --resume DIR to "
                "continue it, or another folder")

    def acquire(self) -> None:
        """Check the folder, take the lock, clean up left-overs (and the old run: overwrite)."""
        self.check()
        self.lock.acquire()
        try:
            self._check_files()  # another run may have finished into the folder meanwhile
        except BaseException:
            self.lock.release()
            raise
        remove_partial_files(self.directory)
        if self.mode == "overwrite":
            remove_run(self.directory)
            self.mode = "resume"  # what is written from now on is this run's


def remove_run(directory) -> list[Path]:
    """Delete a run's files from ``directory`` (what ``overwrite`` does); returns them."""
    found = run_files(directory)
    for p in found:
        p.unlink()
    return found

