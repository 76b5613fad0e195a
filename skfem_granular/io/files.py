"""Files written so that a run killed at any moment leaves each one complete.

Every file goes to a temporary name in the target directory and is then
renamed onto its final name (an atomic operation on POSIX file systems). The
temporary names start with :data:`PARTIAL_PREFIX` (``.partial-``): a run
killed while writing leaves at most such a hidden file next to the complete
ones, and :func:`remove_partial_files` (called when a run resumes) deletes it.
A file may keep its previous version under a second name (``keep``,
:func:`keep_previous`: a checkpoint and the one before it).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import os
import secrets
import shutil
import tempfile
from pathlib import Path

#: Prefix of the temporary files :func:`atomic_path` renames onto their final names.
PARTIAL_PREFIX = ".partial-"
#: errno values of file systems that cannot make hard links (a copy is made instead).
_NO_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS, errno.EMLINK,
             errno.EXDEV}


def check_writable(path, *, create: bool = True) -> None:
    """Refuse (``ValueError``, one line) a file path that cannot be written.

    Refuses a path that is a directory, whose parent (or nearest existing
    ancestor) is not a directory, or is not writable.

    Parameters
    ----------
    path : str or Path
    create : bool
        Create the missing parent directories; ``False`` leaves the file
        system as it is (a check before any work).
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"output path {str(path)!r}: is a directory")
    if not parent.exists():
        if not create:
            while not parent.exists() and parent != parent.parent:
                parent = parent.parent
        else:
            try:
                parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ValueError(f"output path {str(path)!r}: cannot create directory "
                                 f"({exc.strerror})") from None
    if not parent.is_dir():
        raise ValueError(f"output path {str(path)!r}: {str(parent)!r} is not a directory")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"output path {str(path)!r}: directory {str(parent)!r} is not writable")


@functools.cache
def _umask() -> int:
    """The process umask (read once: setting it to read it is not thread-safe)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path, *, fsync: bool = False, keep=None):
    """A temporary file next to ``path``, renamed onto ``path`` when the block succeeds.

    The ``with`` block writes the whole file to the yielded name (a hidden
    ``.partial-*`` file in the same directory, with ``path``'s suffix). When the
    block ends without an exception the file is renamed onto ``path``; when it
    raises, the temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or Path
        Final file name.
    fsync : bool, optional
        Also force the file's data to the disk before the rename (and the
        directory entry after it), so that the file survives a power failure
        too, not only a killed process.
    keep : str or Path, optional
        Keep the file ``path`` held until now under this name (in the same
        directory), replacing what ``keep`` held: once the new file is complete
        (and synced), before it is renamed onto ``path`` (:func:`keep_previous`).
        At every moment ``path`` names a complete file.

    Yields
    ------
    str
        The temporary file's name.

    Raises
    ------
    ValueError
        ``path`` cannot be written (:func:`check_writable`), or no temporary
        file can be made next to it.
    """
    path = Path(path)
    check_writable(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{PARTIAL_PREFIX}{path.stem}-", suffix=path.suffix,
                                   dir=path.parent)
    except OSError as exc:
        raise ValueError(f"output path {str(path)!r}: cannot write ({exc.strerror})") from None
    os.close(fd)
    try:
        yield tmp
        # mkstemp makes the file private (0600); give it the usual permissions
        os.chmod(tmp, 0o666 & ~_umask())
        if fsync:
            _fsync_path(tmp)
        if keep is not None:
            keep_previous(path, keep, fsync=fsync)
        os.replace(tmp, path)
        if fsync:
            _fsync_directory(path.parent)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def keep_previous(path, keep, *, fsync: bool = False) -> bool:
    """Make ``keep`` a second name of the file ``path`` (replacing ``keep``); whether one was.

    ``keep`` gets a hard link to ``path`` under a temporary name first, renamed onto
    ``keep``, so ``path`` stays as it was and ``keep`` is always complete (the old
    ``keep`` or the new). Where hard links cannot be made, the file is copied (and
    synced with ``fsync``) instead. Nothing happens when ``path`` does not exist.

    Parameters
    ----------
    path, keep : str or Path
        In the same directory.
    fsync : bool, optional
        Sync the directory (and a copy) to the disk.
    """
    path, keep = Path(path), Path(keep)
    if not path.is_file():
        return False
    tmp = keep.parent / f"{PARTIAL_PREFIX}{keep.stem}-{secrets.token_hex(4)}{keep.suffix}"
    try:
        try:
            os.link(path, tmp)
        except OSError as exc:
            if exc.errno not in _NO_LINKS:
                raise
            shutil.copyfile(path, tmp)
            if fsync:
                _fsync_path(tmp)
        os.replace(tmp, keep)
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)
    if fsync:
        _fsync_directory(keep.parent)
    return True


def atomic_write(path, write, *, fsync: bool = False, keep=None) -> Path:
    """Call ``write(tmp_path)`` and rename the result onto ``path``.

    Parameters
    ----------
    path : str or Path
        Final file name.
    write : callable
        ``write(tmp)`` writes the whole file to the path ``tmp`` (same suffix).
    fsync, keep : optional
        As for :func:`atomic_path`.

    Returns
    -------
    Path
        ``path``.

    Notes
    -----
    When ``write`` raises, ``path`` keeps its earlier content (or stays
    absent) and no temporary file is left behind (:func:`atomic_path`).
    """
    with atomic_path(path, fsync=fsync, keep=keep) as tmp:
        write(tmp)
    return Path(path)


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`); returns ``path``."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def save_figure(fig, path, **kwargs) -> Path:
    """Save the matplotlib figure ``fig`` to ``path`` atomically; returns ``path``.

    The format is taken from ``path``'s suffix (PNG without one); ``kwargs`` go to
    ``fig.savefig`` (``dpi``).
    """
    fmt = Path(path).suffix[1:].lower() or "png"
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))


def _fsync_path(path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_directory(directory) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # some systems cannot open directories; the rename is done anyway
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def partial_files(directory) -> list[Path]:
    """The temporary files a killed writer left in ``directory`` (``.partial-*``)."""
    d = Path(directory)
    if not d.is_dir():
        return []
    return sorted(p for p in d.iterdir() if p.name.startswith(PARTIAL_PREFIX) and p.is_file())


def remove_partial_files(directory) -> list[Path]:
    """Delete the temporary files a killed writer left in ``directory``; returns them."""
    gone = []
    for p in partial_files(directory):
        try:
            p.unlink()
            gone.append(p)
        except FileNotFoundError:
            pass
    return gone


def check_output_file(option: str, path, suffixes) -> None:
    """Refuse, naming ``option``, an output file of another suffix or that cannot be written
    (the file system is left as it is)."""
    if suffixes and Path(path).suffix.lower() not in suffixes:
        raise ValueError(f"{option} = {str(path)!r}: must end in {' or '.join(suffixes)}")
    try:
        check_writable(Path(path), create=False)
    except ValueError as exc:
        raise ValueError(f"{option} = {str(path)!r}: must be a file that can be written; "
                         f"{exc}") from None
