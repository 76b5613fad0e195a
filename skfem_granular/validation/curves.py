"""Published curves as digitised package data, and how a run is compared with them.

A digitised curve is one JSON file ``curve_<name>.json`` in
:mod:`skfem_granular.validation_data` (plain numbers with their provenance; no
code from the source). Format::

    {
      "curve": "glowinski2001_settling_vy",
      "status": "digitised",
      "description": "vertical velocity of the single settling disk, FEM",
      "x": "t",
      "columns": {
        "t":  {"unit": "s",    "values": [0.0, 0.05, ...]},
        "vy": {"unit": "cm/s", "values": [0.0, -1.2, ...]}
      },
      "source": {
        "paper": "Glowinski, Pan, Hesla, Joseph, Periaux, J. Comput. Phys. 169 (2001)",
        "figure": "the figure the numbers were read from",
        "repository": "owner/name",
        "file": "path/in/the/repository.csv",
        "commit": "40 hex digits or null",
        "notes": "how the numbers were read or converted"
      },
      "setup": {"scene": "settling_disk_channel", "notes": "..."}
    }

Every column is converted to SI by its ``unit`` (:data:`UNITS`, or a unit the file
defines: ``"units": {"tref": {"value": 0.025474, "unit": "s"}}`` for curves in
reference units); ``x`` names the abscissa column, strictly increasing.
``source.paper``, ``source.repository`` and ``source.file`` are required.
:func:`load_curve` reads a curve by name (or a path, to check a file before adding it).

Comparisons (plain arrays, tested on synthetic data with known answers):
:func:`l2_difference` (the L2 difference of two piecewise-linear curves over their
common interval, exact for piecewise-linear data), :func:`fall_positions`
(a height history from a velocity history), :func:`time_to_floor` (when a height
history first reaches a given height) and :func:`time_down` (when the speed has
dropped below a fraction of its maximum after it).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

import numpy as np

__all__ = ["UNITS", "Curve", "CurveDifference", "available_curves", "compare_settling",
           "fall_positions", "l2_difference", "load_curve", "time_down", "time_to_floor"]

#: Units a column may be given in, and their factor to SI.
UNITS = {"s": 1.0, "ms": 1e-3, "m": 1.0, "cm": 1e-2, "mm": 1e-3, "m/s": 1.0,
         "cm/s": 1e-2, "mm/s": 1e-3, "rad": 1.0, "deg": np.pi / 180.0, "1": 1.0}

PREFIX = "curve_"
REQUIRED_SOURCE = ("paper", "repository", "file")


@dataclass(frozen=True)
class Curve:
    """A digitised curve: SI columns and where the numbers come from.

    Attributes
    ----------
    name : str
    x : str
        The abscissa column's name.
    columns : dict of str to ndarray
        Every column in SI units, the same length, ``columns[x]`` strictly increasing.
    source, setup : dict
        Provenance (``paper``, ``repository``, ``file``, ...) and the set-up it belongs to.
    """

    name: str
    x: str
    columns: dict
    source: dict
    setup: dict = field(default_factory=dict)

    def series(self, column: str) -> tuple[np.ndarray, np.ndarray]:
        """``(x values, column values)``, SI."""
        if column not in self.columns or column == self.x:
            others = ", ".join(k for k in self.columns if k != self.x)
            raise ValueError(f"curve {self.name}: no column {column!r}; columns: {others}")
        return self.columns[self.x], self.columns[column]


@dataclass(frozen=True)
class CurveDifference:
    """The L2 difference of a curve from a reference over ``[x0, x1]``.

    ``l2`` is ``sqrt(int (y - y_ref)^2 dx / (x1 - x0))`` (a root-mean-square, in the
    curve's units), ``relative`` is ``sqrt(int (y - y_ref)^2 dx / int y_ref^2 dx)``,
    ``max_abs`` the largest ``|y - y_ref|`` at the sample points of either.
    """

    l2: float
    relative: float
    max_abs: float
    x0: float
    x1: float


def available_curves() -> list[str]:
    """Names of the digitised curves shipped as package data."""
    from ..validation_data import available

    return [n[len(PREFIX):] for n in available() if n.startswith(PREFIX)]


def _fail(where: str, msg: str) -> NoReturn:
    raise ValueError(f"{where}: {msg}")


def _units(where: str, defined) -> dict:
    """:data:`UNITS` and the file's own units (``{"name": {"value": v, "unit": u}}``)."""
    units = dict(UNITS)
    if defined is None:
        return units
    if not isinstance(defined, dict):
        _fail(where, "units must be an object {name: {\"value\": ..., \"unit\": ...}}")
    for name, d in defined.items():
        ok = (isinstance(d, dict) and isinstance(d.get("unit"), str) and d["unit"] in UNITS
              and isinstance(d.get("value"), int | float) and np.isfinite(d["value"])
              and d["value"] > 0)
        if not ok:
            _fail(where, f"units.{name} must be {{\"value\": a number > 0, \"unit\": one of "
                         f"{', '.join(UNITS)}}}")
        units[name] = float(d["value"]) * UNITS[d["unit"]]
    return units


def _column(where: str, key: str, col, units: dict) -> np.ndarray:
    if not isinstance(col, dict) or "values" not in col or "unit" not in col:
        _fail(where, f"columns.{key} must be {{\"unit\": ..., \"values\": [...]}}")
    if not isinstance(col["unit"], str) or col["unit"] not in units:
        _fail(where, f"columns.{key}.unit = {col['unit']!r}: must be one of "
                     f"{', '.join(units)}")
    try:
        v = np.asarray(col["values"], dtype=float)
    except (TypeError, ValueError):
        _fail(where, f"columns.{key}.values must be numbers")
    if v.ndim != 1 or v.size < 2 or not np.all(np.isfinite(v)):
        _fail(where, f"columns.{key}.values must be at least 2 finite numbers")
    return v * units[col["unit"]]


def curve_from_dict(data: dict, where: str = "curve") -> Curve:
    """A :class:`Curve` from the parsed JSON of the module's format; ValueError naming
    the field otherwise."""
    if not isinstance(data, dict):
        _fail(where, "must be a JSON object")
    src = data.get("source")
    if not isinstance(src, dict):
        _fail(where, "source must be an object with " + ", ".join(REQUIRED_SOURCE))
    for k in REQUIRED_SOURCE:
        if not isinstance(src.get(k), str) or not src[k].strip():
            _fail(where, f"source.{k} is required (where the numbers come from)")
    cols = data.get("columns")
    if not isinstance(cols, dict) or len(cols) < 2:
        _fail(where, "columns must hold the abscissa and at least one curve")
    units = _units(where, data.get("units"))
    columns = {k: _column(where, k, c, units) for k, c in cols.items()}
    x = data.get("x")
    if not isinstance(x, str) or x not in columns:
        _fail(where, f"x = {x!r}: must name a column ({', '.join(columns)})")
    n = columns[x].size
    for k, v in columns.items():
        if v.size != n:
            _fail(where, f"columns.{k} has {v.size} values, columns.{x} has {n}")
    if np.any(np.diff(columns[x]) <= 0.0):
        i = int(np.argmax(np.diff(columns[x]) <= 0.0))
        _fail(where, f"columns.{x} must increase strictly (values {i} and {i + 1} do not)")
    return Curve(name=str(data.get("curve", where)), x=x, columns=columns, source=dict(src),
                 setup=dict(data.get("setup") or {}))


def load_curve(name: str | Path) -> Curve:
    """The digitised curve ``name`` (package data ``curve_<name>.json``), or a JSON file."""
    p = Path(name)
    if p.suffix == ".json" and p.exists():
        return curve_from_dict(json.loads(p.read_text(encoding="utf-8")), where=str(p))
    from ..validation_data import load

    names = available_curves()
    if name not in names:
        raise ValueError(f"curve {name!r}: no such digitised curve; available: "
                         f"{', '.join(names) or 'none yet'}")
    return curve_from_dict(load(PREFIX + str(name)), where=f"curve {name}")


def l2_difference(x, y, x_ref, y_ref, interval: tuple[float, float] | None = None
                  ) -> CurveDifference:
    """L2 difference of the piecewise-linear curve ``(x, y)`` from ``(x_ref, y_ref)``.

    Over the common interval of the two curves (narrowed to ``interval`` if given):
    both are interpolated linearly at the union of their sample points, and the
    square of their difference, a quadratic on every piece, is integrated exactly.
    Returns a :class:`CurveDifference`.
    """
    x, y, xr, yr = (np.asarray(a, dtype=float) for a in (x, y, x_ref, y_ref))
    lo, hi = max(x[0], xr[0]), min(x[-1], xr[-1])
    if interval is not None:
        lo, hi = max(lo, float(interval[0])), min(hi, float(interval[1]))
    if not hi > lo:
        raise ValueError(f"l2_difference: the curves share no interval (x in [{x[0]:g}, "
                         f"{x[-1]:g}] and [{xr[0]:g}, {xr[-1]:g}], interval {interval})")
    s = np.union1d(np.concatenate([x, xr]), [lo, hi])
    s = s[(s >= lo) & (s <= hi)]
    d = np.interp(s, x, y) - np.interp(s, xr, yr)
    r = np.interp(s, xr, yr)
    h = np.diff(s)
    sq = np.sum(h * (d[:-1] ** 2 + d[:-1] * d[1:] + d[1:] ** 2)) / 3.0
    ref = np.sum(h * (r[:-1] ** 2 + r[:-1] * r[1:] + r[1:] ** 2)) / 3.0
    return CurveDifference(l2=float(np.sqrt(sq / (hi - lo))),
                           relative=float(np.sqrt(sq / ref)) if ref > 0 else float("inf"),
                           max_abs=float(np.abs(d).max()), x0=float(lo), x1=float(hi))


def fall_positions(t, v, y0: float) -> np.ndarray:
    """Heights ``y(t) = y0 + int_0^t v`` from a velocity history (trapezoidal rule:
    exact for a piecewise-linear ``v``)."""
    t, v = np.asarray(t, dtype=float), np.asarray(v, dtype=float)
    return y0 + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])


