"""The history a checkpoint follows: ``history.csv`` holds the rows, the checkpoint their
count, a checksum of the file's bytes and the last row; a resume reads them back, verifies
and truncates (format 4), or reads the rows a format-3 checkpoint held itself."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np

from ..io import History
from .checkpoint_checks import check_array, check_count, fail

#: The file the rows are in (in the run's output folder).
HISTORY_FILENAME = "history.csv"

def _step_value(v):
    """A step column's value as the row held it: an int stays an int, the rest floats."""
    if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
        return int(v)
    return float(v)


def last_row(hist: History, k: int) -> dict | None:
    """Row ``k`` (the last a checkpoint after step ``k`` follows), or None for ``k = 0``."""
    if k == 0:
        return None
    r = hist.rows[k - 1]
    return {"step": {c: _step_value(r.get(c, np.nan)) for c in hist.STEP_COLUMNS},
            "particle": {c: np.array(r[c], dtype=float).reshape(hist.K)
                         for c in hist.PARTICLE_COLUMNS}}


def history_digest(sim, k: int) -> str:
    """SHA-256 of ``history.csv`` from its start to the end of row ``k - 1``.

    Taken from the run's live history file (:class:`~skfem_granular.io.CSVLog`,
    flushed first if it lags), which keeps the digest as it writes; with no live
    file (a checkpoint written after the run), from the rows as that file holds them.
    """
    rows = max(k - 1, 0)
    log = getattr(getattr(sim, "_output", None), "log", None)
    if log is not None and not log.closed:
        if log.written < k:
            log.flush()
        if log.written == k:
            return log.digest(rows)
    hist = sim.history
    text = ",".join(hist.wide_header()) + "\n" + hist.wide_lines(0, rows)
    return hashlib.sha256(text.encode()).hexdigest()


def history_rows(d, where: str, n_particles: int) -> list:
    """The rows of a version 3 checkpoint, which held them all."""
    def fail(path, problem):
        raise ValueError(f"{where}: {path}: {problem}")

    if not isinstance(d, dict) or set(d) != {"particles", "step", "particle"}:
        fail("history", "must hold 'particles', 'step' and 'particle' (and nothing else)")
    if d["particles"] != n_particles:
        fail("history.particles", f"= {d['particles']!r}: must be {n_particles} (the scene's "
                                  "particles)")
    for name, cols in (("step", History.STEP_COLUMNS), ("particle", History.PARTICLE_COLUMNS)):
        got = d[name]
        if not isinstance(got, dict) or set(got) != set(cols):
            extra = sorted(set(got) - set(cols)) if isinstance(got, dict) else []
            what = f"unknown column {extra[0]!r}" if extra else "columns missing"
            fail(f"history.{name}", f"{what} (columns: {', '.join(cols)})")
    T: int | None = None
    for c in History.STEP_COLUMNS:
        a = d["step"][c]
        if not (isinstance(a, np.ndarray) and a.ndim == 1):
            fail(f"history.step.{c}", "must be a 1-D array")
        T = a.shape[0] if T is None else T
        if a.shape != (T,):
            fail(f"history.step.{c}", f"shape {a.shape}: must be ({T},) like history.step.t")
    assert T is not None  # History has step columns
    for c in History.PARTICLE_COLUMNS:
        a = d["particle"][c]
        if not (isinstance(a, np.ndarray) and a.shape == (T, n_particles)
                and a.dtype == np.float64):
            shape = getattr(a, "shape", None)
            fail(f"history.particle.{c}", f"shape {shape}: must be a ({T}, {n_particles}) "
                                          "float array")
    t = d["step"]["t"]
    if T and not np.all(np.isfinite(t)):
        fail("history.step.t", "contains NaN or inf (must be finite)")
    rows = []
    for i in range(T):
        row = {}
        for c in History.STEP_COLUMNS:
            v = d["step"][c][i]
            row[c] = int(v) if d["step"][c].dtype == np.int64 else float(v)
        for c in History.PARTICLE_COLUMNS:
            row[c] = d["particle"][c][i].copy()
        rows.append(row)
    return rows


_SHA256 = re.compile(r"^[0-9a-f]{64}$")


