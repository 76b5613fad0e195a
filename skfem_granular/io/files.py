"""Files written so that a run killed at any moment leaves each one complete.

Every file goes to a temporary name in the target directory and is then
renamed onto its final name (an atomic operation on POSIX file systems).
"""

from __future__ import annotations

import functools
import os
import tempfile
from pathlib import Path


def check_writable(path: Path) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"output path {str(path)!r}: is a directory")
    if not parent.exists():
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


def atomic_write(path, write) -> Path:
    """Call ``write(tmp_path)`` and rename the result onto ``path``.

    Parameters
    ----------
    path : str or Path
        Final file name.
    write : callable
        ``write(tmp)`` writes the whole file to the path ``tmp`` (same suffix).
    """
    path = Path(path)
    check_writable(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    except OSError as exc:
        raise ValueError(f"output path {str(path)!r}: cannot write ({exc.strerror})") from None
    os.close(fd)
    try:
        write(tmp)
        # mkstemp makes the file private (0600); give it the usual permissions
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