def time_to_floor(t, y, y_stop: float) -> float:
    """The first time the height history ``y`` reaches ``y_stop`` (linear between samples).

    For a disk of radius ``a`` over a floor at ``y_floor``: ``y_stop = y_floor + a``
    (plus the gap at which it counts as landed). Raises ValueError if it never does.
    """
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    below = np.flatnonzero(y <= y_stop)
    if below.size == 0:
        raise ValueError(f"time_to_floor: the height never reaches {y_stop:g} (lowest "
                         f"{y.min():g} at t = {t[np.argmin(y)]:g})")
    k = int(below[0])
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (t[k] - t[k - 1]) * (y[k - 1] - y_stop) / (y[k - 1] - y[k]))


def time_down(t, v, fraction: float = 0.1) -> float:
    """When a settling particle is down: the first time after its largest speed that
    ``|v|`` falls to ``fraction`` of it (linear between samples); NaN if it never does."""
    t, s = np.asarray(t, dtype=float), np.abs(np.asarray(v, dtype=float))
    k = int(np.argmax(s))
    level = fraction * s[k]
    after = np.flatnonzero(s[k:] <= level)
    if after.size == 0:
        return float("nan")
    j = k + int(after[0])
    return float(t[j - 1] + (t[j] - t[j - 1]) * (s[j - 1] - level) / (s[j - 1] - s[j]))


