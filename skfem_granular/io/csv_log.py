"""A table's CSV file kept up to date while a run goes on, and reading such files back.

:class:`CSVLog` writes the header once and appends rows (flushed to the disk on
demand), the same text as :meth:`~skfem_granular.io.table.Table.to_csv` at every
flush; :func:`read_csv` reads either back.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import numpy as np

from .files import atomic_write
from .table import Table


class CSVLog:
    """A table's wide CSV file, kept up to date while rows are added.

    Opening it writes the header and the rows the table already has (one
    atomic write, so a resumed run's file starts as exactly the rows it
    resumes from; a table whose older rows are in this very file, a resumed
    run's, cuts the file after its rows instead); :meth:`flush` appends the
    rows added since, in one write, and forces them to the disk (``flush`` +
    ``os.fsync``); the table then keeps only its newest rows' particle values
    in memory (:meth:`Table.drop_written`). A process killed
    at any moment leaves a file whose complete lines are the rows up to the
    last flush (:func:`read_csv` drops a torn last line, should a kill land
    inside an append). The SHA-256 of the bytes written is kept as they are
    written (:meth:`digest`), so a checkpoint names the rows it follows
    without reading the file back.

    Parameters
    ----------
    table : Table
        The table whose rows are written (kept in memory as usual).
    path : str or Path
        The CSV file (replaced).

    Examples
    --------
    >>> log = CSVLog(history, "out/history.csv")        # doctest: +SKIP
    >>> history.append(...); log.flush()                 # doctest: +SKIP
    >>> log.close()                                      # doctest: +SKIP
    """

    def __init__(self, table: Table, path):
        self.table = table
        self.path = Path(path)
        n = len(table.rows)
        head = (",".join(table.wide_header()) + "\n").encode()
        self._sha = hashlib.sha256(head)
        self._sha_before_last = self._sha.copy()
        if table.dropped and table.file is not None and _same_file(table.file, self.path):
            self._reopen(n)
        else:
            body, last = self._lines(0, n)
            atomic_write(self.path, lambda tmp: Path(tmp).write_bytes(head + body + last))
            self._written(n, body, last)
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        table.drop_written(self.path, self.written)

    def _reopen(self, n: int) -> None:
        """Keep the file that holds the table's dropped rows: cut it after row ``n``.

        Its rows before the last are the table's (a resumed run's checkpoint verified
        them); only the last may differ (in ``t``, :class:`~skfem_granular.simulation.
        Simulation` moves it to a resumed clock), and then the file is rewritten
        atomically with the table's copy of it. The bytes are hashed as they are read.
        """
        last = self.table.wide_lines(n - 1, n).encode()
        with open(self.path, "rb") as f:
            f.readline()  # the header, hashed already
            for i in range(n - 1):
                line = f.readline()
                if not line.endswith(b"\n"):
                    raise ValueError(f"history file {str(self.path)!r}: {i} rows, fewer than "
                                     f"the {n} of its table")
                self._sha.update(line)
            before_last = f.tell()
            same = f.readline() == last
        if same:
            os.truncate(self.path, before_last + len(last))
        else:
            def write(tmp):  # the file's copy, cut before its last row, and the table's
                shutil.copyfile(self.path, tmp)
                os.truncate(tmp, before_last)
                with open(tmp, "ab") as dst:
                    dst.write(last)

            atomic_write(self.path, write)
        self._sha_before_last = self._sha.copy()
        self._sha.update(last)
        self.written = n

    def _lines(self, start: int, stop: int) -> tuple[bytes, bytes]:
        """Rows ``start:stop - 1`` and row ``stop - 1`` as bytes (empty if none)."""
        if stop <= start:
            return b"", b""
        return (self.table.wide_lines(start, stop - 1).encode(),
                self.table.wide_lines(stop - 1, stop).encode())

    def _written(self, n: int, body: bytes, last: bytes) -> None:
        """``body`` and ``last`` are in the file now, which holds ``n`` rows."""
        if last:
            self._sha.update(body)
            self._sha_before_last = self._sha.copy()
            self._sha.update(last)
        self.written = n

    def digest(self, rows: int) -> str:
        """SHA-256 (hex) of the file's bytes from its start to the end of row ``rows``.

        The header line and the first ``rows`` rows, as written; ``rows`` is the
        number of rows written or one fewer.
        """
        if rows == self.written:
            return self._sha.hexdigest()
        if rows == self.written - 1 and rows >= 0:
            return self._sha_before_last.hexdigest()
        raise ValueError(f"rows = {rows}: the digest is kept for {self.written} or "
                         f"{self.written - 1} rows (the rows written)")

    @property
    def closed(self) -> bool:
        return self._fd is None

    def flush(self) -> int:
        """Append the rows added since the last flush and sync them; returns how many."""
        if self._fd is None:
            raise ValueError(f"{str(self.path)!r}: the CSV log is closed")
        n = len(self.table.rows)
        if n > self.written:
            body, last = self._lines(self.written, n)
            view = memoryview(body + last)
            while view:
                view = view[os.write(self._fd, view):]
            self._written(n, body, last)
        os.fsync(self._fd)
        self.table.drop_written(self.path, n)
        return n

    def close(self) -> None:
        """Flush and close (again: nothing)."""
        if self._fd is None:
            return
        try:
            self.flush()
        finally:
            os.close(self._fd)
            self._fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def read_csv(path) -> dict[str, np.ndarray]:
    """The columns of a table's wide CSV file, ``{name: (T,) array}``; also while it grows.

    Only complete lines count: a last line without its newline (a run killed
    inside an append, or a file read while a flush is under way) is left out.

    Raises
    ------
    ValueError
        For a missing file, a file without a header, or a row with the wrong
        number of values.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ValueError(f"CSV file {str(path)!r}: not found") from None
    lines = text.split("\n")
    complete = lines[:-1]  # the piece after the last newline is incomplete (or empty)
    if not complete:
        raise ValueError(f"CSV file {str(path)!r}: no header line")
    head = complete[0].split(",")
    rows = []
    for i, line in enumerate(complete[1:], start=2):
        vals = line.split(",")
        if len(vals) != len(head):
            raise ValueError(f"CSV file {str(path)!r}, line {i}: {len(vals)} values, "
                             f"{len(head)} columns in the header")
        try:
            rows.append([float(v) for v in vals])
        except ValueError:
            raise ValueError(f"CSV file {str(path)!r}, line {i}: not all numbers") from None
    data = np.array(rows, dtype=float).reshape(len(rows), len(head))
    return {name: data[:, j] for j, name in enumerate(head)}
