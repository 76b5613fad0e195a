"""Validators of scene values: each returns the checked value or raises a one-line ValueError."""

from __future__ import annotations

import math

import numpy as np

#: Largest length or coordinate of a scene (m): beyond, areas and inertias of the
#: polygons overflow long before a mesh could resolve anything.
MAX_LENGTH = 1e3
#: Largest initial angle of a particle (rad), either sign.
MAX_ANGLE = 1e3
#: Largest ``sides`` of a regular polygon (the paper's outlines have 24).
MAX_SIDES = 1000


def integer(where: str, name: str, value, lo: int, hi: int | None = None) -> int:
    """An integer (not a bool) in ``[lo, hi]``."""
    ok = isinstance(value, int) and not isinstance(value, bool) and value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        rng = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise ValueError(f"{where}.{name} = {value!r}: must be an integer {rng}")
    return value


def num(section, name, value, *, lo=None, hi=None, lo_open=True, allow_none=False):
    """A finite number in the range ``(lo, hi]`` (``[lo, hi]`` with ``lo_open=False``)."""
    full = f"{section}.{name}"
    if value is None and allow_none:
        return None
    rng = []
    if lo is not None:
        rng.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    msg = f"{full} = {value!r}: must be a finite number {' and '.join(rng)}".rstrip()
    if isinstance(value, bool):  # float(True) == 1.0: a boolean is a typo, not a number
        raise ValueError(msg)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(msg) from None
    ok = math.isfinite(x)
    if ok and lo is not None:
        ok = x > lo if lo_open else x >= lo
    if ok and hi is not None:
        ok = x <= hi
    if not ok:
        raise ValueError(msg)
    return x


def vec(section, name, value, n=2, bound=None):
    """``n`` finite numbers (within ``+-bound`` if given), as a tuple of floats."""
    within = "" if bound is None else f" within +-{bound:g}"
    msg = f"{section}.{name} = {value!r}: must be {n} finite numbers{within}"
    try:
        x = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(msg) from None
    if x.size != n or not np.all(np.isfinite(x)) or (
            bound is not None and np.any(np.abs(x) > bound)):
        raise ValueError(msg)
    return tuple(float(v) for v in x)


def check_keys(section: str, data: dict, allowed) -> None:
    """Refuse the first (sorted) key of ``data`` that is not in ``allowed``."""
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise ValueError(
            f"{section}: unknown key {unknown[0]!r}; allowed keys are {', '.join(sorted(allowed))}"
        )