def compare_settling(t, y, vy, curve: Curve, y_stop: float, y0: float | None = None,
                     column: str = "vy", fraction: float = 0.1, t0: float = 0.0) -> dict:
    """A settling run's velocity history against a digitised curve, over the fall.

    Parameters
    ----------
    t, y, vy : (T,) arrays
        The run's times, centre heights and vertical velocities.
    curve : Curve
        With the velocity column ``column`` (and optionally a height column ``y``).
    y_stop : float
        Height of the centre at which the particle counts as on the floor
        (:func:`time_to_floor`), the same for run and reference.
    y0 : float, optional
        Release height for the reference's heights when the curve has no ``y`` column
        (integrated from its velocities, :func:`fall_positions`); default ``y[0]``.
    fraction : float
        :func:`time_down`'s speed fraction.
    t0 : float
        Release time: a reference whose first sample is later is integrated from rest
        at ``t0`` (the particle is released at rest).

    Returns
    -------
    dict
        ``l2``, ``relative``, ``max_abs`` (:class:`CurveDifference` of the velocities
        over the fall: from the later start to the earlier :func:`time_down`),
        ``interval``, ``t_down`` and ``t_floor`` as ``{"run": ..., "reference": ...}``.
    """
    t, y, vy = (np.asarray(a, dtype=float) for a in (t, y, vy))
    t_ref, v_ref = curve.series(column)
    down = {"run": time_down(t, vy, fraction), "reference": time_down(t_ref, v_ref, fraction)}
    end = np.nanmin([down["run"], down["reference"], t[-1], t_ref[-1]])
    d = l2_difference(t, vy, t_ref, v_ref, interval=(-np.inf, end))
    if "y" in curve.columns:
        y_ref = curve.columns["y"]
    else:
        start = float(y[0] if y0 is None else y0)
        if t_ref[0] > t0:  # from rest at the release
            y_ref = fall_positions(np.r_[t0, t_ref], np.r_[0.0, v_ref], start)[1:]
        else:
            y_ref = fall_positions(t_ref, v_ref, start)
    floor = {}
    for key, (tt, yy) in {"run": (t, y), "reference": (t_ref, y_ref)}.items():
        try:
            floor[key] = time_to_floor(tt, yy, y_stop)
        except ValueError:
            floor[key] = float("nan")
    return {"l2": d.l2, "relative": d.relative, "max_abs": d.max_abs,
            "interval": (d.x0, d.x1), "t_down": down, "t_floor": floor}
