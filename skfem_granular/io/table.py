"""Time-series tables: one row per step, columns as arrays, CSV on disk.

:class:`Table` is the one implementation; :class:`History` is the table of a
coupled run (what :class:`~skfem_granular.simulation.Simulation` records), and
:class:`skfem_granular.dem.History` the table of a dry DEM run.
:meth:`Table.to_csv` writes a whole table atomically; a
:class:`~skfem_granular.io.csv_log.CSVLog` keeps a table's CSV file growing
while a run goes on.

A table whose rows are in such a file keeps in memory only the particle values of
its newest rows (:data:`MEMORY_BYTES` of them): the older ones are read back from
the file when a column is asked for, so a long many-grain run does not grow in
memory with its history (1000 grains: 96 kB a row).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .files import atomic_write

#: number format of every CSV value: full double precision
CSV_FORMAT = "%.17g"

#: Bytes of particle values a table keeps in memory once its rows are in its CSV file
#: (:class:`~skfem_granular.io.CSVLog`); older rows' particle values are read back from the file.
MEMORY_BYTES = 64 * 2**20


class Table:
    """Rows appended once per step: per-step values and per-particle ``(K,)`` arrays.

    Subclasses name their columns in :attr:`STEP_COLUMNS` and
    :attr:`PARTICLE_COLUMNS`. Columns read as arrays: a step column ``(T,)``, a
    particle column ``(T, K)``.

    Rows a :class:`~skfem_granular.io.CSVLog` has written keep their particle values in
    memory only while they are among the newest :data:`MEMORY_BYTES`
    (:meth:`drop_written`); the first :attr:`dropped` rows hold their step values only,
    their particle values are read back from :attr:`file` when a column is asked for.

    Parameters
    ----------
    n_particles : int
        ``K``, the length of every per-particle value.
    """

    STEP_COLUMNS: tuple[str, ...] = ()
    PARTICLE_COLUMNS: tuple[str, ...] = ()

    def __init__(self, n_particles: int):
        self.K = int(n_particles)
        self.rows: list[dict[str, Any]] = []
        self.file: Path | None = None
        self.dropped = 0

    def add_row(self, **values) -> None:
        """Append one step; missing step values are NaN, missing particle values 0."""
        row = {c: values.get(c, np.nan) for c in self.STEP_COLUMNS}
        for c in self.PARTICLE_COLUMNS:
            row[c] = np.array(values.get(c, np.zeros(self.K)), dtype=float).reshape(self.K)
        self.rows.append(row)

    def __len__(self):
        return len(self.rows)

    def __getattr__(self, name):
        if name in type(self).STEP_COLUMNS:
            return np.array([r.get(name, np.nan) for r in self.rows])
        if name in type(self).PARTICLE_COLUMNS:
            out = np.empty((len(self.rows), self.K))
            if self.dropped:
                j, S, P = (type(self).PARTICLE_COLUMNS.index(name), len(self.STEP_COLUMNS),
                           len(self.PARTICLE_COLUMNS))
                out[:self.dropped] = self._file_values([S + k * P + j for k in range(self.K)])
            for i, r in enumerate(self.rows[self.dropped:], start=self.dropped):
                out[i] = r[name]
            return out
        raise AttributeError(name)

    def rows_kept(self) -> int:
        """How many of the newest rows keep their particle values in memory (at least 1)."""
        row_bytes = 8 * self.K * len(self.PARTICLE_COLUMNS)
        return max(1, MEMORY_BYTES // max(row_bytes, 1))

    def drop_written(self, path, written: int) -> None:
        """Forget the particle values of rows that ``path`` holds, but the newest.

        Parameters
        ----------
        path : str or Path
            The table's wide CSV file, holding (at least) its first ``written`` rows
            as :meth:`wide_lines` writes them.
        written : int
            How many rows the file holds.
        """
        stop = min(written, len(self.rows) - self.rows_kept())
        if stop <= self.dropped:
            return
        for r in self.rows[self.dropped:stop]:
            for c in self.PARTICLE_COLUMNS:
                del r[c]
        self.file, self.dropped = Path(path), stop

    def adopt(self, rows: list[dict[str, Any]], file=None) -> None:
        """Take ``rows`` as the table's rows; the first ones may hold step values only
        (their particle values in the wide CSV ``file``, as after :meth:`drop_written`)."""
        first = self.PARTICLE_COLUMNS[0] if self.PARTICLE_COLUMNS else None
        dropped = next((i for i, r in enumerate(rows) if first is None or first in r),
                       len(rows))
        if dropped and file is None:
            raise ValueError(f"rows: the first {dropped} hold no particle values and no file "
                             "holds them")
        self.rows, self.dropped = list(rows), dropped
        self.file = Path(file) if dropped else None

    def _file_values(self, columns: list[int]) -> np.ndarray:
        """Wide-layout values ``(dropped, len(columns))`` of the rows only the file holds."""
        name = f"history file {str(self.file)!r}"
        try:
            with open(self.file) as f:  # type: ignore[arg-type]
                f.readline()
                values = np.loadtxt(f, delimiter=",", usecols=columns, max_rows=self.dropped,
                                    ndmin=2, dtype=np.float64)
        except OSError as exc:
            raise ValueError(f"{name}: cannot be read ({exc.strerror}): it holds the particle "
                             f"values of the table's first {self.dropped} rows") from None
        except ValueError:
            raise ValueError(f"{name}: not a table of numbers: it holds the particle values "
                             f"of the table's first {self.dropped} rows") from None
        if values.shape != (self.dropped, len(columns)):
            raise ValueError(f"{name}: {values.shape[0]} rows, fewer than the "
                             f"{self.dropped} whose particle values it holds")
        return values

    def _file_lines(self, start: int, stop: int) -> str:
        """Lines ``start:stop`` (rows, 0-based) of the table's file, as text."""
        lines = []
        try:
            with open(self.file) as f:  # type: ignore[arg-type]
                f.readline()
                for i, line in enumerate(f):
                    if i >= stop:
                        break
                    if i >= start:
                        lines.append(line)
        except OSError as exc:
            raise ValueError(f"history file {str(self.file)!r}: cannot be read "
                             f"({exc.strerror})") from None
        if len(lines) != stop - start or not lines[-1].endswith("\n"):
            raise ValueError(f"history file {str(self.file)!r}: fewer than the {stop} rows "
                             "whose particle values it holds")
        return "".join(lines)

    def wide_header(self) -> list[str]:
        """Column names of the wide layout: step columns, then ``x_0``, ``y_0``, ... by particle."""
        return list(self.STEP_COLUMNS) + [f"{c}_{k}" for k in range(self.K)
                                          for c in self.PARTICLE_COLUMNS]

    def wide_lines(self, start: int = 0, stop: int | None = None) -> str:
        """Rows ``start:stop`` in the wide layout as CSV text (one line per row, ``\n`` ends)."""
        n = len(self.rows)
        stop = n if stop is None else min(stop + n if stop < 0 else stop, n)
        if start < self.dropped and start < stop:  # rows whose values are in the file only
            return (self._file_lines(start, min(stop, self.dropped))
                    + self.wide_lines(self.dropped, stop))
        rows = self.rows[start:stop]
        if not rows:
            return ""
        ncol = len(self.STEP_COLUMNS) + self.K * len(self.PARTICLE_COLUMNS)
        fmt = ",".join([CSV_FORMAT] * ncol) + "\n"
        out = []
        for r in rows:
            vals = [float(r.get(c, np.nan)) for c in self.STEP_COLUMNS]
            for k in range(self.K):
                vals.extend(float(r[c][k]) for c in self.PARTICLE_COLUMNS)
            out.append(fmt % tuple(vals))
        return "".join(out)

    def rows_from_wide(self, values: np.ndarray) -> list[dict[str, Any]]:
        """Rows from values in the wide layout, ``(T, columns)``: :meth:`wide_lines` read back.

        Step values become floats, particle values ``(K,)`` float arrays (what
        :meth:`add_row` keeps); ``%.17g`` text read back gives the same doubles.
        """
        values = np.asarray(values, dtype=float)
        S, P = len(self.STEP_COLUMNS), len(self.PARTICLE_COLUMNS)
        if values.ndim != 2 or values.shape[1] != S + self.K * P:
            raise ValueError(f"values of shape {values.shape}: must be (T, {S + self.K * P})")
        part = values[:, S:].reshape(len(values), self.K, P)
        rows = []
        for i in range(len(values)):
            row: dict[str, Any] = {c: float(values[i, j]) for j, c in enumerate(self.STEP_COLUMNS)}
            for j, c in enumerate(self.PARTICLE_COLUMNS):
                row[c] = part[i, :, j].copy()
            rows.append(row)
        return rows

    def to_csv(self, path, layout: str = "wide") -> None:
        """Write the table atomically, every number to full precision (``%.17g``).

        Parameters
        ----------
        path : str or Path
        layout : {"wide", "long"}
            ``"wide"``: one row per step, one column per quantity and particle
            (``x_0``, ``y_0``, ...); ``"long"``: one row per step and particle, the
            first step column and ``particle`` first, then the particle columns,
            then the other step columns.
        """
        if layout == "wide":
            text = ",".join(self.wide_header()) + "\n" + self.wide_lines()
            atomic_write(path, lambda tmp: Path(tmp).write_text(text))
            return
        head, data = self.columns(layout)

        def write(tmp):
            np.savetxt(tmp, data, delimiter=",", header=",".join(head), comments="", fmt=CSV_FORMAT)

        atomic_write(path, write)

    def columns(self, layout: str = "wide") -> tuple[list[str], np.ndarray]:
        """Column names and values ``(rows, columns)`` of the table in a layout.

        Parameters
        ----------
        layout : {"wide", "long"}
            As in :meth:`to_csv`.
        """
        T, K = len(self.rows), self.K
        steps, parts = self.STEP_COLUMNS, self.PARTICLE_COLUMNS
        if layout == "wide":
            head = self.wide_header()
            cols = ([getattr(self, c) for c in steps]
                    + [getattr(self, c)[:, k] for k in range(K) for c in parts])
        elif layout == "long":
            first, rest = steps[:1], steps[1:]
            head = list(first) + ["particle"] + list(parts) + list(rest)
            cols = ([np.repeat(getattr(self, c), K) for c in first]
                    + [np.tile(np.arange(K), T)]
                    + [getattr(self, c).ravel() for c in parts]
                    + [np.repeat(getattr(self, c), K) for c in rest])
        else:
            raise ValueError(f"layout = {layout!r}: must be 'wide' or 'long'")
        data = np.column_stack(cols).astype(float) if T else np.zeros((0, len(head)))
        return head, data

    def to_pandas(self, layout: str = "long"):
        """The table as a :class:`pandas.DataFrame` (pandas: the ``pandas`` extra).

        Parameters
        ----------
        layout : {"long", "wide"}
            ``"long"`` (default, tidy): one row per step and particle, with an integer
            ``particle`` column; ``"wide"``: one row per step, columns ``x_0``, ``y_0``, ...
            as in :meth:`to_csv`.
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_pandas needs pandas: pip install 'skfem-granular[pandas]' "
                              "(or pip install pandas)") from None
        head, data = self.columns(layout)
        frame = pd.DataFrame(data, columns=head)
        if "particle" in frame:
            frame["particle"] = frame["particle"].astype(int)
        return frame


class History(Table):
    """The per-step table of a coupled (or dry) run.

    Attributes: ``t``, ``dt``, ``iterations``, ``fluid_energy``, ``error``
    (the local error estimate of adaptive runs, NaN otherwise) ``(N,)`` and for
    each particle column a ``(N, K)`` array: positions ``x``, ``y``, ``angle``,
    velocities ``vx``, ``vy``, ``omega``, accelerations ``ax``, ``ay``, fluid
    forces ``Fx``, ``Fy``, ``torque`` and contact counts.
    """

    STEP_COLUMNS = ("t", "dt", "iterations", "fluid_energy", "error")
    PARTICLE_COLUMNS = ("x", "y", "angle", "vx", "vy", "omega", "ax", "ay", "Fx", "Fy",
                        "torque", "contacts")

    def append(self, t: float, dt: float, iterations: int, fluid_energy: float = float("nan"),
               error: float = float("nan"), **particle):
        """Add one step; ``particle`` holds ``(K,)`` arrays named as :attr:`PARTICLE_COLUMNS`.

        ``fluid_energy`` is the fluid's kinetic energy ``rho u.M u / 2`` (J per unit depth).
        """
        self.add_row(t=t, dt=dt, iterations=iterations, fluid_energy=float(fluid_energy),
                     error=float(error), **particle)