def check_history(d, where: str, K: int) -> None:
    """A version 4 checkpoint's history entry: the rows it follows, their digest, the last."""
    if not isinstance(d, dict) or set(d) != {"rows", "sha256", "last"}:
        fail(where, "history", "must hold 'rows', 'sha256' and 'last' (and nothing else)")
    check_count(where, "history.rows", d["rows"])
    if not (isinstance(d["sha256"], str) and _SHA256.match(d["sha256"])):
        fail(where, "history.sha256", "must be 64 hexadecimal digits (lower case)")
    last = d["last"]
    if d["rows"] == 0 or last is None:
        if not (d["rows"] == 0 and last is None):
            fail(where, "history.last", "must be None exactly when history.rows is 0")
        return
    if not isinstance(last, dict) or set(last) != {"step", "particle"}:
        fail(where, "history.last", "must hold 'step' and 'particle' (and nothing else)")
    for name, cols in (("step", History.STEP_COLUMNS), ("particle", History.PARTICLE_COLUMNS)):
        got = last[name]
        if not isinstance(got, dict) or set(got) != set(cols):
            fail(where, f"history.last.{name}", f"must hold the columns {', '.join(cols)}")
    for c, v in last["step"].items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            fail(where, f"history.last.step.{c}", f"= {v!r}: must be a number")
    if not np.isfinite(last["step"]["t"]):
        fail(where, "history.last.step.t", "must be a finite number")
    for c, a in last["particle"].items():
        check_array(where, f"history.last.particle.{c}", a, (K,))


def _numbers(fields: list[bytes], n: int, name: str, i: int) -> list[float]:
    """The ``n`` numbers of row ``i`` (0-based) of a history file, from its fields."""
    try:
        if len(fields) != n:
            raise ValueError
        return [float(v) for v in fields]
    except ValueError:
        raise ValueError(f"{name}: row {i + 1}: not {n} numbers") from None


def history_from_file(directory: Path, d: dict, K: int, where: str) -> list:
    """The rows a version 4 checkpoint follows, read back from ``history.csv`` and checked.

    The file must hold at least ``d["rows"]`` complete rows, its bytes up to the row
    before the last must have the checkpoint's SHA-256, and that last row must be the
    checkpoint's copy but for its time (see the module notes); the checkpoint's copy
    is the one used. The file is read a row at a time; rows older than the ones a
    table keeps in memory (:meth:`~skfem_granular.io.Table.rows_kept`) come back with
    their step values only (:meth:`~skfem_granular.io.Table.adopt` them with the file).
    """
    path = directory / HISTORY_FILENAME
    name = f"history {str(path)!r}"
    k = d["rows"]
    hist = History(K)
    head = (",".join(hist.wide_header()) + "\n").encode()
    full_from = max(k - hist.rows_kept(), 0)  # rows from here on keep their particle values
    ncol = len(hist.wide_header())
    sha, steps, values = hashlib.sha256(head), [], np.zeros((max(k - 1 - full_from, 0), ncol))
    S = len(hist.STEP_COLUMNS)
    try:
        with open(path, "rb") as f:
            if f.readline() != head:
                raise ValueError(f"{name}: its header line is not the one of {where} (the "
                                 f"columns of a run of K = {K} particles)")
            if k == 0:
                return []
            for i in range(k):
                line = f.readline()
                if not line.endswith(b"\n"):
                    raise ValueError(f"{name}: {i} complete rows, fewer than the {k} {where} "
                                     "follows (the file was cut short)")
                if i == k - 1:
                    theirs = line[:-1].split(b",")
                    break
                sha.update(line)
                if i >= full_from:
                    values[i - full_from] = _numbers(line[:-1].split(b","), ncol, name, i)
                else:
                    steps.append(_numbers(line.split(b",", S)[:S], S, name, i))
    except FileNotFoundError:
        raise ValueError(f"{name}: not found ({where} keeps its {k} rows there)") from None
    except OSError as exc:
        raise ValueError(f"{name}: cannot be read ({exc.strerror})") from None
    if sha.hexdigest() != d["sha256"]:
        what = ("header line" if k == 1 else "header and row 1" if k == 2
                else f"header and rows 1-{k - 1}")
        raise ValueError(f"{name}: the bytes of its {what} are not the ones {where} follows "
                         f"(SHA-256 {sha.hexdigest()[:16]}..., the checkpoint's "
                         f"{d['sha256'][:16]}...): the file was changed")
    last = dict(d["last"]["step"])
    last.update({c: a.copy() for c, a in d["last"]["particle"].items()})
    hist.rows = [last]
    mine = hist.wide_lines().rstrip("\n").encode().split(b",")
    if theirs[1:] != mine[1:]:  # the time may have moved to a resumed run's clock
        raise ValueError(f"{name}: row {k} is not the last row {where} follows (values other "
                         "than t differ): the file was changed")
    rows = [dict(zip(hist.STEP_COLUMNS, v, strict=True)) for v in steps]
    rows += hist.rows_from_wide(values)
    for c, v in d["last"]["step"].items():  # ints stay ints (the iteration counts)
        if isinstance(v, int):
            for r in rows:
                if float(r[c]).is_integer():
                    r[c] = int(r[c])
    rows.append(last)
    return rows
